"""A payload carried by several robots through compliant grasps: the ``payload`` component.

Each grasp joins a point mounted on a robot (``mount``, robot frame) to a point of the
payload (``point``, body frame) by a spring (``spring``), and breaks past its offset
``limit``; a robot with a manipulator in its robot model (``model: xr4000``) lends its
grasp's ``mount``, ``spring`` and ``limit`` to the keys the grasp leaves out. Where it is
read the payload settles where the springs of the *engaged* grasps balance
(:func:`~hybridteam.world.payload.equilibrium`, a weighted Procrustes fit), and each
robot's arm or force sensor reads its grasp's offset in the robot's frame plus the angle
of the payload relative to the robot, counted from the start: the architecture paper's
x_a = [x_a, y_a, θ_a] (``ctx.sense("arm")``). An engaged grasp past its limit drops the
payload: the run ends with outcome ``link_broken``.

Engagement is how a box gets picked up. A grasp with ``engaged: holding`` holds only
while the robot's variable ``holding`` is above 0.5 (a transition sets it); without the
key it always holds. With no grasp engaged the payload stays where it rests — ``pose``,
or the spring equilibrium of every grasp at the start — and from then on where it was
last put down. Arms read their offsets whether engaged or not: an arm touching the box is
how the Labmate docks. A single engaged grasp transmits no torque (a point spring), so
the payload keeps its angle and follows that grasp's point.

The payload's outline (a box, or a bar as a segment) is an obstacle to the range sensors
of the ``obstacles`` component, which asks it where rays meet it and how far it is from
the static obstacles (:meth:`CarriedPayload.ray_hits`, :meth:`CarriedPayload.gap`).

Grasps are judged at their carriers' sensing instants (:meth:`WorldAccess.sensing`: the
law ticks), not located between them: a break is reported at the first such tick past the
limit, at most one law period late, whatever other traffic the team has. The payload
settles only where something reads it (:meth:`CarriedPayload.current`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from hybridteam.arrays import every, filled, some
from hybridteam.errors import ModelError, did_you_mean
from hybridteam.floatpaths import FLOAT_PATHS
from hybridteam.world.access import WorldAccess, require_variable
from hybridteam.world.component import WorldComponent, settings_error, world_component
from hybridteam.world.payload import equilibrium, world_points
from hybridteam.world.raycast import Targets, cast_at
from hybridteam.world.scene import BarShape, BoxShape, PayloadShape, SceneDescription
from hybridteam.world.settle_one import settle_one

if TYPE_CHECKING:
    from hybridteam.model import Agent, Team

_GRASP_KEYS = ("agent", "point", "mount", "spring", "limit", "engaged")
#: A grasp's defaults when neither the grasp nor the robot's model gives them.
_FREE = {"mount": [0.0, 0.0], "spring": 1.0, "limit": math.inf}


def _number(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool)


def _pair(v: Any) -> bool:
    return isinstance(v, list | tuple) and len(v) == 2 and all(map(_number, v))


def grasp_defaults(agent: Agent | None) -> dict[str, Any]:
    """``mount``, ``spring`` and ``limit`` of the agent's manipulator (its robot model's),
    or the free defaults: a grasp at the robot's centre, spring 1, never breaking."""
    arm = getattr(getattr(agent, "preset", None), "manipulator", None)
    if arm is None:
        return dict(_FREE)
    return {
        "mount": [float(arm.mount[0]), float(arm.mount[1])],
        "spring": float(arm.spring),
        "limit": float(arm.limit),
    }


def _unarmed(agent: Agent, grasp: Mapping[str, Any], at: tuple[Any, ...]) -> list[ModelError]:
    """A grasp of a robot whose model has no manipulator (a Scout) must say how it holds.

    Defaulting it to the free grasp (spring 1, no limit) would let a Scout carry a beam
    that can never drop and make a grasp requirement meaningless, so it is refused unless
    the grasp gives its ``spring`` and ``limit``. A robot declared without a model keeps
    the free defaults: it claims no hardware, and an idealized hold is what it models.
    """
    preset = getattr(agent, "preset", None)
    if preset is None or preset.manipulator is not None:
        return []
    missing = [key for key in ("spring", "limit") if key not in grasp]
    if not missing:
        return []
    return [
        ModelError(
            at,
            f"robot '{agent.name}' has no manipulator in its model to take "
            f"the grasp's {' and '.join(missing)} from",
            hint="give them in the grasp (spring: 400, limit: 0.1), or give the "
            "robot a manipulator (manipulator: {kind: spring_link, spring: 400, "
            "limit: 0.1})",
        )
    ]


@dataclass
class PayloadWork:
    """What a :class:`CarriedPayload` computed over a run, all instances together: read
    after the run (``component.work``), as :class:`~hybridteam.world.obstacles.ObstacleWork`
    is, instead of wrapping the component's methods. No result depends on it."""

    #: Gaps measured from the outline to obstacles (:meth:`CarriedPayload.gap` calls).
    gaps: int = 0


@world_component("payload")
class CarriedPayload(WorldComponent):
    """A rigid box or bar held by springs at k grasps (see the module docstring)."""

    params: ClassVar[dict[str, Any]] = {
        "name": "payload",
        "shape": "box",
        "width": 1.0,
        "depth": 0.6,
        "length": 1.0,
        "grasps": [],
        "pose": [],
    }
    sensing_instants_only: ClassVar[bool] = True

    @classmethod
    def check(cls, team: Team, values: Mapping[str, Any]) -> list[ModelError]:
        names = [a.name for a in team.agents]
        grasps = values.get("grasps", [])
        problems = []
        if values.get("shape", "box") not in ("box", "bar"):
            problems.append(
                ModelError(("shape",), f"expected 'box' or 'bar', got {values['shape']!r}")
            )
        pose = values.get("pose", [])
        if pose and not (isinstance(pose, list) and len(pose) == 3 and all(map(_number, pose))):
            problems.append(
                ModelError(("pose",), f"expected [x, y, theta] (theta in radians), got {pose!r}")
            )
        if not grasps:
            problems.append(ModelError(("grasps",), "needs at least one grasp"))
        for k, g in enumerate(grasps):
            at = ("grasps", k)
            if not isinstance(g, dict) or "agent" not in g:
                problems.append(
                    ModelError(
                        at,
                        "a grasp is a mapping with 'agent' and "
                        f"optionally {', '.join(_GRASP_KEYS[1:])}",
                    )
                )
                continue
            for key in g:
                if key not in _GRASP_KEYS:
                    problems.append(
                        ModelError(
                            (*at, key),
                            f"a grasp has no key {key!r}",
                            hint=did_you_mean(str(key), _GRASP_KEYS),
                            at_key=True,
                        )
                    )
            if g["agent"] not in names:
                problems.append(
                    ModelError(
                        (*at, "agent"),
                        f"unknown agent {g['agent']!r}",
                        hint=did_you_mean(str(g["agent"]), names),
                    )
                )
            for key in ("point", "mount"):
                if key in g and not _pair(g[key]):
                    problems.append(ModelError((*at, key), f"expected [x, y], got {g[key]!r}"))
            for key in ("spring", "limit"):
                if key in g and not (_number(g[key]) and g[key] > 0):
                    problems.append(
                        ModelError((*at, key), f"expected a positive number, got {g[key]!r}")
                    )
            if g["agent"] in names:
                problems += _unarmed(team.agents[names.index(g["agent"])], g, at)
            if "engaged" in g and not (
                isinstance(g["engaged"], str) and g["engaged"].isidentifier()
            ):
                problems.append(
                    ModelError(
                        (*at, "engaged"),
                        f"expected the name of one of the agent's variables, got {g['engaged']!r}",
                    )
                )
        return problems

    def __init__(self, team: Team, n: int, values: Mapping[str, Any]) -> None:
        super().__init__(team, n, values)
        problems = self.check(team, values)
        if problems:
            raise settings_error("payload", problems)
        names = [a.name for a in team.agents]
        grasps = values["grasps"]
        self.agents = [names.index(g["agent"]) for g in grasps]
        self.carriers = list(dict.fromkeys(self.agents))  # each robot once
        full = [
            {**grasp_defaults(team.agents[a]), **g}
            for a, g in zip(self.agents, grasps, strict=True)
        ]
        self.body = np.array([g.get("point", [0.0, 0.0]) for g in full], float)
        self.mount = np.array([g["mount"] for g in full], float)
        self.spring = np.array([float(g["spring"]) for g in full])
        self.limit = np.array([float(g["limit"]) for g in full])
        self.engaged_by: list[str | None] = [g.get("engaged") for g in grasps]
        k = len(grasps)
        self.pose = np.full((n, 3), np.nan)
        self.rest = np.full((n, 3), np.nan)  # where it lies when nobody holds it
        self.engaged = np.ones((n, k), bool)
        self.offset = np.full((n, k, 2), np.nan)  # world frame, robot minus grasp point
        self.arm = np.full((n, k, 3), np.nan)  # robot frame, and relative angle
        self.rel0 = np.zeros((n, k))
        self.max_offset = np.zeros((n, k))
        #: the time each instance last settled (NaN: not yet): a payload settles at most
        #: once an instant, when first read (:meth:`current`)
        self.settled_t = np.full(n, np.nan)
        self._one_size: bool | None = None  # whether every instance's outline is one size
        self._outlines: dict[tuple[float, float], Targets] = {}
        self._held_by_code: dict[int, np.ndarray] = {}
        self._halves: tuple[np.ndarray, np.ndarray] | None = None
        self._bits = 1 << np.arange(k)  # grasp j holds: bit j of an engagement code
        #: the work done so far (:class:`PayloadWork`), read after the run
        self.work = PayloadWork()

    def _robot_points(self, world: WorldAccess, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        poses = np.empty((idx.size, len(self.agents), 3))  # (m, k, 3); np.stack's values
        for k, a in enumerate(self.agents):
            poses[:, k] = world.pose(a, idx)
        c, s = np.cos(poses[..., 2]), np.sin(poses[..., 2])
        mx, my = self.mount[:, 0], self.mount[:, 1]
        pts = np.empty((*poses.shape[:2], 2))
        pts[..., 0] = poses[..., 0] + c * mx - s * my
        pts[..., 1] = poses[..., 1] + s * mx + c * my
        return pts, poses[..., 2]

    def start(self, world: WorldAccess) -> None:
        self.world = world  # kept: sense() and sample() settle what they read
        for k, (a, name) in enumerate(zip(self.agents, self.engaged_by, strict=True)):
            if name is not None:
                require_variable(world, a, name, f"payload: grasps[{k}].engaged")
        if self.values["pose"]:
            self.rest[:] = np.asarray(self.values["pose"], float)
        else:
            pts, _ = self._robot_points(world, np.arange(self.n))
            eq = equilibrium(pts, self.body, self.spring)
            self.rest[:] = np.c_[eq.x, eq.y, eq.theta]
        heading = self.settle(world, np.arange(self.n))
        self.rel0[:] = self.pose[:, 2:3] - heading
        self.arm[..., 2] = 0.0

    def engagement(self, world: WorldAccess, idx: np.ndarray) -> np.ndarray:
        """Which grasps hold in instances ``idx``: ``(m, k)`` bool (also the swept settled
        payload's question over an ensemble, :mod:`~hybridteam.world.obstacles`)."""
        on = filled((idx.size, len(self.agents)), True, bool)
        for k, name in enumerate(self.engaged_by):
            if name is not None:
                on[:, k] = world.variable(self.agents[k], name, idx) > 0.5
        return on

    def sole_grasp(self, world: WorldAccess, idx: np.ndarray) -> int | None:
        """The grasp that alone holds in the one instance ``idx``, None where none or
        several do (the swept payload's question, :mod:`~hybridteam.world.swept_payload`;
        on floats)."""
        sole = None
        for k, (a, name) in enumerate(zip(self.agents, self.engaged_by, strict=True)):
            if name is None or world.variable(a, name, idx).item(0) > 0.5:
                if sole is not None:
                    return None
                sole = k
        return sole

    def holding(self, world: WorldAccess, idx: np.ndarray) -> list[int]:
        """The grasps that hold in the one instance ``idx`` (the swept settled payload's
        question, :mod:`~hybridteam.world.swept_settled`; on floats)."""
        return [
            k
            for k, (a, name) in enumerate(zip(self.agents, self.engaged_by, strict=True))
            if name is None or world.variable(a, name, idx).item(0) > 0.5
        ]

    def settle(self, world: WorldAccess, idx: np.ndarray) -> np.ndarray:
        """Pose, offsets and arm readings of instances ``idx`` from the current state;
        returns the robots' headings ``(m, k)`` (the start counts the arms' angles from them).

        A function of the state and of where the payload rests, which it updates to the
        settled pose: calling it twice at one instant gives the same result (the
        ``obstacles`` component does so when it is listed before the payload). Instances
        are grouped by which grasps hold, one equilibrium per group present (at most 2^k,
        usually one), so the work stays vectorized over the ensemble.
        """
        return self._settle(world, idx)[0]

    def _settle(
        self, world: WorldAccess, idx: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`settle`, returning the headings, the offsets ``(m, k, 2)`` and which grasps
        hold ``(m, k)`` (what :meth:`update` checks next, without gathering them again)."""
        if idx.size == 1 and FLOAT_PATHS.on:  # a single run's instant: the same numbers
            return settle_one(self, world, idx)
        pts, heading = self._robot_points(world, idx)
        on = self.engagement(world, idx)
        pose = self.rest[idx]
        k = len(self.agents)
        code = on @ self._bits
        codes = [int(code[0])] if code.size and every(code == code[0]) else np.unique(code).tolist()
        for c in codes:
            # every row under one code (the usual case): whole arrays, not masked copies
            rows: slice | np.ndarray = slice(None) if len(codes) == 1 else code == c
            held = self._held(c)
            if held.size == 1:  # no torque: keep the angle, follow the grasp point
                (j,) = held
                th = pose[rows, 2]
                cs, sn = np.cos(th), np.sin(th)
                bx, by = self.body[j]
                pose[rows, 0] = pts[rows, j, 0] - (cs * bx - sn * by)
                pose[rows, 1] = pts[rows, j, 1] - (sn * bx + cs * by)
            elif held.size > 1:
                some_of = slice(None) if held.size == k else held  # all: views, not copies
                eq = equilibrium(
                    pts[rows][:, some_of], self.body[some_of], self.spring[some_of], offsets=False
                )
                pose[rows, 0], pose[rows, 1], pose[rows, 2] = eq.x, eq.y, eq.theta
        self.pose[idx] = pose
        self.rest[idx] = pose
        self.engaged[idx] = on
        offsets = pts - world_points(pose[:, 0], pose[:, 1], pose[:, 2], self.body)
        self.offset[idx] = offsets
        c, s = np.cos(heading), np.sin(heading)
        ox, oy = offsets[..., 0], offsets[..., 1]
        rel = pose[:, 2:3] - heading - self.rel0[idx]
        arm = np.empty((*offsets.shape[:2], 3))
        arm[..., 0], arm[..., 1] = c * ox + s * oy, -s * ox + c * oy
        arm[..., 2] = np.arctan2(np.sin(rel), np.cos(rel))
        self.arm[idx] = arm
        return heading, offsets, on

    def current(self, world: WorldAccess, idx: np.ndarray) -> None:
        """Settle the instances of ``idx`` not yet settled at their current time.

        The payload is settled when something reads it — its carriers' sensing instants
        (:meth:`update`), a law sensing ``arm`` or ``payload``, the ``obstacles``
        component casting rays at its outline — never at an instant where nobody reads it
        (a stream copy arriving; its series hold the last settling, :meth:`sample`).
        Settling is a function of the carriers' poses, the engagement and where it rests,
        which it leaves where it settled, so settling later on demand gives what settling
        at every instant would have given, except that a single grasp keeps the angle of
        the last settling (not of the last instant) when the others let go."""
        t = world.t[idx]
        stale = self.settled_t[idx] != t
        if not some(stale):
            return
        rows = idx if every(stale) else idx[stale]
        self._settle(world, rows)
        self.settled_t[rows] = t[stale]

    def _held(self, code: int) -> np.ndarray:
        """Indices of the grasps that hold under engagement ``code`` (bit k: grasp k),
        kept: there are a handful of codes, and each instant asks for one."""
        if code not in self._held_by_code:
            bits = (code >> np.arange(len(self.agents))) & 1
            self._held_by_code[code] = np.flatnonzero(bits)
        return self._held_by_code[code]

    def carriers_sensing(self, world: WorldAccess, idx: np.ndarray) -> np.ndarray:
        """The instances of ``idx`` at a sensing instant of some carrier (a robot holding
        a grasp, engaged or not): where the grasps are judged."""
        if idx.size == 1:  # (a single run's instant, on bools: most are arrivals)
            return idx if any(world.sensing(a, idx).item(0) for a in self.carriers) else idx[:0]
        sensing = world.sensing(self.carriers[0], idx)
        for a in self.carriers[1:]:
            sensing = sensing | world.sensing(a, idx)
        return idx if every(sensing) else idx[sensing]

    def update(self, world: WorldAccess, idx: np.ndarray) -> None:
        """Settle and judge the grasps at the carriers' sensing instants (a break is seen
        at the first such instant past the limit); elsewhere nothing (a reader settles what
        it reads, :meth:`current`)."""
        idx = self.carriers_sensing(world, idx)
        if idx.size == 0:
            return
        # settled afresh even where already settled at this time: a state written since
        # at the same time (a live world process's received pose) is seen
        _, offsets, on = self._settle(world, idx)
        self.settled_t[idx] = world.t[idx]
        size = np.hypot(offsets[..., 0], offsets[..., 1])
        self.max_offset[idx] = np.where(
            on, np.maximum(self.max_offset[idx], size), self.max_offset[idx]
        )
        over = (size > self.limit) & on
        bad = over.any(axis=1)
        if some(bad):
            names = [self.team.agents[a].name for a in self.agents]
            rows = dict(zip(idx[bad].tolist(), over[bad], strict=True))
            sizes = dict(zip(idx[bad].tolist(), size[bad], strict=True))
            world.finish(
                idx[bad],
                "link_broken",
                lambda i: "; ".join(
                    f"{self.values['name']} dropped: the grasp of '{names[k]}' is offset "
                    f"{sizes[i][k]:.4g} > limit {self.limit[k]:.4g}"
                    for k in np.flatnonzero(rows[i]).tolist()
                ),
            )

    def senses(self) -> tuple[str, ...]:
        return ("arm", "payload")

    def sense(self, agent: int, idx: np.ndarray, name: str) -> np.ndarray:
        self.current(self.world, idx)
        if name == "payload":
            return self.pose[idx]
        if agent not in self.agents:
            return np.full((len(idx), 3), np.nan)  # this robot holds no grasp
        return self.arm[idx, self.agents.index(agent)]

    def sample_series(self) -> dict[str, tuple[str, ...]]:
        """The pose, and ``<name>_grasp``: each grasp's offset (m) while it holds, 0 while
        not, one column per grasping robot — what requirements such as
        ``always(box_grasp.labmate < 0.15)`` read."""
        names = [self.team.agents[a].name for a in self.agents]
        cols = tuple(n if names.count(n) == 1 else f"{n}_{k}" for k, n in enumerate(names))
        return {self.values["name"]: ("x", "y", "theta"), f"{self.values['name']}_grasp": cols}

    def sample(self, idx: np.ndarray) -> dict[str, np.ndarray]:
        """The pose and grasp offsets as last settled (at a carrier's sensing instant, or
        where something read them): an arrival between ticks settles nothing."""
        size = np.hypot(self.offset[idx, :, 0], self.offset[idx, :, 1])
        return {
            self.values["name"]: self.pose[idx],
            f"{self.values['name']}_grasp": np.where(self.engaged[idx], size, 0.0),
        }

    def summary(self, i: int) -> dict[str, Any]:
        return {"max_grasp_offset": [float(v) for v in self.max_offset[i]]}

    # ------------------------------------------------------------------ the outline
    def half_extents(self, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Half length and half width per instance (a bar is a segment: no width)."""
        if self._halves is None:  # every instance's, once: asked at every instant
            v = self.values
            self._halves = (
                (v["length"] / 2.0, np.zeros(self.n))
                if v["shape"] == "bar"
                else (v["width"] / 2.0, v["depth"] / 2.0)
            )
        return self._halves[0][idx], self._halves[1][idx]

    def ray_hits(
        self, idx: np.ndarray, origins: np.ndarray, directions: np.ndarray, max_range: float
    ) -> np.ndarray:
        """Where rays ``(m, R, 2)`` of instances ``idx`` meet the outline: ``(m, R)``.

        Cast in the body frame, where the outline is one set of segments for every
        instance of a size, so one :func:`~hybridteam.world.raycast.cast_at` serves them all
        (a loop over the distinct sizes, usually one, never over instances).
        """
        pose = self.pose[idx]
        o, d = np.empty(origins.shape), np.empty(directions.shape)
        # _to_body's arithmetic, one rotation for the origins and the directions
        c, s = np.cos(pose[:, 2:3]), np.sin(pose[:, 2:3])
        dx, dy = origins[..., 0] - pose[:, 0:1], origins[..., 1] - pose[:, 1:2]
        o[..., 0], o[..., 1] = c * dx + s * dy, -s * dx + c * dy
        dx, dy = directions[..., 0], directions[..., 1]
        d[..., 0], d[..., 1] = c * dx + s * dy, -s * dx + c * dy
        hw, hd = self.half_extents(idx)
        if self._one_size is None:
            extents = self.half_extents(np.arange(self.n))
            self._one_size = all(every(h == h[0]) for h in extents)
        if self._one_size and hw.size:  # every instance's payload has one size (usual)
            return cast_at(o, d, self._outline(float(hw[0]), float(hd[0])), max_range)
        out = np.full(origins.shape[:2], float(max_range))
        for w, h in np.unique(np.stack([hw, hd], 1), axis=0):
            rows = (hw == w) & (hd == h)
            out[rows] = cast_at(o[rows], d[rows], self._outline(w, h), max_range)
        return out

    def _outline(self, w: float, h: float) -> Targets:
        """The outline of a ``2w x 2h`` box (a bar when ``h`` is 0) in the body frame,
        prepared for casting once per size."""
        key = (float(w), float(h))
        if key not in self._outlines:
            self._outlines[key] = Targets.of(
                [[-w, 0.0, w, 0.0]]
                if h == 0
                else [[-w, -h, w, -h], [w, -h, w, h], [w, h, -w, h], [-w, h, -w, -h]]
            )
        return self._outlines[key]

    def outline_distance(self, idx: np.ndarray, points: np.ndarray) -> np.ndarray:
        """Distance from world points ``(m, 2)`` (or poses) of instances ``idx`` to the
        payload's outline, 0 inside it: no ray from a point meets the outline nearer."""
        x, y = _to_body(points[:, 0], points[:, 1], self.pose[idx])
        hw, hd = self.half_extents(idx)
        return _point_box(x, y, hw, hd)

    def gap(self, idx: np.ndarray, segments: np.ndarray, circles: np.ndarray) -> np.ndarray:
        """Distance from the outline to the nearest of ``segments`` ``(s, 4)`` and
        ``circles`` ``(c, 3)``: ``(m,)``, 0 where they meet or overlap, inf if none."""
        self.work.gaps += 1
        pose = self.pose[idx]
        hw, hd = (h[:, None] for h in self.half_extents(idx))
        out = filled(idx.size, np.inf)
        if len(segments):
            s = np.asarray(segments, float)[None]
            ends_x, ends_y = _to_body(s[..., 0::2], s[..., 1::2], pose)  # both ends at once
            ax, bx, ay, by = ends_x[..., 0], ends_x[..., 1], ends_y[..., 0], ends_y[..., 1]
            out = np.minimum(out, np.minimum.reduce(_segment_box(ax, ay, bx, by, hw, hd), axis=1))
        if len(circles):
            c = np.asarray(circles, float)[None]
            cx, cy = _to_body(c[..., 0], c[..., 1], pose)
            out = np.minimum(
                out,
                np.minimum.reduce(np.maximum(_point_box(cx, cy, hw, hd) - c[..., 2], 0.0), axis=1),
            )
        return out

    def describe(self) -> SceneDescription:
        """The payload's outline, drawn at its pose series (named as the payload)."""
        v = self.values
        shape: PayloadShape = (
            BarShape(float(v["length"][0]))
            if v["shape"] == "bar"
            else BoxShape(float(v["width"][0]), float(v["depth"][0]))
        )
        return SceneDescription(payloads={v["name"]: shape})


def _to_body(
    x: np.ndarray, y: np.ndarray, pose: np.ndarray, move: bool = True
) -> tuple[np.ndarray, np.ndarray]:
    """Points ``(m, ...)`` in the frames of ``m`` poses; with ``move`` false, vectors
    (rotated, not shifted)."""
    shape = (-1,) + (1,) * (max(np.ndim(x), np.ndim(y)) - 1)
    px, py, th = (pose[:, j].reshape(shape) for j in range(3))
    c, s = np.cos(th), np.sin(th)
    dx, dy = (x - px, y - py) if move else (x, y)
    return c * dx + s * dy, -s * dx + c * dy


def _point_box(x: np.ndarray, y: np.ndarray, hw: np.ndarray, hd: np.ndarray) -> np.ndarray:
    """Distance from points to the box ``|x| <= hw, |y| <= hd`` (0 inside)."""
    return np.hypot(np.maximum(np.abs(x) - hw, 0.0), np.maximum(np.abs(y) - hd, 0.0))


def _segment_box(
    ax: np.ndarray, ay: np.ndarray, bx: np.ndarray, by: np.ndarray, hw: np.ndarray, hd: np.ndarray
) -> np.ndarray:
    """Distance between segments ``a -> b`` and the box ``|x| <= hw, |y| <= hd``.

    Zero when they meet (a Liang–Barsky clip of the segment by the box's two slabs is not
    empty); otherwise the distance between two disjoint convex sets is reached at a vertex
    of one of them: a segment end to the box, or a box corner to the segment.
    """
    dx, dy = bx - ax, by - ay
    # both slabs at once, on a leading axis (x, y); only whether t0 <= t1 is kept
    p, d, h = np.stack((ax, ay)), np.stack((dx, dy)), np.stack((hw, hd))
    with np.errstate(divide="ignore", invalid="ignore"):
        ta, tb = (-h - p) / d, (h - p) / d
    flat = d == 0  # parallel to the slab: inside it for every t, or for none
    edge = np.where(np.abs(p) <= h, -np.inf, np.inf)
    low = np.where(flat, edge, np.minimum(ta, tb))
    high = np.where(flat, -edge, np.maximum(ta, tb))
    t0 = np.maximum(np.maximum(low[0], low[1]), 0.0)
    t1 = np.minimum(np.minimum(high[0], high[1]), 1.0)
    dist = np.minimum(_point_box(ax, ay, hw, hd), _point_box(bx, by, hw, hd))
    dd = dx * dx + dy * dy
    # the four corners at once, on a leading axis (the same arithmetic per element as one
    # corner at a time: a single run's gap is a few elements, and the calls are its cost)
    signs = _CORNERS.reshape((2, 4) + (1,) * t0.ndim)  # (t0: the broadcast shape)
    cx, cy = signs[0] * hw, signs[1] * hd
    t = np.clip(((cx - ax) * dx + (cy - ay) * dy) / np.where(dd > 0, dd, 1.0), 0.0, 1.0)
    dist = np.minimum(dist, np.minimum.reduce(np.hypot(ax + t * dx - cx, ay + t * dy - cy), axis=0))
    return np.where(t0 <= t1, 0.0, dist)


#: The signs of a box's corners ``(2, 4)``, x then y, in the order they were once taken
_CORNERS = np.array([[-1, 1, 1, -1], [-1, -1, 1, 1]], float)
