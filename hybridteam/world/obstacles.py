"""Static obstacles and the range sensors that see them: the ``obstacles`` component.

The architecture paper's robots react to what their rings see: the XR4000's infrared ring
detects an obstacle ahead while it carries a box, the Scout's sonar detects one, and the
XR4000's Dock approaches the box guided by its IR. This component holds the world's
static obstacles — walls (segments), circles, and boxes (rectangles, four walls each) —
and, at every instant, casts the range rings of the robots that need them
(:class:`~hybridteam.world.sensors.RangeRing`) against those obstacles *and* the outline
of every ``payload`` component's payload (a resting box is what the Dock's IR approaches).

Nothing is excluded from what a ring sees, not even the payload its own robot carries (a
simple rule is a predictable one): a ``detect`` rule picks the beams that look away from
the payload. Other robots are not obstacles here.

A rule ``{agent, sensor, beams | sector, below, raise}`` raises the local event ``raise``
in ``agent`` when the nearest of its beams drops below ``below`` — on the rising edge
only, per instance, so a robot standing by a wall is told once; before the run nothing
counts as seen, so an obstacle already in range is reported at the first instant. Like
payload breaks, readings are taken at the run's instants (law ticks, events), so a
detection is reported at the first instant past the crossing, at most one period late.
Laws read a ring with ``ctx.sense("ir")``: ``(m, count)`` ranges, ``max_range`` where
nothing is seen. Ring geometry comes from the robot's model (``model: xr4000``) or, for
robots declared without one, from the rule (``ring:`` with :class:`RangeRing`'s
arguments).

Statistics, per instance, minimized over the run's instants: ``min_clearance`` (one entry
per planar robot in the team's order: the gap between its footprint disk and the nearest
static obstacle, negative when overlapping; a robot with no footprint radius is a point)
and ``payload_clearance`` (the gap between any payload's outline and the static
obstacles, 0 when they touch or overlap).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import fields
from typing import TYPE_CHECKING, Any, ClassVar, NamedTuple

import numpy as np

from hybridteam.arrays import every, filled, some, where_true
from hybridteam.errors import ModelError, ModelErrors, did_you_mean
from hybridteam.world.access import WorldAccess
from hybridteam.world.carried import CarriedPayload
from hybridteam.world.collisions import MODES, box_sdf, name_hit, robot_overlaps
from hybridteam.world.component import WorldComponent, settings_error, world_component
from hybridteam.world.raycast import Targets, cast_at
from hybridteam.world.sensors import RangeRing, clearance

if TYPE_CHECKING:
    from hybridteam.model import Agent, Team

#: Rounding allowance (relative to coordinates and range) of the test that lets a reading
#: skip casting against static obstacles beyond the ring's range (``Obstacles.read``)
_SLACK = 1e-9

_RULE_KEYS = ("agent", "sensor", "beams", "sector", "below", "raise", "ring")


class Rule(NamedTuple):
    """A ``detect`` rule, resolved: agent index, sensor, beam indices, threshold, event."""

    agent: int
    sensor: str
    beams: np.ndarray
    below: float
    event: str


def _number(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool)


def _rows(values: Any, size: int, key: str, form: str, problems: list[ModelError]
          ) -> np.ndarray:
    """A list of ``size``-number rows as a float array ``(r, size)``; problems recorded."""
    rows = []
    for k, row in enumerate(values or []):
        if isinstance(row, list) and len(row) == size and all(map(_number, row)):
            rows.append(row)
        else:
            problems.append(ModelError((key, k), f"expected {form}, got {row!r}"))
    return np.array(rows, float).reshape(-1, size)


def _planar(agent: Agent) -> bool:
    return agent.plant.kind in ("unicycle", "holonomic") or {"x", "y"} <= set(agent.plant.state)


def _ring(agent: Agent, rule: Mapping[str, Any], at: tuple) -> RangeRing | ModelError:
    """The ring a rule reads: given inline, else the agent's model's sensor."""
    sensor = rule["sensor"]
    if "ring" in rule:
        spec, keys = rule["ring"], [f.name for f in fields(RangeRing) if f.name != "name"]
        if not (isinstance(spec, dict) and {"count", "max_range"} <= set(spec) <= set(keys)):
            bad = [k for k in spec if k not in keys] if isinstance(spec, dict) else []
            return ModelError((*at, "ring"), f"expected a mapping of {', '.join(keys)} "
                              "(count and max_range required)", hint=did_you_mean(
                                  str(bad[0]), keys) if bad else None)
        try:
            return RangeRing(**{**spec, "name": sensor})
        except (TypeError, ValueError) as exc:
            return ModelError((*at, "ring"), str(exc))
    preset = getattr(agent, "preset", None)
    if preset is None:
        return ModelError((*at, "sensor"), f"agent '{agent.name}' has no robot model to take "
                          f"'{sensor}' from", hint="give the ring inline: ring: {count: 24, "
                          "max_range: 0.5}")
    try:
        return preset.ring(sensor)
    except (ModelError, ModelErrors) as exc:
        e = exc if isinstance(exc, ModelError) else exc.errors[0]
        return ModelError((*at, "sensor"), f"agent '{agent.name}': {e.message}", hint=e.hint)


def _beams(ring: RangeRing, rule: Mapping[str, Any], at: tuple) -> np.ndarray | ModelError:
    """Indices of the beams a rule watches: listed, in a sector, or every beam."""
    if "beams" in rule and "sector" in rule:
        return ModelError(at, "give 'beams' or 'sector', not both")
    if "beams" in rule:
        b = rule["beams"]
        if not (isinstance(b, list) and b and all(isinstance(i, int) and not isinstance(i, bool)
                                                   and 0 <= i < ring.count for i in b)):
            return ModelError((*at, "beams"), f"expected beam indices 0..{ring.count - 1}, "
                              f"got {b!r}")
        return np.array(b, np.intp)
    if "sector" in rule:
        s = rule["sector"]
        if not (isinstance(s, list) and len(s) == 2 and all(map(_number, s)) and s[0] < s[1]):
            return ModelError((*at, "sector"), "expected [from_deg, to_deg] with from < to "
                              f"(counter-clockwise from the heading), got {s!r}")
        width = s[1] - s[0]
        off = (np.degrees(ring.angles) - s[0] + 1e-9) % 360.0
        sel = np.flatnonzero((off <= width + 2e-9) | (width >= 360.0))
        if not sel.size:
            return ModelError((*at, "sector"), f"no beam of '{ring.name}' points within {s}")
        return sel
    return np.arange(ring.count)


def _parse(team: Team, values: Mapping[str, Any]) -> tuple[dict[str, Any], list[ModelError]]:
    """Geometry, rules, inline rings and radii from the settings, and every problem."""
    problems: list[ModelError] = []
    names = [a.name for a in team.agents]
    out: dict[str, Any] = {
        "walls": _rows(values.get("walls"), 4, "walls", "[x0, y0, x1, y1]", problems),
        "circles": _rows(values.get("circles"), 3, "circles", "[x, y, r]", problems),
        "boxes": _rows(values.get("boxes"), 5, "boxes",
                       "[cx, cy, width, depth, theta_deg]", problems),
        "rules": [], "rings": {}, "radius": {}}
    mode = values.get("on_collision", "outcome")
    if mode not in MODES:
        problems.append(ModelError(("on_collision",), f"expected one of {', '.join(MODES)}, "
                                   f"got {mode!r}", hint=did_you_mean(str(mode), MODES)))
    for k in np.flatnonzero(out["circles"][:, 2] <= 0):
        problems.append(ModelError(("circles", int(k)), "a circle's radius must be positive"))
    for k in np.flatnonzero((out["boxes"][:, 2] <= 0) | (out["boxes"][:, 3] <= 0)):
        problems.append(ModelError(("boxes", int(k)), "a box's width and depth must be positive"))
    out["boxes"][:, 4] = np.radians(out["boxes"][:, 4])
    for k, row in enumerate(values.get("radius") or []):
        if not (isinstance(row, list) and len(row) == 2 and _number(row[1]) and row[1] >= 0):
            problems.append(ModelError(("radius", k), f"expected [agent, radius >= 0], got "
                                       f"{row!r}"))
        elif row[0] not in names:
            problems.append(ModelError(("radius", k, 0), f"unknown agent {row[0]!r}",
                                       hint=did_you_mean(str(row[0]), names)))
        else:
            out["radius"][names.index(row[0])] = float(row[1])
    for k, rule in enumerate(values.get("detect") or []):
        at = ("detect", k)
        missing = [key for key in ("agent", "sensor", "below", "raise")
                   if not isinstance(rule, dict) or key not in rule]
        if missing:
            problems.append(ModelError(at, f"a rule needs {', '.join(missing)} (keys: "
                                       f"{', '.join(_RULE_KEYS)})"))
            continue
        if not isinstance(rule["sensor"], str):
            problems.append(ModelError((*at, "sensor"), f"expected a sensor name, got "
                                       f"{rule['sensor']!r}"))
            continue
        bad = [key for key in rule if key not in _RULE_KEYS]
        problems += [ModelError((*at, key), f"a detect rule has no key {key!r}",
                                hint=did_you_mean(str(key), _RULE_KEYS), at_key=True)
                     for key in bad]
        if rule["agent"] not in names:
            problems.append(ModelError((*at, "agent"), f"unknown agent {rule['agent']!r}",
                                       hint=did_you_mean(str(rule["agent"]), names)))
            continue
        a = names.index(rule["agent"])
        if not _planar(team.agents[a]):
            problems.append(ModelError((*at, "agent"), f"agent {rule['agent']!r} has no "
                                       "position (x, y) to sense from"))
            continue
        if not (isinstance(rule["raise"], str) and rule["raise"].isidentifier()):
            problems.append(ModelError((*at, "raise"), f"expected an event name, got "
                                       f"{rule['raise']!r}"))
        ring = _ring(team.agents[a], rule, at)
        if isinstance(ring, ModelError):
            problems.append(ring)
            continue
        key = (a, str(rule["sensor"]))
        if out["rings"].setdefault(key, ring) != ring:
            problems.append(ModelError((*at, "ring"), f"another rule gives agent "
                                       f"{rule['agent']!r} a different '{key[1]}' ring"))
        beams = _beams(ring, rule, at)
        below = rule["below"]
        if not (_number(below) and 0 < below <= ring.max_range):
            problems.append(ModelError((*at, "below"), f"expected a range in (0, max_range = "
                                       f"{ring.max_range:g}], got {below!r}"))
        elif isinstance(beams, ModelError):
            problems.append(beams)
        else:
            out["rules"].append(Rule(a, key[1], beams, float(below), str(rule["raise"])))
    return out, problems


@world_component("obstacles")
class Obstacles(WorldComponent):
    """Walls, circles and boxes; range rings cast against them and the payloads."""

    params: ClassVar[dict[str, Any]] = {
        "walls": [], "circles": [], "boxes": [], "detect": [], "radius": [],
        "on_collision": "outcome",
    }

    @classmethod
    def check(cls, team: Team, values: Mapping[str, Any]) -> list[ModelError]:
        return _parse(team, values)[1]

    def __init__(self, team: Team, n: int, values: Mapping[str, Any]) -> None:
        super().__init__(team, n, values)
        parsed, problems = _parse(team, values)
        if problems:
            raise settings_error("obstacles", problems)
        self.walls, self.circles, self.boxes = parsed["walls"], parsed["circles"], \
            parsed["boxes"]
        self.segments = np.concatenate([self.walls, _box_edges(self.boxes)])
        self.targets = Targets.of(self.segments, self.circles, n)  # walls do not move
        self.rules: list[Rule] = parsed["rules"]
        self.rings: dict[tuple[int, str], RangeRing] = parsed["rings"]
        self.raises = tuple(dict.fromkeys(r.event for r in self.rules))
        # the beams the rules read, per ring: only those are cast at each instant (a rule on
        # the front IR reads 3 of 24 beams), and where each rule's beams are among them
        self.read_beams: dict[tuple[int, str], np.ndarray] = {}
        for rule in self.rules:
            key = (rule.agent, rule.sensor)
            self.read_beams[key] = np.union1d(self.read_beams.get(key, rule.beams), rule.beams)
        self.rule_columns = [np.searchsorted(self.read_beams[(r.agent, r.sensor)], r.beams)
                             for r in self.rules]
        self.planar = [a for a, agent in enumerate(team.agents) if _planar(agent)]
        given = parsed["radius"]
        self.radius = np.array([given.get(a, _footprint(team.agents[a])) for a in self.planar])
        names = {s for _, s in self.rings}
        for agent in team.agents:
            preset = getattr(agent, "preset", None)
            names |= set(preset.rings()) if preset is not None else set()
        self.sensors = tuple(sorted(names))  # what laws may sense (asked at every tick)
        self.payloads: list[CarriedPayload] = []
        self.late: list[CarriedPayload] = []
        self.sensing: set[int] = set()  # agents with a pose, once the run has started
        self.near = np.zeros((len(self.rules), n), bool)
        self.min_clear = np.full((len(self.planar), n), np.inf)
        self.payload_clear = np.full(n, np.inf)
        # on_collision: warn — each party's first collision, per instance
        self.collisions: list[dict[str, str]] = [{} for _ in range(n)]

    def start(self, world: WorldAccess) -> None:
        self.world = world  # kept: sense() reads poses when a law asks
        everyone = world.components()
        mine = everyone.index(self)
        self.payloads = world.components(CarriedPayload)
        # payloads listed after this component settle after it: settle them first here
        self.late = [c for c in self.payloads if everyone.index(c) > mine]
        self.sensing = {*self.planar, *(r.agent for r in self.rules)}
        for a in self.sensing:
            world.pose(a, np.arange(0))  # a plant without x and y fails now, not mid-run

    # ------------------------------------------------------------------ readings
    def _poses(self, a: int, idx: np.ndarray) -> np.ndarray:
        return self.world.pose(a, idx)

    def _ring(self, a: int, sensor: str) -> RangeRing | None:
        if (a, sensor) in self.rings:
            return self.rings[(a, sensor)]
        preset = getattr(self.team.agents[a], "preset", None)
        if preset is None or sensor not in preset.rings():
            return None
        return self.rings.setdefault((a, sensor), preset.ring(sensor))

    def read(self, a: int, ring: RangeRing, idx: np.ndarray,
             reach: np.ndarray | None = None, beams: np.ndarray | None = None) -> np.ndarray:
        """Ring readings of agent ``a`` in instances ``idx`` against the static obstacles and
        every payload's outline: ``(m, count)``, or ``(m, len(beams))`` for those beams only
        (each ray is cast on its own: a beam reads the same whichever others are cast).

        ``reach``: where the robot's centre is known to be farther than this from every
        static obstacle (this instant's clearances), no ray can meet one within the ring's
        range (a ray leaves the ring's mount circle), so those rows read ``max_range`` from
        the static scene without casting — what the cast would give, since it clips there.
        """
        poses = self._poses(a, idx)
        origins, directions = ring.rays(poses)
        count = ring.count
        if beams is not None and beams.size < count:
            rays = (beams[:, None] * ring.rays_per_beam + np.arange(ring.rays_per_beam)).ravel()
            origins, directions, count = origins[:, rays], directions[:, rays], beams.size
        near = None
        if reach is not None:
            slack = _SLACK * (1.0 + np.abs(poses[:, 0]) + np.abs(poses[:, 1]) + ring.max_range)
            near = reach - ring.mount_radius <= ring.max_range + slack
        if near is None or every(near):
            dist = cast_at(origins, directions, self.targets, ring.max_range)
        else:
            dist = filled(origins.shape[:2], float(ring.max_range))
            if some(near):
                dist[near] = cast_at(origins[near], directions[near], self.targets,
                                     ring.max_range)
        for p in self.payloads:
            dist = np.minimum(dist, p.ray_hits(idx, origins, directions, ring.max_range))
        dist = dist.reshape(idx.size, count, ring.rays_per_beam).min(axis=2)
        return np.maximum(dist, ring.min_range)

    def senses(self) -> tuple[str, ...]:
        return self.sensors

    def sense(self, agent: int, idx: np.ndarray, name: str) -> np.ndarray:
        ring = self._ring(agent, name) if agent in self.sensing else None
        if ring is None:
            raise KeyError(f"obstacles: robot '{self.team.agents[agent].name}' has no range "
                           f"ring '{name}' (from its robot model or a detect rule's ring)")
        return self.read(agent, ring, np.asarray(idx, np.intp))

    # ------------------------------------------------------------------ each instant
    def update(self, world: WorldAccess, idx: np.ndarray) -> None:
        for p in self.late:
            p.settle(world, idx)
        reach = self._measure(world, idx)
        readings: dict[tuple[int, str], np.ndarray] = {}
        for r, rule in enumerate(self.rules):
            key = (rule.agent, rule.sensor)
            if key not in readings:
                readings[key] = self.read(rule.agent, self.rings[key], idx,
                                          reach.get(rule.agent), self.read_beams[key])
            near = readings[key][:, self.rule_columns[r]].min(axis=1) < rule.below
            rising = near & ~self.near[r, idx]
            self.near[r, idx] = near
            if some(rising):
                world.raise_event(idx[rising], rule.agent, rule.event)

    def _measure(self, world: WorldAccess, idx: np.ndarray) -> dict[int, np.ndarray]:
        """Running minima of the robots' and the payloads' clearances, and collisions.
        Returns each planar robot's centre clearance from the static obstacles ``(m,)``."""
        hits: list[tuple[int, str, str]] = []  # (instance, who, what happened)
        reach: dict[int, np.ndarray] = {}
        if self.planar:
            points = np.empty((len(self.planar), idx.size, 2))  # (R, m, 2)
            for r, a in enumerate(self.planar):
                points[r] = self._poses(a, idx)[:, :2]
            pts = points.reshape(-1, 2)
            gap = clearance(pts, 0.0, self.walls, self.circles)
            if len(self.boxes):
                gap = np.minimum(gap, box_sdf(pts, self.boxes))
            gap = gap.reshape(len(self.planar), idx.size)
            reach = dict(zip(self.planar, gap, strict=True))
            gap = gap - self.radius[:, None]
            self.min_clear[:, idx] = np.minimum(self.min_clear[:, idx], gap)
            for r, a in enumerate(self.planar) if some(gap < 0) else ():
                for k in np.flatnonzero(gap[r] < 0).tolist():
                    what = name_hit(points[r, k], self.walls, self.circles, self.boxes)
                    who = self.team.agents[a].name
                    hits.append((int(idx[k]), who, f"robot '{who}' hit {what}, its footprint "
                                 f"overlapping it by {-gap[r, k]:.3g}"))
            overlap = robot_overlaps(points, self.radius)
            touch = overlap > 0
            pairs = np.nonzero(np.triu(touch, 1)) if some(touch) else ()
            for k, r1, r2 in zip(*pairs, strict=True):
                names = [self.team.agents[self.planar[r]].name for r in (r1, r2)]
                hits.append((int(idx[k]), " and ".join(names), f"robots '{names[0]}' and "
                             f"'{names[1]}' collided, their footprints overlapping by "
                             f"{overlap[k, r1, r2]:.3g}"))
        for p in self.payloads:
            gap = self._payload_gap(p, idx)
            self.payload_clear[idx] = np.minimum(self.payload_clear[idx], gap)
            for k in where_true(gap <= 0).tolist():
                hits.append((int(idx[k]), p.values["name"],
                             f"payload '{p.values['name']}' hit an obstacle"))
        if hits and self.values["on_collision"] != "ignore":
            self._collide(world, hits)
        return reach

    def _collide(self, world: WorldAccess, hits: list[tuple[int, str, str]]) -> None:
        for i, who, what in hits:
            text = f"{what} at t={float(world.t[i])!r}"
            if self.values["on_collision"] == "outcome":
                world.finish(np.array([i]), "collision", text)
            else:
                self.collisions[i].setdefault(who, text)

    def _payload_gap(self, p: CarriedPayload, idx: np.ndarray) -> np.ndarray:
        """Gap between payload ``p``'s outline and the static obstacles (0 if they meet)."""
        gap = p.gap(idx, self.segments, self.circles)
        if len(self.boxes):  # a payload wholly inside an obstacle box meets no edge
            gap = np.where(box_sdf(p.pose[idx, :2], self.boxes) <= 0.0, 0.0, gap)
        return gap

    # ------------------------------------------------------------------ results
    def summary(self, i: int) -> dict[str, Any]:
        out: dict[str, Any] = {"min_clearance": [_finite(v) for v in self.min_clear[:, i]]}
        if self.values["on_collision"] == "warn":
            out["collisions"] = list(self.collisions[i].values())
        if self.payloads:
            out["payload_clearance"] = _finite(self.payload_clear[i])
        return out

    def meta(self) -> dict[str, Any]:
        obstacles = [{"kind": "wall", "points": [w[:2].tolist(), w[2:].tolist()]}
                     for w in self.walls]
        obstacles += [{"kind": "circle", "x": float(x), "y": float(y), "r": float(r)}
                      for x, y, r in self.circles]
        obstacles += [{"kind": "box", "points": _corners(b).tolist()} for b in self.boxes]
        footprints = {self.team.agents[a].name: {"radius": float(r)}
                      for a, r in zip(self.planar, self.radius, strict=True) if r > 0}
        return {"world": {"obstacles": obstacles}, "footprints": footprints}


def _footprint(agent: Agent) -> float:
    preset = getattr(agent, "preset", None)
    return float(preset.footprint.radius) if preset is not None else 0.0


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
