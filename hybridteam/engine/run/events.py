"""Pending discrete events: scripted scenario events, local events, message deliveries.

Events at the same time are handled in a fixed order — (time, kind, rank, receiving agent,
sequence number) with kinds ordered scenario < message < local < timer — so a run is a pure
function of the model and the seed. ``rank`` is minus a message's declared priority: of two
requests arriving at the same instant, the higher-priority one is handled first. Sequence
numbers count per instance, so an instance's events do not
depend on its neighbours in an ensemble.
"""

from __future__ import annotations

import heapq
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from hybridteam.arrays import spread

SCENARIO, MESSAGE, LOCAL, TIMER = 0, 1, 2, 3


class EventQueue:
    """Per-instance queues with a vector of next due times for the integrator."""

    def __init__(self, n: int, scenario: Sequence[tuple[float, int, str]]) -> None:
        self.n = n
        self.scenario = list(scenario)
        self.scn_t = np.array([s[0] for s in scenario] + [np.inf])
        self.cursor = np.zeros(n, np.intp)
        self.heaps: dict[int, list[tuple]] = {}
        self.seq = np.zeros(n, np.int64)
        self.next = np.full(n, np.inf)
        #: message events no instant needs (:mod:`.quiet`): ``(receiving agent, type)``
        #: pairs whose copies are held apart, out of ``next``, while ``holding`` (per
        #: instance) — but a copy that arrives as it is sent, within its send's instant
        #: (where a law whose mode was entered then samples again); empty unless the
        #: simulator asks (a live run, a verifier never do)
        self.quiet: frozenset[tuple[int, str]] = frozenset()
        self.holding = np.ones(n, bool)
        #: the held copies per instance (a heap of queue entries, the same tuples), and
        #: each instance's earliest (inf: none)
        self.held: dict[int, list[tuple]] = {}
        self.held_next = np.full(n, np.inf)
        self._refresh(np.arange(n))

    def _refresh(self, idx: np.ndarray) -> None:
        scn = self.scn_t[self.cursor[idx]]
        heads = (
            np.array([self.heaps[i][0][0] if self.heaps.get(i) else np.inf for i in idx.tolist()])
            if self.heaps
            else np.full(idx.size, np.inf)
        )
        self.next[idx] = np.minimum(scn, heads)

    def push(
        self, idx: np.ndarray, t: np.ndarray, kind: int, agent: int, name: str, payload: Any = None
    ) -> np.ndarray:
        """Queue one event per instance in ``idx`` at times ``t``; returns their seq numbers."""
        seqs = self.seq[idx].copy()
        self.seq[idx] += 1
        for i, ti, s in zip(
            idx.tolist(), spread(t, idx.shape).tolist(), seqs.tolist(), strict=True
        ):
            heapq.heappush(self.heaps.setdefault(i, []), (ti, kind, 0.0, agent, s, name, payload))
        self.next[idx] = np.minimum(self.next[idx], t)
        return seqs

    def push_each(
        self,
        idx: np.ndarray,
        t: np.ndarray,
        kind: int,
        agent: int,
        name: str,
        payloads: Sequence[Any],
        rank: np.ndarray | float = 0.0,
    ) -> None:
        """Queue one event per instance in ``idx``, each with its own payload (and rank)."""
        if idx.size == 1:  # a single run's or one instance's event: no broadcasting
            self.push_one(
                int(idx[0]),
                float(np.asarray(t).reshape(-1)[0]),
                kind,
                agent,
                name,
                payloads[0],
                float(np.asarray(rank).reshape(-1)[0]),
            )
            return
        seqs = self.seq[idx].copy()
        self.seq[idx] += 1
        ranks = spread(np.asarray(rank, float), idx.shape).tolist()
        entries = zip(
            idx.tolist(), spread(t, idx.shape).tolist(), ranks, seqs.tolist(), payloads, strict=True
        )
        if kind == MESSAGE and (agent, name) in self.quiet:
            for i, ti, r, s, payload in entries:
                entry = (ti, kind, r, agent, s, name, payload)
                if self.holding[i] and ti > payload.t_send:
                    self._hold(i, entry)
                else:
                    heapq.heappush(self.heaps.setdefault(i, []), entry)
                    if ti < self.next[i]:
                        self.next[i] = ti
            return
        for i, ti, r, s, payload in entries:
            heapq.heappush(self.heaps.setdefault(i, []), (ti, kind, r, agent, s, name, payload))
        np.minimum.at(self.next, idx, t)

    def push_one(
        self, i: int, t: float, kind: int, agent: int, name: str, payload: Any, rank: float = 0.0
    ) -> None:
        """:meth:`push_each` for one instance, on plain numbers (a single run's sends)."""
        s = int(self.seq[i])
        self.seq[i] = s + 1
        entry = (t, kind, rank, agent, s, name, payload)
        if (
            kind == MESSAGE
            and self.quiet
            and (agent, name) in self.quiet
            and self.holding[i]
            and t > payload.t_send
        ):
            self._hold(i, entry)
            return
        heapq.heappush(self.heaps.setdefault(i, []), entry)
        if t < self.next[i]:
            self.next[i] = t

    # ------------------------------------------------------------------ quiet copies
    def _hold(self, i: int, entry: tuple) -> None:
        """Keep a quiet copy apart: no step ends at it (it is not in ``next``)."""
        heapq.heappush(self.held.setdefault(i, []), entry)
        if entry[0] < self.held_next[i]:
            self.held_next[i] = entry[0]

    def take_held(self, i: int, t: float) -> list[tuple]:
        """Instance ``i``'s held copies that arrived before ``t``, in the queue's order (to
        be received now, at their own times); those arriving at ``t`` itself join the
        queue, where the instant's discrete phase takes them in order with its other
        events (``next`` then says so)."""
        heap = self.held.get(i)
        out: list[tuple] = []
        while heap and heap[0][0] <= t:
            entry = heapq.heappop(heap)
            if entry[0] < t:
                out.append(entry)
            else:
                heapq.heappush(self.heaps.setdefault(i, []), entry)
                if t < self.next[i]:
                    self.next[i] = t
        self.held_next[i] = heap[0][0] if heap else np.inf
        return out

    def wake(self, i: int) -> None:
        """Stop holding instance ``i``'s copies: those held join the queue (each arrival is
        an instant again), and later ones are queued as they are sent."""
        self.holding[i] = False
        heap = self.held.pop(i, None)
        self.held_next[i] = np.inf
        for entry in heap or ():
            heapq.heappush(self.heaps.setdefault(i, []), entry)
            if entry[0] < self.next[i]:
                self.next[i] = entry[0]

    def pending_messages(self) -> list[tuple[int, Any]]:
        """(instance, payload) of every message still queued, in instance order."""
        out = []
        for i in sorted(self.heaps.keys() | self.held.keys()):
            events = self.heaps.get(i, []) + self.held.get(i, [])
            out += [(i, e[6]) for e in sorted(events, key=lambda e: e[:5]) if e[1] == MESSAGE]
        return out

    def pending(self, idx: np.ndarray) -> np.ndarray:
        """Whether anything is still queued (now or later) for each instance, held copies
        included."""
        queued = np.isfinite(self.next[idx])
        return queued | np.isfinite(self.held_next[idx]) if self.held else queued

    def pop_due(
        self, idx: np.ndarray, t: np.ndarray
    ) -> dict[tuple[int, int, str], list[tuple[int, Any]]]:
        """Pop the first due event of each instance in ``idx``; group them by
        (kind, agent, name) so each group is dispatched as one vectorized step. Members are
        (instance, payload) pairs."""
        due = idx[self.next[idx] <= t[idx]]
        groups: dict[tuple[int, int, str], list[tuple[int, Any]]] = {}
        for i in due.tolist():
            scn, _ = self._first(i, t[i])
            if scn is not None:
                self.cursor[i] += 1
                key, payload = (SCENARIO, scn[1], scn[2]), None
            else:
                ev = heapq.heappop(self.heaps[i])
                key, payload = (ev[1], ev[3], ev[5]), ev[6]
            groups.setdefault(key, []).append((i, payload))
        if due.size:
            self._refresh(due)
        return groups

    def _first(self, i: int, t: float) -> tuple[tuple | None, tuple | None]:
        """Instance ``i``'s first event, which is due: ``(scenario event, None)`` when the
        scenario's comes first, else ``(None, heap head)``."""
        c = int(self.cursor[i])
        heap = self.heaps.get(i)
        scn = self.scenario[c] if c < len(self.scenario) else None
        head = heap[0] if heap else None
        if (
            scn is not None
            and scn[0] <= t
            and (head is None or (scn[0], SCENARIO, 0.0, scn[1]) <= head[:4])
        ):
            return scn, None
        return None, head

    def pop_message(
        self, i: int, t: float, inert: Callable[[int, str], bool]
    ) -> tuple[int, Any] | None:
        """Pop instance ``i``'s first due event if it is a message for which ``inert(agent,
        type)`` holds: ``(agent, payload)``, else None (nothing is popped). The event
        :meth:`pop_due` would pop next for ``i``, by the same rule."""
        if not self.next[i] <= t:
            return None
        scn, head = self._first(i, t)
        if scn is not None or head is None or head[1] != MESSAGE or not inert(head[3], head[5]):
            return None
        heap = self.heaps[i]
        ev = heapq.heappop(heap)
        # (_refresh for one instance, on floats: the same least of two times)
        self.next[i] = min(float(self.scn_t[self.cursor[i]]), heap[0][0] if heap else np.inf)
        return ev[3], ev[6]
