"""What stops an exploration before it has seen every state, and the words it says it in.

An explicit-state search has no natural end on a skeleton that is not finite, and no
natural size on a team of hundreds of agents. Each bound here ends the exploration with a
reason (:attr:`~.explore.Graph.bound`); the states not yet expanded are *cut* (their
successors unknown, not absent), and the verdicts say "holds (bounded)":

- **states** (``--max-states``): the store is full;
- **memory** (``--max-memory``, as ``run`` takes it): before anything is allocated, the
  engine arrays the explorer loads its states into are estimated with ``run``'s estimate
  (:func:`~hybridteam.engine.run.budget.instances_within`), and a batch takes at most half the
  limit (a team whose single instance does not fit is refused); while exploring, the
  process's resident memory is read after each batch, and beyond the limit the
  exploration stops;
- **growth** (``--max-values``): a discrete variable that keeps taking new values — a
  counter ``n = n + 1`` on every ``after:`` — makes the skeleton infinite: one new state
  per level, forever, and with two counters a growing triangle of them. No finite state
  count bounds that in useful time, so the explorer counts each discrete variable's
  distinct values and stops, naming the variable, once one has taken more than the bound
  (256 by default: protocols' discrete variables hold ids, flags and small counters).
"""

from __future__ import annotations

import numpy as np

from hybridteam.verify.abstraction import Skeleton

#: distinct values a discrete variable may take before the skeleton is judged infinite
DEFAULT_MAX_VALUES = 256


class Values:
    """The distinct values each discrete variable has taken in the states computed so far
    (each set kept only up to one past the bound: that is all :meth:`grown` asks)."""

    def __init__(self, sk: Skeleton, limit: int) -> None:
        self.limit = limit
        self.seen: list[list[set[float]]] = [[set() for _ in cols] for cols in sk.discrete_vars]
        names = [{j: name for name, j in ca.var_index.items()} for ca in sk.original.agents]
        self.names = [
            (ca.name, [names[a][j] for j in cols])
            for a, (ca, cols) in enumerate(zip(sk.original.agents, sk.discrete_vars, strict=True))
        ]

    def add(self, a: int, block: np.ndarray) -> None:
        """Agent ``a``'s discrete variables in a batch of states (one row a state)."""
        for j, seen in enumerate(self.seen[a]):
            if len(seen) <= self.limit:
                values = np.unique(block[:, j])
                seen.update(values[~np.isnan(values)].tolist())  # NaN is not a new value

    def grown(self) -> str | None:
        """The reason to stop, naming the first variable past the bound; None if none is."""
        for (agent, names), seen in zip(self.names, self.seen, strict=True):
            for name, values in zip(names, seen, strict=True):
                if len(values) > self.limit:
                    return (
                        f"variable '{name}' of agent '{agent}' took more than "
                        f"{self.limit:,} different values ({min(values):g} to "
                        f"{max(values):g} so far) and keeps taking new ones: it grows "
                        "without bound, so the skeleton is infinite; bound it (a guard "
                        "or a reset), or raise --max-values"
                    )
        return None


def over_memory(resident: float | None, limit: float, states: int) -> str | None:
    """The reason to stop when this process holds more than ``limit`` bytes."""
    if resident is None or resident <= limit:
        return None
    return (
        f"this process reached the memory limit of {limit / 1e9:g} GB after {states:,} "
        f"states ({resident / 1e9:.3f} GB resident; --max-memory GB raises it)"
    )


def full(max_states: int) -> str:
    """The reason when the state store is full."""
    return f"--max-states {max_states:,} reached"
