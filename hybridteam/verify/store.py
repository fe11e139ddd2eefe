"""Explored states and edges, stored compactly: what lets the explorer hold millions.

A skeleton state is a tuple of parts (each agent's configuration and variables, the copies
in flight, the outbox entries, the seen ids, a few counters), and very few distinct parts
occur across millions of states. :class:`Store` numbers each distinct part once and keeps a
state as the bytes of its part numbers (about 50 bytes, against about 1.2 kB for the
tuples; two bytes a number while there are fewer than 65,535 parts), decoding a state only
when it is asked for. :class:`Edges` keeps the graph's edges as three integer arrays
(source, target, choice number) and answers successors from a compressed sparse row view
built once exploring is done.
"""

from __future__ import annotations

from array import array
from collections.abc import Callable, Iterator

import numpy as np

from hybridteam.verify.machine import State

#: The integer arrays' numpy type (``array("I")`` items are 4 bytes wherever we run).
UINT = np.dtype(f"u{array('I').itemsize}")


class Parts:
    """Distinct hashable values, numbered in order of first appearance."""

    __slots__ = ("number", "values")

    def __init__(self) -> None:
        self.number: dict = {}
        self.values: list = []

    def of(self, value) -> int:
        k = self.number.get(value)
        if k is None:
            k = self.number[value] = len(self.values)
            self.values.append(value)
        return k


#: An empty slot of :class:`Keys`' table.
EMPTY = 0xFFFFFFFF


class Keys:
    """Distinct byte strings, numbered in order of arrival, in one buffer.

    A dict of bytes objects costs about 180 bytes a key beyond the key's own bytes (the
    object's header, the entry, the number as an int object); here a key costs its bytes,
    an 8-byte end offset, its hash's low 32 bits and two to four 4-byte slots of an
    open-addressing table (linear probing on Python's hash of the key), about 75 bytes in
    all for a state's key."""

    def __init__(self) -> None:
        self.buf = bytearray()
        self.ends = array("Q")
        self.prints = array("I")  # each key's hash, low 32 bits: most probes stop there
        self.slots = array("I", [EMPTY]) * 1024
        self.mask = 1023

    def __len__(self) -> int:
        return len(self.ends)

    def __getitem__(self, k: int) -> bytes:
        return bytes(self.buf[self.ends[k - 1] if k else 0 : self.ends[k]])

    def get(self, key: bytes) -> int | None:
        """``key``'s number, or None."""
        slots, mask, buf, ends, prints = self.slots, self.mask, self.buf, self.ends, self.prints
        h = hash(key)
        fp = h & EMPTY
        i = h & mask
        while True:
            k = slots[i]
            if k == EMPTY:
                return None
            if prints[k] == fp and buf[ends[k - 1] if k else 0 : ends[k]] == key:
                return k
            i = (i + 1) & mask

    def add(self, key: bytes) -> int:
        """Number a key that :meth:`get` did not find."""
        k = len(self.ends)
        if 2 * (k + 1) > self.mask + 1:
            self._grow()
        h = hash(key)
        self._place(h, k)
        self.prints.append(h & EMPTY)
        self.buf += key
        self.ends.append(len(self.buf))
        return k

    def _place(self, h: int, k: int) -> None:
        slots, mask = self.slots, self.mask
        i = h & mask
        while slots[i] != EMPTY:
            i = (i + 1) & mask
        slots[i] = k

    def _grow(self) -> None:
        self.slots = array("I", [EMPTY]) * (2 * (self.mask + 1))
        self.mask = 2 * self.mask + 1
        for k, fp in enumerate(self.prints):  # the slot comes from the hash's low bits
            self._place(fp, k)


def state_key(parts: Parts, s: State) -> bytes:
    """``s`` as the bytes of its parts' numbers (layout: :class:`Store`)."""
    # (Parts.of written out: a call per part is a fifth of the key's time)
    number, values = parts.number, parts.values
    nums: list[int] = []
    for group in (s.agents, s.inflight, s.outbox, s.seen):
        if nums:  # the groups after the agents are counted
            nums.append(len(group))
        for p in group:
            k = number.get(p)
            if k is None:
                k = number[p] = len(values)
                values.append(p)
            nums.append(k)
    nums += (s.cursor, s.losses, s.dups, *s.next_ids)
    return _pack(nums)


def _pack(nums: list[int]) -> bytes:
    if max(nums) < 0xFFFF:  # two bytes a number while parts are few (the usual case)
        return b"H" + array("H", nums).tobytes()
    return b"I" + array("I", nums).tobytes()


class Renumber:
    """Keys made in other processes (each with its own :class:`Parts`), in this process's
    part numbers. A source sends the values of the parts it numbered since it last sent
    (:meth:`learn`), with its keys; a part gets its number here when a key first reads
    it, in the key's order — the order :func:`state_key` numbers them in — so keys read
    in the order one process would have made them are numbered as that process would."""

    def __init__(self, parts: Parts, agents: int) -> None:
        self.parts, self.agents = parts, agents
        self.values: dict[int, list] = {}  # source -> its parts' values by its numbers
        self.tables: dict[int, list[int]] = {}  # source -> its numbers' here (-1: none yet)

    def learn(self, source: int, new: list) -> None:
        self.values.setdefault(source, []).extend(new)
        self.tables.setdefault(source, []).extend([-1] * len(new))

    def key(self, source: int, key: bytes) -> bytes:
        values, table, of = self.values[source], self.tables[source], self.parts.of
        nums = key_numbers(key).tolist()
        at = list(range(self.agents))  # where the part numbers are (the rest: counts)
        pos = self.agents
        for _ in range(3):
            at += range(pos + 1, pos + 1 + nums[pos])
            pos += 1 + nums[pos]
        for i in at:
            n = nums[i]
            t = table[n]
            if t < 0:
                t = table[n] = of(values[n])
            nums[i] = t
        return _pack(nums)


class Store:
    """States by number: each kept once as the bytes of its parts' numbers.

    Layout of a state's numbers: the agents' parts (one each), then the copies in flight,
    the outbox entries and the seen triples (each a count, then the parts), then cursor,
    losses, duplicates and the agents' next message ids."""

    def __init__(self, agents: int) -> None:
        self.agents = agents
        self.parts = Parts()
        self.keys = Keys()
        self.agent_parts = array("I")  # state k's agent a: agent_parts[k * agents + a]

    def __len__(self) -> int:
        return len(self.keys)

    def key(self, s: State) -> bytes:
        return state_key(self.parts, s)

    def find(self, s: State) -> tuple[bytes, int | None]:
        """``s``'s key and its number, or None if it is not stored."""
        key = self.key(s)
        return key, self.keys.get(key)

    def number(self, key: bytes) -> int | None:
        """The number of the state of ``key``, or None if it is not stored."""
        return self.keys.get(key)

    def add(self, key: bytes) -> int:
        """Store the state of ``key`` (from :meth:`find`); its new number."""
        k = self.keys.add(key)
        self.agent_parts.extend(key_numbers(key)[: self.agents].tolist())
        return k

    def advance(self, frontier: list[int]) -> None:
        """The explorer's next level is ``frontier`` (the exact store keeps every state:
        nothing to let go; :class:`~.storage.PartialStore` lets older ones go)."""

    def agents_of(self, k: int) -> tuple:
        """State ``k``'s agents (modes and discrete variables) without decoding the rest."""
        values = self.parts.values
        return tuple(values[n] for n in self.agent_parts[k * self.agents : (k + 1) * self.agents])

    def __getitem__(self, k: int) -> State:
        if not -len(self.keys) <= k < len(self.keys):
            raise IndexError(k)
        return decode(self.parts, self.agents, self.keys[k % len(self.keys)])

    def __iter__(self) -> Iterator[State]:
        return (self[k] for k in range(len(self.keys)))


def decode(parts: Parts, agents: int, key: bytes) -> State:
    """The state of ``key`` (:func:`state_key`) for a team of ``agents`` agents."""
    nums = key_numbers(key)
    values = parts.values
    pos, groups = agents, []
    for _ in range(3):
        count = nums[pos]
        groups.append(tuple(values[n] for n in nums[pos + 1 : pos + 1 + count]))
        pos += 1 + count
    cursor, losses, dups = nums[pos : pos + 3]
    return State(
        tuple(values[n] for n in nums[:agents]),
        groups[0],
        groups[1],
        groups[2],
        cursor,
        losses,
        dups,
        tuple(nums[pos + 3 :]),
    )


def key_numbers(key: bytes) -> array:
    """A key's numbers (its first byte names their width)."""
    nums = array(chr(key[0]))
    nums.frombytes(key[1:])
    return nums


class Grouped:
    """Each state's agent part numbers kept collapsed (the packed store's): a number per
    state into a table of the distinct tuples. ``grouped[rows]`` is the states ``rows``'
    part numbers ``(len(rows), agents)``, made for those rows only (the checks read them
    block by block)."""

    def __init__(
        self, number: Callable[[slice | np.ndarray], np.ndarray], table: np.ndarray, n: int
    ) -> None:
        self.number, self.table, self.n = number, table, n

    def __len__(self) -> int:
        return self.n

    def __getitem__(self, rows: slice | np.ndarray) -> np.ndarray:
        return self.table[self.number(rows)]


class Edges:
    """The graph's edges (no self-loops) as integer arrays, and successors by state.

    Edges are added while exploring; :meth:`freeze` builds the sparse-row view that
    :meth:`successors`, :meth:`out_degree` and :meth:`choice` read. Of several choices
    between the same two states the first one added is the edge's choice."""

    def __init__(self) -> None:
        self.src = array("I")
        self.dst = array("I")
        self.how = array("I")
        self.choices = Parts()
        self._row: np.ndarray | None = None
        self._dst: np.ndarray | None = None
        self._how: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.src)

    def add(self, a: int, b: int, choice: tuple, tape: tuple = ()) -> None:
        """Edge ``a -> b`` by ``choice`` (``tape``, the free comparisons' answers, is not
        kept: the states are, and a step is matched again from them)."""
        self.src.append(a)
        self.dst.append(b)
        self.how.append(self.choices.of(choice))
        self._row = None

    def freeze(self, states: int) -> None:
        src = np.frombuffer(self.src, UINT) if len(self.src) else np.zeros(0, UINT)
        order = np.argsort(src, kind="stable")  # a state's edges in the order added
        self._dst = (
            np.frombuffer(self.dst, UINT)[order] if len(self.dst) else np.zeros(0, UINT)
        ).astype(np.int64)
        self._how = np.frombuffer(self.how, UINT)[order] if len(self.how) else np.zeros(0, UINT)
        self._row = np.zeros(states + 1, np.int64)
        np.cumsum(np.bincount(src, minlength=states), out=self._row[1:])

    def view(self) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """The sparse-row view: each state's edges ``row[k]:row[k + 1]``, their
        destinations and their choices' numbers (in ``choices``), in the order added."""
        return self._ready()

    def _ready(self) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """The sparse-row view (the choices' numbers None where they are not kept)."""
        if self._row is None or self._dst is None:  # (set together)
            raise RuntimeError("edges are not frozen (call freeze after exploring)")
        return self._row, self._dst, self._how

    def successors(self, k: int) -> list[int]:
        """``k``'s successors, in the order their edges were added, each once."""
        row, dst, _ = self._ready()
        return list(dict.fromkeys(dst[row[k] : row[k + 1]].tolist()))

    def out_degree(self) -> np.ndarray:
        row, _, _ = self._ready()
        return np.diff(row)

    def dead_ends(self) -> np.ndarray:
        """Which states no edge leaves (no array of out-degrees: at 600 million states
        that would be 2.4 GB)."""
        row, _, _ = self._ready()
        return row[1:] == row[:-1]

    def csr(self) -> tuple[np.ndarray, np.ndarray]:
        """``(indptr, indices)`` of the successor lists (duplicates possible)."""
        row, dst, _ = self._ready()
        return row, dst

    def choice(self, a: int, b: int, default: tuple | None = None) -> tuple | None:
        """The choice of edge ``a -> b`` (the first added), or ``default``."""
        row, dst, how = self._ready()
        hits = np.flatnonzero(dst[row[a] : row[a + 1]] == b)
        if not hits.size:
            return default
        assert how is not None  # (kept by these edges)
        return self.choices.values[int(how[row[a] + hits[0]])]
