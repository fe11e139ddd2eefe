"""Static obstacles and the range sensors that see them: the ``obstacles`` component.

The architecture paper's robots react to what their rings see: the XR4000's infrared ring
detects an obstacle ahead while it carries a box, the Scout's sonar detects one, and the
XR4000's Dock approaches the box guided by its IR. This component holds the world's
static obstacles — walls (segments), circles, and boxes (rectangles, four walls each) —
and, at the sensing instants of the robots that need them (their law ticks:
:meth:`~hybridteam.world.access.WorldAccess.sensing`), casts their range rings
(:class:`~hybridteam.world.sensors.RangeRing`) against those obstacles *and* the outline
of every ``payload`` component's payload (a resting box is what the Dock's IR approaches).

A rule's ring is cast only where something is near enough to fire one of its rules: the
robot's clearance from the static scene and from the payloads' outlines bounds every beam
from below (:meth:`Obstacles.floor`), and where that bound is past every threshold the
rules read nothing near without casting; where the last reading saw something within
every instance's threshold, the floor is skipped (it would rule out nothing).

Nothing is excluded from what a ring sees, not even the payload its own robot carries (a
simple rule is a predictable one): a ``detect`` rule picks the beams that look away from
the payload. Other robots are not obstacles here.

A rule ``{agent, sensor, beams | sector, below, raise}`` raises the local event ``raise``
in ``agent`` when the nearest of its beams drops below ``below`` — on the rising edge
only, per instance, so a robot standing by a wall is told once; before the run nothing
counts as seen, so an obstacle already in range is reported at the first instant. Like
payload breaks, a rule reads at its robot's sensing instants, so a detection is reported
at the robot's first tick past the crossing, at most one period late, and a message
arriving between other robots' ticks moves nothing; an instant where no robot this
component judges senses costs it that test alone.
Laws read a ring with ``ctx.sense("ir")``: ``(m, count)`` ranges, ``max_range`` where
nothing is seen. Ring geometry comes from the robot's model (``model: xr4000``) or, for
robots declared without one, from the rule (``ring:`` with :class:`RangeRing`'s
arguments).

Statistics, per instance, minimized over the robots' sensing instants (a payload's: its
carriers') and, for a robot under a held input, over its motion between instants too
(:mod:`hybridteam.world.swept`, exact closed forms): ``min_clearance`` (one entry
per planar robot in the team's order: the gap between its footprint disk and the nearest
static obstacle, negative when overlapping; a robot with no footprint radius is a point)
and ``payload_clearance`` (the gap between any payload's outline and the static
obstacles, 0 when they touch or overlap; a payload held by one grasp of a robot under a
held input over its motion between instants too, :mod:`hybridteam.world.swept_payload`;
by two or more, certified bounds, :mod:`hybridteam.world.swept_settled`).
Two robots under held inputs are judged against each other over their motion between
instants too (:mod:`hybridteam.world.swept_pair`: a collision, at its first contact).
With ``clearance: true`` the same gaps are also
series for requirements, holding between those instants (:meth:`Obstacles.sample`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, NamedTuple

import numpy as np

from hybridteam.arrays import every, filled, some, where_true
from hybridteam.errors import ModelError
from hybridteam.floatpaths import FLOAT_PATHS
from hybridteam.world import sight
from hybridteam.world.access import WorldAccess
from hybridteam.world.carried import CarriedPayload
from hybridteam.world.collisions import box_sdf, name_hit, robot_overlaps
from hybridteam.world.component import (
    WorldComponent,
    lookup,
    settings_error,
    world_component,
)
from hybridteam.world.measure_one import measure_one
from hybridteam.world.obstacle_settings import Rule, parse_settings, planar
from hybridteam.world.raycast import Targets, cast_at
from hybridteam.world.scene import (
    CircleObstacle,
    CollisionMark,
    Footprint,
    Obstacle,
    PolygonObstacle,
    SceneDescription,
    WallObstacle,
)
from hybridteam.world.sensors import RangeRing, clearance
from hybridteam.world.swept import (
    Piece,
    first_contact,
    holds_between_instants,
    least_gap,
    path_length,
    piece,
    point_gap,
)
from hybridteam.world.swept_pair import first_touch, least_separation, may_touch
from hybridteam.world.swept_payload import (
    carry,
    outline,
    payload_first_contact,
    payload_least_gap,
)
from hybridteam.world.swept_settled import GAP_TOLERANCE, Frame, SettledCarry, State, grip

if TYPE_CHECKING:
    from hybridteam.model import Agent, Team

#: Rounding allowance (relative to coordinates and range) of the test that lets a reading
#: skip casting against static obstacles beyond the ring's range (``Obstacles.read``)
_SLACK = 1e-9


@dataclass
class ObstacleWork:
    """What an :class:`Obstacles` component computed over a run, all instances together.

    Counters in the way :class:`~hybridteam.engine.run.costs.Costs` counts the crossing
    search's work: a test asserts how much work a case takes by reading them after the run
    (``component.work``), not by wrapping the component's methods, so a refactor that
    keeps the work keeps the counts. No result depends on them; each is one integer
    addition per call.
    """

    #: Instants updated (:meth:`Obstacles.update` calls, every instance of one at once).
    updates: int = 0
    #: Lower bounds on a ring's readings computed (:meth:`Obstacles.floor` calls).
    floors: int = 0
    #: Ring readings cast (:meth:`Obstacles.read` calls, one per scene where instances'
    #: obstacles differ, plus the call that groups them).
    reads: int = 0
    #: A ring's rule verdicts on the payloads proved by bounds without casting
    #: (:mod:`hybridteam.world.sight`), those kept from an earlier proof, and the casts
    #: of the static obstacles alone that completed them.
    proved: int = 0
    kept: int = 0
    statics: int = 0
    #: A single run's verdicts reused where the ring's robot and every payload stood
    #: still since the last ones.
    still: int = 0


@world_component("obstacles")
class Obstacles(WorldComponent):
    """Walls, circles and boxes; range rings cast against them and the payloads."""

    params: ClassVar[dict[str, Any]] = {
        "walls": [],
        "circles": [],
        "boxes": [],
        "detect": [],
        "radius": [],
        "on_collision": "outcome",
        "clearance": False,
    }
    #: a door's jambs may be expressions of team parameters (a study sweeps its width)
    per_instance: ClassVar[tuple[str, ...]] = ("walls", "circles", "boxes")
    sensing_instants_only: ClassVar[bool] = True

    @classmethod
    def check(cls, team: Team, values: Mapping[str, Any]) -> list[ModelError]:
        parsed, problems = parse_settings(team, values)
        if (
            values.get("clearance")
            and not problems
            and not any(parsed[key].shape[1] for key in ("walls", "circles", "boxes"))
        ):
            problems.append(
                ModelError(
                    ("clearance",), "there is no wall, circle or box to measure a clearance from"
                )
            )
        return problems

    def __init__(self, team: Team, n: int, values: Mapping[str, Any]) -> None:
        super().__init__(team, n, values)
        parsed, problems = parse_settings(team, values, n)
        if problems:
            raise settings_error("obstacles", problems)
        self.scenes, self.scene_of = _scenes(parsed["walls"], parsed["circles"], parsed["boxes"])
        self.rules: list[Rule] = parsed["rules"]
        self.rings: dict[tuple[int, str], RangeRing] = parsed["rings"]
        # (this component's events come from its settings: its instance's, where the base
        # class declares a class's)
        self.raises = tuple(dict.fromkeys(r.event for r in self.rules))  # type: ignore[misc]
        # the beams the rules read, per ring: only those are cast at each instant (a rule on
        # the front IR reads 3 of 24 beams), and where each rule's beams are among them
        self.read_beams: dict[tuple[int, str], np.ndarray] = {}
        for rule in self.rules:
            key = (rule.agent, rule.sensor)
            self.read_beams[key] = np.union1d(self.read_beams.get(key, rule.beams), rule.beams)
        #: per (agent, sensor): the highest threshold of its rules (readings at least that
        #: far fire none)
        self.below = {
            key: max(r.below for r in self.rules if (r.agent, r.sensor) == key)
            for key in self.read_beams
        }
        self.rule_columns = [
            np.searchsorted(self.read_beams[(r.agent, r.sensor)], r.beams) for r in self.rules
        ]
        #: per (agent, sensor): its rules' indices
        self.key_rules = {
            key: [r for r, rule in enumerate(self.rules) if (rule.agent, rule.sensor) == key]
            for key in self.read_beams
        }
        #: per (agent, sensor), a single run's verdicts proved by bounds and where the ring
        #: was relative to each payload then (:meth:`_sighted`)
        self.sighted: dict[tuple[int, str], _Sighted] = {}
        #: per (agent, sensor), a single run's last verdicts and the poses they were made at
        #: (:meth:`_verdicts`)
        self.still: dict[tuple[int, str], _Still] = {}
        #: per (agent, sensor): whether every instance its rules last read saw something
        #: within their highest threshold (a carried box before the IR): then the floor
        #: would rule out no instance and is not computed (:meth:`_rule_readings`)
        self.within: dict[tuple[int, str], bool] = {}
        self.planar = [a for a, agent in enumerate(team.agents) if planar(agent)]
        given = parsed["radius"]
        self.radius = np.array([given.get(a, _footprint(team.agents[a])) for a in self.planar])
        #: the planar robots judged over their motion between instants (:meth:`_sweep`),
        #: as (row in ``planar``, agent, unicycle?): kinematic plants under held inputs
        self.swept = [
            (r, a, team.agents[a].plant.kind == "unicycle")
            for r, a in enumerate(self.planar)
            if team.agents[a].plant.kind in ("unicycle", "holonomic")
            and holds_between_instants(team.agents[a].root)
        ]
        self._turning = {r: turning for r, _, turning in self.swept}
        #: per swept robot: its pose at each instance's last instant and when ``(R, n, 3)``,
        #: ``(n,)``; the least gap over its motion since it last sensed ``(R, n)``, and
        #: its first contact then, per (row, instance): ``(t, x, y, what, overlap)``
        self.last_pose = np.full((len(self.planar), n, 3), np.nan)
        self.last_t = np.full(n, np.nan)
        self.last_gap = np.full((len(self.planar), n), np.nan)  # (at ``last_pose``)
        #: a single run's: per swept row, its last pose and that pose's gap, as floats
        self.last_one: dict[int, tuple[list[float], float]] = {}
        self.swept_gap = np.full((len(self.planar), n), np.inf)
        self.swept_hit: dict[tuple[int, int], tuple[float, float, float, str, float]] = {}
        #: the pairs of swept robots with footprints, judged against each other over their
        #: motion too (:mod:`.swept_pair`): (row, row); and each pair's first contact since
        #: either last sensed, per (row, row, instance): ``(t, x, y, overlap)``; with each
        #: pair, the sum of their radii. None under ``on_collision: ignore``: a pair's
        #: contact is a collision and nothing else (no statistic)
        footed = [(r, self.radius.item(r)) for r, _, _ in self.swept if self.radius[r] > 0]
        self.swept_pairs = [
            (r1, r2, f1 + f2) for k, (r1, f1) in enumerate(footed) for r2, f2 in footed[k + 1 :]
        ]
        if self.values["on_collision"] == "ignore":
            self.swept_pairs = []
        self.pair_hit: dict[tuple[int, int, int], tuple[float, float, float, float]] = {}
        names = {s for _, s in self.rings}
        for agent in team.agents:
            preset = getattr(agent, "preset", None)
            names |= set(preset.rings()) if preset is not None else set()
        self.sensors = tuple(sorted(names))  # what laws may sense (asked at every tick)
        #: the payloads' names, known before the start (the trace's series are declared
        #: before the components start)
        kinds = [(spec, lookup(spec.use)) for spec in team.world]
        self.payload_names = [
            str(spec.values.get("name", cls.params["name"]))
            for spec, cls in kinds
            if issubclass(cls, CarriedPayload)
        ]
        self.payloads: list[CarriedPayload] = []
        self.sensing: set[int] = set()  # agents with a pose, once the run has started
        #: the agents whose sensing instants this component judges at: the planar robots
        #: (clearances, collisions), the rules' robots and the payloads' carriers
        self.judged: list[int] = []
        self.near = np.zeros((len(self.rules), n), bool)
        self.min_clear = np.full((len(self.planar), n), np.inf)
        self.payload_clear = np.full(n, np.inf)
        # each party's first collision per instance: its text (listed under warn) and
        # where and when it happened (marked by the views, under warn and outcome)
        self.collisions: list[dict[str, tuple[str, float, float, float]]] = [{} for _ in range(n)]
        #: the clearances this instant's update measured, for :meth:`sample` at the same
        #: instant: ``(idx, robot centres, payload poses, robot gaps, payload gaps)``
        self._measured: _Measured | None = None
        #: with ``clearance: true``, the series as last measured, robot by robot ``(R, n)``
        #: and payload by payload ``(P, n)``, and when (:meth:`sample` between readings)
        self.robot_gap = np.full((len(self.planar), n), np.nan)
        self.robot_t = np.full((len(self.planar), n), np.nan)
        self.payload_gap = np.full((len(self.payload_names), n), np.nan)
        self.payload_t = np.full((len(self.payload_names), n), np.nan)
        #: the work done so far (:class:`ObstacleWork`), read after the run
        self.work = ObstacleWork()

    def start(self, world: WorldAccess) -> None:
        self.world = world  # kept: sense() reads poses when a law asks
        self.payloads = [
            c for c in world.components(CarriedPayload) if isinstance(c, CarriedPayload)
        ]  # (all are: typed for the reader)
        self.sensing = {*self.planar, *(r.agent for r in self.rules)}
        self.judged = sorted({*self.sensing, *(a for p in self.payloads for a in p.agents)})
        #: the grasps whose robot is swept, per payload: where that grasp alone holds,
        #: the payload is judged over its motion between instants (:mod:`.swept_payload`);
        #: not one beside a grasp that always holds (no ``engaged:``)
        row_of = {a: r for r, a, _ in self.swept}
        self.carried = [
            _Carried.of(k, p, j, row_of[a])
            for k, p in enumerate(self.payloads)
            for j, a in enumerate(p.agents)
            if a in row_of and all(by is not None for g, by in enumerate(p.engaged_by) if g != j)
        ]
        #: the payloads whose robots hold two or more grasps judged over their motion
        #: between instants where those grasps hold (:mod:`.swept_settled`): ``(k,
        #: payload, each grasp's swept row or None)``
        self.settled = [
            (k, p, [row_of.get(a) for a in p.agents])
            for k, p in enumerate(self.payloads)
            if sum(a in row_of for a in p.agents) >= 2
        ]
        #: per payload: its least gap over its motion since a carrier last sensed ``(P, n)``,
        #: and its first contact then, per (payload, instance): ``(t, x, y)``
        self.payload_swept = np.full((len(self.payloads), self.n), np.inf)
        #: per (payload, instance) judged over its motion with two or more grasps: the
        #: last piece's end (which grasps held, their robots' poses) and the payload there,
        #: where the next piece starts if nothing changed between (:meth:`_judge_settled`)
        self.settled_end: dict[tuple[int, int], tuple[Any, State]] = {}
        #: per payload and instance ``(P, n)``: which grasps held when it was last judged
        #: or measured (-1: since forgotten), its gap at that piece's end, and how far it may have
        #: moved since (:meth:`_settled_piece`); and the pieces kept for the summary
        n_payloads = len(self.payloads)
        self.settled_code = np.full((n_payloads, self.n), -1)  # (a bit per holding grasp)
        self.settled_gap = np.full((n_payloads, self.n), np.nan)
        self.settled_moved = np.zeros((n_payloads, self.n))
        #: a single run's: per (payload, grasps held), what its bounds need (:class:`_Fit`),
        #: and per payload the last piece's end, the centroid there (None: not computed)
        #: and a lower bound on its point gap
        self._settled_fit: dict[tuple[int, tuple[int, ...]], _Fit] = {}
        #: per (payload, grasps held, scene, half extents): what its pieces share
        self._settled_frames: dict[tuple[Any, ...], Frame] = {}
        self.settled_prev: dict[int, tuple[_Fit, list[list[float]], Any, float]] = {}
        self.settled_pending: dict[tuple[int, int], list[Any]] = {}
        self._settled_room: dict[tuple[int, int], int] = {}
        self._settled_shape: dict[tuple[int, int], tuple[list[Any], tuple[float, ...]]] = {}
        #: per such (payload, instance): when its last piece ended and which grasps held
        #: over it, and its last gap measured, when, and under which grasps
        #: (:meth:`note_settled_gap`)
        self.settled_last: dict[tuple[int, int], tuple[float, tuple[int, ...]]] = {}
        self.settled_seen: dict[tuple[int, int], tuple[float, float, Any]] = {}
        self.payload_hit: dict[tuple[int, int], tuple[float, float, float]] = {}
        for a in self.sensing:
            world.pose(a, np.arange(0))  # a plant without x and y fails now, not mid-run

    # ------------------------------------------------------------------ readings
    def _poses(self, a: int, idx: np.ndarray) -> np.ndarray:
        return self.world.pose(a, idx)

    def ring(self, a: int, sensor: str) -> RangeRing | None:
        """Agent ``a``'s ring ``sensor``: a detect rule's, else its robot model's; None if
        it has none (a live robot's laser is read as this ring: hybridteam.live)."""
        if (a, sensor) in self.rings:
            return self.rings[(a, sensor)]
        preset = getattr(self.team.agents[a], "preset", None)
        if preset is None or sensor not in preset.rings():
            return None
        return self.rings.setdefault((a, sensor), preset.ring(sensor))

    def read(
        self,
        a: int,
        ring: RangeRing,
        idx: np.ndarray,
        reach: np.ndarray | None = None,
        beams: np.ndarray | None = None,
        horizon: float | None = None,
        scene: Scene | None = None,
    ) -> np.ndarray:
        """Ring readings of agent ``a`` in instances ``idx`` against the static obstacles and
        every payload's outline: ``(m, count)``, or ``(m, len(beams))`` for those beams only
        (each ray is cast on its own: a beam reads the same whichever others are cast).

        ``reach``: where the robot's centre is known to be farther than this from every
        static obstacle (this instant's clearances), no ray can meet one within the ring's
        range (a ray leaves the ring's mount circle), so those rows read ``max_range`` from
        the static scene without casting — what the cast would give, since it clips there.
        ``horizon`` (below ``max_range``) moves that bound nearer, for a reader that only
        asks whether a beam reads below it (the detect rules): rows whose static obstacles
        are all beyond it read as if there were none, which answers that question alike.
        ``scene``: the obstacles every instance of ``idx`` has (None: each its own).
        """
        self.work.reads += 1
        if scene is None and self.scene_of is not None:  # each instance its own obstacles
            out = np.empty((idx.size, ring.count if beams is None else beams.size))
            for own, rows in self._by_scene(idx):
                out[rows] = self.read(
                    a, ring, idx[rows], None if reach is None else reach[rows], beams, horizon, own
                )
            return out
        scene = self.scenes[0] if scene is None else scene
        poses = self._poses(a, idx)
        if beams is not None and beams.size < ring.count:  # (only the rays read)
            origins, directions = ring.rays(poses, beams)
            count = beams.size
        else:
            origins, directions = ring.rays(poses)
            count = ring.count
        near = None
        if reach is not None:
            slack = _SLACK * (1.0 + np.abs(poses[:, 0]) + np.abs(poses[:, 1]) + ring.max_range)
            far = ring.max_range if horizon is None else min(horizon, ring.max_range)
            near = reach - ring.mount_radius <= far + slack
        if near is None or every(near):
            dist = cast_at(origins, directions, scene.targets, ring.max_range)
        else:
            dist = filled(origins.shape[:2], float(ring.max_range))
            if some(near):
                dist[near] = cast_at(origins[near], directions[near], scene.targets, ring.max_range)
        for p in self.payloads:
            dist = np.minimum(dist, p.ray_hits(idx, origins, directions, ring.max_range))
        dist = np.minimum.reduce(dist.reshape(idx.size, count, ring.rays_per_beam), axis=2)
        return np.maximum(dist, ring.min_range)

    def senses(self) -> tuple[str, ...]:
        return self.sensors

    def sense(self, agent: int, idx: np.ndarray, name: str) -> np.ndarray:
        ring = self.ring(agent, name) if agent in self.sensing else None
        if ring is None:
            raise KeyError(
                f"obstacles: robot '{self.team.agents[agent].name}' has no range "
                f"ring '{name}' (from its robot model or a detect rule's ring)"
            )
        idx = np.asarray(idx, np.intp)
        for p in self.payloads:  # (its outline is seen where it is now)
            p.current(self.world, idx)
        return self.read(agent, ring, idx)

    # ------------------------------------------------------------------ each instant
    def update(self, world: WorldAccess, idx: np.ndarray) -> None:
        """Judge the instances of ``idx`` where some robot this component judges senses
        (:meth:`WorldAccess.sensing`): each robot's rules and clearance where it senses,
        each payload's clearance where one of its carriers does. An instant where none
        senses (a stream copy arriving between ticks) costs the test of that alone."""
        if not self.judged:  # (no robot with a pose, no rule, no payload: nothing to judge)
            return
        if self.swept:  # (every instant: each ends one piece of held motion)
            self._sweep(world, idx)
        if idx.size == 1:  # (a single run's instant: whether anyone senses, on bools,
            # before anything is gathered: most instants are arrivals nobody senses at)
            if not any(world.sensing(a, idx).item(0) for a in self.judged):
                return
            anyone = None
            sensing = {a: world.sensing(a, idx) for a in self.judged}
        else:
            sensing = {a: world.sensing(a, idx) for a in self.judged}
            anyone = np.logical_or.reduce(list(sensing.values()), axis=0)
            if not some(anyone):
                return
        if anyone is not None and not every(anyone):
            idx = idx[anyone]
            sensing = {a: own[anyone] for a, own in sensing.items()}
        self.work.updates += 1
        if self.swept:
            self._fold(world, idx, sensing)
        for p in self.payloads:  # its outline where it is now (settled once an instant)
            p.current(world, idx)
        if self.scene_of is None:
            self._update(world, idx, self.scenes[0], sensing)
        else:
            for scene, rows in self._by_scene(idx):
                self._update(world, idx[rows], scene, {a: own[rows] for a, own in sensing.items()})

    def _sweep(self, world: WorldAccess, idx: np.ndarray) -> None:
        """End each swept robot's piece of motion at this instant (:mod:`.swept`): where it
        may have come nearer than its least gap so far, or touched something, its least gap
        over the piece, exactly, and its first contact; kept until it senses (:meth:`_fold`).

        The centre's gap to the obstacles changes no faster than it moves, so a piece ``L``
        long whose ends are ``g0`` and ``g1`` from them comes no nearer than
        ``(g0 + g1 - L) / 2``: where that is past both the least gap so far and contact, the
        piece is not looked at (nearly every instant: a robot driving at an obstacle gets
        nearest at the end of the piece, which that bound is). A single run's instant
        takes this on Python floats (:meth:`_sweep_one`)."""
        if self.last_t.size == 1:
            self._sweep_one(world, idx)
            return
        t = world.t[idx]
        began = self.last_t[idx]
        self.last_t[idx] = t
        ends: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = {}
        for r, a, turning in self.swept:
            poses = self._poses(a, idx)
            was, gap0 = self.last_pose[r, idx], self.last_gap[r, idx]
            gap1 = self._end_gaps(idx, poses)
            self.last_pose[r, idx], self.last_gap[r, idx] = poses, gap1
            ends[r] = (was, poses, gap0, gap1)
            moved = (t > began) & np.any(poses != was, axis=1)  # (nan: the first instant)
            if not some(moved):
                continue
            rows = where_true(moved)
            gone = _path_length(was[rows], poses[rows], turning)
            low = 0.5 * (gap0[rows] + gap1[rows] - gone) - self.radius[r]
            least = np.minimum(self.min_clear[r, idx[rows]], self.swept_gap[r, idx[rows]])
            for k in where_true((low < least) | (low <= 0.0)).tolist():
                path = piece(
                    float(began[rows[k]]),
                    was[rows[k]].tolist(),
                    float(t[rows[k]]),
                    poses[rows[k]].tolist(),
                    turning,
                )
                if path is not None:
                    self._judge_piece(r, int(idx[rows[k]]), path)
        sole: dict[tuple[int, int], int | None] = {}  # (payload, instance): its sole grasp
        for c in self.carried:  # (nan before the first instant: never near)
            was, now, gap0, gap1 = ends[c.row]
            length = _path_length(was, now, self._turning[c.row])
            low = 0.5 * (gap0 + gap1 - length) - c.near[idx]
            least = np.minimum(self.payload_clear[idx], self.payload_swept[c.k, idx])
            for k in where_true((t > began) & ((low < least) | (low <= 0.0))).tolist():
                i, t0, t1 = int(idx[k]), float(began[k]), float(t[k])
                if (c.k, i) not in sole:
                    sole[(c.k, i)] = c.payload.sole_grasp(world, idx[k : k + 1])
                if sole[(c.k, i)] == c.grasp:
                    self._judge_carried(c, i, t0, t1, was[k].tolist(), now[k].tolist())
        for k, p, grasp_rows in self.settled:
            self._sweep_settled(world, idx, k, p, grasp_rows, ends, began)
        for r1, r2, reach in self.swept_pairs:
            (was1, now1, _, _), (was2, now2, _, _) = ends[r1], ends[r2]
            d0 = np.hypot(was1[:, 0] - was2[:, 0], was1[:, 1] - was2[:, 1])
            d1 = np.hypot(now1[:, 0] - now2[:, 0], now1[:, 1] - now2[:, 1])
            length = _path_length(was1, now1, self._turning[r1])
            length = length + _path_length(was2, now2, self._turning[r2])
            low = 0.5 * (d0 + d1 - length) - reach
            for k in where_true((t > began) & (low <= 0.0)).tolist():
                ends_k = (was1[k].tolist(), now1[k].tolist(), was2[k].tolist(), now2[k].tolist())
                self._judge_pair(r1, r2, int(idx[k]), float(began[k]), float(t[k]), *ends_k)

    def _sweep_one(self, world: WorldAccess, idx: np.ndarray) -> None:
        """:meth:`_sweep` of a single run's instant, on Python floats: the same bound and
        the same pieces (a few numpy calls an instant would cost more than the test)."""
        t = world.t.item(0)
        began = self.last_t.item(0)
        self.last_t[0] = t
        scene = self.scenes[0]
        ends: dict[int, tuple[list[float], list[float], float, float, float]] = {}
        for r, a, turning in self.swept:
            pose = self._poses(a, idx)[0].tolist()
            was = self.last_one.get(r)
            gap1 = point_gap(pose[0], pose[1], scene.circle_list, scene.segment_list)
            self.last_one[r] = (pose, gap1)
            if was is None or not t > began:
                continue
            gap0 = was[1]
            if was[0] == pose:
                ends[r] = (pose, pose, gap0, gap1, 0.0)
                continue
            gone = path_length(was[0], pose, turning)
            ends[r] = (was[0], pose, gap0, gap1, gone)
            low = 0.5 * (gap0 + gap1 - gone) - self.radius.item(r)
            least = min(self.min_clear.item(r, 0), self.swept_gap.item(r, 0))
            if low < least or low <= 0.0:
                path = piece(began, was[0], t, pose, turning)
                if path is not None:
                    self._judge_piece(r, 0, path)
        sole: dict[int, int | None] = {}  # payload: its sole grasp, once asked
        for c in self.carried if ends else ():
            first, last, gap0, gap1, gone = ends[c.row]
            if not gone:  # (its carrier stood still: so did it)
                continue
            low = 0.5 * (gap0 + gap1 - gone) - c.near.item(0)
            if low < min(self.payload_clear.item(0), self.payload_swept.item(c.k, 0)) or low <= 0:
                if c.k not in sole:
                    sole[c.k] = c.payload.sole_grasp(world, idx)
                if sole[c.k] == c.grasp:
                    self._judge_carried(c, 0, began, t, first, last)
        for k, p, grasp_rows in self.settled if ends else ():
            held = p.holding(world, idx)
            own, moves, moved = [], [], False
            for j in held:
                row = grasp_rows[j]
                if row is None or row not in ends:
                    break
                start, stop = ends[row][0], ends[row][1]
                own.append(row)
                moves.append((start, stop))
                moved = moved or start != stop
            if len(held) < 2 or len(own) < len(held):
                self.settled_code[k, 0] = -1  # (moved otherwise: its reference is gone)
                continue
            if moved:  # (else its carriers stood still: so did it)
                self._settled_piece(k, p, began, t, held, own, moves)
        for r1, r2, reach in self.swept_pairs if ends else ():
            (was1, now1, _, _, gone1), (was2, now2, _, _, gone2) = ends[r1], ends[r2]
            d0 = math.hypot(was1[0] - was2[0], was1[1] - was2[1])
            d1 = math.hypot(now1[0] - now2[0], now1[1] - now2[1])
            if may_touch(d0, d1, gone1 + gone2, reach):
                self._judge_pair(r1, r2, 0, began, t, was1, now1, was2, now2)

    def _settled_piece(
        self,
        k: int,
        p: CarriedPayload,
        t0: float,
        t1: float,
        held: list[int],
        rows: list[int],
        ends: list[tuple[list[float], list[float]]],
    ) -> None:
        """A single run's payload ``k`` held by grasps ``held`` (their robots' rows, and
        each robot's poses at ``t0`` and ``t1``) over one piece: judged now where it may
        touch something (:meth:`_judge_settled`), kept for the summary where it may only
        come nearer than its least gap so far (:meth:`_pending_settled`), dropped where
        it can do neither.

        Two cheap bounds, on floats. Every point of the outline is within ``rho`` (its
        farthest corner from the body centroid) of the robot points' weighted centroid
        (:mod:`.swept_settled`), which moves no faster than their weighted mean speed
        ``c``: the gap is at least the centroid's point gap over the piece, bounded as a
        robot's (:meth:`_sweep`), less ``rho``. Where that leaves room, the second: no
        point moves farther over the piece than ``c + rho |theta'|`` (``|theta'| <= |z'|
        / |z|``, the springs' fit), so the gap is at least the gap where the payload was
        last judged or measured (a carrier's tick at a piece's end,
        :meth:`note_settled_gap`) less what it has moved since. A piece's end is the next
        one's start:
        what it computed there is kept (``settled_prev``)."""
        key = tuple(held)
        fit = self._settled_fit.get((k, key))
        if fit is None:
            fit = self._settled_fit[(k, key)] = _Fit.of(p, held)
        self.settled_last[(k, 0)] = (t1, key)  # (a gap measured at t1 restarts the bound)
        turning = self._turning
        speeds = []
        drift = 0.0
        for (was, now), r, norm, w in zip(ends, rows, fit.reach, fit.springs, strict=True):
            v = path_length(was, now, turning[r]) + abs(now[2] - was[2]) * norm
            speeds.append(v)
            drift += w * v
        drift /= fit.total
        kept = self.settled_prev.get(k)
        starts = [was for was, _ in ends]
        stops = [now for _, now in ends]
        clear, swept = self.payload_clear.item(0), self.payload_swept.item(k, 0)
        least = clear if clear < swept else swept
        # (the last piece's end where this one starts: the same grasps at the same poses)
        if kept is not None and not (kept[0] is fit and kept[1] == starts):
            kept = None
        if kept is not None:  # (far: the centroid's gap bounded from the last)
            far = kept[3] - drift
            if far - fit.rho > 0.0 and far - fit.rho >= least - GAP_TOLERANCE:
                self.settled_prev[k] = (fit, stops, None, far)
                self.settled_code[k, 0] = -1  # (not followed: its reference is gone)
                return
        first = None if kept is None else kept[2]
        scene = self.scenes[0]
        if first is None:
            first = fit.centroid(starts, scene.circle_list, scene.segment_list)
        last = fit.centroid(stops, scene.circle_list, scene.segment_list)
        self.settled_prev[k] = (fit, stops, last, last[3])
        low = 0.5 * (first[3] + last[3] - drift) - fit.rho
        lever = 0.0
        for m, v in zip(fit.levers, speeds, strict=True):
            lever += m * v
        zmin = 0.5 * (first[2] + last[2] - lever)
        step = drift + fit.rho * lever / zmin if zmin > 0.0 else math.inf
        if self.settled_code.item(k, 0) == fit.code:
            self.settled_moved[k, 0] += step
            low = max(low, self.settled_gap.item(k, 0) - self.settled_moved.item(k, 0))
        else:
            self.settled_code[k, 0] = -1
        if low <= 0.0 or low < least - GAP_TOLERANCE:
            self._settled_decide(k, p, 0, t0, t1, held, rows, ends, low, step)

    def _settled_decide(
        self,
        k: int,
        p: CarriedPayload,
        i: int,
        t0: float,
        t1: float,
        held: list[int],
        rows: list[int],
        ends: list[tuple[list[float], list[float]]],
        low: float,
        step: float,
    ) -> None:
        """:meth:`_settled_piece`'s verdict on a piece whose gap is at least ``low`` and
        whose points move at most ``step``: judged now where it may touch (the payload's
        gap at its end is where the next pieces' second bound starts), kept where it may
        only come nearer than the least gap so far."""
        scene = self.scenes[0 if self.scene_of is None else int(self.scene_of[i])]
        least = min(self.payload_clear.item(i), self.payload_swept.item(k, i))
        if low <= 0.0:
            end = self._judge_settled(k, p, i, t0, t1, held, rows, ends, scene)
            if end is None:
                self.settled_code[k, i] = -1
            else:
                self.settled_code[k, i] = sum(1 << j for j in held)
                self.settled_gap[k, i], self.settled_moved[k, i] = end, 0.0
        elif low < least - GAP_TOLERANCE:
            pending = self.settled_pending.setdefault((k, i), [])
            pending.append((low, step, (k, p, i, t0, t1, held, rows, ends, scene)))
            if len(pending) > self._settled_room.get((k, i), 64):
                # (those the least so far has overtaken go; when the rest fills twice
                # the room again: amortized, not a pass over every kept piece per piece)
                pending[:] = [q for q in pending if q[0] < least - GAP_TOLERANCE]
                self._settled_room[(k, i)] = max(64, 2 * len(pending))
        self.settled_last[(k, i)] = (t1, tuple(held))

    def note_settled_gap(self, k: int, i: int, t: float, gap: float) -> None:
        """Payload ``k``'s gap in instance ``i`` measured at time ``t`` (a carrier's
        sensing instant): where the piece that ends here was kept (:meth:`_settled_piece`)
        and its start was measured too, under the same grasps, its gap is at least the two
        ends' mean less half its motion bound (the gap moves no faster than that): a piece
        that leaves no room below the least gap so far goes. And where a piece ends here,
        the gap measured is where the next pieces' second bound starts (it is the gap
        there, exactly: no judged piece's end is nearer the truth)."""
        last = self.settled_last.get((k, i))
        held = last[1] if last is not None and last[0] == t else None
        seen = self.settled_seen.get((k, i))
        self.settled_seen[(k, i)] = (t, gap, held)
        if held is not None:
            self.settled_code[k, i] = sum(1 << j for j in held)
            self.settled_gap[k, i], self.settled_moved[k, i] = gap, 0.0
        pending = self.settled_pending.get((k, i))
        if not pending or seen is None or held is None:
            return
        low, step, args = pending[-1]
        if args[4] != t or args[3] != seen[0] or seen[2] != held:
            return
        low = max(low, 0.5 * (seen[1] + gap - step))
        if low < self.payload_clear.item(i) - GAP_TOLERANCE:
            pending[-1] = (low, step, args)
        else:
            pending.pop()

    def _pending_settled(self, i: int) -> None:
        """Judge instance ``i``'s kept pieces (:meth:`_settled_piece`) that may come nearer
        than the least gap so far, in time order (one piece's end is the next one's
        start: :meth:`_judge_settled` keeps it), into ``payload_clear``."""
        for k in range(len(self.payloads)):
            for low, _, args in self.settled_pending.pop((k, i), []):
                if low < self.payload_clear.item(i) - GAP_TOLERANCE:
                    _, p, _, t0, t1, held, rows, ends, scene = args
                    below = self.payload_clear.item(i)
                    self._judge_settled(k, p, i, t0, t1, held, rows, ends, scene, below)

    def _sweep_settled(
        self,
        world: WorldAccess,
        idx: np.ndarray,
        k: int,
        p: CarriedPayload,
        rows: list[int | None],
        ends: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]],
        began: np.ndarray,
    ) -> None:
        """:meth:`_settled_piece` over the instances ``idx`` of an ensemble (their pieces
        began at ``began``), on arrays: both bounds, and the verdict
        (:meth:`_settled_decide`) where they leave room below the least gap so far or for
        a contact."""
        t = world.t[idx]
        on = p.engagement(world, idx)
        after = t > began
        usable = after & (on.sum(axis=1) >= 2)
        for j, r in enumerate(rows):
            if r is None:
                usable &= ~on[:, j]
        self.settled_code[k, idx[after & ~usable]] = -1  # (moved otherwise: forgotten)
        if not some(usable):
            return
        m = idx.size
        total, speed = np.zeros(m), np.zeros(m)
        r0, r1, bc = np.zeros((m, 2)), np.zeros((m, 2)), np.zeros((m, 2))
        moved = np.zeros(m, bool)
        points, speeds, weights = {}, {}, {}
        for j, r in enumerate(rows):
            if r is None:
                continue
            was, now = ends[r][0], ends[r][1]
            mx, my = p.mount[j].tolist()
            w = np.where(on[:, j], p.spring[j], 0.0)
            pair = []
            for point, pose in ((r0, was), (r1, now)):
                c, sn = np.cos(pose[:, 2]), np.sin(pose[:, 2])
                px, py = pose[:, 0] + c * mx - sn * my, pose[:, 1] + sn * mx + c * my
                point[:, 0] += w * px
                point[:, 1] += w * py
                pair.append((px, py))
            gone = _path_length(was, now, self._turning[r])
            gone = gone + np.abs(now[:, 2] - was[:, 2]) * math.hypot(mx, my)
            speed += np.where(on[:, j], p.spring[j] * gone, 0.0)
            total += w
            bc += w[:, None] * p.body[j]
            moved |= on[:, j] & np.any(now != was, axis=1)
            points[j], speeds[j], weights[j] = pair, gone, w
        usable &= moved
        share = 1.0 / np.where(usable, total, 1.0)
        r0, r1, bc = r0 * share[:, None], r1 * share[:, None], bc * share[:, None]
        z0, z1, lever = np.zeros((m, 2)), np.zeros((m, 2)), np.zeros(m)
        for j, ((x0, y0), (x1, y1)) in points.items():
            w = weights[j]
            cx, cy = p.body[j, 0] - bc[:, 0], p.body[j, 1] - bc[:, 1]
            for z, (x, y), centre in ((z0, (x0, y0), r0), (z1, (x1, y1), r1)):
                ax, ay = x - centre[:, 0], y - centre[:, 1]
                z[:, 0] += w * (cx * ax + cy * ay)
                z[:, 1] += w * (cx * ay - cy * ax)
            lever += np.where(on[:, j], w * np.hypot(cx, cy) * speeds[j], 0.0)
        gap0, gap1 = self._end_gaps(idx, r0), self._end_gaps(idx, r1)
        hw, hd = p.half_extents(idx)
        rho = np.hypot(hw + np.abs(bc[:, 0]), hd + np.abs(bc[:, 1]))
        drift = speed * share
        low = 0.5 * (gap0 + gap1 - drift) - rho
        zmin = 0.5 * (np.hypot(z0[:, 0], z0[:, 1]) + np.hypot(z1[:, 0], z1[:, 1]) - lever)
        with np.errstate(divide="ignore", invalid="ignore"):
            step = np.where(zmin > 0.0, drift + rho * lever / zmin, np.inf)
        code = on @ (1 << np.arange(on.shape[1]))
        known = usable & (self.settled_code[k, idx] == code)
        self.settled_code[k, idx[usable & ~known]] = -1
        if some(known):
            rows_known = idx[known]
            self.settled_moved[k, rows_known] += step[known]
            since = self.settled_gap[k, rows_known] - self.settled_moved[k, rows_known]
            low[known] = np.maximum(low[known], since)
        least = np.minimum(self.payload_clear[idx], self.payload_swept[k, idx])
        for q in where_true(usable & ((low < least - GAP_TOLERANCE) | (low <= 0.0))).tolist():
            held = where_true(on[q]).tolist()
            own = [r for r in (rows[j] for j in held) if r is not None]
            ends_q = [(ends[r][0][q].tolist(), ends[r][1][q].tolist()) for r in own]
            t0, t1 = float(began[q]), float(t[q])
            self._settled_decide(k, p, int(idx[q]), t0, t1, held, own, ends_q, low[q], step[q])

    def _judge_settled(
        self,
        k: int,
        p: CarriedPayload,
        i: int,
        t0: float,
        t1: float,
        held: list[int],
        rows: list[int],
        ends: list[tuple[list[float], list[float]]],
        scene: Scene,
        below: float | None = None,
    ) -> float | None:
        """Payload ``k`` held by grasps ``held`` (their robots' rows, and each robot's
        poses at ``t0`` and ``t1``) over the motion in instance ``i``
        (:mod:`.swept_settled`): its least gap, and its first contact if it touches
        something; left to the instants where a robot's motion is not rebuilt or the
        bounds do not hold (None). With ``below`` (a kept piece, judged for the summary:
        it cannot touch) the gap goes straight into ``payload_clear``. Returns the gap
        at the end (where the next piece's bound starts from)."""
        shape = self._settled_shape.get((k, i))
        if shape is None:  # (its grasps and extents as floats, once)
            grasps = [
                ((p.mount.item(j, 0), p.mount.item(j, 1)), (p.body.item(j, 0), p.body.item(j, 1)))
                for j in range(len(p.agents))
            ]
            halves = tuple(h.item(0) for h in p.half_extents(np.array([i])))
            shape = self._settled_shape[(k, i)] = (grasps, halves)
        grips = []
        for j, r, (was, now) in zip(held, rows, ends, strict=True):
            mount, body = shape[0][j]
            one = grip(t0, was, t1, now, self._turning[r], mount, body, p.spring.item(j))
            if one is None:
                return None
            grips.append(one)
        hw, hd = shape[1]
        start = (tuple(held), tuple(tuple(was) for was, _ in ends))
        kept = self.settled_end.get((k, i))
        first = kept[1] if kept is not None and kept[0] == start else None
        at = (k, tuple(held), id(scene), hw, hd)
        frame = self._settled_frames.get(at)
        circles, segments = scene.circle_list, scene.segment_list
        motion = SettledCarry(grips, hw, hd, circles, segments, first, frame)
        self._settled_frames[at] = motion.frame
        end = (tuple(held), tuple(tuple(now) for _, now in ends))
        if below is not None:  # (kept for the summary: it starts clear)
            found = motion.least_gap(below, apart=True)
            self.settled_end[(k, i)] = (end, motion.last)
            if found is not None:
                self.payload_clear[i] = min(self.payload_clear.item(i), found[0])
            return None
        found = motion.least_gap(min(self.payload_clear.item(i), self.payload_swept.item(k, i)))
        self.settled_end[(k, i)] = (end, motion.last)
        if found is None:
            return None
        gap, s = found
        if gap < self.payload_swept[k, i]:
            self.payload_swept[k, i] = gap
        if gap <= 0.0 and (k, i) not in self.payload_hit:
            s = motion.first_contact(s)
            x, y, _ = motion.state(s).pose
            self.payload_hit[(k, i)] = (t0 + s * (t1 - t0), x, y)
        return 0.0 if gap <= 0.0 else max(motion.last.gap, 0.0)

    def _end_gaps(self, idx: np.ndarray, poses: np.ndarray) -> np.ndarray:
        """Each centre's distance to the nearest circle's edge or segment of its scene
        (a box by its edges: outside every box, its signed distance; :meth:`_sweep`)."""
        if self.scene_of is None:
            scene = self.scenes[0]
            return clearance(poses, 0.0, scene.segments, scene.circles)
        out = np.empty(idx.size)
        for scene, rows in self._by_scene(idx):
            out[rows] = clearance(poses[rows], 0.0, scene.segments, scene.circles)
        return out

    def _judge_piece(self, r: int, i: int, path: Piece) -> None:
        """Robot row ``r``'s least gap over ``path`` in instance ``i``, and its first
        contact if the footprint touches something on the way."""
        scene = self.scenes[0 if self.scene_of is None else int(self.scene_of[i])]
        radius = float(self.radius[r])
        distance, s = least_gap(path, scene.circle_list, scene.segment_list)
        gap = distance - radius
        if gap < self.swept_gap[r, i]:
            self.swept_gap[r, i] = gap
        if gap < 0.0:
            contact = first_contact(path, radius, scene.circle_list, scene.segment_list)
            s = s if contact is None else contact
            x, y = path.at(s)
            first = self.swept_hit.get((r, i))
            if first is None:
                what = name_hit(np.array([x, y]), scene.walls, scene.circles, scene.boxes)
                self.swept_hit[(r, i)] = (path.time(s), x, y, what, -gap)
            elif -gap > first[4]:  # (the deepest overlap since it last sensed)
                self.swept_hit[(r, i)] = (*first[:4], -gap)

    def _judge_pair(
        self,
        r1: int,
        r2: int,
        i: int,
        t0: float,
        t1: float,
        *poses: list[float],
    ) -> None:
        """Robot rows ``r1`` and ``r2`` against each other over their motion from ``t0`` to
        ``t1`` in instance ``i`` (``poses``: each one's pose at both ends): their first
        contact and deepest overlap, if their footprints touch on the way; a pair with a
        turn not rebuilt (:func:`.piece` None) is left to the instants, and so is a pair
        whose collision is already recorded (only a pair's first is: warned robots that
        stay overlapping cost nothing more)."""
        who = (
            f"{self.team.agents[self.planar[r1]].name} and {self.team.agents[self.planar[r2]].name}"
        )
        if who in self.collisions[i]:
            return
        was1, now1, was2, now2 = poses
        pa = piece(t0, was1, t1, now1, self._turning[r1])
        pb = piece(t0, was2, t1, now2, self._turning[r2])
        if pa is None or pb is None:
            return
        ra, rb = self.radius.item(r1), self.radius.item(r2)
        least, s = least_separation(pa, pb, ra + rb)
        if not least < ra + rb:
            return
        s = first_touch(pa, pb, ra + rb, s)
        (xa, ya), (xb, yb) = pa.at(s), pb.at(s)
        share = ra / (ra + rb)  # (where the disks meet, as at an instant)
        depth = ra + rb - least
        first = self.pair_hit.get((r1, r2, i))
        if first is None:
            self.pair_hit[(r1, r2, i)] = (
                pa.time(s),
                xa + (xb - xa) * share,
                ya + (yb - ya) * share,
                depth,
            )
        elif depth > first[3]:  # (the deepest overlap since either last sensed)
            self.pair_hit[(r1, r2, i)] = (*first[:3], depth)

    def _judge_carried(
        self,
        c: _Carried,
        i: int,
        t0: float,
        t1: float,
        was: list[float],
        now: list[float],
    ) -> None:
        """Payload ``c.k`` over its carrier's motion from ``t0`` to ``t1`` in instance ``i``
        (the carrier's poses ``was`` and ``now``), where grasp ``c.grasp`` alone holds (the
        caller asks: the engagement of (t0, t1], the world running before the discrete
        phase): it translates with the mount point, at the angle it keeps
        (:mod:`.swept_payload`); its least gap, and its first contact if it touches
        something."""
        p, at = c.payload, np.array([i])
        motion = carry(t0, was, t1, now, c.mount, self._turning[c.row])
        if motion is None:
            return
        theta = p.rest.item(i, 2)  # (one grasp keeps the angle: settling leaves it)
        cs, sn = math.cos(theta), math.sin(theta)
        bx, by = c.body
        ox, oy = motion.mx - (cs * bx - sn * by), motion.my - (sn * bx + cs * by)
        hw, hd = (h.item(0) for h in p.half_extents(at))
        corners, edges = outline(ox, oy, theta, hw, hd)
        scene = self.scenes[0 if self.scene_of is None else int(self.scene_of[i])]
        circles, segments = scene.circle_list, scene.segment_list
        gap, s = payload_least_gap(motion, corners, edges, circles, segments)
        if gap < self.payload_swept[c.k, i]:
            self.payload_swept[c.k, i] = gap
        if gap <= 0.0 and (c.k, i) not in self.payload_hit:
            contact = payload_first_contact(motion, corners, edges, circles, segments)
            s = s if contact is None else contact
            x, y = motion.moving(ox, oy).at(s)
            self.payload_hit[(c.k, i)] = (motion.t0 + s * (motion.t1 - motion.t0), x, y)

    def _fold(
        self, world: WorldAccess, idx: np.ndarray, sensing: dict[int, np.ndarray] | None
    ) -> None:
        """Where a swept robot senses, take its least gap over its motion since it last
        sensed into ``min_clear``, and report a contact on the way (at its time)."""
        hits: list[tuple[int, str, str, np.ndarray]] = []
        times: list[float] = []
        if self.last_t.size == 1 and not (self.swept_hit or self.pair_hit or self.payload_hit):
            for r, a, _ in self.swept:  # (a single run: on floats)
                gap = self.swept_gap.item(r, 0)
                if gap < math.inf and (sensing is None or sensing[a].item(0)):
                    self.min_clear[r, 0] = min(self.min_clear.item(r, 0), gap)
                    self.swept_gap[r, 0] = math.inf
            for k, p in enumerate(self.payloads if self.carried or self.settled else ()):
                gap = self.payload_swept.item(k, 0)
                if gap < math.inf and (
                    sensing is None or any(sensing[a].item(0) for a in p.agents)
                ):
                    self.payload_clear[0] = min(self.payload_clear.item(0), gap)
                    self.payload_swept[k, 0] = math.inf
            return
        for r, a, _ in self.swept:
            own = idx if sensing is None else idx[sensing[a]]
            if own.size == 0:
                continue
            self.min_clear[r, own] = np.minimum(self.min_clear[r, own], self.swept_gap[r, own])
            self.swept_gap[r, own] = np.inf
            if not self.swept_hit:
                continue
            who = self.team.agents[a].name
            for i in own.tolist():
                hit = self.swept_hit.pop((r, i), None)
                if hit is not None:
                    t, x, y, what, depth = hit
                    tick = float(world.t[i])
                    text = (
                        f"robot '{who}' hit {what} (its footprint overlapping it by up to "
                        f"{depth:.3g} by its tick at t={tick:.10g}), first touching it"
                    )
                    hits.append((i, who, text, np.array([x, y])))
                    times.append(t)
        if self.carried or self.settled:
            self._fold_payloads(world, idx, sensing, hits, times)
        if self.pair_hit:
            self._fold_pairs(world, idx, sensing, hits, times)
        if hits and self.values["on_collision"] != "ignore":
            order = sorted(range(len(hits)), key=times.__getitem__)  # (the first contact first)
            self._collide(world, [hits[k] for k in order], [times[k] for k in order])

    def _fold_payloads(
        self,
        world: WorldAccess,
        idx: np.ndarray,
        sensing: dict[int, np.ndarray] | None,
        hits: list[tuple[int, str, str, np.ndarray]],
        times: list[float],
    ) -> None:
        """Where a carrier of a payload senses, take the payload's least gap over its
        motion since into ``payload_clear``, and report a contact on the way (at its
        time)."""
        for k, p in enumerate(self.payloads):
            own = idx
            if sensing is not None:
                own = idx[np.logical_or.reduce([sensing[a] for a in p.agents])]
            if own.size == 0:
                continue
            self.payload_clear[own] = np.minimum(
                self.payload_clear[own], self.payload_swept[k, own]
            )
            self.payload_swept[k, own] = np.inf
            for i in own.tolist() if self.payload_hit else ():
                hit = self.payload_hit.pop((k, i), None)
                if hit is not None:
                    name = p.values["name"]
                    text = (
                        f"payload '{name}' hit an obstacle (by its carriers' tick at "
                        f"t={float(world.t[i]):.10g}), first touching it"
                    )
                    hits.append((i, name, text, np.array(hit[1:])))
                    times.append(hit[0])

    def _fold_pairs(
        self,
        world: WorldAccess,
        idx: np.ndarray,
        sensing: dict[int, np.ndarray] | None,
        hits: list[tuple[int, str, str, np.ndarray]],
        times: list[float],
    ) -> None:
        """Report each pair's contact between instants (:meth:`_judge_pair`) where either
        of its robots senses in ``idx``, as a collision at its first contact's time."""
        for (r1, r2, i), (t, x, y, depth) in list(self.pair_hit.items()):
            rows = where_true(idx == i)
            if rows.size == 0:
                continue
            a1, a2 = self.planar[r1], self.planar[r2]
            k = rows.item(0)
            if sensing is not None and not (sensing[a1].item(k) or sensing[a2].item(k)):
                continue
            del self.pair_hit[(r1, r2, i)]
            names = [self.team.agents[a].name for a in (a1, a2)]
            text = (
                f"robots '{names[0]}' and '{names[1]}' collided (their footprints "
                f"overlapping by up to {depth:.3g} by the tick at t={float(world.t[i]):.10g}), "
                "first touching"
            )
            hits.append((i, " and ".join(names), text, np.array([x, y])))
            times.append(t)

    def _by_scene(self, idx: np.ndarray) -> list[tuple[Scene, np.ndarray]]:
        """The instances of ``idx`` grouped by their scene: ``(scene, rows of idx)``, for
        an ensemble whose obstacles differ between instances (a swept door width)."""
        assert self.scene_of is not None  # (called only where the scenes differ)
        codes = self.scene_of[idx]
        return [(self.scenes[c], where_true(codes == c)) for c in np.unique(codes).tolist()]

    def _update(
        self,
        world: WorldAccess,
        idx: np.ndarray,
        scene: Scene,
        sensing: dict[int, np.ndarray] | None = None,
    ) -> None:
        """:meth:`update` of instances ``idx``, which share ``scene``; ``sensing``: per
        judged agent, whether it senses in each of them (None: every one in all)."""
        reach = self._measure(world, idx, scene, sensing)
        verdicts: dict[tuple[int, str], dict[int, np.ndarray]] = {}
        for r, rule in enumerate(self.rules):
            key = (rule.agent, rule.sensor)
            if key not in verdicts:
                verdicts[key] = self._verdicts(key, idx, scene, reach.get(rule.agent))
            near = verdicts[key][r]
            own = None if sensing is None else sensing[rule.agent]
            if own is not None and not every(own):  # where its robot does not sense,
                # what it saw last stands
                near = np.where(own, near, self.near[r, idx])
            rising = near & ~self.near[r, idx]
            self.near[r, idx] = near
            if some(rising):
                world.raise_event(idx[rising], rule.agent, rule.event)

    def _verdicts(
        self, key: tuple[int, str], idx: np.ndarray, scene: Scene, reach: np.ndarray | None
    ) -> dict[int, np.ndarray]:
        """Whether each rule of ``key`` sees something below its threshold in the instances
        of ``idx``: rule index -> ``(m,)`` bool, read from the cast beams.

        A single run's instant takes two shortcuts with the same verdicts: where the ring's
        robot and every payload stand where they stood at its last verdicts, bit for bit
        (a robot waiting while its forks lift a box), those (they are a function of these
        poses and the static scene); else, unless the floor rules every beam out, the bounds
        of :meth:`_sighted`, where they settle every rule."""
        single = idx.size == 1 and FLOAT_PATHS.on
        if single:
            i, poses = idx.item(0), self._poses(key[0], idx).tobytes()
            poses += b"".join(p.pose[idx].tobytes() for p in self.payloads)
            still = self.still.get(key)
            if still is not None and still.instance == i and still.poses == poses:
                self.work.still += 1
                return still.verdicts
        out = None
        if single and self.payloads and reach is not None:
            a, ring, below = key[0], self.rings[key], self.below[key]
            if not self.within.get(key, False) and every(self.floor(a, ring, idx, reach) >= below):
                out = {r: _NO for r in self.key_rules[key]}  # (no beam may read below: cheaper)
            else:
                out = self._sighted(key, idx, scene, reach.item(0))
                if out is not None:  # (a beam below a threshold: the floor rules out none)
                    self.within[key] = any(v is _YES for v in out.values())
        if out is None:
            dist, rows = self._rule_readings(key, idx, scene, reach)
            out = {}
            for r in self.key_rules[key]:
                cols, threshold = self.rule_columns[r], self.rules[r].below
                near = np.minimum.reduce(dist[:, cols], axis=1) < threshold
                if rows is not None:  # the others read no nearer than any rule's threshold
                    near, seen = np.zeros(idx.size, bool), near
                    near[rows] = seen
                out[r] = near
        if single:
            self.still[key] = _Still(i, poses, out)
        return out

    def _sighted(
        self, key: tuple[int, str], idx: np.ndarray, scene: Scene, reach: float
    ) -> dict[int, np.ndarray] | None:
        """The verdicts of ``key``'s rules in a single run's instance ``idx`` without
        casting at the payloads (each a box): what the ring reads of them is bounded
        (:meth:`_payload_verdicts`), and the static obstacles, where one may be within the
        rules' reach (``reach``: the robot's centre clearance), are cast alone. None where
        the bounds leave a rule open (a bar, a beam within the margin of a threshold, a
        sensor inside a box): the rules read the cast beams.

        A rule whose beams surely read a payload below its threshold sees something; one
        whose beams surely read every payload at or beyond it sees what the static
        obstacles give (nothing, beyond its reach): the verdicts the cast beams give."""
        a, ring, below = key[0], self.rings[key], self.below[key]
        poses = self._poses(a, idx)
        pose = poses[0].tolist()
        boxes = []
        for p in self.payloads:
            hw, hd = (float(h[0]) for h in p.half_extents(idx))
            if not hd > 0.0:  # a bar: a segment has no inside to prove a hit by
                return None
            boxes.append((sight.relative_pose(pose, p.pose[idx[0]].tolist()), hw, hd))
        seen = self._payload_verdicts(key, idx.item(0), boxes)
        slack = _SLACK * (1.0 + abs(pose[0]) + abs(pose[1]) + ring.max_range)
        if seen is None or reach - ring.mount_radius > below + slack:
            return seen  # (open, or no static obstacle within any rule's threshold)
        beams = self.read_beams[key]
        origins, directions = ring.rays(poses, beams)
        self.work.statics += 1
        static = cast_at(origins, directions, scene.targets, ring.max_range)
        static = np.minimum.reduce(static.reshape(beams.size, ring.rays_per_beam), axis=1)
        out = {}
        for r, payload in seen.items():
            threshold = self.rules[r].below
            near = payload is _YES or (
                ring.min_range < threshold and some(static[self.rule_columns[r]] < threshold)
            )
            out[r] = _YES if near else _NO
        return out

    def _payload_verdicts(
        self, key: tuple[int, str], i: int, boxes: list[tuple[sight.Pose, float, float]]
    ) -> dict[int, np.ndarray] | None:
        """Per rule of ``key``, in instance ``i``: ``_YES`` where its beams surely read a
        payload below its threshold, ``_NO`` where they surely read every payload at or
        beyond it; None if a rule is neither (:func:`~hybridteam.world.sight.box_reading_bounds`
        of each payload, ``boxes``: the ring's robot in its frame, its half extents).

        Verdicts proved at an earlier instant are kept while the ring has moved less than
        :func:`~hybridteam.world.sight.kept_for` relative to every payload since: what a
        carried box costs its carrier's ticks is then a comparison on floats."""
        ring, below = self.rings[key], self.below[key]
        kept = self.sighted.get(key)
        if kept is not None and kept.instance == i:
            reach = ring.mount_radius + below
            if all(
                sight.motion(was, now, reach) <= sight.kept_for(hw, hd)
                for was, (now, hw, hd) in zip(kept.poses, boxes, strict=True)
            ):
                self.work.kept += 1
                return kept.verdicts
        beams = self.read_beams[key]
        lower, upper = np.full(beams.size, np.inf), np.full(beams.size, np.inf)
        for rel, hw, hd in boxes:
            low, high = sight.box_reading_bounds(ring, beams, rel, hw, hd)
            lower, upper = np.minimum(lower, low), np.minimum(upper, high)
        out = {}
        margin = min(sight.kept_for(hw, hd) for _, hw, hd in boxes)  # (what keeping needs)
        for r in self.key_rules[key]:
            cols, threshold = self.rule_columns[r], self.rules[r].below
            if ring.min_range < threshold and some(upper[cols] < threshold - margin):
                out[r] = _YES
            elif threshold <= ring.max_range and every(lower[cols] >= threshold):
                out[r] = _NO
            else:  # within the margin of its threshold: cast
                self.sighted.pop(key, None)
                return None
        self.sighted[key] = _Sighted(i, [rel for rel, _, _ in boxes], out)
        self.work.proved += 1
        return out

    def _rule_readings(
        self, key: tuple[int, str], idx: np.ndarray, scene: Scene, reach: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """The beams the rules of ``key`` read, for the instances of ``idx`` where some rule
        may see something: ``(readings, rows)``, rows None for all of ``idx``. Where the
        :meth:`floor` is at least every rule's threshold no rule can fire, and what a cast
        would give is not needed (most of experiment 3's sonar instants: the Scout is far
        from everything). Elsewhere the static obstacles are cast against only where one is
        within that threshold (``horizon``): a carried box keeps the floor low, but the
        robot is mostly far from every static obstacle (experiment 2's XR4000).

        Where every instance saw something within the threshold at the last reading (the
        XR4000's IR on the box it carries, most of experiment 3), the floor is not asked:
        it would rule out none, and the rules' verdicts are the same either way (a row the
        floor rules out reads no nearer than the threshold when cast)."""
        a, ring, below = key[0], self.rings[key], self.below[key]
        if reach is not None and not self.within.get(key, False):
            may = self.floor(a, ring, idx, reach) < below
            if not every(may):
                self.within[key] = False
                rows = where_true(may)
                if rows.size == 0:
                    return np.empty((0, self.read_beams[key].size)), rows
                return self.read(
                    a, ring, idx[rows], reach[rows], self.read_beams[key], below, scene
                ), rows
        dist = self.read(a, ring, idx, reach, self.read_beams[key], below, scene)
        self.within[key] = every(np.minimum.reduce(dist, axis=1) < below)
        return dist, None

    def floor(self, a: int, ring: RangeRing, idx: np.ndarray, reach: np.ndarray) -> np.ndarray:
        """A lower bound on every beam of ``ring`` on robot ``a`` in instances ``idx``,
        given its centre's clearance ``reach`` from the static obstacles: ``(m,)``.

        The rays start within ``mount_radius`` of the centre, so none meets a static
        obstacle nearer than ``reach`` minus that, nor a payload nearer than the centre's
        distance to its outline minus that (less a rounding allowance); readings are then
        clipped to ``[min_range, max_range]``.
        """
        self.work.floors += 1
        pose = self._poses(a, idx)
        near = reach
        for p in self.payloads:
            near = np.minimum(near, p.outline_distance(idx, pose))
        slack = _SLACK * (1.0 + np.abs(pose[:, 0]) + np.abs(pose[:, 1]) + ring.max_range)
        return np.maximum(
            np.minimum(near - ring.mount_radius - slack, ring.max_range), ring.min_range
        )

    def _measure(
        self,
        world: WorldAccess,
        idx: np.ndarray,
        scene: Scene,
        sensing: dict[int, np.ndarray] | None = None,
    ) -> dict[int, np.ndarray]:
        """Running minima of the robots' and the payloads' clearances, and collisions, each
        where its robot (a pair: either robot; a payload: one of its carriers) senses.
        Returns each planar robot's centre clearance from the static obstacles ``(m,)``.
        ``sensing``: as :meth:`_update`'s (None: every robot senses in every instance).

        A single run's instant in a scene of circles (posts) takes :func:`measure_one`, on
        floats, unless a gap shows a collision."""
        if (
            idx.size == 1
            and FLOAT_PATHS.on
            and not self.values["clearance"]
            and not len(scene.segments)
            and not len(scene.boxes)
        ):
            on_floats = measure_one(self, world, idx, scene, sensing)
            if on_floats is not None:
                return on_floats
        hits: list[tuple[int, str, str, np.ndarray]] = []  # (instance, who, what, where)
        reach: dict[int, np.ndarray] = {}
        points, gap, payload_gaps = np.empty((0, idx.size, 2)), np.empty((0, idx.size)), []
        if self.planar:
            points, gap = self._centre_gaps(idx, scene)
            reach = dict(zip(self.planar, gap, strict=True))
            gap = gap - self.radius[:, None]
            own = (
                np.ones(gap.shape, bool)
                if sensing is None
                else np.array([sensing[a] for a in self.planar])
            )  # (R, m)
            everyone = every(own)
            judged = gap if everyone else np.where(own, gap, np.inf)
            self.min_clear[:, idx] = np.minimum(self.min_clear[:, idx], judged)
            for r, a in enumerate(self.planar) if some(judged < 0) else ():
                for k in np.flatnonzero(judged[r] < 0).tolist():
                    what = name_hit(points[r, k], scene.walls, scene.circles, scene.boxes)
                    who = self.team.agents[a].name
                    hits.append(
                        (
                            int(idx[k]),
                            who,
                            f"robot '{who}' hit {what}, its footprint "
                            f"overlapping it by {-gap[r, k]:.3g}",
                            points[r, k],
                        )
                    )
            overlap = robot_overlaps(points, self.radius)
            touch = overlap > 0
            if not everyone:  # (m, R, R): where either robot of the pair senses
                touch &= own.T[:, :, None] | own.T[:, None, :]
            pairs = np.nonzero(np.triu(touch, 1)) if some(touch) else ()
            for k, r1, r2 in zip(*pairs, strict=True):
                names = [self.team.agents[self.planar[r]].name for r in (r1, r2)]
                r_1, r_2 = self.radius[r1], self.radius[r2]  # where the disks meet
                contact = points[r1, k] + (points[r2, k] - points[r1, k]) * r_1 / (r_1 + r_2)
                hits.append(
                    (
                        int(idx[k]),
                        " and ".join(names),
                        f"robots '{names[0]}' and "
                        f"'{names[1]}' collided, their footprints overlapping by "
                        f"{overlap[k, r1, r2]:.3g}",
                        contact,
                    )
                )
        robot_gaps = gap
        for kp, p in enumerate(self.payloads):
            gap = self._payload_gap(p, idx, scene)
            payload_gaps.append(gap)
            carried = None
            if sensing is not None:  # where one of its carriers senses
                carried = sensing[p.agents[0]]
                for a in p.agents[1:]:
                    carried = carried | sensing[a]
            judged = gap if carried is None or every(carried) else np.where(carried, gap, np.inf)
            self.payload_clear[idx] = np.minimum(self.payload_clear[idx], judged)
            if self.settled_last and idx.size == 1:  # (a single run: on floats)
                if judged.item(0) < math.inf:
                    i = idx.item(0)
                    self.note_settled_gap(kp, i, world.t.item(i), judged.item(0))
            elif self.settled_last:
                for q in where_true(judged < math.inf).tolist():
                    i = int(idx[q])
                    self.note_settled_gap(kp, i, world.t.item(i), judged.item(q))
            for k in where_true(judged <= 0).tolist():
                hits.append(
                    (
                        int(idx[k]),
                        p.values["name"],
                        f"payload '{p.values['name']}' hit an obstacle",
                        p.pose[idx[k], :2],
                    )
                )
        if self.values["clearance"]:  # (the series sample them)
            self._hold(world.t[idx], idx, sensing, robot_gaps, payload_gaps)
            if self.scene_of is None:
                self._measured = _Measured(
                    idx.copy(),
                    points,
                    [p.pose[idx] for p in self.payloads],
                    robot_gaps,
                    payload_gaps,
                )
        if hits and self.values["on_collision"] != "ignore":
            self._collide(world, hits)
        return reach

    def _hold(
        self,
        t: np.ndarray,
        idx: np.ndarray,
        sensing: dict[int, np.ndarray] | None,
        robot_gaps: np.ndarray,
        payload_gaps: list[np.ndarray],
    ) -> None:
        """Keep the gaps just measured as the series' values (and when), each where its
        robot senses (a payload's: one of its carriers), until the next reading."""
        for r, a in enumerate(self.planar):
            own: slice | np.ndarray = slice(None) if sensing is None else sensing[a]
            self.robot_gap[r, idx[own]], self.robot_t[r, idx[own]] = robot_gaps[r][own], t[own]
        for k, (p, gap) in enumerate(zip(self.payloads, payload_gaps, strict=True)):
            carried: slice | np.ndarray = slice(None)
            if sensing is not None:
                carried = np.logical_or.reduce([sensing[a] for a in p.agents])
            self.payload_gap[k, idx[carried]], self.payload_t[k, idx[carried]] = (
                gap[carried],
                t[carried],
            )

    def _centre_gaps(self, idx: np.ndarray, scene: Scene) -> tuple[np.ndarray, np.ndarray]:
        """The planar robots' centres ``(R, m, 2)`` in instances ``idx`` and each centre's
        distance to the nearest obstacle of ``scene`` ``(R, m)`` (negative inside a box)."""
        points = np.empty((len(self.planar), idx.size, 2))  # (R, m, 2)
        for r, a in enumerate(self.planar):
            points[r] = self._poses(a, idx)[:, :2]
        pts = points.reshape(-1, 2)
        gap = clearance(pts, 0.0, scene.walls, scene.circles)
        if len(scene.boxes):
            gap = np.minimum(gap, box_sdf(pts, scene.boxes))
        return points, gap.reshape(len(self.planar), idx.size)

    def _collide(
        self,
        world: WorldAccess,
        hits: list[tuple[int, str, str, np.ndarray]],
        times: list[float] | None = None,
    ) -> None:
        """Record and act on ``hits`` (instance, who, what, where), at this instant or at
        ``times`` (a contact between instants, found by :meth:`_sweep`)."""
        for k, (i, who, what, (x, y)) in enumerate(hits):
            t = float(world.t[i]) if times is None else times[k]
            text = f"{what} at t={t!r}"
            self.collisions[i].setdefault(who, (text, t, float(x), float(y)))
            if self.values["on_collision"] == "outcome":
                world.finish(np.array([i]), "collision", text)

    def _payload_gap(self, p: CarriedPayload, idx: np.ndarray, scene: Scene) -> np.ndarray:
        """Gap between payload ``p``'s outline and the obstacles of ``scene`` (0 if they
        meet)."""
        gap = p.gap(idx, scene.segments, scene.circles)
        if len(scene.boxes):  # a payload wholly inside an obstacle box meets no edge
            gap = np.where(box_sdf(p.pose[idx, :2], scene.boxes) <= 0.0, 0.0, gap)
        return gap

    # ------------------------------------------------------------------ results
    def sample_series(self) -> dict[str, tuple[str, ...]]:
        """With ``clearance: true``: ``robot_clearance``, a column per planar robot (its
        footprint's gap to the nearest static obstacle, negative when overlapping), and
        ``payload_clearance``, a column per payload (its outline's gap, 0 when touching) —
        the readings of what ``min_clearance`` and ``payload_clearance`` summarise,
        as series requirements read (``always(payload_clearance.beam > 0.05)``). Off by
        default: the trace and every snapshot would carry them for runs that never read
        them."""
        if not self.values["clearance"]:
            return {}
        out = {}
        if self.planar:
            out["robot_clearance"] = tuple(self.team.agents[a].name for a in self.planar)
        if self.payload_names:
            out["payload_clearance"] = tuple(self.payload_names)
        return out

    def sample(self, idx: np.ndarray) -> dict[str, np.ndarray]:
        """The :meth:`sample_series` of instances ``idx``, as read at the robots' (the
        payloads' carriers') last sensing instants: between them a series holds, as the
        statistics do (an arrival between ticks costs no measuring). At a sensing instant
        the gaps are those of the current state — the robots' poses as they are now (the
        discrete phase may have moved one), the payloads where they last settled."""
        if not self.values["clearance"]:
            return {}
        t = self.world.t[idx]
        fresh_r, fresh_p = self.robot_t[:, idx] == t, self.payload_t[:, idx] == t
        robots = np.ascontiguousarray(self.robot_gap[:, idx].T)
        payloads = np.ascontiguousarray(self.payload_gap[:, idx].T)
        fresh = np.logical_or.reduce(fresh_r, axis=0) | np.logical_or.reduce(fresh_p, axis=0)
        if some(fresh):
            rows = slice(None) if every(fresh) else where_true(fresh)
            now = self._gaps_now(idx[rows])
            if self.planar:
                robots[rows] = np.where(fresh_r.T[rows], now["robot_clearance"], robots[rows])
            if self.payloads:
                payloads[rows] = np.where(fresh_p.T[rows], now["payload_clearance"], payloads[rows])
        out = {"robot_clearance": robots} if self.planar else {}
        if self.payloads:
            out["payload_clearance"] = payloads
        return out

    def _gaps_now(self, idx: np.ndarray) -> dict[str, np.ndarray]:
        """The series' gaps at the current state of instances ``idx``."""
        measured = self._measured_at(idx)
        if measured is not None:
            return measured
        robots = np.empty((idx.size, len(self.planar)))
        payloads = np.empty((idx.size, len(self.payloads)))
        for scene, rows in (
            [(self.scenes[0], slice(None))] if self.scene_of is None else self._by_scene(idx)
        ):
            if self.planar:
                robots[rows] = (self._centre_gaps(idx[rows], scene)[1] - self.radius[:, None]).T
            for k, p in enumerate(self.payloads):
                payloads[rows, k] = self._payload_gap(p, idx[rows], scene)
        out = {"robot_clearance": robots} if self.planar else {}
        if self.payloads:
            out["payload_clearance"] = payloads
        return out

    def _measured_at(self, idx: np.ndarray) -> dict[str, np.ndarray] | None:
        """:meth:`sample`'s series from the gaps this instant's :meth:`update` measured,
        where they still hold: the same instances, and every robot centre and payload pose
        as it was then (the discrete phase between them may have moved a robot); None
        otherwise. The gaps are functions of those alone (the scene does not move), so
        reusing them gives the very numbers measuring again would, at the cost of a
        comparison (the payload gaps are most of an instant's cost in the doorway team)."""
        m = self._measured
        if m is None or not _same(m.idx, idx):
            return None
        if self.planar:
            points = np.empty_like(m.points)
            for r, a in enumerate(self.planar):
                points[r] = self._poses(a, idx)[:, :2]
            if not _same(points, m.points):
                return None
        if not all(
            _same(p.pose[idx], pose) for p, pose in zip(self.payloads, m.payload_poses, strict=True)
        ):
            return None
        out = {"robot_clearance": np.ascontiguousarray(m.robot_gaps.T)} if self.planar else {}
        if self.payloads:
            out["payload_clearance"] = np.stack(m.payload_gaps, axis=1)
        return out

    def summary(self, i: int) -> dict[str, Any]:
        if self.settled_pending:
            self._pending_settled(i)
        out: dict[str, Any] = {"min_clearance": [_finite(v) for v in self.min_clear[:, i]]}
        if self.values["on_collision"] == "warn":
            out["collisions"] = [text for text, *_ in self.collisions[i].values()]
        if self.payloads:
            out["payload_clearance"] = _finite(self.payload_clear[i])
        return out

    def describe(self) -> SceneDescription:
        """What the views draw: the obstacles of instance 0 (where a study varies them,
        its other instances' differ), where each party first collided, and the robots'
        footprints."""
        scene = self.scenes[0 if self.scene_of is None else int(self.scene_of[0])]
        obstacles: list[Obstacle] = [
            WallObstacle((w[0], w[1]), (w[2], w[3])) for w in scene.walls.tolist()
        ]
        obstacles += [CircleObstacle(x, y, r) for x, y, r in scene.circles.tolist()]
        obstacles += [
            PolygonObstacle(tuple((x, y) for x, y in _corners(b).tolist())) for b in scene.boxes
        ]
        footprints = {
            self.team.agents[a].name: Footprint(float(r))
            for a, r in zip(self.planar, self.radius, strict=True)
            if r > 0
        }
        marks = tuple(
            CollisionMark(i, who, t, x, y)
            for i, firsts in enumerate(self.collisions)
            for who, (_text, t, x, y) in firsts.items()
        )
        return SceneDescription(obstacles=tuple(obstacles), collisions=marks, footprints=footprints)


class _Carried(NamedTuple):
    """A grasp of payload ``k`` (``payload``, its grasp ``grasp``) whose robot is swept
    (``row`` in ``Obstacles.planar``): its ``mount`` (robot frame) and ``body`` point."""

    k: int
    payload: CarriedPayload
    grasp: int
    row: int
    mount: tuple[float, float]
    body: tuple[float, float]
    #: per instance: how far from the robot's centre the payload reaches ``(n,)`` (the
    #: mount's offset, and the body point's farthest corner): what rules a piece out
    near: np.ndarray

    @classmethod
    def of(cls, k: int, payload: CarriedPayload, grasp: int, row: int) -> _Carried:
        mount, body = payload.mount[grasp].tolist(), payload.body[grasp].tolist()
        hw, hd = payload.half_extents(np.arange(payload.n))
        near = np.hypot(hw + abs(body[0]), hd + abs(body[1])) + math.hypot(*mount)
        return cls(k, payload, grasp, row, (mount[0], mount[1]), (body[0], body[1]), near)


class _Fit(NamedTuple):
    """What a single run's bounds on a payload held by grasps ``held`` need, once
    (``Obstacles._settled_piece``): the grasps' springs, mounts, their mounts' distances
    from the robots' centres (``reach``), the body centroid ``bc``, the grasps' levers
    ``w |b - bc|``, the outline's farthest corner from ``bc`` (``rho``), and the
    engagement code."""

    springs: list[float]
    mounts: list[tuple[float, float]]
    reach: list[float]
    centred: list[tuple[float, float]]
    levers: list[float]
    total: float
    rho: float
    code: int

    @classmethod
    def of(cls, p: CarriedPayload, held: list[int]) -> _Fit:
        springs = [p.spring.item(j) for j in held]
        mounts = [(p.mount.item(j, 0), p.mount.item(j, 1)) for j in held]
        body = [(p.body.item(j, 0), p.body.item(j, 1)) for j in held]
        total = math.fsum(springs)
        bcx = math.fsum(w * b[0] for w, b in zip(springs, body, strict=True)) / total
        bcy = math.fsum(w * b[1] for w, b in zip(springs, body, strict=True)) / total
        centred = [(b[0] - bcx, b[1] - bcy) for b in body]
        hw, hd = (h.item(0) for h in p.half_extents(np.zeros(1, int)))
        return cls(
            springs,
            mounts,
            [math.hypot(*m) for m in mounts],
            centred,
            [w * math.hypot(*c) for w, c in zip(springs, centred, strict=True)],
            total,
            math.hypot(hw + abs(bcx), hd + abs(bcy)),
            sum(1 << j for j in held),
        )

    def centroid(
        self,
        poses: list[list[float]],
        circles: list[tuple[float, float, float]],
        segments: list[tuple[float, float, float, float]],
    ) -> tuple[float, float, float, float]:
        """The robot points' weighted centroid at robot poses ``poses``, ``|z|`` there
        (:mod:`.swept_settled`) and the centroid's point gap to the obstacles."""
        points = []
        rx = ry = 0.0
        for (x, y, th), (mx, my), w in zip(poses, self.mounts, self.springs, strict=True):
            c, sn = math.cos(th), math.sin(th)
            qx, qy = x + c * mx - sn * my, y + sn * mx + c * my
            points.append((qx, qy))
            rx += w * qx
            ry += w * qy
        rx /= self.total
        ry /= self.total
        zx = zy = 0.0
        for w, (cx, cy), (qx, qy) in zip(self.springs, self.centred, points, strict=True):
            zx += w * (cx * (qx - rx) + cy * (qy - ry))
            zy += w * (cx * (qy - ry) - cy * (qx - rx))
        return rx, ry, math.hypot(zx, zy), point_gap(rx, ry, circles, segments)


class _Sighted(NamedTuple):
    """Verdicts a ring's rules got from bounds (``Obstacles.sighted``): in instance
    ``instance``, with the ring's robot at ``poses`` in each payload's frame (in the
    component's payload order), ``verdicts`` per rule index (read-only rows)."""

    instance: int
    poses: list[sight.Pose]
    verdicts: dict[int, np.ndarray]


class _Still(NamedTuple):
    """A ring's last verdicts in a single run (``Obstacles.still``): in instance
    ``instance``, with its robot's pose and every payload's as ``poses`` (their bytes),
    ``verdicts`` per rule index."""

    instance: int
    poses: bytes
    verdicts: dict[int, np.ndarray]


#: A single instance's verdicts (read-only: shared by every instant that keeps them)
_YES, _NO = np.ones(1, bool), np.zeros(1, bool)
_YES.flags.writeable = _NO.flags.writeable = False


class _Measured(NamedTuple):
    """What one instant's update measured (``Obstacles._measured``): for instances ``idx``,
    the planar robots' centres ``(R, m, 2)`` and each payload's pose ``(m, 3)`` it measured
    at, the robots' footprint gaps ``(R, m)`` and each payload's gap ``(m,)``."""

    idx: np.ndarray
    points: np.ndarray
    payload_poses: list[np.ndarray]
    robot_gaps: np.ndarray
    payload_gaps: list[np.ndarray]


class Scene(NamedTuple):
    """The static obstacles of one instance (of all of them, unless a study varies them):
    walls ``(w, 4)``, circles ``(c, 3)``, boxes ``(b, 5)`` (theta in radians), every edge
    as segments ``(s, 4)``, and those prepared for casting (built once: walls do not
    move)."""

    walls: np.ndarray
    circles: np.ndarray
    boxes: np.ndarray
    segments: np.ndarray
    targets: Targets
    #: circles and segments as Python floats (the swept test's: :mod:`.swept`)
    circle_list: list[tuple[float, float, float]]
    segment_list: list[tuple[float, float, float, float]]

    @classmethod
    def of(cls, walls: np.ndarray, circles: np.ndarray, boxes: np.ndarray) -> Scene:
        segments = np.concatenate([walls, _box_edges(boxes)])
        return cls(
            walls,
            circles,
            boxes,
            segments,
            Targets.of(segments, circles),
            [(x, y, r) for x, y, r in circles.tolist()],
            [(x0, y0, x1, y1) for x0, y0, x1, y1 in segments.tolist()],
        )


def _scenes(
    walls: np.ndarray, circles: np.ndarray, boxes: np.ndarray
) -> tuple[list[Scene], np.ndarray | None]:
    """The distinct scenes of instances whose geometry is ``(n, r, size)`` arrays, and the
    scene of each instance — None when all share one (the usual case, and every single
    run's: then nothing is grouped at any instant)."""
    n = walls.shape[0]
    flat = np.concatenate(
        [walls.reshape(n, -1), circles.reshape(n, -1), boxes.reshape(n, -1)], axis=1
    )
    if n <= 1 or every(flat == flat[0]):
        return [Scene.of(walls[0], circles[0], boxes[0])], None
    _, first, scene_of = np.unique(flat, axis=0, return_index=True, return_inverse=True)
    return [
        Scene.of(walls[i], circles[i], boxes[i]) for i in first.tolist()
    ], scene_of.ravel().astype(np.intp)


def _path_length(was: np.ndarray, now: np.ndarray, turning: bool) -> np.ndarray:
    """The length of each held-input path from poses ``was`` to ``now`` ``(m, 3)``: the
    chord, times ``(turn / 2) / sin(turn / 2)`` along an arc (a turn of half a revolution
    or more: inf, the bound then rules nothing out)."""
    chord = np.hypot(now[:, 0] - was[:, 0], now[:, 1] - was[:, 1])
    if not turning:
        return chord
    half = 0.5 * np.abs(now[:, 2] - was[:, 2])
    ratio = np.where(half >= 0.5 * np.pi, np.inf, 1.0)
    arc = (half > 0.0) & (half < 0.5 * np.pi)
    ratio[arc] = half[arc] / np.sin(half[arc])
    return chord * ratio


def _footprint(agent: Agent) -> float:
    preset = getattr(agent, "preset", None)
    return float(preset.footprint.radius) if preset is not None else 0.0


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    """Bit for bit the same numbers (-0.0 is not 0.0 here: a gap could keep the sign)."""
    return a.shape == b.shape and a.tobytes() == b.tobytes()


def _finite(v: float) -> float | None:
    """JSON has no infinity: a clearance with nothing to measure against is None."""
    return float(v) if math.isfinite(v) else None


# ---------------------------------------------------------------------- geometry
def _corners(box: np.ndarray) -> np.ndarray:
    """World corners ``(4, 2)`` of a box ``[cx, cy, width, depth, theta_rad]``, CCW."""
    cx, cy, w, d, th = box
    local = np.array([[-w, -d], [w, -d], [w, d], [-w, d]]) / 2.0
    c, s = math.cos(th), math.sin(th)
    return local @ np.array([[c, s], [-s, c]]) + [cx, cy]


def _box_edges(boxes: np.ndarray) -> np.ndarray:
    """The four walls of every box: ``(4 b, 4)``."""
    if not len(boxes):
        return np.zeros((0, 4))
    return np.concatenate([np.c_[c, np.roll(c, -1, axis=0)] for c in map(_corners, boxes)])
