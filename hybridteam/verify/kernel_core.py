"""The compiled loop of the packed explorer (:mod:`.kernel`): numba functions over rows.

A state is one row of small unsigned integers (layout: :class:`~.kernel.Layout`): each
agent's part number, the copies in flight (``template * IDS + id``), the outbox entries
(``template * IDS + id``), the seen triples (``(receiver * agents + sender) * IDS + id``),
then cursor, losses, duplicates and the agents' next ids. Templates, parts and reactions
are numbered by the Python side (:mod:`.kernel`), which also fills whatever the loop does
not know (a reaction the engine has not computed, a state whose parts are not settled):
this module only follows the rules of :func:`~.explore.choices`,
:meth:`~.reactions.Reactions._compose` and :meth:`~.machine.Machine.canonical`, which stay
the reference semantics (``tests/verify/test_verify_kernel.py`` compares the graphs).

Every function is compiled once and cached on disk (``cache=True``): the first run of a
machine pays a few seconds of compilation, later runs load it.
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: Message ids per template (ids are renumbered 0.. per sender: a bit each in a uint64).
IDS = 64
#: Choice kinds, in a choice code's bits 40 and up (x: bits 20-39, y: bits 0-19).
DELIVER, LOSE, DUP, TIMER, SCENARIO, TIME, WORLD = range(7)
#: Copy templates' kinds: a plain message (no id), an acknowledged one (an id), an ack.
PLAIN, WITH_ID, ACK_COPY = 0, 1, 2
#: A sent copy's id: none, the choice's input id, the agent's next id plus an offset.
NO_ID, INPUT_ID, NEW_ID = 0, 1, 2
#: What a job or a pass ended with: done, a successor the tables do not know, a group
#: wider than the layout's slots, a message id beyond :data:`IDS`.
OK, MISS, OVERFLOW, TOO_MANY_IDS = 0, 1, 2, 3
#: Scratch room for a state's copies, entries and seen triples while it is composed.
ROOM = 256


@njit(cache=True)
def choice_code(kind: int, x: int, y: int) -> int:
    return (kind << 40) | (x << 20) | y


@njit(cache=True)
def row_hash(row: np.ndarray) -> np.uint64:
    h = np.uint64(1469598103934665603)
    for v in row:
        h = (h ^ np.uint64(v)) * np.uint64(1099511628211)
    return h ^ (h >> np.uint64(29))


@njit(cache=True)
def find_row(rows: np.ndarray, slots: np.ndarray, row: np.ndarray) -> tuple[int, int]:
    """``(number, -1)`` of a stored row equal to ``row``, or ``(-1, slot)`` where it goes."""
    mask = slots.size - 1
    i = np.int64(row_hash(row) & np.uint64(mask))
    w = row.size
    while True:
        k = slots[i]
        if k < 0:
            return -1, i
        same = True
        for j in range(w):
            if rows[k, j] != row[j]:
                same = False
                break
        if same:
            return k, -1
        i = (i + 1) & mask


@njit(cache=True)
def rehash(rows: np.ndarray, n: int, slots: np.ndarray) -> None:
    """Place rows ``0..n-1`` in an empty table ``slots``."""
    mask = slots.size - 1
    for k in range(n):
        i = np.int64(row_hash(rows[k]) & np.uint64(mask))
        while slots[i] >= 0:
            i = (i + 1) & mask
        slots[i] = k


@njit(cache=True)
def find_reaction(rk: np.ndarray, rslots: np.ndarray, inkey: int, part: int, tape: int) -> int:
    """The reaction numbered for ``(input, part, tape)``, or -1 (an open-addressing table
    over the rows of ``rk``: input key, part, tape, reaction)."""
    mask = rslots.size - 1
    h = np.uint64(inkey) * np.uint64(0x9E3779B97F4A7C15)
    h = (h ^ np.uint64(part)) * np.uint64(0xBF58476D1CE4E5B9)
    h = (h ^ np.uint64(tape)) * np.uint64(0x94D049BB133111EB)
    i = np.int64((h ^ (h >> np.uint64(31))) & np.uint64(mask))
    while True:
        r = rslots[i]
        if r < 0:
            return -1
        if rk[r, 0] == inkey and rk[r, 1] == part and rk[r, 2] == tape:
            return rk[r, 3]
        i = (i + 1) & mask


@njit(cache=True)
def place_reaction(rk: np.ndarray, rslots: np.ndarray, r: int) -> None:
    mask = rslots.size - 1
    h = np.uint64(rk[r, 0]) * np.uint64(0x9E3779B97F4A7C15)
    h = (h ^ np.uint64(rk[r, 1])) * np.uint64(0xBF58476D1CE4E5B9)
    h = (h ^ np.uint64(rk[r, 2])) * np.uint64(0x94D049BB133111EB)
    i = np.int64((h ^ (h >> np.uint64(31))) & np.uint64(mask))
    while rslots[i] >= 0:
        i = (i + 1) & mask
    rslots[i] = r


@njit(cache=True)
def _popcount(x: np.uint64) -> int:
    n = 0
    while x:
        x &= x - np.uint64(1)
        n += 1
    return n


@njit(cache=True)
def _rank(mask: np.uint64, k: int) -> int:
    return _popcount(mask & ((np.uint64(1) << np.uint64(k)) - np.uint64(1)))


class _State:
    """(documentation only) A decoded state in the loop's scratch arrays ``st``:
    st[0]: nc, no, ns, cursor, losses, dups; parts in ``ag``, next ids in ``nid``; copies
    ``ct``/``ci``; entries ``et``/``ei``; seen ``sr``/``ss``/``sk``."""


@njit(cache=True)
def decode(row, lay, ag, nid, ct, ci, et, ei, sr, ss, sk, head) -> None:
    """Unpack ``row`` (layout ``lay``: agents, copy slots, entry slots, seen slots) into
    the scratch arrays; ``head``: copies, entries, seen, cursor, losses, dups."""
    na, cs, os_, ss_ = lay[0], lay[1], lay[2], lay[3]
    for a in range(na):
        ag[a] = row[a]
    p = na
    nc = int(row[p])
    for i in range(nc):
        v = int(row[p + 1 + i])
        ct[i], ci[i] = v // IDS, v % IDS
    p += 1 + cs
    no = int(row[p])
    for i in range(no):
        v = int(row[p + 1 + i])
        et[i], ei[i] = v // IDS, v % IDS
    p += 1 + os_
    ns = int(row[p])
    for i in range(ns):
        v = int(row[p + 1 + i])
        sk[i] = v % IDS
        v //= IDS
        ss[i] = v % na
        sr[i] = v // na
    p += 1 + ss_
    head[0], head[1], head[2] = nc, no, ns
    head[3], head[4], head[5] = row[p], row[p + 1], row[p + 2]
    for a in range(na):
        nid[a] = row[p + 3 + a]


@njit(cache=True)
def choices(lay, tb, opt, ag, ct, ci, et, ei, sr, ss, sk, head, out) -> int:
    """The choice codes of a decoded state into ``out``, in the order of
    :func:`~.explore.choices`; their number."""
    (t_kind, t_snd, t_rcv, t_heard, t_key, t_field, t_link) = tb[0]
    (e_snd, e_wait, e_rest) = tb[1]
    (p_t0, p_tn, timed_j, timed_untimed, p_world, world_agent) = tb[2]
    fifo, bounded, timeouts, max_losses, max_dups, nscen = (
        opt[0],
        opt[1],
        opt[2],
        opt[3],
        opt[4],
        opt[5],
    )
    na = lay[0]
    nc, no, ns, cur, los, dup = head[0], head[1], head[2], head[3], head[4], head[5]
    n = 0
    # the arrivals: all copies, or the first on each link (fifo)
    quiet = -1
    for k in range(nc):
        if fifo:
            first = True
            for j in range(k):
                if t_link[ct[j]] == t_link[ct[k]]:
                    first = False
                    break
            if not first:
                continue
        if bounded and quiet < 0:
            t = ct[k]
            if t_kind[t] == ACK_COPY or t_heard[t] == 0:
                quiet = k
            elif t_kind[t] == WITH_ID:
                for j in range(ns):
                    if sr[j] == t_rcv[t] and ss[j] == t_snd[t] and sk[j] == ci[k]:
                        quiet = k
                        break
    if quiet >= 0:  # a copy no mode sees: only its fates
        out[n] = choice_code(DELIVER, quiet, 0)
        n += 1
        if los < max_losses:
            out[n] = choice_code(LOSE, quiet, 0)
            n += 1
        if dup < max_dups:
            out[n] = choice_code(DUP, quiet, 0)
            n += 1
        return n
    for k in range(nc):
        if fifo:
            first = True
            for j in range(k):
                if t_link[ct[j]] == t_link[ct[k]]:
                    first = False
                    break
            if not first:
                continue
        again = False  # an identical copy among the arrivals before it
        for j in range(k):
            if ct[j] == ct[k] and ci[j] == ci[k]:
                if fifo:
                    firstj = True
                    for i in range(j):
                        if t_link[ct[i]] == t_link[ct[j]]:
                            firstj = False
                            break
                    if not firstj:
                        continue
                again = True
                break
        if again:
            continue
        out[n] = choice_code(DELIVER, k, 0)
        n += 1
        if los < max_losses:
            out[n] = choice_code(LOSE, k, 0)
            n += 1
        if dup < max_dups:
            out[n] = choice_code(DUP, k, 0)
            n += 1
    for k in range(no):
        snd, mid = e_snd[et[k]], ei[k]
        flying = False
        if bounded:
            for j in range(nc):
                t = ct[j]
                if t_kind[t] == ACK_COPY:
                    if t_rcv[t] == snd and ci[j] == mid:
                        flying = True
                        break
                elif t_kind[t] == WITH_ID and t_snd[t] == snd and ci[j] == mid:
                    flying = True
                    break
        if not flying:
            out[n] = choice_code(TIMER, k, 0)
            n += 1
    if cur < nscen:
        out[n] = choice_code(SCENARIO, 0, 0)
        n += 1
    net_quiet = nc == 0 and no == 0
    for a in range(na):
        p = ag[a]
        if p_tn[p] == 0:
            continue
        settled = True
        if timeouts == 1:
            for j in range(nc):
                t = ct[j]
                if t_snd[t] == a and t_kind[t] != ACK_COPY:
                    settled = False
                    break
            for j in range(no):
                if e_snd[et[j]] == a:
                    settled = False
                    break
        for i in range(p_t0[p], p_t0[p] + p_tn[p]):
            if timeouts == 2:
                ok = net_quiet
            else:
                ok = settled
            if timeouts == 0 or timed_untimed[i] != 0 or ok:
                out[n] = choice_code(TIME, a, timed_j[i])
                n += 1
    for w in range(world_agent.size):
        if p_world[ag[world_agent[w]], w] != 0:
            out[n] = choice_code(WORLD, world_agent[w], w)
            n += 1
    return n


@njit(cache=True)
def canonical(lay, tb, fifo, nc, ct, ci, no, et, ei, ns, sr, ss, sk, nid, cnt) -> int:
    """:meth:`~.machine.Machine.canonical` in place on the scratch arrays: drop the acks
    no entry waits for and the filter entries no copy can match, renumber ids per sender,
    sort. ``cnt`` gets the new lengths (copies, entries, seen); returns OK or
    TOO_MANY_IDS."""
    (t_kind, t_snd, t_rcv, t_heard, t_key, t_field, t_link) = tb[0]
    (e_snd, e_wait, e_rest) = tb[1]
    na = lay[0]
    live = np.zeros(na, np.uint64)
    one = np.uint64(1)
    m = 0
    for i in range(nc):
        t, k = ct[i], ci[i]
        if k >= IDS:
            return TOO_MANY_IDS
        if t_kind[t] == ACK_COPY:
            snd, rcv = t_snd[t], t_rcv[t]
            waits = False
            for j in range(no):
                if e_snd[et[j]] == rcv and ei[j] == k and ((e_wait[et[j]] >> snd) & 1) != 0:
                    waits = True
                    break
            if not waits:
                continue
            live[rcv] |= one << np.uint64(k)
        elif t_kind[t] == WITH_ID:
            live[t_snd[t]] |= one << np.uint64(k)
        ct[m], ci[m] = t, k
        m += 1
    nc = m
    for j in range(no):
        if ei[j] >= IDS:
            return TOO_MANY_IDS
        live[e_snd[et[j]]] |= one << np.uint64(ei[j])
    m = 0
    for i in range(ns):
        r, s, k = sr[i], ss[i], sk[i]
        keep = False
        for j in range(nc):
            t = ct[j]
            if t_kind[t] == WITH_ID and t_snd[t] == s and t_rcv[t] == r and ci[j] == k:
                keep = True
                break
        if not keep:
            for j in range(no):
                if e_snd[et[j]] == s and ei[j] == k and ((e_wait[et[j]] >> r) & 1) != 0:
                    keep = True
                    break
        if keep:
            dupe = False
            for j in range(m):
                if sr[j] == r and ss[j] == s and sk[j] == k:
                    dupe = True
                    break
            if not dupe:
                sr[m], ss[m], sk[m] = r, s, k
                m += 1
                live[s] |= one << np.uint64(k)
    ns = m
    for a in range(na):
        nid[a] = _popcount(live[a])
    # renumber
    for i in range(nc):
        t = ct[i]
        if t_kind[t] == ACK_COPY:
            ci[i] = _rank(live[t_rcv[t]], ci[i])
        elif t_kind[t] == WITH_ID:
            ci[i] = _rank(live[t_snd[t]], ci[i])
    for j in range(no):
        ei[j] = _rank(live[e_snd[et[j]]], ei[j])
    for i in range(ns):
        sk[i] = _rank(live[ss[i]], sk[i])
    # sort the copies: by the Copy tuple, or (fifo) stably by link
    for i in range(1, nc):
        t, k = ct[i], ci[i]
        if fifo:
            key = t_link[t]
        elif t_kind[t] == ACK_COPY:
            key = (t_key[t] << 32) | k
        elif t_kind[t] == WITH_ID:
            key = (t_key[t] << 32) | ((k + 1) << 24) | t_field[t]
        else:
            key = (t_key[t] << 32) | t_field[t]
        j = i - 1
        while j >= 0:
            u, v = ct[j], ci[j]
            if fifo:
                kj = t_link[u]
            elif t_kind[u] == ACK_COPY:
                kj = (t_key[u] << 32) | v
            elif t_kind[u] == WITH_ID:
                kj = (t_key[u] << 32) | ((v + 1) << 24) | t_field[u]
            else:
                kj = (t_key[u] << 32) | t_field[u]
            if kj <= key:
                break
            ct[j + 1], ci[j + 1] = u, v
            j -= 1
        ct[j + 1], ci[j + 1] = t, k
    for i in range(1, no):
        t, k = et[i], ei[i]
        key = (e_snd[t] << 48) | (k << 40) | e_rest[t]
        j = i - 1
        while j >= 0 and ((e_snd[et[j]] << 48) | (ei[j] << 40) | e_rest[et[j]]) > key:
            et[j + 1], ei[j + 1] = et[j], ei[j]
            j -= 1
        et[j + 1], ei[j + 1] = t, k
    for i in range(1, ns):
        r, s, k = sr[i], ss[i], sk[i]
        key = (r * na + s) * IDS + k
        j = i - 1
        while j >= 0 and (sr[j] * na + ss[j]) * IDS + sk[j] > key:
            sr[j + 1], ss[j + 1], sk[j + 1] = sr[j], ss[j], sk[j]
            j -= 1
        sr[j + 1], ss[j + 1], sk[j + 1] = r, s, k
    cnt[0], cnt[1], cnt[2] = nc, no, ns
    return OK


@njit(cache=True)
def encode(lay, out, ag, nid, nc, ct, ci, no, et, ei, ns, sr, ss, sk, cur, los, dup) -> int:
    """Pack a canonical state into ``out`` (zeroed first); OVERFLOW when a group does not
    fit its slots."""
    na, cs, os_, ss_ = lay[0], lay[1], lay[2], lay[3]
    if nc > cs or no > os_ or ns > ss_:
        return OVERFLOW
    out[:] = 0
    for a in range(na):
        out[a] = ag[a]
    p = na
    out[p] = nc
    for i in range(nc):
        out[p + 1 + i] = ct[i] * IDS + ci[i]
    p += 1 + cs
    out[p] = no
    for i in range(no):
        out[p + 1 + i] = et[i] * IDS + ei[i]
    p += 1 + os_
    out[p] = ns
    for i in range(ns):
        out[p + 1 + i] = (sr[i] * na + ss[i]) * IDS + sk[i]
    p += 1 + ss_
    out[p], out[p + 1], out[p + 2] = cur, los, dup
    for a in range(na):
        out[p + 3 + a] = nid[a]
    return OK


@njit(cache=True)
def successor(lay, tb, rt, opt, settled, code, tape, ag, nid, ct, ci, et, ei, sr, ss, sk, head,
              w_ag, w_ct, w_ci, w_et, w_ei, w_sr, w_ss, w_sk, w_nid, cnt, out, res) -> int:
    """The successor of the decoded state by choice ``code`` with oracle tape ``tape``
    into ``out``; ``res`` gets (zeno, reads). MISS when the reaction is not in the table
    (or the state is not settled), OVERFLOW when it does not fit the layout."""
    (t_kind, t_snd, t_rcv, t_heard, t_key, t_field, t_link) = tb[0]
    (e_snd, e_wait, e_rest) = tb[1]
    scen_agent = tb[3]
    (rk, rslots, r_part, r_zeno, r_reads, r_c0, r_cn, rc_tmpl, rc_how, rc_off, r_kept,
     r_e0, r_en, re_tmpl, re_off, r_filtered) = rt
    fifo = opt[0]
    na = lay[0]
    nc, no, ns, cur, los, dup = head[0], head[1], head[2], head[3], head[4], head[5]
    kind, x, y = code >> 40, (code >> 20) & 0xFFFFF, code & 0xFFFFF
    for a in range(na):
        w_ag[a] = ag[a]
    m = 0
    for i in range(nc):
        w_ct[m], w_ci[m] = ct[i], ci[i]
        m += 1
    for j in range(no):
        w_et[j], w_ei[j] = et[j], ei[j]
    for j in range(ns):
        w_sr[j], w_ss[j], w_sk[j] = sr[j], ss[j], sk[j]
    res[0], res[1] = 0, 0
    if kind == LOSE or kind == DUP:
        if kind == LOSE:
            for i in range(x, nc - 1):
                w_ct[i], w_ci[i] = w_ct[i + 1], w_ci[i + 1]
            m = nc - 1
            los += 1
        else:
            w_ct[nc], w_ci[nc] = ct[x], ci[x]
            m = nc + 1
            dup += 1
        got = canonical(lay, tb, fifo, m, w_ct, w_ci, no, w_et, w_ei, ns, w_sr, w_ss, w_sk,
                        w_nid, cnt)
        if got != OK:
            return got
        return encode(lay, out, w_ag, w_nid, cnt[0], w_ct, w_ci, cnt[1], w_et, w_ei, cnt[2],
                      w_sr, w_ss, w_sk, cur, los, dup)
    for a in range(na):
        if settled[ag[a]] == 0:
            return MISS
    touched = -1
    k_in = -1
    sender = -1
    if kind == DELIVER:
        t = ct[x]
        a = t_rcv[t]
        sender = t_snd[t]
        if t_kind[t] == ACK_COPY:
            k_in = ci[x]
            etm = -1
            for j in range(no):
                if e_snd[et[j]] == a and ei[j] == k_in:
                    touched, etm = j, et[j]
                    break
            inkey = choice_code(1, t, etm + 1)
        else:
            held = 0
            if t_kind[t] == WITH_ID:
                k_in = ci[x]
                for j in range(ns):
                    if sr[j] == a and ss[j] == sender and sk[j] == k_in:
                        held = 1
                        break
            inkey = choice_code(0, t, held)
    elif kind == TIMER:
        a = e_snd[et[x]]
        k_in = ei[x]
        touched = x
        inkey = choice_code(2, et[x], 0)
    elif kind == SCENARIO:
        a = scen_agent[cur]
        inkey = choice_code(3, cur, 0)
    elif kind == TIME:
        a = x
        inkey = choice_code(4, x, y)
    else:
        a = x
        inkey = choice_code(5, y, 0)
    r = find_reaction(rk, rslots, inkey, ag[a], tape)
    if r < 0:
        return MISS
    base = nid[a]
    if kind == DELIVER:
        for i in range(x, nc - 1):
            w_ct[i], w_ci[i] = w_ct[i + 1], w_ci[i + 1]
        m = nc - 1
    for i in range(r_c0[r], r_c0[r] + r_cn[r]):
        t = rc_tmpl[i]
        if m >= ROOM:
            return OVERFLOW
        w_ct[m] = t
        if t_kind[t] == PLAIN:
            w_ci[m] = 0
        elif t_kind[t] == ACK_COPY or rc_how[i] == INPUT_ID:
            w_ci[m] = k_in
        else:
            w_ci[m] = base + rc_off[i]
        m += 1
    mo = no
    if touched >= 0:
        for j in range(touched, no - 1):
            w_et[j], w_ei[j] = w_et[j + 1], w_ei[j + 1]
        mo = no - 1
        if r_kept[r] >= 0:
            w_et[mo], w_ei[mo] = r_kept[r], k_in
            mo += 1
    for i in range(r_e0[r], r_e0[r] + r_en[r]):
        if mo >= ROOM:
            return OVERFLOW
        w_et[mo], w_ei[mo] = re_tmpl[i], base + re_off[i]
        mo += 1
    ms = ns
    if r_filtered[r] != 0:
        w_sr[ms], w_ss[ms], w_sk[ms] = a, sender, k_in
        ms += 1
    w_ag[a] = r_part[r]
    if kind == SCENARIO:
        cur += 1
    res[0], res[1] = r_zeno[r], r_reads[r]
    got = canonical(lay, tb, fifo, m, w_ct, w_ci, mo, w_et, w_ei, ms, w_sr, w_ss, w_sk, w_nid,
                    cnt)
    if got != OK:
        return got
    return encode(lay, out, w_ag, w_nid, cnt[0], w_ct, w_ci, cnt[1], w_et, w_ei, cnt[2],
                  w_sr, w_ss, w_sk, cur, los, dup)


@njit(cache=True)
def level(rows, n, lo, hi, slots, lay, tb, rt, opt, settled, pre_ord, pre_rows, pre_res,
          apply, max_states, new_parent, e_src, e_dst, e_how, zeno, cut, misses):
    """One breadth-first level: the jobs of states ``lo..hi-1`` in the order of
    :func:`~.explore._jobs`, then the free comparisons' retries in the order of
    :func:`~.explore._chunks`. A job numbered in ``pre_ord`` takes its successor from
    ``pre_rows``/``pre_res`` (computed in Python), any other from the tables.

    ``apply`` False (a dry pass): only find the jobs the tables cannot answer, into
    ``misses`` (ordinal, state, choice, tape); after the first miss no further retry is
    queued (its position would depend on the miss's reads). ``apply`` True: number the
    new states (appended to ``rows`` from ``n``), record parents, edges, Zeno and cut
    states. Returns (status, jobs, new n, edges, zeno, cut, misses)."""
    na = lay[0]
    w = rows.shape[1]
    ag = np.zeros(na, np.int64)
    nid = np.zeros(na, np.int64)
    w_ag = np.zeros(na, np.int64)
    w_nid = np.zeros(na, np.int64)
    ct = np.zeros(ROOM, np.int64)
    ci = np.zeros(ROOM, np.int64)
    et = np.zeros(ROOM, np.int64)
    ei = np.zeros(ROOM, np.int64)
    sr = np.zeros(ROOM, np.int64)
    ss = np.zeros(ROOM, np.int64)
    sk = np.zeros(ROOM, np.int64)
    w_ct = np.zeros(ROOM, np.int64)
    w_ci = np.zeros(ROOM, np.int64)
    w_et = np.zeros(ROOM, np.int64)
    w_ei = np.zeros(ROOM, np.int64)
    w_sr = np.zeros(ROOM, np.int64)
    w_ss = np.zeros(ROOM, np.int64)
    w_sk = np.zeros(ROOM, np.int64)
    head = np.zeros(6, np.int64)
    cnt = np.zeros(3, np.int64)
    res = np.zeros(2, np.int64)
    codes = np.zeros(4 * ROOM, np.int64)
    out = np.zeros(w, rows.dtype)
    q_sid = [np.int64(0)]
    q_code = [np.int64(0)]
    q_tape = [np.int64(0)]
    q_sid.pop()
    q_code.pop()
    q_tape.pop()
    ordinal = 0
    pre = 0
    ne = 0
    nz = 0
    nx = 0
    nm = 0
    frozen = False
    sid = lo
    nchoice = 0
    ci_at = 0
    qi = 0
    decoded = -1
    status = OK
    while True:
        # the next job: the level's, then the queued retries
        if sid < hi:
            if ci_at == 0:
                decode(rows[sid], lay, ag, nid, ct, ci, et, ei, sr, ss, sk, head)
                decoded = sid
                nchoice = choices(lay, tb, opt, ag, ct, ci, et, ei, sr, ss, sk, head, codes)
            if ci_at >= nchoice:
                sid += 1
                ci_at = 0
                continue
            j_sid, j_code, j_tape = sid, codes[ci_at], 1
            ci_at += 1
        elif qi < len(q_sid):
            j_sid, j_code, j_tape = q_sid[qi], q_code[qi], q_tape[qi]
            qi += 1
            if decoded != j_sid:
                decode(rows[j_sid], lay, ag, nid, ct, ci, et, ei, sr, ss, sk, head)
                decoded = j_sid
        else:
            break
        while pre < pre_ord.size and pre_ord[pre] < ordinal:
            pre += 1
        if pre < pre_ord.size and pre_ord[pre] == ordinal:
            out[:] = pre_rows[pre]
            res[0], res[1] = pre_res[pre, 0], pre_res[pre, 1]
            got = OK
        else:
            got = successor(lay, tb, rt, opt, settled, j_code, j_tape, ag, nid, ct, ci, et, ei,
                            sr, ss, sk, head, w_ag, w_ct, w_ci, w_et, w_ei, w_sr, w_ss, w_sk,
                            w_nid, cnt, out, res)
        ordinal += 1
        if got == OVERFLOW or got == TOO_MANY_IDS:
            return got, ordinal, n, ne, nz, nx, nm
        if got == MISS:
            if apply:
                return MISS, ordinal, n, ne, nz, nx, nm
            if nm < misses.shape[0]:
                misses[nm, 0], misses[nm, 1] = ordinal - 1, j_sid
                misses[nm, 2], misses[nm, 3] = j_code, j_tape
                nm += 1
            frozen = True
            continue
        # the other answers of the free comparisons it read, after the level's jobs
        length = 0
        while (j_tape >> (length + 1)) != 0:
            length += 1
        if not frozen:
            bits = j_tape & ((1 << length) - 1)
            for k in range(length, res[1]):
                q_sid.append(j_sid)
                q_code.append(j_code)
                q_tape.append((1 << (k + 1)) | bits | (1 << k))
        if not apply:
            continue
        k, slot = find_row(rows, slots, out)
        if k < 0:
            if n >= max_states:
                cut[nx] = j_sid
                nx += 1
                continue
            rows[n] = out
            slots[slot] = n
            new_parent[n] = j_sid
            k = n
            n += 1
        if res[0] != 0:
            zeno[nz] = k
            nz += 1
        if k != j_sid:
            e_src[ne], e_dst[ne], e_how[ne] = j_sid, k, j_code
            ne += 1
    return status, ordinal, n, ne, nz, nx, nm
