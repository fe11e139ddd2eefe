"""Falsification: search parameters and seeds for a run that violates a requirement.

The search minimises the requirement's robustness (negative = violated) over a box of
override values (``--vary KEY=LO:HI``) and, optionally, the run's seed. Each generation of
candidates is simulated as one ensemble (:class:`~.evaluate.Evaluator`), so a generation of
30 costs about what one run costs plus its share of the work. Two methods:

- ``random``: uniform draws, generation after generation: the baseline any guided method
  must beat;
- ``de``: scipy's differential evolution (``vectorized``, ``updating='deferred'``: a
  generation is one call), robustness-guided; the seed is an integer dimension.

Both are deterministic given ``search_seed``, which is what makes a search resumable: a
resumed search replays the same proposals and takes each generation's results from the
record instead of simulating again.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

METHODS = ("random", "de")


@dataclass(frozen=True)
class Vary:
    """One searched override: its key and the box ``[lo, hi]``."""

    key: str
    lo: float
    hi: float


@dataclass
class Generation:
    """One batch of candidates and what their runs gave."""

    x: np.ndarray  # (P, d) override values
    seeds: np.ndarray  # (P,) run seeds
    robustness: np.ndarray
    outcomes: list[str]

    def to_json(self) -> dict[str, Any]:
        return {
            "x": self.x.tolist(),
            "seeds": self.seeds.tolist(),
            "robustness": [_finite(r) for r in self.robustness.tolist()],
            "outcomes": list(self.outcomes),
        }

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> Generation:
        return cls(
            np.asarray(d["x"], float).reshape(len(d["seeds"]), -1),
            np.asarray(d["seeds"], np.int64),
            np.asarray([_unfinite(r) for r in d["robustness"]], float),
            list(d["outcomes"]),
        )


def _finite(r: float) -> float | str:
    return r if math.isfinite(r) else ("inf" if r > 0 else "-inf")


def _unfinite(r: float | str) -> float:
    return float(r) if not isinstance(r, str) else (math.inf if r == "inf" else -math.inf)


@dataclass
class Search:
    """What a search did: every generation, and where it first falsified."""

    varies: list[Vary]
    generations: list[Generation] = field(default_factory=list)

    @property
    def evaluations(self) -> int:
        return sum(len(g.seeds) for g in self.generations)

    def flat(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[str]]:
        if not self.generations:
            return np.zeros((0, len(self.varies))), np.zeros(0, np.int64), np.zeros(0), []
        return (
            np.concatenate([g.x for g in self.generations]),
            np.concatenate([g.seeds for g in self.generations]),
            np.concatenate([g.robustness for g in self.generations]),
            [o for g in self.generations for o in g.outcomes],
        )

    def first_falsified(self) -> int | None:
        """Simulations up to and including the first violating one (None: none did)."""
        rho = self.flat()[2]
        bad = np.flatnonzero(rho < 0)
        return int(bad[0]) + 1 if bad.size else None

    def best(self) -> int:
        """Index of the lowest robustness (the first of equals)."""
        return int(np.argmin(self.flat()[2]))

    def best_so_far(self) -> np.ndarray:
        return np.minimum.accumulate(self.flat()[2])


class _Stop(Exception):
    """Raised inside an optimiser's objective to end the search."""


Evaluate = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, list[str]]]


class _Driver:
    """Feeds proposals to ``evaluate`` (or to the record when resuming), keeps the
    history, and stops at the budget or at the first violation."""

    def __init__(
        self,
        search: Search,
        evaluate: Evaluate,
        budget: int,
        record: list[Generation],
        on_generation: Callable[[Search], None],
        stop_on_violation: bool,
    ) -> None:
        self.search, self.evaluate, self.budget = search, evaluate, budget
        self.record, self.on_generation = record, on_generation
        self.stop_on_violation = stop_on_violation

    def __call__(self, x: np.ndarray, seeds: np.ndarray) -> np.ndarray:
        done = self.search.evaluations
        room = self.budget - done
        if room <= 0:
            raise _Stop
        x, seeds = x[:room], seeds[:room]
        k = len(self.search.generations)
        old = self.record[k] if k < len(self.record) else None
        if (
            old is not None
            and old.x.shape == x.shape
            and np.array_equal(old.x, x)
            and np.array_equal(old.seeds, seeds)
        ):
            gen = old  # resuming: this generation was simulated before
        else:
            rho, outcomes = self.evaluate(x, seeds)
            gen = Generation(x.copy(), seeds.copy(), np.asarray(rho, float), outcomes)
            self.record[k:] = []  # a different proposal: the rest of the record is stale
        self.search.generations.append(gen)
        self.on_generation(self.search)
        if (
            self.stop_on_violation and (gen.robustness < 0).any()
        ) or self.search.evaluations >= self.budget:
            raise _Stop
        return gen.robustness


def run_search(
    varies: list[Vary],
    seeds: int,
    base_seed: int,
    evaluate: Evaluate,
    *,
    budget: int,
    method: str = "de",
    population: int = 20,
    search_seed: int = 0,
    record: list[Generation] | None = None,
    on_generation: Callable[[Search], None] = lambda s: None,
    stop_on_violation: bool = True,
) -> Search:
    """Search until a violation (unless told not to stop) or ``budget`` simulations.

    ``seeds``: how many run seeds to search (``base_seed`` .. ``base_seed + seeds - 1``);
    1 keeps the team's seed.
    """
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r} (methods: {', '.join(METHODS)})")
    search = Search(varies)
    drive = _Driver(search, evaluate, budget, list(record or []), on_generation, stop_on_violation)
    try:
        if method == "random":
            _random(varies, seeds, base_seed, drive, population, search_seed)
        else:
            _differential_evolution(varies, seeds, base_seed, drive, population, search_seed)
    except _Stop:
        pass
    return search


def _random(
    varies: list[Vary], seeds: int, base: int, drive: _Driver, population: int, search_seed: int
) -> None:
    rng = np.random.default_rng(search_seed)
    lo = np.array([v.lo for v in varies])
    hi = np.array([v.hi for v in varies])
    while True:
        x = lo + (hi - lo) * rng.random((population, len(varies)))
        s = base + rng.integers(0, seeds, population)
        drive(x, s)


def _differential_evolution(
    varies: list[Vary], seeds: int, base: int, drive: _Driver, population: int, search_seed: int
) -> None:
    from scipy.optimize import differential_evolution

    bounds = [(v.lo, v.hi) for v in varies]
    integrality = [False] * len(varies)
    if seeds > 1:  # the seed as one more (integer) dimension
        bounds.append((0, seeds - 1))
        integrality.append(True)
    dims = len(bounds)

    def objective(z: np.ndarray) -> np.ndarray:  # z: (dims, S), the whole generation
        z = np.atleast_2d(z.T)
        s = base + (np.rint(z[:, -1]).astype(np.int64) if seeds > 1 else np.zeros(len(z), np.int64))
        rho = drive(z[:, : len(varies)].copy(), s)
        # an infinite robustness (a Boolean verdict) gives the optimiser no slope: clip it
        return np.clip(rho, -1e300, 1e300)

    # (scipy-stubs types the scalar objective and tuple bounds: not vectorized=True's
    # objective of a population, nor the sequence of (low, high) pairs scipy documents)
    differential_evolution(
        objective,  # type: ignore[arg-type]
        bounds,  # type: ignore[arg-type]
        integrality=integrality if seeds > 1 else None,
        vectorized=True,
        updating="deferred",
        popsize=max(1, math.ceil(population / dims)),
        maxiter=10**6,
        tol=0,
        atol=0,
        seed=search_seed,
        polish=False,
        init="latinhypercube",
    )
