"""The ``docking.station`` world component: a charging dock that robots seek.

At every instant of the run (the robots' law ticks) the station measures each listed
robot's distance to the dock and raises ``docked`` in a robot the first time it is within
``radius`` — checked at instants, like every world component's judgments, so a robot is
told at most one control period late. It records when each robot docked and how close it
ever came (``summary``), tells the robots where the dock is (``sense("dock")``) and draws
itself as a labelled region in trajectory plots.

Its batch fast path (:meth:`Station.batch`) recognises plain docking teams — every agent a
holonomic robot running ``docking.seek`` from the start until ``docked`` ends it, this
station the only world component, no messages — and computes their runs with one
vectorized loop over control periods instead of the engine. It must give the engine's
rows; ``tests/test_extending.py`` in hybridteam checks that it does, instance by instance.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from hybridteam.library import (
    BatchRequest,
    ModelError,
    Region,
    SceneDescription,
    Team,
    WorldAccess,
    WorldComponent,
    settings_error,
    world_component,
)

from .seek import seek_velocity

EVENT = "docked"


@world_component("docking.station")
class Station(WorldComponent):
    """A dock at (``x``, ``y``) with a capture ``radius``, for the robots in ``robots``."""

    params: ClassVar[dict[str, Any]] = {"x": 0.0, "y": 0.0, "radius": 0.1, "robots": []}
    raises: ClassVar[tuple[str, ...]] = (EVENT,)

    @classmethod
    def check(cls, team: Team, values: Mapping[str, Any]) -> list[ModelError]:
        names = [a.name for a in team.agents]
        robots = values.get("robots", [])
        problems = []
        if not robots:
            problems.append(ModelError(("robots",), "list the robots that seek the dock"))
        for k, name in enumerate(robots):
            if name not in names:
                problems.append(
                    ModelError(
                        ("robots", k), f"unknown agent {name!r} (agents: {', '.join(names)})"
                    )
                )
        radius = values.get("radius", 0.1)
        if isinstance(radius, int | float) and not radius > 0:
            problems.append(ModelError(("radius",), f"must be positive, got {radius!r}"))
        return problems

    def __init__(self, team: Team, n: int, values: Mapping[str, Any]) -> None:
        super().__init__(team, n, values)
        problems = self.check(team, values)
        if problems:
            raise settings_error("docking.station", problems)
        count = len(values["robots"])
        self.docked = np.zeros((n, count), bool)
        self.when = np.full((n, count), np.nan)
        self.closest = np.full((n, count), np.inf)

    def start(self, world: WorldAccess) -> None:
        self.robots = [world.agent(name) for name in self.values["robots"]]
        for a in self.robots:
            world.pose(a, np.arange(0))  # a robot without x and y fails now, not mid-run

    def update(self, world: WorldAccess, idx: np.ndarray) -> None:
        v = self.values
        for r, a in enumerate(self.robots):
            p = world.pose(a, idx)
            d = np.hypot(p[:, 0] - v["x"][idx], p[:, 1] - v["y"][idx])
            self.closest[idx, r] = np.minimum(self.closest[idx, r], d)
            new = (d <= v["radius"][idx]) & ~self.docked[idx, r]
            if new.any():
                who = idx[new]
                self.docked[who, r] = True
                self.when[who, r] = world.t[who]
                world.raise_event(who, a, EVENT)

    def senses(self) -> tuple[str, ...]:
        return ("dock",)

    def sense(self, agent: int, idx: np.ndarray, name: str) -> np.ndarray:
        return np.column_stack([self.values["x"][idx], self.values["y"][idx]])

    def summary(self, i: int) -> dict[str, Any]:
        return _stats(self.when[i], self.closest[i])

    def describe(self) -> SceneDescription:
        """The dock's circle, drawn as a labelled region."""
        x, y, r = (float(self.values[k][0]) for k in ("x", "y", "radius"))
        ring = tuple(
            (x + r * math.cos(a), y + r * math.sin(a))
            for a in np.linspace(0.0, 2 * math.pi, 24, endpoint=False)
        )
        return SceneDescription(regions=(Region(ring, "dock"),))

    # ------------------------------------------------------------------ fast path
    @classmethod
    def batch(cls, request: BatchRequest) -> list[dict[str, Any]] | None:
        """The engine's rows for a plain docking team, without the engine (else None)."""
        plan = _plain(request)
        if plan is None:
            return None
        return _simulate(request, *plan)


def _stats(when: np.ndarray, closest: np.ndarray) -> dict[str, Any]:
    return {
        "dock_time": [None if math.isnan(t) else float(t) for t in when],
        "closest": [float(d) for d in closest],
    }


def _plain(request: BatchRequest) -> tuple[float, str] | None:
    """(control period, outcome of docking) if the team is one the fast path computes."""
    robots = list(request.settings["robots"])
    if (
        request.components != ("docking.station",)
        or not request.quiet
        or sorted(robots) != sorted(a.name for a in request.agents)
    ):
        return None
    periods, outcomes = set(), set()
    for name in robots:
        shape = request.agent(name)
        plan = shape.one_law()
        if (
            plan is None
            or shape.plant != "holonomic"
            or plan.law != "docking.seek"
            or plan.period <= 0
            or set(plan.ends) != {EVENT}
        ):
            return None
        periods.add(plan.period)
        outcomes.add(plan.ends[EVENT])
    if len(periods) != 1 or len(outcomes) != 1:
        return None
    return periods.pop(), outcomes.pop()


def _simulate(request: BatchRequest, period: float, outcome: str) -> list[dict[str, Any]]:
    """Every instance at once, one control period per iteration, exactly as the engine:
    judge at the instant, then sample the law and hold it until the next instant."""
    v, n = request.settings, request.n
    shapes = [request.agent(name) for name in v["robots"]]
    pos = np.stack([np.column_stack([s.initial["x"], s.initial["y"]]) for s in shapes], 1)
    plans = [s.one_law() for s in shapes]
    gain = np.stack([p.params["gain"] for p in plans], 1)  # type: ignore[union-attr]
    vmax = np.stack([p.params["vmax"] for p in plans], 1)  # type: ignore[union-attr]
    lo = np.array([[s.limits[k][0] for k in ("vx", "vy")] for s in shapes])  # (R, 2)
    hi = np.array([[s.limits[k][1] for k in ("vx", "vy")] for s in shapes])
    dock_x, dock_y, radius = (np.asarray(v[k], float)[:, None] for k in ("x", "y", "radius"))
    docked = np.zeros(pos.shape[:2], bool)
    when = np.full(pos.shape[:2], np.nan)
    closest = np.full(pos.shape[:2], np.inf)
    live = np.ones(n, bool)
    ends = np.full(n, request.duration)
    result = np.full(n, "ok", dtype=object)
    t, k = 0.0, 0
    while True:
        d = np.hypot(pos[..., 0] - dock_x, pos[..., 1] - dock_y)
        closest[live] = np.minimum(closest[live], d[live])
        new = live[:, None] & (d <= radius) & ~docked
        docked |= new
        when[new] = t
        done = live & docked.all(axis=1)
        result[done], ends[done] = outcome, t
        live &= ~done
        if t >= request.duration or not live.any():
            break
        vx, vy = seek_velocity(pos[..., 0], pos[..., 1], dock_x, dock_y, gain, vmax)
        u = np.minimum(np.maximum(np.stack([vx, vy], -1), lo), hi)
        u[docked] = 0.0  # a docked robot's final mode has no law: it stands still
        k += 1
        t_next = min(k * period, request.duration)
        pos = pos + u * (t_next - t)
        t = t_next
    return [
        {
            "instance": i,
            "outcome": result[i],
            "t_end": float(ends[i]),
            **_stats(when[i], closest[i]),
        }
        for i in range(n)
    ]
