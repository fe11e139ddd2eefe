"""The corridor and the ladder as an engine world component (``ladder.corridor``).

Two robot agents carry the ladder; this component is everything that belongs to neither:
the corridor, the ladder on its springs, each robot's guide path, and the referee. At every
instant it

1. finds the ladder's spring equilibrium from both robots' positions (Sec. 2) and ends the
   run with outcome ``link_broken`` when an offset exceeds its limit;
2. raises ``arrived`` in both robots when both are within ``arrive_tol`` of their goals,
   and ``stuck`` when the pair has not come closer to its goals by ``stuck_tol`` within
   ``stuck_window`` steps (the robots' modes turn these into final modes with outcomes);
3. keeps the paper's statistics: steps, steps with the ladder in the corner square, path
   lengths in total and in the corner, the largest offsets.

What a robot may sense (``ctx.sense``): ``partner`` (the other end's robot, as the ladder
tells it), ``path`` (its guide path), ``goal_heading``, ``length``, ``sc_partner``, the
``corridor`` map, its ``frame`` and the ``correction`` reading; ``period`` is the tuple
``(partner, length, sc_partner, frame, correction)``, what the law reads at every period,
in one call. Guide paths are built once, at the start, from the robots' initial
positions, their ``alpha`` parameters and the goals this component places (``goal_gap``
before the exit on the centre line, the rear robot one ladder length behind).

Judgments, statistics and their order are those of :func:`.kernel.simulate`, so a team
run through the engine reproduces the vectorized stepper (the tests compare them).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace
from typing import Any, ClassVar

import numpy as np

from hybridteam.library import (
    FLOAT_PATHS,
    BarShape,
    BatchRequest,
    Footprint,
    GuidePath,
    ModelError,
    SceneDescription,
    Team,
    WorldAccess,
    WorldComponent,
    world_component,
)
from hybridteam.world.geometry import corridor_with_turn, segment_segment_distances

from . import law
from .frame import CornerFrame
from .guide import guide_paths
from .kernel import in_corner
from .params import CORRECTIONS, UPDATES
from .world_one import update_few

#: Up to this many instances an instant runs on floats (:mod:`.world_one`).
FEW = 4

#: Corridor settings: one corridor for the whole ensemble.
_CORRIDOR = ("width_in", "width_out", "outer_leg_in", "outer_leg_out")


@world_component("ladder.corridor")
class LadderCorridor(WorldComponent):
    """A corridor with one turn, a ladder on two springs, guide paths and the referee."""

    raises: ClassVar[tuple[str, ...]] = ("arrived", "stuck")
    params: ClassVar[dict[str, Any]] = {
        "front": "R1",
        "rear": "R2",
        "turn": "right",
        "width_in": 200.0,
        "width_out": 200.0,
        "outer_leg_in": 1200.0,
        "outer_leg_out": 1200.0,
        "length": 450.0,
        "goal_gap": 70.0,
        "path_points": 160.0,
        "tension": 0.0,
        "approach": 0.0,
        "alpha_inset": 0.0,
        "arrive_tol": 0.5,
        "stuck_window": 200.0,
        "stuck_tol": 1.0,
        "clearance": False,
        "correction": "scaled",
        "update": "synchronous",
    }

    @classmethod
    def check(cls, team: Team, values: Mapping[str, Any]) -> list[ModelError]:
        """The readings of Section 3 (``correction``, ``update``) must be known names."""
        return [
            ModelError((name,), f"expected one of {', '.join(allowed)}, got {values[name]!r}")
            for name, allowed in (("correction", CORRECTIONS), ("update", UPDATES))
            if name in values and values[name] not in allowed
        ]

    @classmethod
    def batch(cls, request: BatchRequest) -> list[dict[str, Any]] | None:
        """Plain ladder teams run on the vectorized stepper (see :mod:`.batch`)."""
        from .batch import rows

        return rows(request)

    # ------------------------------------------------------------------ set-up
    def start(self, world: WorldAccess) -> None:
        v = self.values
        names = world.agents
        for role in ("front", "rear"):
            if v[role] not in names:
                raise ValueError(
                    f"ladder.corridor: {role} robot '{v[role]}' is not an agent "
                    f"of the team (agents: {', '.join(names)})"
                )
        self.robots = (world.agent(v["front"]), world.agent(v["rear"]))
        problems = self.check(self.team, v)  # teams built in Python skip validate
        if problems:
            raise problems[0]
        self.correction = str(v["correction"])
        if v["update"] != "synchronous":
            raise ModelError(
                ("update",),
                (
                    f"'{v['update']}' moves one robot after the other within a step, which only "
                    "the vectorized stepper does (plain ladder teams in studies and "
                    "hybridteam.api.summaries); the engine moves both robots at once"
                ),
            )
        dims = {}
        for key in (*_CORRIDOR, "path_points", "approach", "tension", "alpha_inset"):
            if np.ptp(v[key]) != 0:
                raise ValueError(f"ladder.corridor: '{key}' must be the same in every instance")
            dims[key] = float(v[key][0])
        self.corridor = corridor_with_turn(
            dims["width_in"],
            dims["width_out"],
            dims["outer_leg_in"],
            dims["outer_leg_out"],
            turn=v["turn"],
        )
        self.frame = CornerFrame.of(self.corridor)
        n = self.n
        length = v["length"]
        goal = np.stack(
            [
                self.corridor.leg_point("out", v["goal_gap"]),
                self.corridor.leg_point("out", v["goal_gap"] + length),
            ]
        )  # (2, n, 2)
        everyone = np.arange(n)
        start = np.stack([world.pose(a, everyone)[:, :2] for a in self.robots])
        same = np.flatnonzero((start[0] == start[1]).all(axis=1))
        if same.size:  # the springs' equilibrium divides by the robots' distance
            i = int(same[0])
            raise ValueError(
                f"ladder.corridor: the front and rear robots ('{v['front']}', "
                f"'{v['rear']}') start at the same point "
                f"({start[0, i, 0]:g}, {start[0, i, 1]:g}) in instance {i}: the "
                "ladder between them has no direction"
            )
        param = self._robot_params(world)
        self.paths = np.stack(
            [
                guide_paths(
                    self.corridor,
                    start[r],
                    goal[r],
                    param["alpha"][r],
                    count=int(dims["path_points"]),
                    tension=dims["tension"],
                    approach=dims["approach"] if dims["approach"] > 0 else None,
                    inset=dims["alpha_inset"],
                )
                for r in range(2)
            ]
        )  # (2, n, P, 2)
        self.goal = goal
        heading = goal - goal[::-1]
        self.heading = heading / np.hypot(heading[..., 0], heading[..., 1])[..., None]
        sc = param["sc"]
        self.sc, self.olim = sc, param["olim"]
        self.share = sc[::-1] / (sc + sc[::-1])
        self.length = length
        self.radius = param["radius"]
        # statistics and referee state, per instance (robot ones (2, n))
        self.prev = np.full((2, n, 2), np.nan)
        #: each robot's partner's row of ``prev`` and of ``sc`` (views, made once)
        self.partner_prev, self.partner_sc = (self.prev[1], self.prev[0]), (sc[1], sc[0])
        self.was_corner = np.zeros(n, bool)
        self.steps = np.zeros(n, np.int64)
        self.corner_steps = np.zeros(n, np.int64)
        self.path = np.zeros((2, n))
        self.corner_path = np.zeros((2, n))
        self.max_offset = np.zeros((2, n))
        self.offset = np.zeros_like(self.max_offset)  # each robot's, at the last step
        self.best = np.full(n, np.inf)
        self.improved_at = np.zeros(n, np.int64)
        self.tips = np.full((2, n, 2), np.nan)
        #: each instance's constants for the float instant (:func:`.world_one.constants`)
        self.constants: dict[int, Any] = {}

    def _robot_params(self, world: WorldAccess) -> dict[str, np.ndarray]:
        out = {}
        for key in ("alpha", "sc", "olim", "radius"):
            rows = []
            for a in self.robots:
                if key not in world.parameter_names(a):
                    raise ValueError(
                        f"ladder.corridor: robot '{world.agents[a]}' has no parameter '{key}'"
                    )
                rows.append(world.parameter(a, key))
            out[key] = np.stack(rows)
        return out

    # ------------------------------------------------------------------ each instant
    def update(self, world: WorldAccess, idx: np.ndarray) -> None:
        if idx.size <= FEW and FLOAT_PATHS.on and update_few(self, world, idx):
            return  # a single run's instant: on floats, the same bits
        pos = np.empty((len(self.robots), idx.size, 2))  # (2, m, 2)
        for r, a in enumerate(self.robots):
            pos[r] = world.pose(a, idx)[:, :2]
        in_frame = self.frame.to_frame(pos)
        fx, fy = in_frame[..., 0], in_frame[..., 1]  # (2, m) each
        ox, oy, _ = law.spring_offsets(
            fx, fy, fx[::-1], fy[::-1], self.length[idx], self.share[:, idx]
        )
        no = law.norm(ox, oy)
        ax, ay = fx + ox, fy + oy
        tips = np.empty((*ax.shape, 2))
        tips[..., 0], tips[..., 1] = ax, ay
        self.tips[:, idx] = self.frame.to_world(tips)
        # statistics of the step that led here
        prev = self.prev[:, idx]
        moved = ~np.isnan(prev[0, :, 0])
        if moved.any():
            d = pos - prev
            dist = np.where(moved, law.norm(d[..., 0], d[..., 1]), 0.0)
            corner = self.was_corner[idx] & moved
            self.path[:, idx] += dist
            self.corner_path[:, idx] += np.where(corner, dist, 0.0)
            self.steps[idx] += moved
            self.corner_steps[idx] += corner
        self.prev[:, idx] = pos
        self.was_corner[idx] = in_corner(
            ax[0], ay[0], ax[1], ay[1], self.frame.width_in, self.frame.width_out
        )
        # the referee: a broken link, arrival, no progress
        self.max_offset[:, idx] = np.maximum(self.max_offset[:, idx], no)
        self.offset[:, idx] = no
        broken = (no > self.olim[:, idx]).any(axis=0)
        if broken.any():
            self.fail(world, idx[broken])
        gx, gy = self.goal[:, idx, 0], self.goal[:, idx, 1]
        dgoal = law.norm(gx - pos[..., 0], gy - pos[..., 1])
        progress = dgoal[0] + dgoal[1]
        step = self.steps[idx]
        better = progress < self.best[idx] - self.values["stuck_tol"][idx]
        self.best[idx] = np.where(better, progress, self.best[idx])
        self.improved_at[idx] = np.where(better, step, self.improved_at[idx])
        arrived = (dgoal <= self.values["arrive_tol"][idx]).all(axis=0) & ~broken
        stuck = (
            ~broken & ~arrived & (self.improved_at[idx] <= step - self.values["stuck_window"][idx])
        )
        for event, mask in (("arrived", arrived), ("stuck", stuck)):
            if mask.any():
                for a in self.robots:
                    world.raise_event(idx[mask], a, event)

    def fail(self, world: WorldAccess, bad: np.ndarray) -> None:
        """End instances ``bad`` with outcome ``link_broken``."""
        world.finish(
            bad,
            "link_broken",
            lambda i: (
                f"a ladder link broke at step {self.steps[i]}: offsets "
                f"{', '.join(f'{o:.3g}' for o in self._offsets(i))}, limits "
                f"{', '.join(f'{o:.3g}' for o in self.olim[:, i])}"
            ),
        )

    def _offsets(self, i: int) -> np.ndarray:
        d = self.tips[:, i] - self.prev[:, i]
        return np.hypot(d[:, 0], d[:, 1])

    # ------------------------------------------------------------------ what robots sense
    def senses(self) -> tuple[str, ...]:
        return (
            "partner",
            "path",
            "goal_heading",
            "length",
            "sc_partner",
            "corridor",
            "frame",
            "correction",
            "period",
        )

    def sense(self, agent: int, idx: np.ndarray, name: str) -> Any:
        if agent not in self.robots:
            raise KeyError(f"ladder.corridor: agent {agent} does not hold the ladder")
        row = self.robots.index(agent)
        # a robot's row, then its instances: the copy a[k, idx] gives (numpy 2 indexes an
        # integer and an array together four times slower; take is the faster for rows of
        # arrays, plain indexing for rows of numbers)
        if name == "period":  # what the law reads at every period, in one call
            return (
                self.partner_prev[row].take(idx, 0),
                self.length[idx],
                self.partner_sc[row][idx],
                self.frame,
                self.correction,
            )
        if name == "partner":
            return self.partner_prev[row].take(idx, 0)
        if name == "path":
            return self.paths[row].take(idx, 0)
        if name == "goal_heading":
            return self.heading[row].take(idx, 0)
        if name == "length":
            return self.length[idx]
        if name == "sc_partner":
            return self.partner_sc[row][idx]
        if name == "corridor":
            return self.corridor
        if name == "frame":
            return self.frame
        if name == "correction":
            return self.correction
        raise KeyError(name)

    # ------------------------------------------------------------------ results
    def sample_series(self) -> dict[str, tuple[str, ...]]:
        """The ladder's pose, and ``ladder_offset``: each robot's spring offset at the last
        step (the link breaks past ``olim``), which requirements read."""
        names = (str(self.values["front"]), str(self.values["rear"]))
        series = {"ladder": ("x", "y", "theta"), "ladder_offset": names}
        if self.values["clearance"]:
            series["ladder_clearance"] = ("walls",)
        return series

    def sample(self, idx: np.ndarray) -> dict[str, np.ndarray]:
        """With ``clearance: true`` also ``ladder_clearance.walls``: the distance from the
        ladder (a segment of its length through its centre) to the nearest wall, 0 when
        they touch. Off by default: at every step it costs more than the rest of an
        engine run."""
        if idx.size == 1 and FEW >= 1 and FLOAT_PATHS.on and not self.values["clearance"]:
            return self._sample_one(int(idx[0]))
        a, b = self.tips[0, idx], self.tips[1, idx]
        c = 0.5 * (a + b)
        th = np.arctan2(a[:, 1] - b[:, 1], a[:, 0] - b[:, 0])
        pose = np.empty((idx.size, 3))  # np.column_stack's values, without its checks
        pose[:, :2], pose[:, 2] = c, th
        out = {"ladder": pose, "ladder_offset": self.offset[:, idx].T}
        if self.values["clearance"]:
            half = 0.5 * self.length[idx, None] * np.column_stack([np.cos(th), np.sin(th)])
            bar = np.hstack([c - half, c + half])
            out["ladder_clearance"] = segment_segment_distances(bar, self.corridor.walls).min(
                axis=1
            )[:, None]
        return out

    def _sample_one(self, i: int) -> dict[str, np.ndarray]:
        """:meth:`sample` of one instance on floats (the same operations, the same bits)."""
        (ax, ay), (bx, by) = self.tips[:, i].tolist()
        th = np.arctan2(ay - by, ax - bx)
        row = np.array(
            [[0.5 * (ax + bx), 0.5 * (ay + by), th, self.offset.item(0, i), self.offset.item(1, i)]]
        )  # one array for both series
        return {"ladder": row[:, :3], "ladder_offset": row[:, 3:]}

    def summary(self, i: int) -> dict[str, Any]:
        return {
            "steps": int(self.steps[i]),
            "steps_in_corner": int(self.corner_steps[i]),
            "path_length": [float(v) for v in self.path[:, i]],
            "corner_path_length": [float(v) for v in self.corner_path[:, i]],
            "max_offset": [float(v) for v in self.max_offset[:, i]],
        }

    def describe(self) -> SceneDescription:
        """The corridor in the paper's units (one time unit is one step), the guide
        paths of the first instances, the ladder's outline and the robots' footprints."""
        shown = min(self.n, 8)  # guide paths of the first instances, for the plots
        paths = tuple(
            GuidePath(
                i,
                self.team.agents[a].name,
                tuple((x, y) for x, y in self.paths[r, i].round(3).tolist()),
            )
            for i in range(shown)
            for r, a in enumerate(self.robots)
        )
        lengths = np.unique(self.length)
        footprints = {
            self.team.agents[a].name: Footprint(float(self.radius[r, 0]))
            for r, a in enumerate(self.robots)
        }
        return replace(
            self.corridor.describe(),
            units="units",
            paths=paths,
            payloads={"ladder": BarShape(float(lengths[0]), 6.0)},
            footprints=footprints,
        )
