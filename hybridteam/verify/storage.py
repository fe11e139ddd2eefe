"""Partial-search storage: visited states as hashes, for state spaces beyond memory.

The exact store (:mod:`hybridteam.verify.store`) keeps every state, so a check is
exhaustive but its size is bounded by memory. Like SPIN, the explorer can instead remember
only a hash of each visited state (``--storage``):

- **hashcompact**: a 64-bit hash per state in an open-addressing table (8 bytes a slot, at
  most half full). Two states with the same hash are taken for one, and the second is not
  explored: with ``n`` states the expected number of such omissions is about
  ``n (n - 1) / 2**65`` (each new state meets each stored hash with probability
  ``2**-64``), a few in a billion at a million states.
- **bitstate**: a Bloom filter, SPIN's supertrace: ``k`` hash functions set ``k`` bits per
  state in a bit array of a fixed size (``--bitstate-mb``, SPIN's ``-w``). The i-th new
  state is taken for a visited one when its ``k`` bits are all set already, with
  probability ``(1 - exp(-k i / m))**k`` for ``m`` bits; the sum over the states
  explored is the expected number of omissions. SPIN's *hash factor* ``m / n`` (bits per
  state) says the same more roughly: above 100 omissions are rare.

Either way the search is **partial**: a state taken for a visited one is not expanded, so
its successors may be missed too; the verdicts say so, with the estimate. What is kept
per state is what the checks and the counterexamples need and not the state itself: its
parent and the choice that reached it (:class:`Trail`), and its agents' parts (the modes
and discrete variables the invariants and ``deadlock`` read, a few numbers a state).
The states of the two BFS levels at work are held as their keys (the exact store's
compact form, :func:`~.store.state_key`); a state on a counterexample
is computed again from the initial state along its path of choices (as SPIN follows its
trail), with the explorer's own successor function.
"""

from __future__ import annotations

import hashlib
import math
from array import array
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from hybridteam.verify.machine import State
from hybridteam.verify.store import Parts, decode, key_numbers, state_key

#: The storage modes; "exact" is :class:`~.store.Store`.
STORAGES = ("exact", "hashcompact", "bitstate")
#: Bits set per state in bitstate mode unless told (SPIN's ``-k`` default).
DEFAULT_HASH_FUNCTIONS = 3
#: The bit array's size in bitstate mode unless told (MB of 2**20 bytes).
DEFAULT_BITSTATE_MB = 64.0
#: ``find``'s answer for a state seen before whose number is not kept.
SEEN = -1


def digest(key: bytes) -> tuple[int, int]:
    """Two independent 64-bit hashes of a state's key (BLAKE2b: the same in every process
    and run, unlike Python's salted ``hash``; a search is repeatable)."""
    d = hashlib.blake2b(key, digest_size=16).digest()
    return int.from_bytes(d[:8], "little"), int.from_bytes(d[8:], "little")


@dataclass
class Coverage:
    """How complete a partial search is estimated to be."""

    storage: str
    states: int
    expected_omissions: float  # states estimated to have been taken for visited ones
    bytes: int  # the visited set's memory
    hash_factor: float | None = None  # bitstate: bits per state (SPIN's hash factor)
    hash_functions: int | None = None

    @property
    def any_omission(self) -> float:
        """The probability that at least one state was omitted (omissions as rare
        independent events: Poisson, ``1 - exp(-expected omissions)``)."""
        return -math.expm1(-self.expected_omissions)

    @property
    def coverage(self) -> float:
        """The estimated share of the states reached that were explored (omitted states'
        own successors are not counted: an estimate, as SPIN's)."""
        return self.states / (self.states + self.expected_omissions) if self.states else 1.0

    def words(self) -> str:
        """One line: what was searched and how completely."""
        extra = (
            f", hash factor {self.hash_factor:,.1f} bits/state with {self.hash_functions} "
            "hash functions"
            if self.hash_factor is not None
            else ""
        )
        share = "above 99.9999%" if self.coverage > 0.999999 else f"{100 * self.coverage:.4f}%"
        return (
            f"PARTIAL search ({self.storage}, {self.bytes / 2**20:,.1f} MB{extra}): expected "
            f"omissions {self.expected_omissions:.3g}, estimated coverage {share}"
        )

    def summary(self) -> dict:
        return {
            "storage": self.storage,
            "partial": True,
            "states": self.states,
            "expected_omissions": self.expected_omissions,
            "probability_of_an_omission": self.any_omission,
            "estimated_coverage": self.coverage,
            "visited_bytes": self.bytes,
            **(
                {"hash_factor": self.hash_factor, "hash_functions": self.hash_functions}
                if self.hash_factor is not None
                else {}
            ),
        }


class HashCompact:
    """Visited states as 64-bit hashes in a numpy open-addressing table (linear probing;
    0 marks an empty slot, so a hash of 0 is stored as 1). The table doubles at half full."""

    name = "hashcompact"

    def __init__(self, slots: int = 1 << 16) -> None:
        self.table = np.zeros(slots, np.uint64)
        self.mask = slots - 1
        self.count = 0

    def _slot(self, h: int) -> tuple[int, bool]:
        """``h``'s slot and whether it holds ``h`` (else it is the empty slot to fill)."""
        table, mask = self.table, self.mask
        i = h & mask
        while True:
            k = int(table[i])
            if k == 0:
                return i, False
            if k == h:
                return i, True
            i = (i + 1) & mask

    def contains(self, d: tuple[int, int]) -> bool:
        return self._slot(d[0] or 1)[1]

    def add(self, d: tuple[int, int]) -> None:
        if 2 * (self.count + 1) > self.mask + 1:
            self._grow()
        h = d[0] or 1
        i, there = self._slot(h)
        if not there:
            self.table[i] = h
            self.count += 1

    def _grow(self) -> None:
        old = self.table[self.table != 0]
        self.table = np.zeros(2 * (self.mask + 1), np.uint64)
        self.mask = 2 * self.mask + 1
        for h in old.tolist():
            self.table[self._slot(h)[0]] = h

    def coverage(self, states: int) -> Coverage:
        return Coverage(self.name, states, states * (states - 1) / 2.0**65, self.table.nbytes)


class Bitstate:
    """Visited states as ``k`` bits each in a fixed bit array (a Bloom filter). The ``k``
    bit positions come from the digest's two hashes by double hashing (``h1 + i h2``),
    as good as ``k`` independent hashes for a Bloom filter (Kirsch and Mitzenmacher)."""

    name = "bitstate"

    def __init__(self, megabytes: float, hash_functions: int) -> None:
        self.bits = np.zeros(max(1, int(megabytes * 2**20)), np.uint8)
        self.m = self.bits.size * 8
        self.k = hash_functions
        self.count = 0

    def _positions(self, d: tuple[int, int]) -> list[int]:
        h1, h2 = d
        return [(h1 + i * h2) % self.m for i in range(self.k)]

    def contains(self, d: tuple[int, int]) -> bool:
        bits = self.bits
        return all(bits[p >> 3] >> (p & 7) & 1 for p in self._positions(d))

    def add(self, d: tuple[int, int]) -> None:
        for p in self._positions(d):
            self.bits[p >> 3] |= 1 << (p & 7)
        self.count += 1

    def coverage(self, states: int) -> Coverage:
        return Coverage(
            self.name,
            states,
            omissions(states, self.m, self.k),
            self.bits.nbytes,
            self.m / states if states else math.inf,
            self.k,
        )


def omissions(n: int, m: int, k: int) -> float:
    """Expected states taken for visited ones when ``n`` states enter a Bloom filter of
    ``m`` bits and ``k`` hash functions: the i-th finds its ``k`` bits set with
    probability ``(1 - exp(-k i / m))**k`` (``i`` states in already)."""
    total = 0.0
    for lo in range(0, n, 1 << 20):
        i = np.arange(lo, min(n, lo + (1 << 20)), dtype=float)
        total += float(np.sum((-np.expm1(-k * i / m)) ** k))
    return total


Visited = HashCompact | Bitstate


def visited_set(storage: str, bitstate_mb: float, hash_functions: int) -> Visited:
    """The visited set of a partial search of kind ``storage``."""
    if storage == "hashcompact":
        return HashCompact()
    if storage == "bitstate" and bitstate_mb > 0 and hash_functions >= 1:
        return Bitstate(bitstate_mb, hash_functions)
    raise ValueError(
        f"no partial storage {storage!r} with {bitstate_mb:g} MB and {hash_functions} "
        f"hash functions (storage: one of {', '.join(STORAGES)}; MB > 0; 1 hash function "
        "or more)"
    )


class Trail:
    """What a partial search keeps of the graph: for each state the choice (and the free
    comparisons' answers) that first reached it from its parent, and how many transitions
    leave it to another state (no edge lists: their targets are not numbered). Enough
    for the BFS tree's paths, dead ends and ``deadlock``; not for liveness."""

    def __init__(self, parent: array) -> None:
        self.parent = parent
        self.how = array("I", [0])  # state k's (choice, tape): self.steps.values[how[k]]
        self.steps = Parts()
        self.steps.of(("initial", ()))
        self.out = array("I", [0])
        self.count = 0
        self._degree: np.ndarray | None = None

    def __len__(self) -> int:
        return self.count

    def add(self, a: int, b: int, choice: tuple, tape: tuple = ()) -> None:
        """A transition from ``a`` to ``b`` (:data:`SEEN`: a state seen before, number
        not kept); the first one to a new state is its way there."""
        self.count += 1
        self.out[a] += 1
        if b == len(self.how):
            self.how.append(self.steps.of((choice, tape)))
            self.out.append(0)
        self._degree = None

    def freeze(self, states: int) -> None:
        self._degree = np.frombuffer(self.out, np.uint32)[:states].astype(np.int64)

    def out_degree(self) -> np.ndarray:
        if self._degree is None:
            raise RuntimeError("the trail is not frozen (call freeze after exploring)")
        return self._degree

    def dead_ends(self) -> np.ndarray:
        """Which states no edge leaves."""
        return self.out_degree() == 0

    def way(self, k: int) -> tuple[tuple, tuple]:
        """The (choice, tape) that first reached state ``k`` from its parent."""
        return self.steps.values[self.how[k]]

    def choice(self, a: int, b: int, default: tuple | None = None) -> tuple | None:
        """The choice from ``a`` to ``b`` where ``a`` is ``b``'s parent (a path of the
        BFS tree); other edges are not kept."""
        if 0 < b < len(self.how) and self.parent[b] == a:
            return self.way(b)[0]
        return default

    def successors(self, k: int) -> list[int]:
        raise RuntimeError("a partial search keeps no edge lists (use --storage exact)")

    def csr(self) -> tuple[np.ndarray, np.ndarray]:
        raise RuntimeError("a partial search keeps no edge lists (use --storage exact)")


#: Decoded states kept for paths computed again (counterexamples share their prefixes).
CACHE = 4096


class PartialStore:
    """States by number, as :class:`~.store.Store` answers for them, with only hashes of
    the visited ones: the states of the BFS levels at work are held as their keys (as
    the exact store holds every state), older ones are computed again along their path
    (:meth:`__getitem__`)."""

    def __init__(self, agents: int, visited: Visited) -> None:
        self.agents = agents
        self.visited = visited
        self.parts = Parts()  # numbers of states' parts, for keys and agent entries
        self.agent_parts = array("I")
        self.held: dict[int, bytes] = {}  # the current and the next level: their keys
        self.numbers: dict[bytes, int] = {}  # and their numbers by key
        self.count = 0
        self._last: tuple[bytes, tuple[int, int]] | None = None  # number()'s, for add()
        self._root: bytes | None = None  # the initial state's key
        self._cache: OrderedDict[int, State] = OrderedDict()
        #: (state, choice, tape) -> successor: set by the explorer, to compute a state again
        self.successor: Callable[[State, tuple, tuple], State] | None = None
        self.trail: Trail | None = None

    def __len__(self) -> int:
        return self.count

    def key(self, s: State) -> bytes:
        return state_key(self.parts, s)

    def find(self, s: State) -> tuple[bytes, int | None]:
        """``s``'s key and its number (:meth:`number`)."""
        key = self.key(s)
        return key, self.number(key)

    def number(self, key: bytes) -> int | None:
        """The number of the state of ``key``, :data:`SEEN` when it was visited but its
        number is not kept, or None if it is new."""
        k = self.numbers.get(key)
        if k is not None:
            return k
        d = digest(key)
        self._last = (key, d)
        return SEEN if self.visited.contains(d) else None

    def add(self, key: bytes) -> int:
        """Store the state of ``key`` (the last one :meth:`number` was asked); its
        number."""
        assert self._last is not None and self._last[0] == key, "add follows number"
        k = self.count
        self.count += 1
        self.visited.add(self._last[1])
        self.agent_parts.extend(key_numbers(key)[: self.agents].tolist())
        self.held[k] = key
        self.numbers[key] = k
        if k == 0:
            self._root = key
        return k

    def advance(self, frontier: list[int]) -> None:
        """The next level is ``frontier``: states before it are no longer held."""
        keep = set(frontier)
        self.held = {k: key for k, key in self.held.items() if k in keep}
        self.numbers = {key: k for k, key in self.held.items()}

    def agents_of(self, k: int) -> tuple:
        """State ``k``'s agents (modes and discrete variables), from what is kept."""
        values = self.parts.values
        return tuple(values[n] for n in self.agent_parts[k * self.agents : (k + 1) * self.agents])

    def __getitem__(self, k: int) -> State:
        if not -len(self) <= k < len(self):
            raise IndexError(k)
        k %= len(self)
        known = self._known(k)
        if known is not None:
            return known
        assert self.successor is not None and self.trail is not None, "set by the explorer"
        # up the BFS tree to a state held, cached or the initial one, then down again
        # (a loop, not a recursion: a path may be long)
        path = [k]
        while (s := self._known(self.trail.parent[path[-1]])) is None:
            path.append(self.trail.parent[path[-1]])
        for j in reversed(path):
            choice, tape = self.trail.way(j)
            s = self.successor(s, choice, tape)
            if s.agents != self.agents_of(j) or not self.visited.contains(
                digest(state_key(self.parts, s))
            ):
                raise RuntimeError(
                    f"state {j} computed again differs from the one explored: the successor "
                    "function is not deterministic"
                )
            self._cache[j] = s
            if len(self._cache) > CACHE:
                self._cache.popitem(last=False)
        return s

    def _known(self, k: int) -> State | None:
        """State ``k`` if it is held, cached or the initial one, else None."""
        if k in self.held:
            return decode(self.parts, self.agents, self.held[k])
        if k == 0 and self._root is not None:
            return decode(self.parts, self.agents, self._root)
        if k in self._cache:
            self._cache.move_to_end(k)
            return self._cache[k]
        return None

    def __iter__(self):
        return (self[k] for k in range(len(self)))
