"""Successors from per-agent reaction tables that the engine fills: the explorer's default.

Every choice but a loss or a duplication acts on ONE agent: a copy arrives at its receiver,
a retransmission timer of its sender expires, the scenario's next event or a world event
reaches its agent, or a time-driven transition of an agent fires. What the engine's
discrete phase then does depends only on that agent's local part, because

* an agent's guards and actions read its own variables, parameters, plant state, ``t`` and
  the triggering message (:func:`hybridteam.engine.compile.scope.symbols`); the skeleton
  makes every read of time, plant state, stream estimates and world readings a free
  comparison (:mod:`.abstraction`), answered from the choice's oracle tape;
* a send lands in the (muted) medium one time unit ahead (:class:`~.machine.Machine`):
  no other agent sees it within the choice;
* the acknowledged layer reads one outbox entry (the timer's, or the one an ack
  acknowledges) and one duplicate-filter entry (the arriving copy's), and writes new
  outbox entries of the sender, its filter entry and acks (:mod:`~hybridteam.engine.run.reliable`);
* every other agent is quiescent: its urgent (eventless, exact) transitions are disabled.
  That holds for every agent part the engine ever left at the end of a phase that was not
  cut short as Zeno, so a state whose every part is of that kind (*settled*) is expanded
  from the tables, and any other state by the engine.

So a reaction is keyed on exactly what it reads — the agent's part (configuration bytes,
discrete variables), the choice's input (the copy's sender, socket, type and exact fields,
whether it carries an id and whether the receiver's filter already holds it; the outbox
entry without its id; the scenario event; the transition) and the oracle tape — and stores
the agent's new part, the copies it sends, the outbox and filter entries it adds or
changes, its Zeno flag and the free comparisons it read. Message ids are stored relative
to the agent's next id (new ids) or as the choice's input id (an ack, a retransmission), so
one entry serves every state with that local part. A miss runs the engine
(:class:`~.machine.Machine`, the same batches); its result is the successor, and the entry
made from it is checked at once: composing the entry onto the parent must give the
engine's own successor, and the reaction must have left every other agent as it was
(otherwise exploring stops with an error, rather than trusting a table that is not the
engine's semantics). ``Options(reference=True)`` (``verify --reference``) explores with the
engine alone.
"""

from __future__ import annotations

from typing import NamedTuple

from hybridteam.engine.run.reliable import ACK
from hybridteam.verify.abstraction import Skeleton
from hybridteam.verify.bounds import Values
from hybridteam.verify.machine import Copy, Machine, OutboxEntry, Result, State

#: How a sent copy's message id is rebuilt: no id (a plain message), the choice's input id
#: (a retransmission's, or the id an ack acknowledges), or the agent's next id plus an offset.
NO_ID, INPUT_ID, NEW_ID = 0, 1, 2


class Reaction(NamedTuple):
    """What one choice did to its agent (a table entry)."""

    part: tuple  # the agent's new (configuration bytes, discrete variables)
    copies: tuple  # (template Copy, how its id is rebuilt, offset), in sending order
    kept: OutboxEntry | None  # the input outbox entry as it is after (its id is the input id)
    entries: tuple  # (template OutboxEntry, offset): new outbox entries, ids after the next id
    filtered: bool  # the receiver's filter now holds the arriving copy's id
    zeno: bool
    reads: int


class Reactions:
    """Successors of skeleton states, composed from reaction tables; the engine on a miss.

    The same interface as :class:`~.machine.Machine` to the explorer (``initial``, ``run``,
    ``scenario``, ``values``), so a canonical-form step or a process pool composes with
    either."""

    def __init__(self, sk: Skeleton, capacity: int = 1024, fifo: bool = False) -> None:
        self.sk, self.capacity = sk, capacity
        # raw: the engine's own ids and sending order, from which a reaction is read off
        self.engine = Machine(sk, capacity, fifo=fifo, raw=True)
        self.table: dict[tuple, Reaction] = {}
        #: per agent: parts the engine left at the end of a phase not cut short (quiescent)
        self.settled: list[set] = [set() for _ in sk.cteam.agents]
        self.hits = 0
        self.misses = 0

    @property
    def local_choices(self) -> dict[tuple, tuple]:
        """What each agent part enables (:func:`~.explore.choices`' memo)."""
        return self.engine.local_choices

    @property
    def values(self) -> Values | None:
        return self.engine.values

    @values.setter
    def values(self, values: Values | None) -> None:
        # (only the engine computes new parts: a table's parts were counted when made)
        self.engine.values = values

    @property
    def scenario(self) -> list[tuple[float, int, str]]:
        return self.engine.scenario

    def initial(self) -> State:
        s = self.engine.initial()
        if not self.engine.ens.done[0]:
            self._settle(s.agents)
        return self.engine.canonical(s)

    def _settle(self, parts: tuple) -> None:
        for a, part in enumerate(parts):
            self.settled[a].add(part)

    # ------------------------------------------------------------------ successors
    def run(self, jobs: list[tuple[State, tuple, tuple]]) -> list[Result]:
        """Successors of ``(state, choice, tape)`` jobs (at most ``capacity`` of them)."""
        canonical = self.engine.canonical
        table = self.table
        results: list[Result | None] = [None] * len(jobs)
        misses: list[tuple[int, tuple | None, int, int]] = []  # job, key, agent, input id
        last: State | None = None
        settled = False
        for i, (s, choice, tape) in enumerate(jobs):
            kind = choice[0]
            if kind == "lose" or kind == "dup":
                c = s.inflight[choice[1]]
                nxt = (
                    s._replace(
                        inflight=s.inflight[: choice[1]] + s.inflight[choice[1] + 1 :],
                        losses=s.losses + 1,
                    )
                    if kind == "lose"
                    else s._replace(inflight=(*s.inflight, c), dups=s.dups + 1)
                )
                results[i] = Result(canonical(nxt), False, 0)
                continue
            if s is not last:  # (a state's jobs come together)
                last = s
                settled = all(p in self.settled[a] for a, p in enumerate(s.agents))
            key, a, k_in = self._key(s, choice, tape)
            r = table.get(key) if settled else None
            if r is None:
                misses.append((i, key if settled else None, a, k_in))
                continue
            self.hits += 1
            if not r.zeno:
                self.settled[a].add(r.part)
            results[i] = Result(canonical(self._compose(s, choice, a, k_in, r)), r.zeno, r.reads)
        if misses:
            self.misses += len(misses)
            got = self.engine.run([jobs[i] for i, _, _, _ in misses])
            for (i, entry, a, k_in), res in zip(misses, got, strict=True):
                s, choice, _ = jobs[i]
                succ = canonical(res.state)
                if not res.zeno:
                    self._settle(res.state.agents)
                if entry is not None:
                    r = self._reaction(s, choice, a, k_in, res)
                    if canonical(self._compose(s, choice, a, k_in, r)) != succ:
                        raise RuntimeError(  # a bug, not a model's fault: say so, loudly
                            f"reaction table: {choice} on agent {a} does not reproduce "
                            "the engine's successor"
                        )
                    table[entry] = r
                results[i] = Result(succ, res.zeno, res.reads)
        return results  # type: ignore[return-value]  # (each job got its result)

    def _key(self, s: State, choice: tuple, tape: tuple) -> tuple[tuple, int, int]:
        """What the choice's reaction reads, its agent, and its input id (-1: none)."""
        kind = choice[0]
        if kind == "deliver":
            c = s.inflight[choice[1]]
            a = c.receiver
            if c.type == ACK:
                k = int(c.fields[0][1])
                e = _entry_of(s, a, k)
                return (ACK, a, c.sender, c.socket, _sans_id(e), s.agents[a], tape), a, k
            k = c.msg_id
            held = k >= 0 and (a, c.sender, k) in s.seen
            key = (kind, a, c.sender, c.socket, c.type, c.fields, k >= 0, held, s.agents[a], tape)
            return key, a, k
        if kind == "timer":
            e = s.outbox[choice[1]]
            return (kind, e.sender, _sans_id(e), s.agents[e.sender], tape), e.sender, e.msg_id
        if kind == "scenario":
            _, a, name = self.scenario[s.cursor]
            return (kind, a, name, s.agents[a], tape), a, -1
        a = choice[1]  # world (agent, event), time (agent, transition)
        return (kind, a, choice[2], s.agents[a], tape), a, -1

    def _reaction(self, s: State, choice: tuple, a: int, k_in: int, res: Result) -> Reaction:
        """The table entry read off the engine's raw successor ``res`` of ``s``."""
        raw = res.state
        for b, (before, after) in enumerate(zip(s.agents, raw.agents, strict=True)):
            if b != a and before != after:
                raise RuntimeError(
                    f"reaction table: {choice} on agent {a} changed agent {b}; the "
                    "reactions are not local (explore with --reference)"
                )
        base = s.next_ids[a]
        stays = len(s.inflight) - (choice[0] == "deliver")
        copies = []
        for c in raw.inflight[stays:]:
            if c.type == ACK:
                copies.append((c._replace(fields=()), INPUT_ID, 0))
            elif c.msg_id < 0:
                copies.append((c, NO_ID, 0))
            elif c.sender == a and c.msg_id >= base:
                copies.append((c._replace(msg_id=-1), NEW_ID, c.msg_id - base))
            elif c.sender == a and c.msg_id == k_in:
                copies.append((c._replace(msg_id=-1), INPUT_ID, 0))
            else:
                raise RuntimeError(f"reaction table: {choice} sent a copy {c} it cannot own")
        touched = _touched(s, choice, a, k_in)
        kept = None
        entries = []
        for e in raw.outbox[len(s.outbox) - (touched >= 0) :]:
            if touched >= 0 and e.sender == a and e.msg_id == k_in:
                kept = e._replace(msg_id=-1)
            elif e.sender == a and e.msg_id >= base:
                entries.append((e._replace(msg_id=-1), e.msg_id - base))
            else:
                raise RuntimeError(f"reaction table: {choice} made an outbox entry {e}")
        added = set(raw.seen) - set(s.seen)
        if added and (choice[0] != "deliver" or added != {(a, s.inflight[choice[1]].sender, k_in)}):
            raise RuntimeError(f"reaction table: {choice} filtered {added}")
        return Reaction(
            raw.agents[a], tuple(copies), kept, tuple(entries), bool(added), res.zeno, res.reads
        )

    def _compose(self, s: State, choice: tuple, a: int, k_in: int, r: Reaction) -> State:
        """``s`` after reaction ``r`` (not yet in canonical form)."""
        kind = choice[0]
        base = s.next_ids[a]
        inflight = list(s.inflight)
        if kind == "deliver":
            sender = inflight.pop(choice[1]).sender
        for c, how, offset in r.copies:
            if how == NO_ID:
                inflight.append(c)
            elif c.type == ACK:
                inflight.append(
                    Copy(c.sender, c.receiver, c.socket, ACK, c.msg_id, (("id", float(k_in)),))
                )
            else:
                k = k_in if how == INPUT_ID else base + offset
                inflight.append(Copy(c.sender, c.receiver, c.socket, c.type, k, c.fields))
        outbox = list(s.outbox)
        touched = _touched(s, choice, a, k_in)
        if touched >= 0:
            del outbox[touched]
            if r.kept is not None:
                outbox.append(r.kept._replace(msg_id=k_in))
        outbox += [e._replace(msg_id=base + offset) for e, offset in r.entries]
        seen = s.seen
        if r.filtered:
            seen = (*seen, (a, sender, k_in))
        agents = (*s.agents[:a], r.part, *s.agents[a + 1 :])
        cursor = s.cursor + (kind == "scenario")
        return State(
            agents, tuple(inflight), tuple(outbox), seen, cursor, s.losses, s.dups, s.next_ids
        )


def _sans_id(e: OutboxEntry | None) -> OutboxEntry | None:
    return None if e is None else e._replace(msg_id=-1)


def _entry_of(s: State, sender: int, msg_id: int) -> OutboxEntry | None:
    for e in s.outbox:
        if e.sender == sender and e.msg_id == msg_id:
            return e
    return None


def _touched(s: State, choice: tuple, a: int, k_in: int) -> int:
    """Where the outbox entry the choice reads sits in ``s.outbox`` (-1: none): the timer's
    own, or the one an arriving ack acknowledges."""
    if choice[0] == "timer":
        return choice[1]
    if choice[0] == "deliver" and s.inflight[choice[1]].type == ACK:
        for k, e in enumerate(s.outbox):
            if e.sender == a and e.msg_id == k_in:
                return k
    return -1
