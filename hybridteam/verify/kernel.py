"""The packed explorer: the common case of :func:`~.explore.explore` in a compiled loop.

Exact storage, no symmetry or ample-set reduction, the reaction tables: there each
successor is a table lookup, a composition and the canonical form, which Python does at
about 30,000 states a second. Here a state is one fixed-width row of small unsigned
integers (:class:`Layout`), stored collapsed: each of its groups (agents, copies, entries,
seen) numbered once in a table of its own, the state a few bytes of group numbers
(:class:`PackedStore`), the visited set an open-addressing table of state numbers; a
breadth-first level is expanded a chunk at a time (:class:`_Explorer`), its successors
computed by :func:`.kernel_core.successors` and numbered by :func:`.kernel_core.commit`
(numba, on ``--jobs`` threads): the same choices in the same order, the same reactions,
the same canonical form, the same numbering, so the graph is the Python path's, state for
state and edge for edge.

What the loop does not know it leaves to Python, job by job: numbering stops at a job the
tables cannot answer — a reaction the engine has not computed, a state whose parts are
not all settled (a Zeno phase's) — :class:`~.reactions.Reactions` computes it as it always
does (the engine, the checks of each new table entry), and numbering goes on from that
job. The Python path's functions stay the reference semantics:
``tests/verify/test_verify_kernel.py`` compares the two graphs on every verify test model.

numba is an optional dependency (``pip install hybridteam[fast]``); without it, or with
``HYBRIDTEAM_NUMBA=0`` (the public switch the tests use), ``--kernel auto`` explores in
Python and says so.
"""

from __future__ import annotations

import os
import tempfile
import time
from array import array
from collections.abc import Callable, Iterable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from functools import partial
from itertools import islice
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

import numpy as np

from hybridteam.engine.run.budget import resident_bytes
from hybridteam.engine.run.reliable import ACK
from hybridteam.verify.abstraction import Skeleton
from hybridteam.verify.bounds import Values, full, over_memory
from hybridteam.verify.machine import Copy, OutboxEntry, State
from hybridteam.verify.reactions import INPUT_ID, NEW_ID, NO_ID, Reactions
from hybridteam.verify.store import UINT, Edges, Grouped

if TYPE_CHECKING:
    from hybridteam.verify.explore import Graph, Options, Progress

#: Message ids per template in a row's numbers (:data:`.kernel_core.IDS`).
IDS = 64
#: The most copies (or entries) a state may hold (:data:`.kernel_core.ROOM`).
ROOM = 256
#: A stored state's collapsed groups (:data:`.kernel_core.GROUPS`, :class:`PackedStore`).
GROUPS = 4
#: Choice kinds (:mod:`.kernel_core`), and their words in a choice tuple.
KINDS = ("deliver", "lose", "dup", "timer", "scenario", "time", "world")
#: Copy templates' kinds: a plain message, an acknowledged one (an id), an ack.
PLAIN, WITH_ID, ACK_COPY = 0, 1, 2


def numba_available() -> bool:
    """Whether the compiled loop can run: numba importable and not switched off with
    ``HYBRIDTEAM_NUMBA=0`` (how a test, or a user, takes the Python path under ``auto``)."""
    if os.environ.get("HYBRIDTEAM_NUMBA", "1") == "0":
        return False
    try:
        import numba  # noqa: F401
    except ImportError:
        return False
    return True


def unavailable_reason(opts: Options, agents: int = 0) -> str | None:
    """Why the options (or a team of ``agents`` agents) keep the compiled loop out
    (None: they allow it)."""
    if opts.reference:
        return "--reference computes every successor with the engine"
    if opts.storage != "exact":
        return f"--storage {opts.storage} is a partial search"
    if opts.losses > 0xFFFF or opts.duplicates > 0xFFFF:
        return "the bounds exceed the packed rows' counters"
    if agents > 0xFF:
        return "more than 255 agents (an edge's choice keeps an agent in 8 bits)"
    return None


def chosen(opts: Options, reduced: bool, agents: int) -> tuple[bool, str]:
    """Whether to explore with the compiled loop (``opts.kernel``), and which loop
    explores, in words (verify's first line says it). ``reduced``: a symmetry or ample-set
    reduction is in effect (the Python loop explores it, ``on`` or not). Raises ValueError
    for ``kernel="on"`` without numba or with options it does not serve."""
    if opts.kernel not in ("auto", "on", "off"):
        raise ValueError(f"kernel must be auto, on or off, got {opts.kernel!r}")
    if opts.kernel == "off":
        return False, "python loop: --kernel off"
    reason = unavailable_reason(opts, agents)
    if reason is None and not numba_available():
        reason = "numba is not installed: pip install 'hybridteam[fast]'"
    if reason is not None and opts.kernel == "on":
        raise ValueError(f"--kernel on: {reason}")
    if reason is None and reduced:
        reason = "symmetry or ample-set reduction is on"
    if reason is not None:
        return False, f"python loop: {reason}"
    return True, "compiled kernel" + (f", {opts.jobs} threads" if opts.jobs > 1 else "")


def cache_dir() -> str:
    """Where numba keeps the compiled loop between runs: ``NUMBA_CACHE_DIR`` if set,
    else the user's cache folder (the package's own folder may not be writable)."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return os.environ.setdefault("NUMBA_CACHE_DIR", str(Path(base) / "hybridteam" / "numba"))


@dataclass
class Layout:
    """Where a row keeps what: ``agents`` part numbers, then ``copies`` slots, ``entries``
    slots and ``seen`` slots (each number plus one, 0 an empty slot), then cursor, losses
    and duplicates. The next ids are not kept: a canonical state's are the counts of the
    ids its agents have in use (:func:`.kernel_core.decode`)."""

    agents: int
    copies: int = 0
    entries: int = 0
    seen: int = 0

    @property
    def width(self) -> int:
        return self.agents + self.copies + self.entries + self.seen + 3

    def array(self) -> np.ndarray:
        return np.array([self.agents, self.copies, self.entries, self.seen], np.int64)

    def fit(self, need: tuple[int, int, int]) -> Layout:
        """This layout with room for ``need`` (copies, entries, seen)."""
        if max(need) > ROOM:
            raise RuntimeError(f"kernel: a state with more than {ROOM} copies or entries")
        return Layout(
            self.agents,
            max(self.copies, need[0]),
            max(self.entries, need[1]),
            max(self.seen, need[2]),
        )

    def widen(self, rows: np.ndarray, new: Layout) -> np.ndarray:
        """``rows`` in layout ``new`` (each group at its new place)."""
        out = np.zeros((rows.shape[0], new.width), rows.dtype)
        src = dst = self.agents
        out[:, :src] = rows[:, :src]
        for old_n, new_n in (
            (self.copies, new.copies),
            (self.entries, new.entries),
            (self.seen, new.seen),
        ):
            out[:, dst : dst + old_n] = rows[:, src : src + old_n]
            src, dst = src + old_n, dst + new_n
        out[:, dst:] = rows[:, src:]
        return out


class Packing:
    """The numbers a row is made of: agent parts, copy templates, outbox-entry templates,
    and the arrays the loop reads about them (rebuilt when something new is numbered)."""

    def __init__(self, sk: Skeleton, m: Reactions) -> None:
        self.sk, self.m = sk, m
        self.agents = len(sk.cteam.agents)
        self.part_number: dict[tuple, int] = {}
        self.values: list[tuple] = []  # part number -> the agent's part
        self.part_agent: list[int] = []
        self.templates: dict[tuple, int] = {}
        self.template_values: list[tuple] = []
        self.entry_number: dict[tuple, int] = {}
        self.entry_values: list[OutboxEntry] = []
        self.hears = sk.hears
        self.scenario = m.scenario
        self.dirty = True

    # ------------------------------------------------------------------ numbering
    def part(self, a: int, part: tuple) -> int:
        k = self.part_number.get((a, part))
        if k is None:
            k = self.part_number[(a, part)] = len(self.values)
            self.values.append(part)
            self.part_agent.append(a)
            self.dirty = True
        return k

    def template(self, t: tuple) -> int:
        k = self.templates.get(t)
        if k is None:
            k = self.templates[t] = len(self.template_values)
            self.template_values.append(t)
            self.dirty = True
        return k

    def entry(self, e: OutboxEntry) -> int:
        """An outbox entry's template (the entry with msg_id -1)."""
        e = e._replace(msg_id=-1)
        k = self.entry_number.get(e)
        if k is None:
            k = self.entry_number[e] = len(self.entry_values)
            self.entry_values.append(e)
            self.dirty = True
        return k

    def copy(self, c: Copy) -> tuple[int, int]:
        """A copy as (template, id)."""
        if c.type == ACK:
            if c.msg_id != -1 or len(c.fields) != 1:
                raise RuntimeError(f"kernel: an ack copy it cannot pack: {c}")
            t = (ACK_COPY, c.sender, c.receiver, c.socket, ACK, ())
            return self.template(t), int(c.fields[0][1])
        if c.msg_id >= 0:
            return self.template((WITH_ID, c.sender, c.receiver, c.socket, c.type, c.fields)), (
                c.msg_id
            )
        return self.template((PLAIN, c.sender, c.receiver, c.socket, c.type, c.fields)), 0

    def copy_of(self, t: int, k: int) -> Copy:
        kind, snd, rcv, socket, type_, fields = self.template_values[t]
        if kind == ACK_COPY:
            return Copy(snd, rcv, socket, ACK, -1, (("id", float(k)),))
        return Copy(snd, rcv, socket, type_, k if kind == WITH_ID else -1, fields)

    # ------------------------------------------------------------------ rows
    def pack(self, s: State, lay: Layout, out: np.ndarray) -> bool:
        """Write canonical state ``s`` into ``out``; False when it does not fit ``lay``."""
        if len(s.inflight) > lay.copies or len(s.outbox) > lay.entries or len(s.seen) > lay.seen:
            return False
        if s.next_ids != self._ids(s):
            raise RuntimeError(f"kernel: a state that is not canonical: {s}")
        out[:] = 0
        a = self.agents
        for b, part in enumerate(s.agents):
            out[b] = self.part(b, part)
        p = a
        for i, c in enumerate(s.inflight):
            t, k = self.copy(c)
            out[p + i] = t * IDS + k + 1
        p += lay.copies
        for i, e in enumerate(s.outbox):
            out[p + i] = self.entry(e) * IDS + e.msg_id + 1
        p += lay.entries
        for i, (r, snd, k) in enumerate(s.seen):
            out[p + i] = (r * a + snd) * IDS + k + 1
        p += lay.seen
        out[p : p + 3] = (s.cursor, s.losses, s.dups)
        return True

    def unpack(self, row: np.ndarray, lay: Layout) -> State:
        """The state of ``row``; its next ids are the counts of its ids in use per agent
        (as :meth:`~.machine.Machine.canonical` counts them)."""
        nums = row.tolist()
        a = self.agents
        agents = tuple(self.values[n] for n in nums[:a])
        p = a
        codes = [v - 1 for v in nums[p : p + lay.copies] if v]
        inflight = tuple(self.copy_of(v // IDS, v % IDS) for v in codes)
        p += lay.copies
        outbox = tuple(
            self.entry_values[v // IDS]._replace(msg_id=v % IDS)
            for v in (v - 1 for v in nums[p : p + lay.entries] if v)
        )
        p += lay.entries
        seen = tuple(
            (v // IDS // a, v // IDS % a, v % IDS)
            for v in (v - 1 for v in nums[p : p + lay.seen] if v)
        )
        p += lay.seen
        s = State(agents, inflight, outbox, seen, nums[p], nums[p + 1], nums[p + 2])
        return s._replace(next_ids=self._ids(s))

    def _ids(self, s: State) -> tuple:
        """Per agent, how many of its message ids ``s`` has in use (a canonical state's
        next ids: its ids are 0..n-1)."""
        live: list[set[int]] = [set() for _ in range(self.agents)]
        for c in s.inflight:
            if c.type == ACK:
                live[c.receiver].add(int(c.fields[0][1]))
            elif c.msg_id >= 0:
                live[c.sender].add(c.msg_id)
        for e in s.outbox:
            live[e.sender].add(e.msg_id)
        for _, snd, k in s.seen:
            live[snd].add(k)
        return tuple(len(ids) for ids in live)

    def fits16(self) -> bool:
        """Whether every number a row holds fits two bytes."""
        return (
            len(self.template_values) < 0xFFFF // IDS
            and len(self.entry_values) < 0xFFFF // IDS
            and len(self.values) < 0xFFFF
            and self.agents * self.agents * IDS < 0xFFFF
            and len(self.scenario) < 0xFFFF
        )

    # ------------------------------------------------------------------ the loop's arrays
    def tables(self) -> tuple:
        """The arrays :func:`.kernel_core.level` reads (rebuilt when something new was
        numbered: templates' sort ranks change as new ones arrive): per copy template its
        kind, sender, receiver, whether the receiver hears it, and its ranks (sender to
        type, fields, link); per entry template its sender, waiting mask and rank; per
        part where its time-driven transitions start and how many, those transitions
        (index, untimed), which world events it waits for; the world events' agents; the
        scenario's agents."""
        from hybridteam.verify.explore import _local

        sk, tv, ev = self.sk, self.template_values, self.entry_values
        key_rank = _ranks([(t[1], t[2], t[3], t[4]) for t in tv])
        field_rank = _ranks([t[5] for t in tv])
        link_rank = _ranks([(t[1], t[2], t[3]) for t in tv])
        copies = np.zeros((7, max(1, len(tv))), np.int64)
        for t, (kind, snd, rcv, _, type_, _) in enumerate(tv):
            copies[:4, t] = (kind, snd, rcv, type_ in self.hears[rcv])
        copies[4, : len(tv)] = key_rank[: len(tv)]
        copies[5, : len(tv)] = field_rank[: len(tv)]
        copies[6, : len(tv)] = link_rank[: len(tv)]
        rest = _ranks(
            [(e.type, e.socket, e.fields, e.waiting, e.retries_left, e.timeout, e.rank) for e in ev]
        )
        entries = np.zeros((3, max(1, len(ev))), np.int64)
        for k, e in enumerate(ev):
            entries[:2, k] = (e.sender, sum(1 << b for b in e.waiting))
        entries[2, : len(ev)] = rest[: len(ev)]
        t0: list[int] = []
        tn: list[int] = []
        tj: list[int] = []
        tu: list[int] = []
        world = np.zeros((max(1, len(self.values)), max(1, len(sk.world_events))), np.uint8)
        for p, (a, part) in enumerate(zip(self.part_agent, self.values, strict=True)):
            timed, events = _local(self.m.local_choices, sk, a, part)
            t0.append(len(tj))
            tn.append(len(timed))
            for j, untimed in timed:
                tj.append(j)
                tu.append(untimed)
            for w, (b, event) in enumerate(sk.world_events):
                world[p, w] = b == a and event in events
        starts = np.array([t0 or [0], tn or [0]], np.int64)
        flat = np.array([tj or [0], tu or [0]], np.int64)
        agents = np.array([a for a, _ in sk.world_events], np.int64)
        scen = np.array([a for _, a, _ in self.scenario] or [0], np.int64)
        self.dirty = False
        return copies, entries, starts, flat, world, agents, scen


def _ranks(values: list) -> np.ndarray:
    """Each value's rank among the distinct ``values`` in Python's order."""
    order = {v: k for k, v in enumerate(sorted(set(values)))}
    return np.array([order[v] for v in values] or [0], np.int64)


class Table:
    """The reaction tables as the loop reads them: a key row (input, part, tape) per
    kernel key, and per reaction its new part, Zeno flag, reads, copies, kept entry,
    new entries and filter flag (:class:`~.reactions.Reaction`, numbered)."""

    def __init__(self, pk: Packing) -> None:
        self.pk = pk
        self.synced = 0
        self.keys: list[tuple[int, int, int, int]] = []
        self.part: list[int] = []
        self.zeno: list[int] = []
        self.reads: list[int] = []
        self.c0: list[int] = []
        self.cn: list[int] = []
        self.c_tmpl: list[int] = []
        self.c_how: list[int] = []
        self.c_off: list[int] = []
        self.kept: list[int] = []
        self.e0: list[int] = []
        self.en: list[int] = []
        self.e_tmpl: list[int] = []
        self.e_off: list[int] = []
        self.filtered: list[int] = []
        self.arrays: tuple | None = None

    def sync(self) -> bool:
        """Number the entries the engine added since last time; whether any were."""
        table = self.pk.m.table
        if len(table) == self.synced:
            return False
        for key, r in islice(table.items(), self.synced, None):
            self._add(key, r)
        self.synced = len(table)
        self.arrays = None
        return True

    def _add(self, key: tuple, r) -> None:
        pk = self.pk
        kind = key[0]
        part, tape = key[-2], _tape(key[-1])
        if kind == "deliver":
            _, a, snd, socket, type_, fields, has_id, held = key[:8]
            t = pk.template((WITH_ID if has_id else PLAIN, snd, a, socket, type_, fields))
            inkeys = [_code(0, t, int(held))]
        elif kind == ACK:
            _, a, snd, socket, e = key[:5]
            t = pk.template((ACK_COPY, snd, a, socket, ACK, ()))
            inkeys = [_code(1, t, 0 if e is None else pk.entry(e) + 1)]
        elif kind == "timer":
            a = key[1]
            inkeys = [_code(2, pk.entry(key[2]), 0)]
        elif kind == "scenario":
            a, name = key[1], key[2]
            inkeys = [
                _code(3, c, 0) for c, (_, b, n) in enumerate(pk.scenario) if (b, n) == (a, name)
            ]
        elif kind == "time":
            a = key[1]
            inkeys = [_code(4, a, key[2])]
        else:  # world
            a = key[1]
            inkeys = [
                _code(5, w, 0) for w, ev in enumerate(pk.sk.world_events) if ev == (a, key[2])
            ]
        n = len(self.part)
        p = pk.part(a, part)
        self.keys += [(k, p, tape, n) for k in inkeys]
        self.part.append(pk.part(a, r.part))
        self.zeno.append(int(r.zeno))
        self.reads.append(r.reads)
        self.c0.append(len(self.c_tmpl))
        self.cn.append(len(r.copies))
        for c, how, off in r.copies:
            if c.type == ACK:
                t = pk.template((ACK_COPY, c.sender, c.receiver, c.socket, ACK, ()))
            else:
                kind_c = PLAIN if how == NO_ID else WITH_ID
                t = pk.template((kind_c, c.sender, c.receiver, c.socket, c.type, c.fields))
            self.c_tmpl.append(t)
            self.c_how.append({NO_ID: 0, INPUT_ID: 1, NEW_ID: 2}[how])
            self.c_off.append(off)
        self.kept.append(-1 if r.kept is None else pk.entry(r.kept))
        self.e0.append(len(self.e_tmpl))
        self.en.append(len(r.entries))
        for e, off in r.entries:
            self.e_tmpl.append(pk.entry(e))
            self.e_off.append(off)
        self.filtered.append(int(r.filtered))

    def array(self) -> tuple:
        if self.arrays is None:
            from hybridteam.verify.kernel_core import place_reaction

            rk = np.array(self.keys or [(-1, -1, -1, -1)], np.int64)
            slots = np.full(_pow2(2 * len(self.keys) + 2), -1, np.int64)
            for r in range(len(self.keys)):
                place_reaction(rk, slots, r)

            def rows(*columns: list[int]) -> np.ndarray:
                return np.array([c or [0] for c in columns], np.int64)

            self.arrays = (
                rk,
                slots,
                rows(
                    self.part,
                    self.zeno,
                    self.reads,
                    self.c0,
                    self.cn,
                    self.kept,
                    self.e0,
                    self.en,
                    self.filtered,
                ),
                rows(self.c_tmpl, self.c_how, self.c_off),
                rows(self.e_tmpl, self.e_off),
            )
        return self.arrays


def _code(kind: int, x: int, y: int) -> int:
    return (kind << 40) | (x << 20) | y


def _tape(tape: tuple) -> int:
    """A tape of answers as one number: a leading 1, then the answers (bit i: answer i)."""
    return (1 << len(tape)) | sum(1 << i for i, b in enumerate(tape) if b)


def _untape(code: int) -> tuple:
    n = code.bit_length() - 1
    return tuple(bool(code >> i & 1) for i in range(n))


def _pow2(n: int) -> int:
    return 1 << max(4, (n - 1).bit_length())


class PackedStore:
    """The explored states, collapsed (SPIN's COLLAPSE idea): a state's row
    (:class:`Layout`) is cut into groups — the agents' parts, the copies, the entries,
    the seen triples with the counters — and each group's distinct sub-rows are kept
    once, in a table of their own found again through an open-addressing table; a state
    is its groups' numbers, each in as few bytes as its group needs (a key), found again
    through an open-addressing table of state numbers. The groups repeat: three robots
    with one loss have 2.4 million states but 156 agent tuples and about 200,000 copy
    and entry tuples each, so a state takes 9 bytes instead of a 58-byte row. The
    canonical row is what is interned, so a state's identity, and with it the numbering,
    is the row's. ``store[k]`` decodes state ``k``; answers what properties,
    counterexamples and replays ask of :class:`~.store.Store`: ``len``, ``store[k]``,
    ``agents_of(k)``, ``agent_parts`` and ``parts.values``."""

    def __init__(self, pk: Packing, lay: Layout) -> None:
        self.pk, self.lay = pk, lay
        self.dtype: Any = np.dtype(np.uint16)
        self.widths = np.ones(GROUPS, np.int64)  # each group number's bytes in a key
        self.keys = np.zeros((1024, GROUPS), np.uint8)
        self.n = 0
        self.slots = np.full(2048, -1, np.int32)
        bounds = self.bounds
        self.groups = [np.zeros((16, bounds[g + 1] - bounds[g]), self.dtype) for g in range(GROUPS)]
        self.group_slots = [np.full(32, -1, np.int32) for _ in range(GROUPS)]
        self.counts = np.zeros(GROUPS, np.int64)
        self.parts = pk  # ``parts.values``: agent parts by number

    @property
    def bounds(self) -> list[int]:
        """Where each group's columns start in a row, and the row's end."""
        from hybridteam.verify.kernel_core import group_bounds

        return group_bounds(self.lay.array()).tolist()

    def __len__(self) -> int:
        return self.n

    def __getitem__(self, k: int) -> State:
        if not -self.n <= k < self.n:
            raise IndexError(k)
        return self.pk.unpack(self.row(k % self.n), self.lay)

    def __iter__(self):
        return (self[k] for k in range(self.n))

    def numbers(self, g: int, rows: slice | np.ndarray) -> np.ndarray:
        """Group ``g``'s numbers of the states ``rows`` (from their keys' bytes)."""
        at = int(self.widths[:g].sum())
        out = np.zeros(self.keys[rows, 0].shape, np.int64)
        for i in range(int(self.widths[g])):
            out |= self.keys[rows, at + i].astype(np.int64) << (8 * i)
        return out

    def states(self, numbers: list[int]) -> dict[int, State]:
        """The states ``numbers``, decoded together (the groups' numbers read once for
        all of them)."""
        rows = self.rows(np.array(numbers, np.int64))
        return {k: self.pk.unpack(row, self.lay) for k, row in zip(numbers, rows, strict=True)}

    def rows(self, at: np.ndarray) -> np.ndarray:
        """The rows of states ``at``, each its groups' sub-rows side by side."""
        return np.concatenate([self.groups[g][self.numbers(g, at)] for g in range(GROUPS)], axis=1)

    def row(self, k: int) -> np.ndarray:
        """State ``k``'s row."""
        return self.rows(np.array([k]))[0]

    def agents_of(self, k: int) -> tuple:
        parts = self.groups[0][self.numbers(0, np.array([k]))[0]]
        return tuple(self.pk.values[p] for p in parts.tolist())

    @property
    def agent_parts(self) -> Grouped:
        """Each state's agent part numbers, as its agents group's number and that group's
        table (the checks read them block by block: no column of every state)."""
        return Grouped(partial(self.numbers, 0), self.groups[0][: self.counts[0]], self.n)

    def add(self, row: np.ndarray) -> int:
        """The number of the state whose row is ``row``, stored if it is new."""
        from hybridteam.verify.kernel_core import grow, intern, key_offsets

        self.reserve(1)
        if not self.group_slots[0].size:  # (sealed: the lookup tables went)
            self._regroup()
        while True:
            k, got = intern(
                self.keys,
                self.n,
                self.slots,
                tuple(self.groups),
                tuple(self.group_slots),
                self.counts,
                np.array(self.bounds, np.int64),
                key_offsets(self.widths),
                self.widths,
                row,
                np.zeros(GROUPS, np.int64),
                np.zeros(self.keys.shape[1], np.uint8),
                True,
                row,
                np.full(GROUPS, -1, np.int64),
            )
            if k >= -1:
                self.n += got
                return k
            if k == -2:
                self.widen_key(got)
            else:
                groups, slots = grow(tuple(self.groups), tuple(self.group_slots), self.counts, got)
                self.groups, self.group_slots = list(groups), list(slots)

    def reserve(self, more: int) -> None:
        """Room for ``more`` keys, and a table at most half full with them (the groups'
        tables grow as the loop fills them)."""
        need = self.n + more
        if need > self.keys.shape[0]:  # (in place where the allocator can: no second copy)
            grown = max(need, self.keys.shape[0] + self.keys.shape[0] // 16)
            self.keys.resize((grown, self.keys.shape[1]), refcheck=False)
        if 10 * need > 7 * self.slots.size:  # at most 70 % full
            self._rehash(_pow2(2 * need))

    def seal(self) -> None:
        """Exploring is done: the keys and the groups' tables shrink to what they hold
        and the lookup tables go (states are only read by number from now on), before
        the checks take their arrays."""
        self.keys.resize((max(self.n, 1), self.keys.shape[1]), refcheck=False)
        self.slots = np.zeros(0, np.int32)
        for g in range(GROUPS):
            self.groups[g] = self.groups[g][: max(int(self.counts[g]), 1)].copy()
            self.group_slots[g] = np.zeros(0, np.int32)

    def _rehash(self, size: int = 0) -> None:
        """The table of states built again, of ``size`` slots or more."""
        from hybridteam.verify.kernel_core import rehash

        self.slots = np.zeros(0, np.int32)  # (the old one goes first)
        self.slots = np.full(max(size, _pow2(2 * self.n)), -1, np.int32)
        rehash(self.keys, self.n, self.slots)

    def widen_key(self, g: int) -> None:
        """One more byte for group ``g``'s numbers in every key (the group outgrew its
        bytes); the table of states is built again."""
        if self.widths[g] >= 4:
            raise RuntimeError("kernel: more than 2**32 distinct sub-rows in a group")
        at = int(self.widths[: g + 1].sum())
        keys = np.zeros((self.keys.shape[0], self.keys.shape[1] + 1), np.uint8)
        keys[:, :at] = self.keys[:, :at]
        keys[:, at + 1 :] = self.keys[:, at:]
        self.keys = keys
        self.widths[g] += 1
        self._rehash(self.slots.size)  # (as large as the level reserved)

    def relayout(self, lay: Layout, dtype: Any) -> None:
        """Rows in a wider layout or a wider integer type (a count or a number outgrew
        them): each group's table widened; the keys, and the states' numbers, stay."""
        old = self.bounds
        wide = np.zeros((max(int(self.counts.max()), 1), self.lay.width), self.dtype)
        rows = [np.zeros(0)] * GROUPS
        for g in range(GROUPS):  # (each group through the layout's widening, alone)
            wide[:] = 0
            c = int(self.counts[g])
            wide[:c, old[g] : old[g + 1]] = self.groups[g][:c]
            rows[g] = self.lay.widen(wide, lay)
        self.lay, self.dtype = lay, np.dtype(dtype)
        new = self.bounds
        tables = []
        for g in range(GROUPS):
            c = int(self.counts[g])
            table = np.zeros((max(self.groups[g].shape[0], 16), new[g + 1] - new[g]), self.dtype)
            table[:c] = rows[g][:c, new[g] : new[g + 1]]
            tables.append(table)
        self.groups = tables
        self._regroup()

    def _regroup(self) -> None:
        """The groups' lookup tables built again (at most half full)."""
        from hybridteam.verify.kernel_core import regroup

        self.group_slots = [np.full(_pow2(2 * max(int(c), 16)), -1, np.int32) for c in self.counts]
        regroup(tuple(self.groups), tuple(self.group_slots), self.counts)


def explore_packed(
    sk: Skeleton,
    opts: Options,
    m: Reactions,
    g: Graph,
    values: Values,
    limit: float,
    start: float,
    progress: Progress | None,
    note: Callable[[str], None] | None = None,
) -> None:
    """:func:`~.explore._levels` for the packed store: fills ``g`` (its ``states``
    become a :class:`PackedStore`, its edges an :class:`~.store.Edges`), with
    ``opts.jobs`` threads computing successors."""
    where = cache_dir()
    from hybridteam.verify import kernel_core as kc

    if note is not None and not kc.commit.signatures:  # (not yet loaded in this process)
        note(f"compiled kernel: loading it from {where}, or compiling it there (first run)")
    if opts.jobs == 1:
        _Explorer(sk, opts, m, g, None).run(values, limit, start, progress)
        return
    with ThreadPoolExecutor(opts.jobs, thread_name_prefix="verify") as pool:
        _Explorer(sk, opts, m, g, pool).run(values, limit, start, progress)


#: States a chunk of a level takes at a time (shared by the threads), and queued retries.
CHUNK = 32768
#: Below this many states a chunk is not shared (a thread's start costs more).
SHARED = 2048


@dataclass
class _Part:
    """One thread's share of a chunk: the jobs of states ``lo..hi-1`` (``main``) or the
    queued retries ``lo..hi-1``; the arrays phase A reads, as they stood when the share
    was cut (``args``: phase B may append to the store meanwhile, never move what phase
    A reads), and its layout; its output (:func:`.kernel_core.successors`): ``count``
    jobs in ``job`` and ``rows``."""

    main: bool
    lo: int
    hi: int
    buffer: tuple[int, int]  # (which of the two chunks in the making, which share)
    args: tuple
    lay: Layout
    job: np.ndarray
    rows: np.ndarray
    count: int = 0

    def fit(self, lay: Layout, dtype: Any) -> None:
        """Its rows in the store's layout and integer type, if either changed since phase
        A computed them."""
        if lay != self.lay or self.rows.dtype != dtype:
            self.rows = self.lay.widen(self.rows[: self.count], lay).astype(dtype)
            self.lay = lay


class _Explorer:
    """The breadth-first levels of the compiled loop. A level is taken a chunk at a time,
    each in two phases: the successors of the chunk's jobs (phase A: it writes nothing
    shared), then their numbering in the order one thread would take them (phase B,
    :func:`.kernel_core.commit`: the store, parents, edges, the queue of retries). Phase
    B stops where it cannot go on: a job the tables did not answer (Python computes it,
    :meth:`_fill`), a successor wider than the layout, an array full; that is fixed and
    phase B goes on from that job. So the graph is the one-threaded loop's, state for
    state, with any number of threads.

    With a ``pool``, phase A of a level's first chunk is shared by its threads, and
    while phase B numbers a chunk, a thread computes the next chunk's successors (phase
    B is as long as phase A, and one thread's: the two cores are both busy). Phase B
    only appends to the store's arrays meanwhile; what would move them (a larger key
    array) waits for that thread (:meth:`_quiet`)."""

    def __init__(
        self, sk: Skeleton, opts: Options, m: Reactions, g: Graph, pool: ThreadPoolExecutor | None
    ) -> None:
        self.sk, self.opts, self.m, self.g, self.pool = sk, opts, m, g, pool
        self.threads = opts.jobs if pool is not None else 1
        self.pk = Packing(sk, m)
        self.table = Table(self.pk)
        self.store = PackedStore(self.pk, Layout(self.pk.agents))
        initial = m.initial()
        self.store.relayout(self.store.lay.fit(_counts(initial)), self.store.dtype)
        first = np.zeros(self.store.lay.width, self.store.dtype)
        self.pk.pack(initial, self.store.lay, first)
        self.store.add(first)
        self.parent = np.full(1024, 0xFFFFFFFF, np.uint32)  # a level's, from ``st[8]``
        timeouts = {"any": 0, "own": 1, "long": 2}[opts.timeouts]
        self.opt = np.array(
            [
                opts.order == "fifo",
                opts.ack_timing == "bounded",
                timeouts,
                opts.losses,
                opts.duplicates,
                len(m.scenario),
            ],
            np.int64,
        )
        self.tb: tuple = ()
        self.settled = np.zeros(1, np.uint8)
        self.edges = PackedEdges(partial(first_choices, sk, opts, m, self.store))
        # each share's output, by (which of the two chunks in the making, which share)
        self.shares: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]] = {}
        self.pending: Future | None = None  # the next chunk's phase A, on a thread
        # this level's edges, Zeno and cut states, queued retries
        self.e_src, self.e_dst = np.zeros(1024, np.uint32), np.zeros(1024, np.uint32)
        self.zeno = np.zeros(1024, np.uint32)
        self.cut = np.zeros(1024, np.uint32)
        self.queue = np.zeros((3, 1024), np.int64)
        # phase B's counts: states, edges, Zeno, cut, queued, next job, a full group; the
        # level's jobs taken; the state of ``parent[0]``
        self.st = np.zeros(9, np.int64)
        self.parents = Column()  # each state's, from the levels done

    def run(self, values: Values, limit: float, start: float, progress: Progress | None) -> None:
        g, store, opts = self.g, self.store, self.opts
        lo, hi = 0, 1
        depth = 0
        while lo < hi:
            self._level(lo, hi)
            ne, nz, nx = (int(v) for v in self.st[1:4])
            g.transitions += int(self.st[7])
            self.edges.add_level(lo, hi, self.e_src[:ne], self.e_dst[:ne])
            g.zeno.update(self.zeno[:nz].tolist())
            if nx:
                g.exhaustive = False
                g.bound = g.bound or full(opts.max_states)
                g.cut.update(self.cut[:nx].tolist())
            lo, hi = hi, store.n
            depth += 1
            if progress is not None:
                progress(store.n, hi - lo, depth, time.perf_counter() - start)
            stop = over_memory(resident_bytes(), limit, store.n)
            if stop is None:
                stop = values.grown()
            if stop is not None:
                _stop(g, stop, range(lo, hi))
                break
        if progress is not None:
            progress(store.n, 0, depth, time.perf_counter() - start)
        store.seal()
        g.states = store
        g.parent = self.parents.view()
        g.edges = self.edges

    # ------------------------------------------------------------------ a level
    def _level(self, lo: int, hi: int) -> None:
        """Expand states ``lo..hi-1``: their jobs, then the retries they queue."""
        store = self.store
        store.reserve(hi - lo)
        self.st[:8] = 0
        self.st[0] = store.n
        self._grow_level(2 * (hi - lo))
        chunks = [(a, min(hi, a + CHUNK)) for a in range(lo, hi, CHUNK)]
        for c, (a, b) in enumerate(chunks):
            if self.pending is None:
                self._prepare()
                parts = self._phase_a(self._split(True, a, b, c % 2, self.threads))
            else:
                parts = self.pending.result()
                self.pending = None
            if self.pool is not None and c + 1 < len(chunks):
                self._prepare()
                after = self._split(True, *chunks[c + 1], (c + 1) % 2, 1)
                self.pending = self.pool.submit(self._phase_a, after)
            self._commit_all(parts)
        done = 0
        while done < self.st[4]:  # the retries the level queued, a chunk at a time
            self._prepare()
            parts = self._split(False, done, min(int(self.st[4]), done + CHUNK), 0, self.threads)
            done = parts[-1].hi
            self._commit_all(self._phase_a(parts))
        store.n = int(self.st[0])
        self.parents.append(self.parent[: store.n - int(self.st[8])])
        self.st[8] = store.n

    def _grow_level(self, edges: int) -> None:
        """The level's arrays, at least ``edges`` long for its edges."""
        if self.e_dst.size < edges:
            self.e_src = np.zeros(edges, np.uint32)
            self.e_dst = np.zeros(edges, np.uint32)

    def _prepare(self) -> None:
        """The tables as the loop reads them, with whatever Python numbered since."""
        self.table.sync()
        if self.store.dtype == np.uint16 and not self.pk.fits16():
            self.store.relayout(self.store.lay, np.uint32)
        if self.pk.dirty or not self.tb:
            self.tb = self.pk.tables()
        self.settled = _settled(self.pk, self.m)

    def _split(self, main: bool, lo: int, hi: int, which: int, threads: int) -> list[_Part]:
        """Jobs ``lo..hi-1`` (states' or queued), one share per thread (one below
        :data:`SHARED` jobs); ``which``: the chunk's buffers (0 or 1)."""
        from hybridteam.verify.kernel_core import JOB_COLUMNS

        store = self.store
        shares = threads if hi - lo >= SHARED else 1
        width, dtype = store.lay.width, store.dtype
        args = (
            store.keys,
            tuple(store.groups),
            store.widths.copy(),
            store.lay.array(),
            *self.tb,
            *self.table.array(),
            self.opt,
            self.settled,
        )
        cuts = [lo + (hi - lo) * t // shares for t in range(shares + 1)]
        parts = []
        for t in range(shares):
            job, rows = self.shares.get((which, t), (np.zeros((0, 0), np.int64), None))
            want = 2 * (cuts[t + 1] - cuts[t]) + 64 if main else cuts[t + 1] - cuts[t]
            if rows is None or job.shape[0] < want or rows.shape[1] != width or rows.dtype != dtype:
                size = max(want, job.shape[0])
                job = np.zeros((size, JOB_COLUMNS), np.int64)
                rows = np.zeros((size, width), dtype)
                self.shares[(which, t)] = (job, rows)
            parts.append(_Part(main, cuts[t], cuts[t + 1], (which, t), args, store.lay, job, rows))
        return parts

    def _phase_a(self, parts: list[_Part]) -> list[_Part]:
        """Phase A of a chunk's shares (each on a thread of the pool, if there is one)."""
        if self.pool is None or len(parts) == 1:
            for part in parts:
                self._successors(part)
        else:
            for f in [self.pool.submit(self._successors, part) for part in parts]:
                f.result()
        return parts

    def _successors(self, part: _Part) -> None:
        """Phase A of one share (from the arrays as they stood when it was cut): its
        output grows as it fills."""
        from hybridteam.verify.kernel_core import successors

        at = np.zeros(3, np.int64)
        lo, ci = part.lo, 0
        queue = self.queue
        while not successors(  # type: ignore[call-arg]
            *part.args, lo, part.hi, ci, queue, part.main, part.job, part.rows, at
        ):
            lo, ci = int(at[1]), int(at[2])
            part.job = _grown(part.job, 2 * part.job.shape[0])
            part.rows = _grown(part.rows, 2 * part.rows.shape[0])
            self.shares[part.buffer] = (part.job, part.rows)
        part.count = int(at[0])

    def _quiet(self) -> None:
        """Wait for the next chunk's phase A, if one is under way (before the store's
        arrays move)."""
        if self.pending is not None:
            self.pending.result()

    def _commit_all(self, parts: list[_Part]) -> None:
        for part in parts:
            part.fit(self.store.lay, self.store.dtype)  # (widened while it waited)
            self._commit(part)
            self.st[7] += part.count

    def _commit(self, part: _Part) -> None:
        """Phase B of a share, from its first job to its last."""
        from hybridteam.verify import kernel_core as kc

        store, st = self.store, self.st
        st[5] = 0
        while True:
            status, groups, slots = kc.commit(
                store.keys,
                store.slots,
                tuple(store.groups),
                tuple(store.group_slots),
                store.counts,
                store.widths,
                store.lay.array(),
                part.job,
                part.rows,
                part.count,
                self.opts.max_states,
                self.parent,
                self.e_src,
                self.e_dst,
                self.zeno,
                self.cut,
                self.queue,
                st,
            )
            store.groups, store.group_slots = list(groups), list(slots)
            store.n = int(st[0])
            if status == kc.OK:
                return
            if status == kc.FULL:
                self._room()
            elif status == kc.GROUP_FULL:  # a group outgrew its bytes in the keys
                store.widen_key(int(st[6]))
            elif status in (kc.MISS, kc.OVERFLOW):
                self._fill(part, int(st[5]))
            else:
                raise RuntimeError(f"kernel: more than {IDS} message ids of one agent at once")

    def _room(self) -> None:
        """Whichever of phase B's arrays is full, grown (the store's by a level's worth)."""
        from hybridteam.verify.kernel_core import MAX_READS

        n, ne, nz, nx, nq = (int(v) for v in self.st[:5])
        store = self.store
        self._quiet()  # (a larger key array may move)
        store.reserve(max(1024, n // 8))
        if n - int(self.st[8]) >= self.parent.size:
            self.parent = _grown(self.parent, self.parent.size * 3 // 2 + 1024, 0xFFFFFFFF)
        if ne >= self.e_dst.size:
            size = self.e_dst.size * 3 // 2 + 1024
            self.e_src = _grown(self.e_src, size)
            self.e_dst = _grown(self.e_dst, size)
        if nz >= self.zeno.size:
            self.zeno = _grown(self.zeno, 2 * self.zeno.size)
        if nx >= self.cut.size:
            self.cut = _grown(self.cut, 2 * self.cut.size)
        if nq + MAX_READS > self.queue.shape[1]:
            queue = np.zeros((3, 2 * self.queue.shape[1]), np.int64)
            queue[:, :nq] = self.queue[:, :nq]
            self.queue = queue

    def _fill(self, part: _Part, first: int) -> None:
        """The jobs of a share from ``first`` that phase A could not take (a reaction the
        tables do not hold, a part not settled, a successor wider than the layout),
        computed by Python (the engine, through the reaction tables) into the share's
        output; the layout widened if one needs it (the share's rows with it; the other
        shares' before their phase B, :meth:`_commit_all`)."""
        from hybridteam.verify import kernel_core as kc

        store = self.store
        status = part.job[first : part.count, 3]
        todo = np.flatnonzero((status == kc.MISS) | (status == kc.OVERFLOW)) + first
        asked = part.job[todo, :3].tolist()
        states = store.states(sorted({sid for sid, _, _ in asked}))
        jobs = [
            (
                states[sid],
                _choice(self.sk, code >> 40, (code >> 20) & 0xFFFFF, code & 0xFFFFF),
                _untape(tape),
            )
            for sid, code, tape in asked
        ]
        results = []
        for i in range(0, len(jobs), self.g.batch):
            results += self.m.run(jobs[i : i + self.g.batch])
        lay = store.lay.fit(_most(r.state for r in results))
        rows = np.zeros((len(todo), lay.width), np.int64)
        for j, r in enumerate(results):
            self.pk.pack(r.state, lay, rows[j])
        dtype = store.dtype if self.pk.fits16() else np.dtype(np.uint32)
        if lay != store.lay or dtype != store.dtype:
            store.relayout(lay, dtype)
            part.fit(lay, dtype)
        for j, (i, r) in enumerate(zip(todo.tolist(), results, strict=True)):
            part.rows[i] = rows[j]
            part.job[i, 3:6] = (kc.OK, int(r.zeno), r.reads)


def _grown(a: np.ndarray, size: int, fill: int = 0) -> np.ndarray:
    """``a`` in a longer array (its first axis ``size``), the rest ``fill``."""
    out = np.full((size, *a.shape[1:]), fill, a.dtype)
    out[: a.shape[0]] = a
    return out


def _stop(g: Graph, reason: str, unexpanded: range) -> None:
    g.exhaustive = False
    g.bound = reason if g.bound is None else f"{g.bound}; {reason}"
    g.cut.update(unexpanded)


def _settled(pk: Packing, m: Reactions) -> np.ndarray:
    """Per part number: whether the engine left it settled (:class:`~.reactions.Reactions`)."""
    return np.array(
        [part in m.settled[a] for a, part in zip(pk.part_agent, pk.values, strict=True)] or [False],
        np.uint8,
    )


def _counts(s: State) -> tuple[int, int, int]:
    return len(s.inflight), len(s.outbox), len(s.seen)


def _most(states: Iterable[State]) -> tuple[int, int, int]:
    """The most copies, entries and seen triples any of ``states`` holds."""
    copies = entries = seen = 0
    for s in states:
        copies, entries, seen = (
            max(copies, len(s.inflight)),
            max(entries, len(s.outbox)),
            max(seen, len(s.seen)),
        )
    return copies, entries, seen


def _choice(sk: Skeleton, kind: int, x: int, y: int) -> tuple:
    """A choice (kind, x, y) as the explorer's choice tuple."""
    word = KINDS[kind]
    if word in ("deliver", "lose", "dup", "timer"):
        return (word, x)
    if word == "scenario":
        return ("scenario",)
    if word == "time":
        return ("time", x, y)
    return ("world", x, sk.world_events[y][1])


class PackedEdges(Edges):
    """:class:`~.store.Edges` kept in sparse-row order as they come, so that freezing
    copies nothing: a level expands states ``lo..hi`` and its edges are placed by source
    (a counting sort, each state's in the order added) before they are appended, which
    puts every edge after those of earlier states. Instead of a source an edge, each
    expanded state's edge count is kept (two bytes while every count fits them). An
    edge's choice is not kept: only a path's edges need it (a counterexample, a replay),
    so :meth:`choice` works it out again from the edge's states (:func:`first_choices`:
    the first of the source's jobs, in the order the loop takes them, whose successor is
    the destination). At hundreds of millions of edges the edges are most of what exploring
    and the checks hold: 4 bytes an edge and 2 a state (the Python loop's
    :class:`~.store.Edges`: 12 an edge, and a sorted copy when frozen)."""

    def __init__(self, first_choices: Callable[[int, list[int]], dict[int, tuple]]) -> None:
        super().__init__()
        self.first_choices = first_choices
        self.column = Column()  # the destinations (in memory, or spilled to a file)
        self._of = -1  # the last state asked, and its edges' choices
        self._firsts: dict[int, tuple] = {}
        self.degree = array("H")  # the edges of each state expanded so far

    def __len__(self) -> int:
        return len(self.column)

    def add_level(self, lo: int, hi: int, src: np.ndarray, dst: np.ndarray) -> None:
        """Append the edges of the level that expanded states ``lo..hi``, in the order
        the loop made them."""
        from hybridteam.verify.kernel_core import by_source, row_offsets

        if src.size and not lo <= int(src.min()) <= int(src.max()) < hi:
            raise RuntimeError(f"kernel: a level's edge leaves from outside states {lo}..{hi}")
        rel = src.astype(np.int64) - lo
        row = np.zeros(hi - lo + 1, np.int64)
        row_offsets(rel, row)
        placed = np.zeros(rel.size, UINT)
        by_source(rel, row, dst.astype(UINT, copy=False), placed)
        del rel
        self.column.append(placed)
        degree = np.diff(row)
        if self.degree.typecode == "H" and degree.size and int(degree.max()) > 0xFFFF:
            self.degree = array("I", self.degree)
        self.degree.frombytes(degree.astype(self.degree.typecode).tobytes())

    def freeze(self, states: int) -> None:
        """The sparse-row view: the edges as they are, and the offsets summed from the
        counts (states never expanded, beyond a bound, have none)."""
        if self._row is not None:
            return
        degree = np.frombuffer(self.degree, self.degree.typecode) if len(self.degree) else None
        # 32-bit offsets while they fit: the checks' sparse arrays take them as they are
        row = np.zeros(states + 1, np.int32 if len(self.column) < 2**31 else np.int64)
        if degree is not None:
            row[1 : degree.size + 1] = degree
        np.cumsum(row, out=row)
        del degree
        self.degree = array("H")
        if row[-1] != len(self.column):
            raise RuntimeError("kernel: the edge counts do not add up to the edges")
        self._row, self._dst = row, self.column.view()

    def choice(self, a: int, b: int, default: tuple | None = None) -> tuple | None:
        """The choice of edge ``a -> b`` (the first the loop took), or ``default``."""
        row, dst, _ = self._ready()
        if not (dst[row[a] : row[a + 1]] == b).any():
            return default
        if self._of != a:  # (a path asks state by state: its edges' choices at once)
            self._of, self._firsts = a, self.first_choices(a, dst[row[a] : row[a + 1]].tolist())
        if b not in self._firsts:
            raise RuntimeError(f"kernel: no choice of state {a} leads to state {b}")
        return self._firsts[b]


def first_choices(
    sk: Skeleton, opts: Options, m: Reactions, states: PackedStore, a: int, ends: list[int]
) -> dict[int, tuple]:
    """For each of the states ``ends``, the first choice of state ``a`` that leads there,
    in the order the loop takes ``a``'s jobs (its choices, then the free comparisons'
    other answers each asks for, in the order asked: :func:`~.explore._chunks` keeps one
    state's jobs in that order), computed by the Python loop's successor function."""
    from hybridteam.verify.explore import choices, other_answers

    decoded = states.states([a, *ends])
    s = decoded[a]
    number = {decoded[b]: b for b in ends}
    firsts: dict[int, tuple] = {}
    jobs: list[tuple[tuple, tuple]] = [(ch, ()) for ch in choices(m, sk, s, opts)]
    done = 0
    while done < len(jobs) and len(firsts) < len(number):
        batch = jobs[done : done + m.capacity]
        done += len(batch)
        for (ch, tape), r in zip(batch, m.run([(s, ch, tape) for ch, tape in batch]), strict=True):
            jobs += [(ch, other) for other in other_answers(tape, r.reads)]
            b = number.get(r.state)
            if b is not None and b not in firsts:
                firsts[b] = ch
    return firsts


#: A :class:`Column` past this many bytes moves to a temporary file.
SPILL = 1 << 30


class Column:
    """An append-only column of 32-bit numbers (an edge's destination, a state's parent):
    in memory up to :data:`SPILL` bytes, then in an unnamed temporary file (in ``TMPDIR``,
    gone with the process), written a level at a time and read back mapped
    (:meth:`view`). Beyond a few hundred million states these columns are a third of
    what a check holds, and only a path (its parents, its edges' choices) and the checks'
    block-by-block passes read them: the system keeps in memory what it has room for."""

    def __init__(self) -> None:
        self.memory = array("I")
        self.file: IO[bytes] | None = None
        self.n = 0

    def __len__(self) -> int:
        return self.n

    def append(self, values: np.ndarray) -> None:
        values = values.astype(UINT, copy=False)
        if self.file is None and 4 * (self.n + values.size) > SPILL:
            # (open as long as the column: closed with it, when the graph goes)
            self.file = tempfile.TemporaryFile(prefix="hybridteam-verify-")  # noqa: SIM115
            self.file.write(memoryview(self.memory).cast("B"))
            self.memory = array("I")
        raw = np.ascontiguousarray(values).data.cast("B")  # (not copied)
        if self.file is not None:
            self.file.write(raw)
        else:
            self.memory.frombytes(raw)
        self.n += values.size

    def view(self) -> np.ndarray:
        """The numbers, not copied (a read-only map of the file once spilled)."""
        if not self.n:
            return np.zeros(0, UINT)
        if self.file is None:
            return np.frombuffer(self.memory, UINT)
        self.file.flush()
        return np.memmap(self.file, UINT, "r", shape=(self.n,))
