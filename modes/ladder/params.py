"""Parameters of a ladder run: the paper's table (Sec. 4) and what the paper leaves silent.

:class:`Robot` holds one robot's run-time parameters, :class:`Settings` the choices the
paper does not state (start and goal placement, spline, arrival and stuck rules), and
:class:`Pairs` n pairs as arrays for the vectorized stepper. :func:`sample_run` is the
Section 4 sample run; :func:`random_pairs` draws the Section 4 population S.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace
from typing import Any

import numpy as np

#: Readings of how v_max enters the motion vector (see ``law.combine``).
CORRECTIONS = ("scaled", "distance", "capped")
#: Readings of the step: both robots on the same state, or one after the other.
UPDATES = ("synchronous", "front_first", "rear_first")

#: Per-robot fields, in the order random populations are drawn and arrays are stacked.
ROBOT_FIELDS = (
    "v_max",
    "lookahead",
    "alpha",
    "olim",
    "orsp",
    "kc",
    "kr",
    "sc",
    "radius",
    "ladder_margin",
)


@dataclass(frozen=True)
class Robot:
    """One robot's run-time parameters (paper Sec. 3 and 4).

    ``radius`` and ``ladder_margin`` are not in the paper: the robot's disk radius (the
    paper calls ladder 485 "close to the physical limit", which with 200-wide corridors
    puts the radius near 25-28; see ``limits.longest_ladder``), and how close the ladder
    may come to the inner walls before Fig. 7(b)'s rule applies. The margin must exceed a
    step (``v_max``) for the rule to keep the ladder off the walls.
    """

    v_max: float = 2.0
    lookahead: int = 16
    alpha: float = 0.65
    olim: float = 10.0
    orsp: float = 0.0
    kc: float = 1.0
    kr: float = 0.0
    sc: float = 1.0
    radius: float = 26.0
    ladder_margin: float = 4.0


@dataclass(frozen=True)
class Settings:
    """Choices the paper leaves open, shared by every pair of a batch (see README)."""

    start_gap: float = 70.0  # rear robot's centre, distance from the entrance line
    goal_gap: float = 70.0  # front robot's goal, distance before the exit line
    path_points: int = 160  # points per guide path (the paper's 160)
    tension: float = 0.0  # cardinal spline tension (0: Catmull-Rom)
    approach: float | None = None  # optional centre-line control points before/after the corner
    alpha_inset: float = 0.0  # alpha 0/1 put the corner control points this far from walls
    window: int = 16  # nearest-point search: +- this many points around the last
    arrive_tol: float = 0.5  # both robots within this of their goals: success
    stuck_window: int = 200  # no progress for this many steps: stuck
    stuck_tol: float = 1.0  # progress = the sum of goal distances drops by more than this
    max_steps: int = 50_000  # hard stop, reported as stuck
    # Readings of Section 3 where the paper admits more than one (README, "Readings"):
    correction: str = "scaled"  # how v_max enters 3.2.2: scaled | distance | capped
    update: str = "synchronous"  # who moves first in a step: synchronous | front_first | rear_first

    def check(self) -> None:
        """Raise ValueError for settings the stepper cannot run with."""
        if self.window < 1 or self.path_points < 2:
            raise ValueError("settings need window >= 1 and path_points >= 2")
        for name, allowed in (("correction", CORRECTIONS), ("update", UPDATES)):
            if getattr(self, name) not in allowed:
                raise ValueError(
                    f"unknown {name} reading '{getattr(self, name)}' (one of {', '.join(allowed)})"
                )


@dataclass(frozen=True)
class Scenario:
    """One pair and its ladder: front robot R1, rear robot R2, ladder length."""

    length: float = 450.0
    front: Robot = field(default_factory=lambda: Robot(alpha=0.65, sc=0.8))
    rear: Robot = field(default_factory=lambda: Robot(alpha=0.8, sc=1.0))


def sample_run() -> Scenario:
    """The Section 4 sample run (Fig. 8): ladder 450, R1 (alpha 0.65, sc 0.8) in front."""
    return Scenario()


@dataclass(frozen=True)
class Pairs:
    """n pairs as arrays: ``length`` ``(n,)`` and every robot field ``(2, n)`` (row 0 front)."""

    length: np.ndarray
    robot: dict[str, np.ndarray]

    @property
    def size(self) -> int:
        return int(self.length.shape[0])

    @classmethod
    def of(cls, scenarios: list[Scenario] | Scenario) -> Pairs:
        if isinstance(scenarios, Scenario):
            scenarios = [scenarios]
        length = np.array([s.length for s in scenarios], dtype=float)
        robot = {
            name: np.array(
                [
                    [getattr(s.front, name) for s in scenarios],
                    [getattr(s.rear, name) for s in scenarios],
                ],
                dtype=float,
            )
            for name in ROBOT_FIELDS
        }
        return cls(length, robot)

    def check(self) -> None:
        """Raise ValueError for values the law cannot run with (one message per problem)."""
        r = self.robot
        problems = [
            f"{name} must be positive" for name in ("v_max", "olim", "sc") if np.any(r[name] <= 0)
        ]
        problems += [
            f"{name} must not be negative"
            for name in ("orsp", "radius", "ladder_margin", "lookahead")
            if np.any(r[name] < 0)
        ]
        if np.any(self.length <= 0):
            problems.append("ladder length must be positive")
        if problems:
            raise ValueError("; ".join(problems))

    def take(self, index) -> Pairs:
        """The pairs at ``index`` (an int, slice or index array) as a new batch."""
        idx = np.atleast_1d(np.arange(self.size)[index])
        return Pairs(self.length[idx].copy(), {k: v[:, idx].copy() for k, v in self.robot.items()})

    def scenario(self, i: int) -> Scenario:
        """Pair ``i`` as a scenario (for the scalar reference)."""

        def robot(row: int) -> Robot:
            vals: dict[str, Any] = {
                f.name: float(self.robot[f.name][row, i]) for f in fields(Robot)
            }
            vals["lookahead"] = int(vals["lookahead"])
            return Robot(**vals)

        return Scenario(float(self.length[i]), robot(0), robot(1))


def random_pairs(
    rng: np.random.Generator, n: int, length: float = 450.0, base: Robot | None = None
) -> Pairs:
    """The paper's population S (Sec. 4): n pairs of randomized, non-identical robots.

    orsp uniform in [0, 0.2] * olim, v_max in [0.5, 1.5], lookahead an integer in 0..20,
    alpha in [0.35, 0.9]; k_c = 1, sc = 1, k_r = 0 and the rest from ``base``. Draws are
    made per pair in a fixed order, so pair i is the same whatever n is.
    """
    base = base or Robot(kc=1.0, sc=1.0, kr=0.0)
    rows = []
    for _ in range(n):
        pair = []
        for _robot in range(2):
            orsp = rng.uniform(0.0, 0.2) * base.olim
            v_max = rng.uniform(0.5, 1.5)
            lookahead = int(rng.integers(0, 21))
            alpha = rng.uniform(0.35, 0.9)
            pair.append(replace(base, orsp=orsp, v_max=v_max, lookahead=lookahead, alpha=alpha))
        rows.append(Scenario(length, pair[0], pair[1]))
    return Pairs.of(rows)
