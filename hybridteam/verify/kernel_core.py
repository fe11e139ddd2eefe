"""The compiled loop of the packed explorer (:mod:`.kernel`): numba functions over rows.

A state is one row of small unsigned integers (layout: :class:`~.kernel.Layout`): each
agent's part number, the copies in flight (``template * IDS + id``), the outbox entries
(``template * IDS + id``), the seen triples (``(receiver * agents + sender) * IDS + id``),
each plus one (0: an empty slot), then cursor, losses and duplicates. A stored state is
that row collapsed (:class:`~.kernel.PackedStore`): its :data:`GROUPS` groups' numbers in
a key of a few bytes, each group's distinct sub-rows in a table of their own
(:func:`intern`, :func:`expand`). Templates, parts and reactions
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
#: wider than the layout's slots, a message id beyond :data:`IDS`, a collapsed group with
#: more sub-rows than its bytes in a key can number, an array of :func:`commit` full.
OK, MISS, OVERFLOW, TOO_MANY_IDS, GROUP_FULL, FULL = 0, 1, 2, 3, 4, 5
#: Scratch room for a state's copies, entries and seen triples while it is composed.
ROOM = 256
#: A stored state's collapsed groups (:func:`group_bounds`).
GROUPS = 4


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
    return find_sub(rows, slots, row, 0, row.size)


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
def group_bounds(lay) -> np.ndarray:
    """Where a row's collapsed groups start and end (:data:`GROUPS` + 1 columns): the
    agents' parts, the copies, the entries, and the seen triples with the counters."""
    na, cs, os_, ss_ = lay[0], lay[1], lay[2], lay[3]
    return np.array([0, na, na + cs, na + cs + os_, na + cs + os_ + ss_ + 3], np.int64)


@njit(cache=True)
def key_offsets(kw) -> np.ndarray:
    """Where each group's number starts in a key, from the groups' widths in bytes."""
    koff = np.zeros(GROUPS, np.int64)
    for g in range(1, GROUPS):
        koff[g] = koff[g - 1] + kw[g - 1]
    return koff


@njit(cache=True, inline="always")
def key_number(key, at, width) -> int:
    """The group number kept in ``width`` bytes of ``key`` from ``at`` (little-endian)."""
    v = 0
    for i in range(width):
        v |= int(key[at + i]) << (8 * i)
    return v


@njit(cache=True, inline="always")
def expand(key, GT, gb, koff, kw, row, nums) -> None:
    """The wide row of a stored state: each group's sub-row, from its number in ``key``
    (into ``nums``)."""
    for g in range(GROUPS):
        table = GT[g]
        k = key_number(key, koff[g], kw[g])
        nums[g] = k
        for j in range(gb[g], gb[g + 1]):
            row[j] = table[k, j - gb[g]]


@njit(cache=True, inline="always")
def find_sub(table, slots, row, lo, hi) -> tuple[int, int]:
    """``(number, -1)`` of the stored row of ``table`` equal to the sub-row ``row[lo:hi]``,
    or ``(-1, slot)`` where it goes (the same hash as :func:`row_hash` of a table row,
    without a slice of ``row``; :func:`find_row` is the whole row's case)."""
    h = np.uint64(1469598103934665603)
    for j in range(lo, hi):
        h = (h ^ np.uint64(row[j])) * np.uint64(1099511628211)
    h = h ^ (h >> np.uint64(29))
    mask = slots.size - 1
    i = np.int64(h & np.uint64(mask))
    while True:
        k = slots[i]
        if k < 0:
            return -1, int(i)
        same = True
        for j in range(lo, hi):
            if table[k, j - lo] != row[j]:
                same = False
                break
        if same:
            return int(k), -1
        i = (i + 1) & mask


@njit(cache=True)
def _put(arrays, g, a):
    """The tuple ``arrays`` with ``a`` in place ``g`` (a group's grown table)."""
    if g == 0:
        return (a, arrays[1], arrays[2], arrays[3])
    if g == 1:
        return (arrays[0], a, arrays[2], arrays[3])
    if g == 2:
        return (arrays[0], arrays[1], a, arrays[3])
    return (arrays[0], arrays[1], arrays[2], a)


@njit(cache=True, inline="always")
def intern(
    keys, n, slots, GT, GS, counts, gb, koff, kw, row, gi, key, room, prev, pn
) -> tuple[int, int]:
    """The number of the state whose wide row is ``row``: ``(k, 0)`` when stored; else,
    with ``room``, its groups numbered (each new sub-row appended to its group's table)
    and it stored as state ``n``: ``(n, 1)``; without room ``(-1, 0)``; ``(-2, g)`` when
    group ``g`` has more sub-rows than its bytes in a key can number (the state not
    stored, sub-rows of the groups before it perhaps: the caller widens the keys and
    asks again, which finds those); ``(-3, g)`` when group
    ``g``'s tables are full (the caller grows them, :func:`grow`, and asks again).
    ``prev``: the row of the state it succeeds, its groups' numbers ``pn`` (-1: none): a
    group a step left as it was is not looked up (most steps change one or two)."""
    fresh = False
    for g in range(GROUPS):
        if pn[g] >= 0:
            same = True
            for j in range(gb[g], gb[g + 1]):
                if row[j] != prev[j]:
                    same = False
                    break
            if same:
                gi[g] = pn[g]
                continue
        i, _ = find_sub(GT[g], GS[g], row, gb[g], gb[g + 1])
        gi[g] = i
        if i < 0:
            fresh = True  # (a sub-row never seen: a state never seen)
    if fresh:
        if not room:
            return -1, 0
        for g in range(GROUPS):
            if gi[g] >= 0:
                continue
            c = counts[g]
            if c >> (8 * kw[g]) != 0:
                return -2, g
            table, places = GT[g], GS[g]
            if c >= table.shape[0] or 10 * (c + 1) > 7 * places.size:
                return -3, g
            for j in range(gb[g], gb[g + 1]):
                table[c, j - gb[g]] = row[j]
            _, s = find_sub(table, places, row, gb[g], gb[g + 1])
            places[s] = c
            counts[g] = c + 1
            gi[g] = c
    for g in range(GROUPS):
        v = gi[g]
        for i in range(kw[g]):
            key[koff[g] + i] = (v >> (8 * i)) & 0xFF
    k, s = find_row(keys, slots, key)
    if k >= 0:
        return k, 0
    if not room:
        return -1, 0
    keys[n] = key
    slots[s] = n
    return n, 1


@njit(cache=True)
def grow(GT, GS, counts, g):
    """Group ``g``'s tables grown: its table of sub-rows by a quarter when it is full (a
    few groups hold tens of millions of sub-rows: doubling would leave half of that
    unused), their lookup table twice the size when it is 70 % full: the tuples with the
    new ones."""
    c = counts[g]
    table, places = GT[g], GS[g]
    if c >= table.shape[0]:
        table = np.zeros(
            (table.shape[0] + max(table.shape[0] // 4, 16), table.shape[1]), table.dtype
        )
        table[:c] = GT[g][:c]
    if 10 * (c + 1) > 7 * places.size:
        places = np.full(2 * places.size, -1, places.dtype)
        rehash(table, c, places)
    return _put(GT, g, table), _put(GS, g, places)


@njit(cache=True)
def regroup(GT, GS, counts) -> None:
    """Each group's table of sub-row numbers built again over its first ``counts``."""
    for g in range(GROUPS):
        GS[g][:] = -1
        rehash(GT[g], counts[g], GS[g])


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


@njit(cache=True)
def decode(row, lay, TT, EN, D, head, live) -> None:
    """Unpack ``row`` (layout ``lay``: agents, copy slots, entry slots, seen slots, each
    number stored plus one, 0 an empty slot) into ``D``'s rows: 0 the agents' parts, 1
    their next ids, 2-3 the copies' templates and ids, 4-5 the entries' templates and
    ids, 6-8 the seen triples (receiver, sender, id); ``head``: copies, entries, seen,
    cursor, losses, dups. A canonical state's next ids are not stored: an agent's is the
    number of its ids in use (they are 0..n-1)."""
    na, cs, os_, ss_ = lay[0], lay[1], lay[2], lay[3]
    live[:] = 0
    one = np.uint64(1)
    for a in range(na):
        D[0, a] = row[a]
    p = na
    nc = 0
    while nc < cs and row[p + nc] != 0:
        v = int(row[p + nc]) - 1
        t, k = v // IDS, v % IDS
        D[2, nc], D[3, nc] = t, k
        if TT[0, t] == ACK_COPY:
            live[TT[2, t]] |= one << np.uint64(k)
        elif TT[0, t] == WITH_ID:
            live[TT[1, t]] |= one << np.uint64(k)
        nc += 1
    p += cs
    no = 0
    while no < os_ and row[p + no] != 0:
        v = int(row[p + no]) - 1
        t, k = v // IDS, v % IDS
        D[4, no], D[5, no] = t, k
        live[EN[0, t]] |= one << np.uint64(k)
        no += 1
    p += os_
    ns = 0
    while ns < ss_ and row[p + ns] != 0:
        v = int(row[p + ns]) - 1
        k = v % IDS
        v //= IDS
        D[8, ns], D[7, ns], D[6, ns] = k, v % na, v // na
        live[v % na] |= one << np.uint64(k)
        ns += 1
    p += ss_
    head[0], head[1], head[2] = nc, no, ns
    head[3], head[4], head[5] = row[p], row[p + 1], row[p + 2]
    for a in range(na):
        D[1, a] = _popcount(live[a])


@njit(cache=True)
def choices(lay, TT, EN, PT, TJ, PW, WA, opt, D, head, out) -> int:
    """The choice codes of a decoded state into ``out``, in the order of
    :func:`~.explore.choices`; their number."""
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
                if TT[6, D[2, j]] == TT[6, D[2, k]]:
                    first = False
                    break
            if not first:
                continue
        if bounded and quiet < 0:
            t = D[2, k]
            if TT[0, t] == ACK_COPY or TT[3, t] == 0:
                quiet = k
            elif TT[0, t] == WITH_ID:
                for j in range(ns):
                    if D[6, j] == TT[2, t] and D[7, j] == TT[1, t] and D[8, j] == D[3, k]:
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
                if TT[6, D[2, j]] == TT[6, D[2, k]]:
                    first = False
                    break
            if not first:
                continue
        again = False  # an identical copy among the arrivals before it
        for j in range(k):
            if D[2, j] == D[2, k] and D[3, j] == D[3, k]:
                if fifo:
                    firstj = True
                    for i in range(j):
                        if TT[6, D[2, i]] == TT[6, D[2, j]]:
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
        snd, mid = EN[0, D[4, k]], D[5, k]
        flying = False
        if bounded:
            for j in range(nc):
                t = D[2, j]
                if TT[0, t] == ACK_COPY:
                    if TT[2, t] == snd and D[3, j] == mid:
                        flying = True
                        break
                elif TT[0, t] == WITH_ID and TT[1, t] == snd and D[3, j] == mid:
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
        p = D[0, a]
        if PT[1, p] == 0:
            continue
        settled = True
        if timeouts == 1:
            for j in range(nc):
                t = D[2, j]
                if TT[1, t] == a and TT[0, t] != ACK_COPY:
                    settled = False
                    break
            for j in range(no):
                if EN[0, D[4, j]] == a:
                    settled = False
                    break
        for i in range(PT[0, p], PT[0, p] + PT[1, p]):
            if timeouts == 2:
                ok = net_quiet
            else:
                ok = settled
            if timeouts == 0 or TJ[1, i] != 0 or ok:
                out[n] = choice_code(TIME, a, TJ[0, i])
                n += 1
    for w in range(WA.size):
        if PW[D[0, WA[w]], w] != 0:
            out[n] = choice_code(WORLD, WA[w], w)
            n += 1
    return n


@njit(cache=True)
def canonical(lay, TT, EN, fifo, nc, D, no, ns, cnt, live) -> int:
    """:meth:`~.machine.Machine.canonical` in place on the scratch arrays: drop the acks
    no entry waits for and the filter entries no copy can match, renumber ids per sender,
    sort. ``cnt`` gets the new lengths (copies, entries, seen); returns OK or
    TOO_MANY_IDS."""
    na = lay[0]
    live[:] = 0
    one = np.uint64(1)
    m = 0
    for i in range(nc):
        t, k = D[2, i], D[3, i]
        if k >= IDS:
            return TOO_MANY_IDS
        if TT[0, t] == ACK_COPY:
            snd, rcv = TT[1, t], TT[2, t]
            waits = False
            for j in range(no):
                if EN[0, D[4, j]] == rcv and D[5, j] == k and ((EN[1, D[4, j]] >> snd) & 1) != 0:
                    waits = True
                    break
            if not waits:
                continue
            live[rcv] |= one << np.uint64(k)
        elif TT[0, t] == WITH_ID:
            live[TT[1, t]] |= one << np.uint64(k)
        D[2, m], D[3, m] = t, k
        m += 1
    nc = m
    for j in range(no):
        if D[5, j] >= IDS:
            return TOO_MANY_IDS
        live[EN[0, D[4, j]]] |= one << np.uint64(D[5, j])
    m = 0
    for i in range(ns):
        r, s, k = D[6, i], D[7, i], D[8, i]
        keep = False
        for j in range(nc):
            t = D[2, j]
            if TT[0, t] == WITH_ID and TT[1, t] == s and TT[2, t] == r and D[3, j] == k:
                keep = True
                break
        if not keep:
            for j in range(no):
                if EN[0, D[4, j]] == s and D[5, j] == k and ((EN[1, D[4, j]] >> r) & 1) != 0:
                    keep = True
                    break
        if keep:
            dupe = False
            for j in range(m):
                if D[6, j] == r and D[7, j] == s and D[8, j] == k:
                    dupe = True
                    break
            if not dupe:
                D[6, m], D[7, m], D[8, m] = r, s, k
                m += 1
                live[s] |= one << np.uint64(k)
    ns = m
    for a in range(na):
        D[1, a] = _popcount(live[a])
    # renumber
    for i in range(nc):
        t = D[2, i]
        if TT[0, t] == ACK_COPY:
            D[3, i] = _rank(live[TT[2, t]], D[3, i])
        elif TT[0, t] == WITH_ID:
            D[3, i] = _rank(live[TT[1, t]], D[3, i])
    for j in range(no):
        D[5, j] = _rank(live[EN[0, D[4, j]]], D[5, j])
    for i in range(ns):
        D[8, i] = _rank(live[D[7, i]], D[8, i])
    # sort the copies: by the Copy tuple, or (fifo) stably by link
    for i in range(1, nc):
        t, k = D[2, i], D[3, i]
        if fifo:
            key = TT[6, t]
        elif TT[0, t] == ACK_COPY:
            key = (TT[4, t] << 32) | k
        elif TT[0, t] == WITH_ID:
            key = (TT[4, t] << 32) | ((k + 1) << 24) | TT[5, t]
        else:
            key = (TT[4, t] << 32) | TT[5, t]
        j = i - 1
        while j >= 0:
            u, v = D[2, j], D[3, j]
            if fifo:
                kj = TT[6, u]
            elif TT[0, u] == ACK_COPY:
                kj = (TT[4, u] << 32) | v
            elif TT[0, u] == WITH_ID:
                kj = (TT[4, u] << 32) | ((v + 1) << 24) | TT[5, u]
            else:
                kj = (TT[4, u] << 32) | TT[5, u]
            if kj <= key:
                break
            D[2, j + 1], D[3, j + 1] = u, v
            j -= 1
        D[2, j + 1], D[3, j + 1] = t, k
    for i in range(1, no):
        t, k = D[4, i], D[5, i]
        key = (EN[0, t] << 48) | (k << 40) | EN[2, t]
        j = i - 1
        while j >= 0 and ((EN[0, D[4, j]] << 48) | (D[5, j] << 40) | EN[2, D[4, j]]) > key:
            D[4, j + 1], D[5, j + 1] = D[4, j], D[5, j]
            j -= 1
        D[4, j + 1], D[5, j + 1] = t, k
    for i in range(1, ns):
        r, s, k = D[6, i], D[7, i], D[8, i]
        key = (r * na + s) * IDS + k
        j = i - 1
        while j >= 0 and (D[6, j] * na + D[7, j]) * IDS + D[8, j] > key:
            D[6, j + 1], D[7, j + 1], D[8, j + 1] = D[6, j], D[7, j], D[8, j]
            j -= 1
        D[6, j + 1], D[7, j + 1], D[8, j + 1] = r, s, k
    cnt[0], cnt[1], cnt[2] = nc, no, ns
    return OK


@njit(cache=True)
def encode(lay, out, D, nc, no, ns, cur, los, dup) -> int:
    """Pack a canonical state into ``out`` (the layout of :func:`decode`); OVERFLOW when
    a group does not fit its slots."""
    na, cs, os_, ss_ = lay[0], lay[1], lay[2], lay[3]
    if nc > cs or no > os_ or ns > ss_:  # (the counts are in ``cnt``)
        return OVERFLOW
    out[:] = 0
    for a in range(na):
        out[a] = D[0, a]
    p = na
    for i in range(nc):
        out[p + i] = D[2, i] * IDS + D[3, i] + 1
    p += cs
    for i in range(no):
        out[p + i] = D[4, i] * IDS + D[5, i] + 1
    p += os_
    for i in range(ns):
        out[p + i] = (D[6, i] * na + D[7, i]) * IDS + D[8, i] + 1
    p += ss_
    out[p], out[p + 1], out[p + 2] = cur, los, dup
    return OK


@njit(cache=True)
def _copy(D, Wk, na, nc, no, ns) -> None:
    """The decoded state into the successor's rows, to be changed there."""
    Wk[0, :na] = D[0, :na]
    Wk[2:4, :nc] = D[2:4, :nc]
    Wk[4:6, :no] = D[4:6, :no]
    Wk[6:9, :ns] = D[6:9, :ns]


@njit(cache=True)
def successor(
    lay,
    TT,
    EN,
    SA,
    RK,
    RS,
    RR,
    RC,
    RE,
    opt,
    settled,
    code,
    tape,
    D,
    head,
    Wk,
    cnt,
    live,
    out,
    res,
) -> int:
    """The successor of the decoded state by choice ``code`` with oracle tape ``tape``
    into ``out``; ``res`` gets (zeno, reads). MISS when the reaction is not in the table
    (or the state is not settled), OVERFLOW when it does not fit the layout."""
    fifo = opt[0]
    na = lay[0]
    nc, no, ns, cur, los, dup = head[0], head[1], head[2], head[3], head[4], head[5]
    kind, x, y = code >> 40, (code >> 20) & 0xFFFFF, code & 0xFFFFF
    res[0], res[1] = 0, 0
    if LOSE <= kind <= DUP:
        _copy(D, Wk, na, nc, no, ns)
        if kind == LOSE:
            for i in range(x, nc - 1):
                Wk[2, i], Wk[3, i] = Wk[2, i + 1], Wk[3, i + 1]
            m = nc - 1
            los += 1
        else:
            Wk[2, nc], Wk[3, nc] = D[2, x], D[3, x]
            m = nc + 1
            dup += 1
        got = canonical(lay, TT, EN, fifo, m, Wk, no, ns, cnt, live)
        if got != OK:
            return got
        return encode(lay, out, Wk, cnt[0], cnt[1], cnt[2], cur, los, dup)
    for a in range(na):
        if settled[D[0, a]] == 0:
            return MISS
    touched = -1
    k_in = -1
    sender = -1
    if kind == DELIVER:
        t = D[2, x]
        a = TT[2, t]
        sender = TT[1, t]
        if TT[0, t] == ACK_COPY:
            k_in = D[3, x]
            etm = -1
            for j in range(no):
                if EN[0, D[4, j]] == a and D[5, j] == k_in:
                    touched, etm = j, D[4, j]
                    break
            inkey = choice_code(1, t, etm + 1)
        else:
            held = 0
            if TT[0, t] == WITH_ID:
                k_in = D[3, x]
                for j in range(ns):
                    if D[6, j] == a and D[7, j] == sender and D[8, j] == k_in:
                        held = 1
                        break
            inkey = choice_code(0, t, held)
    elif kind == TIMER:
        a = EN[0, D[4, x]]
        k_in = D[5, x]
        touched = x
        inkey = choice_code(2, D[4, x], 0)
    elif kind == SCENARIO:
        a = SA[cur]
        inkey = choice_code(3, cur, 0)
    elif kind == TIME:
        a = x
        inkey = choice_code(4, x, y)
    else:
        a = x
        inkey = choice_code(5, y, 0)
    r = find_reaction(RK, RS, inkey, D[0, a], tape)
    if r < 0:
        return MISS
    _copy(D, Wk, na, nc, no, ns)
    m = nc
    base = D[1, a]
    if kind == DELIVER:
        for i in range(x, nc - 1):
            Wk[2, i], Wk[3, i] = Wk[2, i + 1], Wk[3, i + 1]
        m = nc - 1
    for i in range(RR[3, r], RR[3, r] + RR[4, r]):
        t = RC[0, i]
        if m >= ROOM:  # (beyond any layout: the caller stops)
            cnt[0], cnt[1], cnt[2] = ROOM + 1, 0, 0
            return OVERFLOW
        Wk[2, m] = t
        if TT[0, t] == PLAIN:
            Wk[3, m] = 0
        elif TT[0, t] == ACK_COPY or RC[1, i] == INPUT_ID:
            Wk[3, m] = k_in
        else:
            Wk[3, m] = base + RC[2, i]
        m += 1
    mo = no
    if touched >= 0:
        for j in range(touched, no - 1):
            Wk[4, j], Wk[5, j] = Wk[4, j + 1], Wk[5, j + 1]
        mo = no - 1
        if RR[5, r] >= 0:
            Wk[4, mo], Wk[5, mo] = RR[5, r], k_in
            mo += 1
    for i in range(RR[6, r], RR[6, r] + RR[7, r]):
        if mo >= ROOM:
            cnt[0], cnt[1], cnt[2] = 0, ROOM + 1, 0
            return OVERFLOW
        Wk[4, mo], Wk[5, mo] = RE[0, i], base + RE[1, i]
        mo += 1
    ms = ns
    if RR[8, r] != 0:
        Wk[6, ms], Wk[7, ms], Wk[8, ms] = a, sender, k_in
        ms += 1
    Wk[0, a] = RR[0, r]
    if kind == SCENARIO:
        cur += 1
    res[0], res[1] = RR[1, r], RR[2, r]
    got = canonical(lay, TT, EN, fifo, m, Wk, mo, ms, cnt, live)
    if got != OK:
        return got
    return encode(lay, out, Wk, cnt[0], cnt[1], cnt[2], cur, los, dup)


#: A job's columns in the phase-A output (:func:`successors`): its state, choice, tape,
#: status, Zeno flag and reads (a successor that outgrew the layout is computed again in
#: Python, and the layout fitted to it there).
JOB_COLUMNS = 6
#: The most free comparisons one step reads (a tape is an int64: a leading bit, then the
#: answers); :func:`commit` keeps this much room in the queue of retries.
MAX_READS = 62


@njit(cache=True, nogil=True)
def successors(
    keys,
    GT,
    kw,
    lay,
    TT,
    EN,
    PT,
    TJ,
    PW,
    WA,
    SA,
    RK,
    RS,
    RR,
    RC,
    RE,
    opt,
    settled,
    lo,
    hi,
    ci,
    queue,
    main,
    out_job,
    out_rows,
    at,
):
    """Phase A of a chunk: the successors of jobs, into ``out_job`` (per job its state,
    choice, tape, status, Zeno flag and reads) and
    ``out_rows`` (the successor's row), from ``at[0]`` on. ``main``: the jobs of states
    ``lo..hi-1``, every choice in the order of :func:`choices`, from choice ``ci`` of
    state ``lo``; else the queued retries ``queue[:, lo:hi]`` (state, choice, tape).
    Nothing shared is written (no store, no table): two threads run this on two halves
    of a chunk at once (``nogil``). Returns True when done; False when the output is
    full, ``at`` then says where to go on: (jobs written, state or queue place, choice)."""
    na = lay[0]
    gb = group_bounds(lay)
    w = gb[GROUPS]
    koff = key_offsets(kw)
    pn = np.zeros(GROUPS, np.int64)
    wide = np.zeros(w, GT[0].dtype)
    D = np.zeros((9, ROOM), np.int64)
    Wk = np.zeros((9, ROOM), np.int64)
    head = np.zeros(6, np.int64)
    cnt = np.zeros(3, np.int64)
    res = np.zeros(2, np.int64)
    live = np.zeros(na, np.uint64)
    codes = np.zeros(4 * ROOM, np.int64)
    m = at[0]
    cap = out_job.shape[0]
    decoded = -1
    nchoice = 0
    k = lo
    while k < hi:
        sid = k if main else queue[0, k]
        if decoded != sid:
            expand(keys[sid], GT, gb, koff, kw, wide, pn)
            decode(wide, lay, TT, EN, D, head, live)
            decoded = sid
            if main:
                nchoice = choices(lay, TT, EN, PT, TJ, PW, WA, opt, D, head, codes)
        if not main:
            code, tape = queue[1, k], queue[2, k]
        elif ci < nchoice:
            code, tape = int(codes[ci]), 1
        else:
            k += 1
            ci = 0
            continue
        if m >= cap:
            at[0], at[1], at[2] = m, k, ci
            return False
        got = successor(
            lay,
            TT,
            EN,
            SA,
            RK,
            RS,
            RR,
            RC,
            RE,
            opt,
            settled,
            code,
            tape,
            D,
            head,
            Wk,
            cnt,
            live,
            out_rows[m],
            res,
        )
        out_job[m, 0], out_job[m, 1], out_job[m, 2] = sid, code, tape
        out_job[m, 3], out_job[m, 4], out_job[m, 5] = got, res[0], res[1]
        m += 1
        if main:
            ci += 1
        else:
            k += 1
    at[0], at[1], at[2] = m, hi, 0
    return True


@njit(cache=True, nogil=True)
def commit(
    keys,
    slots,
    GT,
    GS,
    counts,
    kw,
    lay,
    out_job,
    out_rows,
    jobs,
    max_states,
    parent,
    e_src,
    e_dst,
    zeno,
    cut,
    queue,
    st,
):
    """Phase B of a chunk: its jobs ``st[5]..jobs-1`` in order, as one thread would take
    them: each successor numbered (:func:`intern`, new states' keys appended from
    ``st[0]``), its parent, edge (source and destination: an edge's choice is worked out
    again when a path needs it, :class:`~.kernel.PackedEdges`), Zeno flag or cut
    recorded, and its free comparisons' other answers queued after the level's jobs
    (the order of :func:`~.explore._chunks`). ``st``: (states, edges, Zeno, cut, queued,
    next job, ...), updated as it goes; ``parent[k]`` is state ``st[8] + k``'s. Stops at
    a job it cannot take: its status (MISS, OVERFLOW, TOO_MANY_IDS from phase A;
    GROUP_FULL, the group in ``st[6]``; FULL, an array here is full), ``st[5]`` that job;
    OK when every job is taken. Returns the status and the groups' tables (:func:`grow`
    grows them)."""
    gb = group_bounds(lay)
    w = gb[GROUPS]
    koff = key_offsets(kw)
    gi = np.zeros(GROUPS, np.int64)
    pn = np.zeros(GROUPS, np.int64)
    key = np.zeros(keys.shape[1], keys.dtype)
    prev = np.zeros(w, GT[0].dtype)
    n, ne, nz, nx, nq = st[0], st[1], st[2], st[3], st[4]
    last = -1
    status = OK
    i = st[5]
    while i < jobs:
        if (
            n >= keys.shape[0]
            or 10 * (n + 1) > 7 * slots.size
            or n - st[8] >= parent.size
            or ne >= e_dst.size
            or nz >= zeno.size
            or nx >= cut.size
            or nq + MAX_READS > queue.shape[1]
        ):
            status = FULL
            break
        got = out_job[i, 3]
        if got != OK:
            status = got
            break
        sid, code, tape, reads = out_job[i, 0], out_job[i, 1], out_job[i, 2], out_job[i, 5]
        if sid != last:
            expand(keys[sid], GT, gb, koff, kw, prev, pn)
            last = sid
        row = out_rows[i]
        while True:  # (a group's tables full, -3: grown here)
            k, fresh = intern(
                keys,
                n,
                slots,
                GT,
                GS,
                counts,
                gb,
                koff,
                kw,
                row,
                gi,
                key,
                n < max_states,
                prev,
                pn,
            )
            if k != -3:
                break
            GT, GS = grow(GT, GS, counts, fresh)
        if k == -2:
            st[6] = fresh
            status = GROUP_FULL
            break
        length = 0
        while (tape >> (length + 1)) != 0:
            length += 1
        bits = tape & ((1 << length) - 1)
        for j in range(length, reads):  # the other answers of the comparisons it read
            queue[0, nq], queue[1, nq] = sid, code
            queue[2, nq] = (1 << (j + 1)) | bits | (1 << j)
            nq += 1
        i += 1
        if k < 0:
            cut[nx] = sid
            nx += 1
            continue
        if fresh:
            parent[n - st[8]] = sid
            n += 1
        if out_job[i - 1, 4] != 0:
            zeno[nz] = k
            nz += 1
        if k != sid:
            e_src[ne], e_dst[ne] = sid, k
            ne += 1
    st[0], st[1], st[2], st[3], st[4], st[5] = n, ne, nz, nx, nq, i
    return status, GT, GS


@njit(cache=True)
def row_offsets(src, row) -> None:
    """The edges' sparse-row offsets (``row``: n + 1, zeros): a count of each state's
    edges, summed."""
    for k in range(src.size):
        row[src[k] + 1] += 1
    for k in range(1, row.size):
        row[k] += row[k - 1]


@njit(cache=True)
def by_source(src, row, values, out) -> None:
    """``values`` (one per edge) in sparse-row order (``row``: :func:`row_offsets`), each
    state's in the order added: the placing pass of a counting sort by source."""
    at = row[:-1].copy()
    for k in range(src.size):
        j = at[src[k]]
        out[j] = values[k]
        at[src[k]] = j + 1
