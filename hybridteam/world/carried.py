"""A payload carried by several robots through compliant grasps: the ``payload`` component.

Each grasp joins a point mounted on a robot (``mount``, robot frame) to a point of the
payload (``point``, body frame) by a spring (``spring``), and breaks past its offset
``limit``. At every instant the payload settles where the springs balance
(:func:`~hybridteam.world.payload.equilibrium`, a weighted Procrustes fit), and each
robot's arm or force sensor reads its grasp's offset in the robot's frame plus the angle
of the payload relative to the robot, counted from the start: the architecture paper's
x_a = [x_a, y_a, θ_a] (``ctx.sense("arm")``). A grasp past its limit drops the payload:
the run ends with outcome ``link_broken``.

Grasps are checked at the run's instants (law ticks, events), not located between them:
a break is reported at the first instant past the limit, at most one law period late.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from hybridteam.world.component import WorldComponent, world_component
from hybridteam.world.payload import equilibrium

if TYPE_CHECKING:
    from hybridteam.engine.simulator import Simulator
    from hybridteam.model import Team

_GRASP_KEYS = {"agent", "point", "mount", "spring", "limit"}


@world_component("payload")
class CarriedPayload(WorldComponent):
    """A rigid box or bar held by springs at k grasps (see the module docstring)."""

    params: ClassVar[dict[str, Any]] = {
        "name": "payload", "shape": "box", "width": 1.0, "depth": 0.6, "length": 1.0,
        "grasps": [],
    }

    def __init__(self, team: Team, n: int, values: Mapping[str, Any]) -> None:
        super().__init__(team, n, values)
        names = [a.name for a in team.agents]
        grasps = values["grasps"]
        problems = []
        if len(grasps) < 1:
            problems.append("'grasps' needs at least one grasp")
        for k, g in enumerate(grasps):
            if not isinstance(g, dict) or set(g) - _GRASP_KEYS or "agent" not in g:
                problems.append(f"grasp {k} must be a mapping with 'agent' and optionally "
                                f"'point', 'mount', 'spring', 'limit'")
            elif g["agent"] not in names:
                problems.append(f"grasp {k}: unknown agent '{g['agent']}'")
        if problems:
            raise ValueError("payload: " + "; ".join(problems))
        self.agents = [names.index(g["agent"]) for g in grasps]
        self.body = np.array([g.get("point", [0.0, 0.0]) for g in grasps], float)
        self.mount = np.array([g.get("mount", [0.0, 0.0]) for g in grasps], float)
        self.spring = np.array([float(g.get("spring", 1.0)) for g in grasps])
        self.limit = np.array([float(g.get("limit", np.inf)) for g in grasps])
        if self.body.shape != (len(grasps), 2) or self.mount.shape != (len(grasps), 2) \
                or np.any(self.spring <= 0) or np.any(self.limit <= 0):
            raise ValueError("payload: grasp points and mounts are [x, y]; springs and "
                             "limits must be positive")
        k = len(grasps)
        self.pose = np.full((n, 3), np.nan)
        self.offset = np.full((n, k, 2), np.nan)     # world frame, robot minus grasp point
        self.arm = np.full((n, k, 3), np.nan)        # robot frame, and relative angle
        self.rel0 = np.zeros((n, k))
        self.max_offset = np.zeros((n, k))

    def _robot_points(self, sim: Simulator, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        poses = np.stack([sim.states[a].x[idx, :3] if sim.states[a].x.shape[1] >= 3 else
                          np.c_[sim.states[a].x[idx, :2], np.zeros(idx.size)]
                          for a in self.agents], axis=1)                 # (m, k, 3)
        c, s = np.cos(poses[..., 2]), np.sin(poses[..., 2])
        mx, my = self.mount[:, 0], self.mount[:, 1]
        pts = np.stack([poses[..., 0] + c * mx - s * my, poses[..., 1] + s * mx + c * my], -1)
        return pts, poses[..., 2]

    def start(self, sim: Simulator) -> None:
        heading = self._settle(sim, np.arange(self.n))
        self.rel0[:] = self.pose[:, 2:3] - heading
        self.arm[..., 2] = 0.0

    def _settle(self, sim: Simulator, idx: np.ndarray) -> np.ndarray:
        """Pose, offsets and arm readings of instances ``idx``; returns the robots' headings
        ``(m, k)`` (the start counts the arms' angles from them)."""
        pts, heading = self._robot_points(sim, idx)
        eq = equilibrium(pts, self.body, self.spring)
        self.pose[idx] = np.c_[eq.x, eq.y, eq.theta]
        self.offset[idx] = eq.offsets
        c, s = np.cos(heading), np.sin(heading)
        ox, oy = eq.offsets[..., 0], eq.offsets[..., 1]
        rel = eq.theta[:, None] - heading - self.rel0[idx]
        self.arm[idx] = np.stack([c * ox + s * oy, -s * ox + c * oy,
                                  np.arctan2(np.sin(rel), np.cos(rel))], -1)
        return heading

    def update(self, sim: Simulator, idx: np.ndarray) -> np.ndarray | None:
        self._settle(sim, idx)
        size = np.hypot(self.offset[idx, :, 0], self.offset[idx, :, 1])
        self.max_offset[idx] = np.maximum(self.max_offset[idx], size)
        over = size > self.limit
        bad = over.any(axis=1)
        if bad.any():
            names = [self.team.agents[a].name for a in self.agents]
            rows = dict(zip(idx[bad].tolist(), over[bad], strict=True))
            sizes = dict(zip(idx[bad].tolist(), size[bad], strict=True))
            sim.finish(idx[bad], "link_broken", lambda i: "; ".join(
                f"{self.values['name']} dropped: the grasp of '{names[k]}' is offset "
                f"{sizes[i][k]:.4g} > limit {self.limit[k]:.4g}"
                for k in np.flatnonzero(rows[i]).tolist()))
        return None

    def senses(self) -> tuple[str, ...]:
        return ("arm", "payload")

    def sense(self, agent: int, idx: np.ndarray, name: str) -> np.ndarray:
        if name == "payload":
            return self.pose[idx]
        if agent not in self.agents:
            return np.full((len(idx), 3), np.nan)  # this robot holds no grasp
        return self.arm[idx, self.agents.index(agent)]

    def sample_series(self) -> dict[str, tuple[str, ...]]:
        return {self.values["name"]: ("x", "y", "theta")}

    def sample(self, idx: np.ndarray) -> dict[str, np.ndarray]:
        return {self.values["name"]: self.pose[idx]}

    def summary(self, i: int) -> dict[str, Any]:
        return {"max_grasp_offset": [float(v) for v in self.max_offset[i]]}

    def meta(self) -> dict[str, Any]:
        v = self.values
        shape = ({"kind": "bar", "length": float(v["length"][0])} if v["shape"] == "bar" else
                 {"kind": "box", "width": float(v["width"][0]),
                  "depth": float(v["depth"][0])})
        return {"payloads": [v["name"]], "payload_shapes": {v["name"]: shape}}
