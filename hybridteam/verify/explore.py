"""Explicit-state breadth-first exploration of a team's skeleton.

From a state the explorer may: deliver any copy in flight (any order, or only the oldest on
each link with ``order="fifo"``), lose one (up to ``losses`` per path), duplicate one (up to
``duplicates``), expire a retransmission timer of any unacknowledged message, raise the
next scenario event (in the scenario's order, each once), raise an event a world component
declares, or fire a time-driven transition. A choice that makes a free comparison decide
is tried with every answer. Successors come from the engine in batches
(:class:`~.machine.Machine`); states are stored compactly and found again by their key
(:mod:`.store`), so each is expanded once, and the graph (edges without self-loops) is
kept for the liveness checks. With ``storage`` "hashcompact" or "bitstate" only hashes of
the visited states are kept (:mod:`.storage`, a partial search); with ``jobs`` > 1 the
successors are computed by a pool of processes (:mod:`.pool`), the graph unchanged.
"""

from __future__ import annotations

import gc
import time
from array import array
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import overload

import numpy as np

from hybridteam.engine.run.budget import instances_within, memory_limit, resident_bytes
from hybridteam.engine.run.reliable import ACK
from hybridteam.verify.abstraction import Skeleton
from hybridteam.verify.bounds import DEFAULT_MAX_VALUES, Values, full, over_memory
from hybridteam.verify.kernel import PackedStore, chosen, explore_packed
from hybridteam.verify.machine import Machine, Result, State
from hybridteam.verify.pool import Pool, Successors
from hybridteam.verify.reactions import Reactions
from hybridteam.verify.storage import (
    DEFAULT_BITSTATE_MB,
    DEFAULT_HASH_FUNCTIONS,
    Coverage,
    PartialStore,
    Trail,
    visited_set,
)
from hybridteam.verify.store import Edges, Renumber, Store, key_numbers


@dataclass
class Options:
    losses: int = 2  # copies the network may lose on one path
    duplicates: int = 0  # copies it may duplicate on one path
    order: str = "any"  # "any": any copy in flight may arrive next; "fifo": per link
    max_states: int = 2_000_000  # stop (verdicts say "bounded") beyond this many states
    batch: int = 2048  # choices applied per engine call
    #: "bounded": a retransmission timer expires only once every copy of its message and
    #: every ack of it has arrived or been lost (true when the ack timeout exceeds the round
    #: trip, as the protocols' do); "any": at any moment (a full over-approximation)
    ack_timing: str = "bounded"
    #: "any": an ``after:`` timeout may expire at any moment; "own": only once the agent's
    #: own messages are settled (none of its copies but acks in flight, nothing in its
    #: outbox) — timeouts that exceed the agent's own exchanges; "long": only once the
    #: whole network is quiet (nothing in flight, nothing unacknowledged) — timeouts that
    #: exceed every message exchange. "own" and "long" leave out behaviours ("any" does
    #: not): a check under them holds under that timing assumption
    timeouts: str = "any"
    #: bytes this process may hold (None: run's limit, ``HYBRIDTEAM_MAX_MEMORY_GB`` or 4 GB)
    max_memory: float | None = None
    #: distinct values a discrete variable may take before the skeleton is judged infinite
    max_values: int = DEFAULT_MAX_VALUES
    #: "exact": every state kept (exhaustive); "hashcompact" or "bitstate": only hashes of
    #: the visited states, a partial search (:mod:`.storage`)
    storage: str = "exact"
    bitstate_mb: float = DEFAULT_BITSTATE_MB  # the bit array's size with "bitstate"
    hash_functions: int = DEFAULT_HASH_FUNCTIONS  # bits set per state with "bitstate"
    jobs: int = 1  # processes computing successors (:mod:`.pool`)
    #: "on": agents interchangeable where the properties allow it are explored once per
    #: arrangement (:mod:`.symmetry`; states counted are representatives); "off": not
    symmetry: str = "on"
    #: "basic": a copy no mode can see is explored alone first (:func:`_invisible`);
    #: "ample": also one copy to a receiver nothing else can reach, where no property
    #: reads the receiver (:mod:`.ample`)
    por: str = "basic"
    #: successors from the engine alone, one load and read-back each (:class:`~.machine.Machine`),
    #: instead of the reaction tables it fills (:class:`~.reactions.Reactions`, the default)
    reference: bool = False
    #: "auto": the compiled loop (:mod:`.kernel`) where numba is importable and the other
    #: options allow it (exact storage, one process, no reduction, the reaction tables);
    #: "on": the same, and an error without numba; "off": the Python loop
    kernel: str = "auto"


@dataclass
class Graph:
    """The explored state graph: states by number (:class:`~.store.Store`), the BFS tree
    (each state's parent; the choice that first reached it is the edge's, from the
    parent), the edges (:class:`~.store.Edges`, no self-loops), Zeno and cut states."""

    states: Store | PartialStore | PackedStore
    parent: array | np.ndarray  # (the compiled loop's: mapped from a file past a size)
    edges: Edges | Trail
    zeno: set[int] = field(default_factory=set)
    cut: set[int] = field(default_factory=set)  # states with a successor refused (the bound)
    exhaustive: bool = True
    bound: str | None = None  # why the exploration stopped short (:mod:`.bounds`)
    batch: int = 0  # states and choices the engine took at a time
    seconds: float = 0.0
    transitions: int = 0
    coverage: Coverage | None = None  # a partial search's estimate (None: exact storage)
    explorer: str = "python"  # which loop explored, in words (:func:`.kernel.chosen`)

    def path(self, k: int) -> list[int]:
        """State indices from the initial state to ``k`` (a shortest path)."""
        out = [k]
        while self.parent[out[-1]] != NONE:
            out.append(self.parent[out[-1]])
        return out[::-1]

    def succ(self, k: int) -> list[int]:
        """``k``'s successors (each once, in the order first reached)."""
        return self.edges.successors(k)

    @overload
    def edge_choice(self, a: int, b: int) -> tuple | None: ...

    @overload
    def edge_choice(self, a: int, b: int, default: tuple) -> tuple: ...

    def edge_choice(self, a: int, b: int, default: tuple | None = None) -> tuple | None:
        """The choice that leads from ``a`` to ``b`` (the first one tried)."""
        return self.edges.choice(a, b, default)

    def terminal(self) -> np.ndarray:
        """Which states are dead ends: no successor, and none refused by the bound (a cut
        state's successors are unknown, not absent)."""
        out = self.edges.dead_ends()
        out[list(self.cut)] = False
        return out


#: The fewest jobs a worker of a pool is given at a time (an engine call has a fixed cost).
MIN_CHUNK = 256

#: The most jobs the compiled loop gives the engine at a time.
KERNEL_BATCH = 1024

#: ``Graph.parent`` of the initial state.
NONE = 0xFFFFFFFF


def active_of(s: State, a: int, modes: int) -> np.ndarray:
    return np.frombuffer(s.agents[a][0][:modes], np.uint8).astype(bool)


def choices(m: Machine | Reactions, sk: Skeleton, s: State, opts: Options) -> list[tuple]:
    quiet = _invisible(s, opts, sk.hears)
    if quiet is not None:  # an ample set: only what can happen to that copy
        return _fates(s, opts, quiet)
    out: list[tuple] = []
    tried: set = set()
    for k, c in _arrivals(s, opts):
        if c not in tried:  # identical copies have identical successors
            tried.add(c)
            out += _fates(s, opts, k)
    for k, e in enumerate(s.outbox):
        if opts.ack_timing == "any" or not _in_flight(s, e):
            out.append(("timer", k))
    if s.cursor < len(m.scenario):
        out.append(("scenario",))
    local = [_local(m.local_choices, sk, a, part) for a, part in enumerate(s.agents)]
    quiet = not s.inflight and not s.outbox
    for a, (timed, _) in enumerate(local):
        for j, untimed in timed:
            if (
                opts.timeouts == "any"
                or untimed
                or (quiet if opts.timeouts == "long" else _settled(s, a))
            ):
                out.append(("time", a, j))
    for a, event in sk.world_events:
        if event in local[a][1]:
            out.append(("world", a, event))
    return out


def _local(cache: dict, sk: Skeleton, a: int, part: tuple) -> tuple:
    """What agent ``a``'s part enables, whatever the rest of the state: its time-driven
    transitions ``(j, untimed)`` (``untimed``: no ``after:``) whose source is active, and
    the world events some active mode waits for. Few distinct parts occur, each in many
    states (the store numbers each once), so each is worked out once (``cache``: the
    successor function's; an entry a part)."""
    got = cache.get((a, part))
    if got is None:
        ca = sk.cteam.agents[a]
        act = np.frombuffer(part[0][: len(ca.modes)], np.uint8).astype(bool)
        timed = tuple(
            (j, ca.transitions[j].after is None)
            for j in sk.time_driven[a]
            if act[ca.transitions[j].source]
        )
        events = frozenset(
            event
            for b, event in sk.world_events
            if b == a and any(act[ca.transitions[j].source] for j in ca.waiting(event))
        )
        got = cache[(a, part)] = (timed, events)
    return got


def _arrivals(s: State, opts: Options):
    """(position, copy) of the copies that may arrive next: all of them, or in fifo order
    the oldest on each link."""
    links: set = set()
    for k, c in enumerate(s.inflight):
        if opts.order == "fifo":
            link = (c.sender, c.receiver, c.socket)
            if link in links:
                continue
            links.add(link)
        yield k, c


def _fates(s: State, opts: Options, k: int) -> list[tuple]:
    """What may happen to copy ``k``: it arrives, or (within the bounds) is lost or
    duplicated."""
    out = [("deliver", k)]
    if s.losses < opts.losses:
        out.append(("lose", k))
    if s.dups < opts.duplicates:
        out.append(("dup", k))
    return out


def _invisible(s: State, opts: Options, hears: list[set[str]]) -> int | None:
    """A copy whose arrival no agent's modes see: an ack, a copy the receiver's duplicate
    filter withholds (it only answers with an ack), or a copy of a type its receiver has no
    transition for in any mode (``hears[a]``: the names agent ``a`` reacts to). Its arrival
    commutes with every other choice and no retransmission timer can expire while it
    flies (bounded ack timing), so exploring it first, alone with its loss and
    duplication, loses no behaviour (a partial-order reduction)."""
    if opts.ack_timing != "bounded":
        return None
    seen = set(s.seen)
    for k, c in _arrivals(s, opts):
        if (
            c.type == ACK
            or (c.msg_id >= 0 and (c.receiver, c.sender, c.msg_id) in seen)
            or c.type not in hears[c.receiver]
        ):
            return k
    return None


def _settled(s: State, a: int) -> bool:
    """Whether agent ``a``'s own messages are settled: none of its copies but acks in
    flight, nothing of it awaiting acks."""
    return not any(c.sender == a and c.type != ACK for c in s.inflight) and not any(
        e.sender == a for e in s.outbox
    )


def _in_flight(s: State, e) -> bool:
    """Whether a copy of outbox entry ``e`` or an ack of it is still in flight."""
    for c in s.inflight:
        if c.type == ACK:
            if c.receiver == e.sender and int(dict(c.fields)["id"]) == e.msg_id:
                return True
        elif c.sender == e.sender and c.msg_id == e.msg_id:
            return True
    return False


Progress = Callable[[int, int, int, float], None]  # states, frontier, depth, seconds
#: A state's representative under a reduction of equivalent states (:mod:`.symmetry`)
Reduce = Callable[[State], State]
#: An ample subset of a state's choices, or None (:mod:`.ample`)
Choose = Callable[[State, list[tuple]], list[tuple] | None]


def explore(
    sk: Skeleton,
    opts: Options,
    progress: Progress | None = None,
    reduce: Reduce | None = None,
    choose: Choose | None = None,
    note: Callable[[str], None] | None = None,
) -> Graph:
    """Every state reachable in the skeleton (up to ``opts.max_states``); with ``reduce``,
    one representative per class of equivalent states (each state is replaced by
    ``reduce(state)`` once computed); with ``choose``, a state is expanded by the subset
    of its choices ``choose`` picks, and fully once one of those leads to a state already
    stored (the cycle proviso: every cycle of the graph then has a fully expanded state).

    Python's cycle collector is off meanwhile: it would walk the millions of state tuples
    again and again (nearly half the time at 400,000 states), and exploring makes no
    cyclic garbage worth its work (the peak memory is the same with it on)."""
    was = gc.isenabled()
    gc.disable()
    try:
        return _explore(sk, opts, progress, reduce, choose, note)
    finally:
        if was:
            gc.enable()


def machine(sk: Skeleton, opts: Options, capacity: int) -> Machine | Reactions:
    """The successor function (each worker of a pool builds its own): the reaction tables,
    or with ``opts.reference`` the engine for every successor."""
    fifo = opts.order == "fifo"
    return (
        Machine(sk, capacity, fifo=fifo) if opts.reference else Reactions(sk, capacity, fifo=fifo)
    )


class _Reduced:
    """A machine whose successors are replaced by their representatives (``reduce``)."""

    def __init__(self, m: Machine | Reactions, reduce: Reduce) -> None:
        self.m, self.reduce = m, reduce

    def run(self, jobs: list[tuple]) -> list[Result]:
        return [Result(self.reduce(r.state), r.zeno, r.reads) for r in self.m.run(jobs)]


def reduced(m: Machine | Reactions, reduce: Reduce | None) -> Successors:
    """``m``, or ``m`` with each successor replaced by ``reduce(successor)``."""
    return m if reduce is None else _Reduced(m, reduce)


def _explore(
    sk: Skeleton,
    opts: Options,
    progress: Progress | None,
    reduce: Reduce | None,
    choose: Choose | None,
    note: Callable[[str], None] | None = None,
) -> Graph:
    if opts.jobs < 1:
        raise ValueError(f"jobs must be at least 1, got {opts.jobs}")
    start = time.perf_counter()
    limit = memory_limit(opts.max_memory)
    use, explorer = chosen(opts, reduce is not None or choose is not None, len(sk.cteam.agents))
    # the compiled loop's threads share this process's machine; a pool's workers each
    # have their own
    workers = 1 if use else opts.jobs
    # the engine's arrays take at most half the limit, shared by the workers; the
    # states, the rest (bounds.py)
    batch = instances_within(sk.cteam, opts.batch, limit, "verify", share=0.5 / workers)
    if use:  # the compiled loop asks the engine for new reactions only, a few at a time:
        # a smaller ensemble is built sooner (2,048 instances took 4 ms, 1,024 half a ms)
        batch = min(batch, KERNEL_BATCH)
    # with a pool, this process's machine only gives the initial state and the choices
    m = machine(sk, opts, batch if workers == 1 else 1)
    m.values = values = Values(sk, opts.max_values)
    succ = reduced(m, reduce)
    parent = array("I", [NONE])
    store: Store | PartialStore
    edges: Edges | Trail
    if opts.storage == "exact":
        store, edges = Store(len(sk.cteam.agents)), Edges()
    else:
        visited = visited_set(opts.storage, opts.bitstate_mb, opts.hash_functions)
        trail = Trail(parent)
        store, edges = PartialStore(len(sk.cteam.agents), visited), trail
        store.trail, store.successor = trail, _again(succ)
    g = Graph(store, parent, edges, batch=batch, explorer=explorer)
    if use:
        assert isinstance(m, Reactions)
        explore_packed(sk, opts, m, g, values, limit, start, progress, note)
        g.edges.freeze(len(g.states))
        g.seconds = time.perf_counter() - start
        return g
    initial = m.initial()
    store.add(store.find(initial if reduce is None else reduce(initial))[0])
    if opts.jobs > 1:
        with Pool(lambda: reduced(machine(sk, opts, batch), reduce), opts.jobs) as pool:
            _levels(sk, opts, m, succ, g, values, pool, limit, start, progress, choose)
    else:
        _levels(sk, opts, m, succ, g, values, None, limit, start, progress, choose)
    g.edges.freeze(len(store))
    if isinstance(store, PartialStore):
        store.advance([])
        g.coverage = store.visited.coverage(len(store))
        g.exhaustive = False
    g.seconds = time.perf_counter() - start
    return g


def _again(succ: Successors) -> Callable[[State, tuple, tuple], State]:
    """A state computed again from its parent, its choice and its tape."""
    return lambda s, choice, tape: succ.run([(s, choice, tape)])[0].state


def _levels(
    sk: Skeleton,
    opts: Options,
    m: Machine | Reactions,
    succ: Successors,
    g: Graph,
    values: Values,
    pool: Pool | None,
    limit: float,
    start: float,
    progress: Progress | None,
    choose: Choose | None,
) -> None:
    """The breadth-first search, level by level, from the initial state in ``g``."""
    store, batch = g.states, g.batch
    assert not isinstance(store, PackedStore)  # (the compiled loop has levels of its own)
    renumber = Renumber(store.parts, len(sk.cteam.agents))
    frontier = [0]
    depth = 0
    last = start
    stopped = False
    parents = g.parent
    assert isinstance(parents, array)  # (this loop's: in memory)
    while frontier and not stopped:
        nxt: list[int] = []
        retries: list[tuple] = []  # free comparisons' other answers, after the level's jobs
        put_off: dict[int, list[tuple]] = {}  # state -> the choices an ample set left out
        jobs = _jobs(m, sk, store, frontier, opts, choose, put_off)
        done: Iterator[tuple]
        if pool is None:
            done = _here(succ, store, _chunks(jobs, retries, batch))
        else:  # chunks small enough that a level keeps every worker busy
            size = min(batch, max(MIN_CHUNK, len(frontier) // pool.workers))
            done = pool.in_order(_chunks(jobs, [], size), retries, size, renumber)
        for chunk, results in done:
            if pool is not None:  # the workers' machines did not count the values
                _count_values(values, sk, store, [key for key, _, _ in results])
            for (sid, state, ch, tape), (key, zeno, reads) in zip(chunk, results, strict=True):
                retries += [(sid, state, ch, other) for other in other_answers(tape, reads)]
                g.transitions += 1
                tid = store.number(key)
                if tid is not None and sid in put_off:  # the cycle proviso: expand fully
                    retries += [(sid, state, c, ()) for c in put_off.pop(sid)]
                if tid is None:
                    if len(store) >= opts.max_states:
                        g.exhaustive = False
                        g.bound = g.bound or full(opts.max_states)
                        g.cut.add(sid)  # not a dead end: its successors are unknown
                        continue
                    tid = store.add(key)
                    parents.append(sid)
                    nxt.append(tid)
                if zeno and tid >= 0:
                    g.zeno.add(tid)
                if tid != sid:
                    g.edges.add(sid, tid, ch, tape)
            now = time.perf_counter()
            if progress is not None and now - last >= 1.0:
                progress(len(store), len(nxt), depth, now - start)
                last = now
            stop = over_memory(resident_bytes(), limit, len(store))
            if stop is not None:  # this level's states may be half expanded: all are cut
                stopped = _stop(g, stop, frontier, nxt)
                break
        else:
            stop = values.grown()
            if stop is not None:
                stopped = _stop(g, stop, nxt)
        frontier = nxt
        store.advance(frontier)
        depth += 1
    if progress is not None:
        progress(len(store), 0, depth, time.perf_counter() - start)


def _here(m: Successors, store: Store | PartialStore, chunks: Iterator[list]) -> Iterator[tuple]:
    """``(chunk, results)`` computed in this process: each job's successor as
    ``(key, zeno, reads)``, as a pool gives them (:meth:`.pool.Pool.in_order`)."""
    for chunk in chunks:
        results = m.run([job[1:] for job in chunk])
        yield chunk, [(store.key(r.state), r.zeno, r.reads) for r in results]


def _count_values(
    values: Values, sk: Skeleton, store: Store | PartialStore, keys: list[bytes]
) -> None:
    """Count the discrete variables' values of the states of ``keys`` (:mod:`.bounds`),
    as the machine does for the states it computes."""
    parts, count = store.parts.values, len(sk.discrete_vars)
    rows = [key_numbers(key)[:count] for key in keys]
    for a, cols in enumerate(sk.discrete_vars):
        if cols:
            block = np.array([parts[row[a]][1] for row in rows], float)
            values.add(a, block.reshape(len(keys), len(cols)))


def _stop(g: Graph, reason: str, *unexpanded: list[int]) -> bool:
    """End the exploration for ``reason`` (True); the states not (fully) expanded are cut:
    their successors are unknown, not absent."""
    g.exhaustive = False
    g.bound = reason if g.bound is None else f"{g.bound}; {reason}"
    for states in unexpanded:
        g.cut.update(states)
    return True


def other_answers(tape: tuple, reads: int) -> list[tuple]:
    """The tapes still to try after a step that answered ``tape`` and read ``reads`` free
    comparisons: each later comparison answered True, those before it as ``tape`` did
    (or False past its end) — so every combination of answers is tried once, in the
    order all the explorers, paths and replays share."""
    return [tape + (False,) * (k - len(tape)) + (True,) for k in range(len(tape), reads)]


def _jobs(
    m: Machine | Reactions,
    sk: Skeleton,
    store: Store | PartialStore,
    frontier: list[int],
    opts: Options,
    choose: Choose | None = None,
    put_off: dict[int, list[tuple]] | None = None,
):
    """A level's jobs ``(state number, state, choice, tape)``, state by state: each state
    is decoded once, and only the states of the chunk at work are held decoded. With
    ``choose``, the choices an ample subset leaves out go to ``put_off``."""
    for sid in frontier:
        state = store[sid]
        todo = choices(m, sk, state, opts)
        if choose is not None and put_off is not None:
            subset = choose(state, todo)
            if subset is not None:
                put_off[sid] = [c for c in todo if c not in subset]
                todo = subset
        for ch in todo:
            yield sid, state, ch, ()


def _chunks(jobs, retries: list, size: int):
    """Chunks of ``size`` jobs: the level's, then the retries the chunks append (in the
    order a single list of jobs growing at its end would give)."""
    chunk: list = []
    for job in jobs:
        chunk.append(job)
        if len(chunk) == size:
            yield chunk
            chunk = []
    done = 0
    while True:
        take = retries[done : done + size - len(chunk)]
        done += len(take)
        chunk += take
        if not chunk:
            return
        if len(chunk) == size or done == len(retries):
            yield chunk
            chunk = []
