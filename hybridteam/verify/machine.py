"""Skeleton states and their successors, computed by the engine itself.

A skeleton state (:class:`State`) is plain hashable data: every agent's active modes (and
the history a later entry may restore), its discrete variables, the copies in flight, the
acknowledged layer's outboxes and duplicate filters, how far the scenario has got, and how
many losses and duplications the path has used. :class:`Machine` loads a batch of states
into one engine :class:`~hybridteam.engine.run.ensemble.Ensemble` (one instance per state and
choice), applies each choice as the engine would see it — a message arrives, a
retransmission timer expires, a scenario event or a world event is raised, a time-driven
transition fires — and runs the engine's own discrete phase to quiescence; then it reads
the instances back as states. Sends land in the (muted) medium one time unit ahead and are
read back as copies in flight: the explorer, not the medium, decides which arrives next.

States are canonical: message ids are renumbered per sender (only which copies share an
id matters) and duplicate-filter entries that no copy can ever match again are dropped, so
behaviours that differ only in bookkeeping meet in one state.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from hybridteam.engine.run.discrete import discrete_phase
from hybridteam.engine.run.ensemble import Ensemble
from hybridteam.engine.run.events import LOCAL, MESSAGE, SCENARIO, TIMER
from hybridteam.engine.run.network import Message
from hybridteam.engine.run.reliable import ACK, Pending
from hybridteam.verify.abstraction import Skeleton
from hybridteam.verify.bounds import Values


class Copy(NamedTuple):
    sender: int
    receiver: int
    socket: str
    type: str
    msg_id: int
    fields: tuple  # ((name, value), ...) of the exact fields


class OutboxEntry(NamedTuple):
    """An acknowledged message waiting for acks (the reliable layer's outbox)."""

    sender: int
    msg_id: int
    type: str
    socket: str
    fields: tuple
    waiting: tuple
    retries_left: int
    timeout: float
    rank: float


class State(NamedTuple):
    agents: tuple  # per agent: (configuration bytes, discrete variable values)
    inflight: tuple  # Copy, in sending order
    outbox: tuple  # OutboxEntry, sorted
    seen: tuple  # (receiver, sender, id), sorted
    cursor: int  # scenario entries raised so far
    losses: int
    dups: int
    next_ids: tuple = ()  # per agent: its next message id (ids are 0.. in canonical form)


class _NullRecorder:
    """The explorer keeps no trace: every record is dropped."""

    snapshots = None

    def __getattr__(self, name):
        return lambda *a, **k: None


@dataclass
class Result:
    """One applied choice: the successor, whether it ended Zeno, and how many free
    comparisons it read (answers beyond its tape were False)."""

    state: State
    zeno: bool
    reads: int


class Machine:
    """Computes successors of skeleton states in batches on one engine ensemble."""

    def __init__(
        self, sk: Skeleton, capacity: int = 1024, fifo: bool = False, raw: bool = False
    ) -> None:
        """``raw``: successors keep the engine's own message ids and the copies' sending
        order (no canonical form), so a replay can follow each copy along a path."""
        self.sk, self.capacity, self.fifo, self.raw = sk, capacity, fifo, raw
        self.cteam = sk.cteam
        ens = Ensemble(sk.cteam, capacity, 0, 1.0, {})
        null = _NullRecorder()
        ens.rec = ens.network.rec = null  # type: ignore[assignment]  # (a recorder of nothing)
        one, zero = np.ones(capacity), np.zeros(capacity)
        ens.network.default = (one, zero, zero)  # sends land at t + 1: the explorer delivers
        ens.network.links = {}
        ens.network.limits = {}
        self.ens = ens
        self._interned: dict = {}  # one object per distinct agent entry and copy
        #: what each agent part enables (:func:`~.explore.choices`' memo)
        self.local_choices: dict[tuple, tuple] = {}
        #: where the explorer counts the discrete variables' values (:mod:`.bounds`)
        self.values: Values | None = None
        self.fields = self._fields()
        self.hist = [
            np.array([m.index for m in ca.modes if self._restorable(ca, m.index)], np.intp)
            for ca in sk.cteam.agents
        ]
        self.or_parent = []
        for ca in sk.cteam.agents:
            kids = [m.index for m in ca.modes if m.parent >= 0 and ca.modes[m.parent].kind == "or"]
            self.or_parent.append(
                (np.array(kids, np.intp), np.array([ca.modes[k].parent for k in kids], np.intp))
            )

    # ------------------------------------------------------------------ setup
    def _fields(self) -> dict[str, list[str]]:
        from hybridteam.engine.compile.compiler import message_fields

        out = {k: sorted(v) for k, v in message_fields(self.cteam.team).items()}
        out[ACK] = ["id"]
        return out

    @staticmethod
    def _restorable(ca, m: int) -> bool:
        """Whether mode ``m``'s last active child can matter later: it has history, or an
        ancestor restores deeply."""
        mode = ca.modes[m]
        if mode.kind != "or":
            return False
        if mode.history != "none":
            return True
        p = mode.parent
        while p >= 0:
            if ca.modes[p].history == "deep":
                return True
            p = ca.modes[p].parent
        return False

    def initial(self) -> State:
        """The state after the run's first instant (initial modes entered, urgent
        transitions taken)."""
        ens = self.ens
        self._clear(1)
        idx = np.arange(1)
        for a, st in enumerate(ens.states):
            x, v = st.ca.initial_values(st.p[:1])
            st.x[:1], st.v[:1] = x, v
            st.v[0, self.sk.inst_col[a]] = 0
            st.activate(0, idx, ens.t)
            st.enter_default(0, idx, ens.t)
        #: the delays of the after: timeouts the initial modes armed (a replay needs them)
        self.armed0 = [st.deadline[0].copy() for st in ens.states]
        for st in ens.states:
            st.deadline[:1] = -np.inf
        discrete_phase(ens, idx)
        per_out, per_seen = self._by_instance()
        return self._read(
            0, State((), (), (), (), 0, 0, 0, ()), None, per_out.get(0, []), per_seen.get(0, [])
        ).state

    # ------------------------------------------------------------------ batches
    def _clear(self, n: int) -> None:
        ens = self.ens
        ens.t[:] = 0.0
        ens.done[:] = False
        ens.outcomes = [None] * ens.n
        ens.micro[:] = 0
        ens.changed[:] = False
        ens.zeno.clear()
        q = ens.queue
        q.heaps.clear()
        q.seq[:] = 0
        q.next[:] = np.inf
        rel = ens.reliable
        rel.outbox.clear()
        rel.seen.clear()
        for c in ens.network.count:
            c[:] = 0
        for st in ens.states:
            st.active[:n] = False
            st.child[:n] = -1
            st.last[:n] = -1
            st.entry[:n] = 0.0
        self.sk.oracle.reset(ens.n)

    def run(self, jobs: list[tuple[State, tuple, tuple]]) -> list[Result]:
        """Successors of ``(state, choice, tape)`` jobs (at most ``capacity`` of them)."""
        ens = self.ens
        n = len(jobs)
        self._clear(n)
        self._load([s for s, _, _ in jobs])
        oracle = self.sk.oracle
        rel = ens.reliable
        results: list[Result | None] = [None] * n
        engine = []
        touched: list[int] = [-1] * n  # the parent's outbox entry the choice works on
        for i, (s, choice, tape) in enumerate(jobs):
            oracle.tape[i] = tape
            kind = choice[0]
            one = np.array([i])
            if kind in ("lose", "dup"):
                c = s.inflight[choice[1]]
                rest = s.inflight[: choice[1]] + s.inflight[choice[1] + 1 :]
                nxt = (
                    s._replace(inflight=rest, losses=s.losses + 1)
                    if kind == "lose"
                    else s._replace(inflight=(*s.inflight, c), dups=s.dups + 1)
                )
                results[i] = Result(self._finish(nxt), False, 0)
                continue
            engine.append(i)
            if kind == "deliver":
                c = s.inflight[choice[1]]
                names = self.fields.get(c.type, [])
                values = dict(c.fields)
                msg = Message(
                    c.sender,
                    c.receiver,
                    0,
                    0.0,
                    c.socket,
                    c.type,
                    {f: values.get(f, 0.0) for f in names},
                    c.msg_id,
                )
                ens.queue.push_each(one, np.zeros(1), MESSAGE, c.receiver, c.type, [msg])
                # the reliable layer reads one outbox entry (an ack) or one filter entry
                if c.type == ACK:
                    touched[i] = self._put(i, s, c.receiver, int(values["id"]))
                elif c.msg_id >= 0 and (c.receiver, c.sender, c.msg_id) in s.seen:
                    rel.seen.add((i, c.receiver, c.sender, c.msg_id))
            elif kind == "timer":
                e = s.outbox[choice[1]]
                touched[i] = self._put(i, s, e.sender, e.msg_id)
                ens.queue.push(one, np.zeros(1), TIMER, e.sender, "retransmit", e.msg_id)
            elif kind == "scenario":
                _, agent, name = self.scenario[s.cursor]
                ens.queue.push(one, np.zeros(1), SCENARIO, agent, name)
            elif kind == "world":
                ens.queue.push(one, np.zeros(1), LOCAL, choice[1], choice[2])
            elif kind == "time":
                oracle.chosen[i] = choice[1] * 1_000_000 + choice[2]
        if engine:
            discrete_phase(ens, np.array(engine, np.intp))
            per_out, per_seen = self._by_instance()
            rows = self._agents(np.array(engine, np.intp))
            for i, agents in zip(engine, rows, strict=True):
                s, choice, _ = jobs[i]
                kept = (
                    s.outbox
                    if touched[i] < 0
                    else s.outbox[: touched[i]] + s.outbox[touched[i] + 1 :]
                )
                results[i] = self._read(
                    i,
                    s,
                    choice,
                    kept + tuple(per_out.get(i, ())),
                    s.seen + tuple(per_seen.get(i, ())),
                    agents,
                )
        return results  # type: ignore[return-value]  # (each job got its result)

    def _put(self, i: int, s: State, sender: int, msg_id: int) -> int:
        """Load the parent's outbox entry ``(sender, msg_id)`` into instance ``i``; its
        position in the parent's outbox, or -1 when there is none."""
        for k, e in enumerate(s.outbox):
            if e.sender == sender and e.msg_id == msg_id:
                self.ens.reliable.outbox[(i, sender, msg_id)] = Pending(
                    e.type,
                    e.socket,
                    {f: np.array([v]) for f, v in self._all_fields(e)},
                    set(e.waiting),
                    e.retries_left,
                    e.timeout,
                    e.rank,
                )
                return k
        return -1

    @property
    def scenario(self) -> list[tuple[float, int, str]]:
        return self.sk.original.scenario

    def _load(self, states: list[State]) -> None:
        """Configurations, variables and id counters of ``states`` into rows 0..n-1."""
        ens, n = self.ens, len(states)
        for a, st in enumerate(ens.states):
            m = len(st.ca.modes)
            h = self.hist[a]
            raw = np.frombuffer(b"".join(s.agents[a][0] for s in states), np.uint8)
            raw = raw.reshape(n, m + 2 * h.size)
            st.active[:n] = raw[:, :m].astype(bool)
            if h.size:
                st.last[:n, h] = raw[:, m:].copy().view(np.int16).astype(np.intp)
            kids, parents = self.or_parent[a]
            rows, cols = np.nonzero(st.active[:n][:, kids])
            st.child[rows, parents[cols]] = kids[cols]
            cols_v = self.sk.discrete_vars[a]
            st.v[:n] = 0.0
            if cols_v:
                at = np.ix_(np.arange(n), np.asarray(cols_v, np.intp))
                st.v[at] = np.array([s.agents[a][1] for s in states], float).reshape(n, len(cols_v))
            st.v[:n, self.sk.inst_col[a]] = np.arange(n)
            st.deadline[:n] = -np.inf
            ens.reliable.next_id[a][:n] = [s.next_ids[a] if s.next_ids else 0 for s in states]

    def _all_fields(self, e: OutboxEntry):
        values = dict(e.fields)
        return [(f, values.get(f, 0.0)) for f in self.fields.get(e.type, [])]

    def _by_instance(self):
        per_out: dict[int, list] = {}
        for (i, snd, k), p in self.ens.reliable.outbox.items():
            per_out.setdefault(i, []).append(
                OutboxEntry(
                    snd,
                    k,
                    p.type,
                    p.socket,
                    self._exact(p.type, {f: float(v[0]) for f, v in p.fields.items()}),
                    tuple(sorted(p.waiting)),
                    p.retries_left,
                    p.timeout,
                    p.rank,
                )
            )
        per_seen: dict[int, list] = {}
        for i, r, snd, k in self.ens.reliable.seen:
            per_seen.setdefault(i, []).append((r, snd, k))
        return per_out, per_seen

    def _exact(self, type_: str, fields: dict) -> tuple:
        drop = self.sk.abstract_fields
        return tuple(sorted((f, v) for f, v in fields.items() if (type_, f) not in drop))

    def _agents(self, rows: np.ndarray) -> list[tuple]:
        """Each listed instance's agents entry: per agent, its configuration bytes (active
        modes, then the restorable last children as int16) and discrete variables. Read
        for the whole batch at once; equal entries are one object (states share most of
        them, and the explorer holds millions of states)."""
        per_agent = []
        for a, st in enumerate(self.ens.states):
            h = self.hist[a]
            raw = st.active[rows].astype(np.uint8)
            if h.size:
                last = np.ascontiguousarray(st.last[np.ix_(rows, h)].astype(np.int16))
                raw = np.concatenate([raw, last.view(np.uint8)], axis=1)
            cols = self.sk.discrete_vars[a]
            if cols:
                block = st.v[np.ix_(rows, np.asarray(cols, np.intp))]
                if self.values is not None:
                    self.values.add(a, block)
                values = block.tolist()
            else:
                values = [[]] * rows.size
            intern = self._interned
            per_agent.append(
                [
                    intern.setdefault(e, e)
                    for e in zip((r.tobytes() for r in raw), map(tuple, values), strict=True)
                ]
            )
        return list(zip(*per_agent, strict=True))

    def _read(
        self,
        i: int,
        parent: State,
        choice: tuple | None,
        outbox=(),
        seen=(),
        agents: tuple | None = None,
    ) -> Result:
        ens = self.ens
        if agents is None:
            agents = self._agents(np.array([i]))[0]
        inflight = list(parent.inflight)
        if choice is not None and choice[0] == "deliver":
            del inflight[choice[1]]
        for ev in sorted(ens.queue.heaps.get(i, []), key=lambda e: e[:5]):
            if ev[1] == MESSAGE:
                m = ev[6]
                c = Copy(
                    m.sender, m.receiver, m.socket, m.type, m.msg_id, self._exact(m.type, m.fields)
                )
                inflight.append(self._interned.setdefault(c, c))
        cursor = parent.cursor + (1 if choice is not None and choice[0] == "scenario" else 0)
        ids = tuple(int(n[i]) for n in ens.reliable.next_id) if self.raw else ()
        nxt = State(
            agents,
            tuple(inflight),
            tuple(outbox),
            tuple(seen),
            cursor,
            parent.losses,
            parent.dups,
            ids,
        )
        return Result(self._finish(nxt), bool(ens.done[i]), int(self.sk.oracle.reads[i]))

    # ------------------------------------------------------------------ canonical form
    def _finish(self, s: State) -> State:
        return s if self.raw else self.canonical(s)

    def canonical(self, s: State) -> State:
        """Drop what can no longer matter and renumber message ids per sender.

        Every successor passes here, so it is one pass over the copies that unpacks each
        (a named tuple's attribute reads, and a comprehension per question, cost more)."""
        outbox = s.outbox
        waiting = {(e[0], e[1]): e[5] for e in outbox} if outbox else {}
        live: dict[int, set[int]] = {}
        flying = set()
        inflight = []
        for c in s.inflight:
            snd, rcv, _, typ, k, fields = c
            if typ == ACK:
                k = int(fields[0][1])
                if snd not in waiting.get((rcv, k), ()):
                    continue  # no outbox entry waits for it any more
                owner = rcv
            else:
                flying.add((snd, rcv, k))
                if k < 0:
                    inflight.append(c)
                    continue
                owner = snd
            inflight.append(c)
            ids = live.get(owner)
            if ids is None:
                live[owner] = {k}
            else:
                ids.add(k)
        for e in outbox:
            ids = live.get(e[0])
            if ids is None:
                live[e[0]] = {e[1]}
            else:
                ids.add(e[1])
        seen = []
        if s.seen:  # (a set: the parent's entries)
            seen = sorted(
                {
                    t
                    for t in s.seen
                    if (t[1], t[0], t[2]) in flying or t[0] in waiting.get((t[1], t[2]), ())
                }
            )
            for _, snd, k in seen:
                ids = live.get(snd)
                if ids is None:
                    live[snd] = {k}
                else:
                    ids.add(k)
        counts = tuple(len(live[a]) if a in live else 0 for a in range(len(self.cteam.agents)))
        order = _link if self.fifo else None
        for ks in live.values():
            if max(ks) != len(ks) - 1:
                break
        else:  # ids are 0.. already
            return State(
                s.agents,
                tuple(sorted(inflight, key=order)),
                tuple(sorted(outbox)),
                tuple(seen),
                s.cursor,
                s.losses,
                s.dups,
                counts,
            )
        new = {a: {k: j for j, k in enumerate(sorted(ks))} for a, ks in live.items()}
        intern = self._interned

        def copy(c: Copy) -> Copy:
            if c.type == ACK:
                c = c._replace(fields=(("id", float(new[c.receiver][_ack_id(c)])),))
            elif c.msg_id >= 0:
                c = c._replace(msg_id=new[c.sender][c.msg_id])
            return intern.setdefault(c, c)

        # in fifo order per-link order matters, not the interleaving of links (stable sort)
        return State(
            s.agents,
            tuple(sorted((copy(c) for c in inflight), key=order)),
            tuple(sorted(e._replace(msg_id=new[e.sender][e.msg_id]) for e in outbox)),
            tuple(sorted((r, snd, new[snd][k]) for r, snd, k in seen)),
            s.cursor,
            s.losses,
            s.dups,
            counts,
        )


def _ack_id(c: Copy) -> int:
    """The message id an ack copy acknowledges (its only field)."""
    return int(c.fields[0][1])


def _link(c: Copy) -> tuple:
    return c.sender, c.receiver, c.socket
