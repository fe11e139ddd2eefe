"""What the views draw of the world: the typed scene description of a run.

A world component knows what a reader of the plots should see of it — a corridor's walls
and its corner, the obstacles of a doorway, the outline of a carried box, how big each
robot is — and says so with :meth:`WorldComponent.describe
<hybridteam.world.component.WorldComponent.describe>`, returning a
:class:`SceneDescription`. The engine writes every component's description into the
trace's metadata (:meth:`SceneDescription.to_meta`: the JSON keys ``world``,
``payloads``, ``payload_shapes`` and ``footprints`` that traces have always carried), and
the views read it back from a trace, loaded or fresh, with
:meth:`SceneDescription.from_meta`. Coordinates are in the team's plane and units.

Everything here is plain, immutable data: a description is made once, at the end of a
run, and never touches the engine's hot path.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

Point = tuple[float, float]
"""A point of the plane, ``(x, y)``."""


def _points(values: Iterable[Iterable[float]]) -> tuple[Point, ...]:
    return tuple((float(x), float(y)) for x, y in values)


def _listed(points: tuple[Point, ...]) -> list[list[float]]:
    return [[x, y] for x, y in points]


# ---------------------------------------------------------------------- obstacles
@dataclass(frozen=True)
class WallObstacle:
    """A wall without thickness, from ``start`` to ``end``: drawn as a heavy stroke."""

    start: Point
    end: Point

    def to_meta(self) -> dict[str, Any]:
        return {"kind": "wall", "points": _listed((self.start, self.end))}


@dataclass(frozen=True)
class CircleObstacle:
    """A round obstacle (a post, a pillar) of radius ``r`` centred at ``(x, y)``."""

    x: float
    y: float
    r: float

    def to_meta(self) -> dict[str, Any]:
        return {"kind": "circle", "x": self.x, "y": self.y, "r": self.r}


@dataclass(frozen=True)
class PolygonObstacle:
    """A solid obstacle outlined by its ``corners`` in order (a box is four)."""

    corners: tuple[Point, ...]
    #: what it is called in the trace (``box``: the obstacles component's rotated boxes)
    kind: str = "box"

    def to_meta(self) -> dict[str, Any]:
        return {"kind": self.kind, "points": _listed(self.corners)}


Obstacle = WallObstacle | CircleObstacle | PolygonObstacle


def _obstacle(entry: Mapping[str, Any]) -> Obstacle:
    kind = entry.get("kind")
    if kind == "circle":
        return CircleObstacle(float(entry["x"]), float(entry["y"]), float(entry["r"]))
    points = _points(entry["points"])
    if kind == "wall":
        return WallObstacle(points[0], points[1])
    return PolygonObstacle(points, str(kind))


# ---------------------------------------------------------------------- regions and marks
@dataclass(frozen=True)
class Region:
    """An area of the floor drawn shaded under everything (a corridor's corner, a dock),
    with an optional ``label`` at its centre."""

    outline: tuple[Point, ...]
    label: str | None = None

    def to_meta(self) -> dict[str, Any]:
        out: dict[str, Any] = {"points": _listed(self.outline)}
        if self.label is not None:
            out["label"] = self.label
        return out


@dataclass(frozen=True)
class GuidePath:
    """A path ``agent`` was planned to follow in ``instance`` (the ladder's guide paths),
    drawn dashed in the agent's colour under its actual path."""

    instance: int | None  # None: every instance
    agent: str
    points: tuple[Point, ...]

    def to_meta(self) -> dict[str, Any]:
        out: dict[str, Any] = {} if self.instance is None else {"instance": self.instance}
        return {**out, "agent": self.agent, "points": _listed(self.points)}


@dataclass(frozen=True)
class CollisionMark:
    """Where and when ``who`` (a robot, a pair of robots, a payload) first collided in
    ``instance``: marked with a star in the plots and the animation."""

    instance: int | None  # None: every instance
    who: str
    t: float
    x: float
    y: float

    def to_meta(self) -> dict[str, Any]:
        out: dict[str, Any] = {} if self.instance is None else {"instance": self.instance}
        return {**out, "who": self.who, "t": self.t, "x": self.x, "y": self.y}


# ---------------------------------------------------------------------- bodies
@dataclass(frozen=True)
class BoxShape:
    """A payload's rectangle: ``width`` along its heading, ``depth`` across it."""

    width: float
    depth: float

    @property
    def size(self) -> tuple[float, float]:
        """The rectangle drawn: (along the heading, across it)."""
        return self.width, self.depth

    @property
    def measures(self) -> tuple[float, ...]:
        """The lengths the shape was given (the views step its outlines by the least)."""
        return self.width, self.depth

    def to_meta(self) -> dict[str, Any]:
        return {"kind": "box", "width": self.width, "depth": self.depth}


@dataclass(frozen=True)
class BarShape:
    """A long payload (a beam, a ladder) of ``length`` along its heading, drawn ``width``
    thick (4 % of its length when not given)."""

    length: float
    width: float | None = None

    @property
    def size(self) -> tuple[float, float]:
        return self.length, self.length * 0.04 if self.width is None else self.width

    @property
    def measures(self) -> tuple[float, ...]:
        return (self.length,) if self.width is None else (self.length, self.width)

    def to_meta(self) -> dict[str, Any]:
        out: dict[str, Any] = {"kind": "bar", "length": self.length}
        if self.width is not None:
            out["width"] = self.width
        return out


PayloadShape = BoxShape | BarShape

#: the shape drawn for a payload whose trace does not say: a 0.3 m box
DEFAULT_PAYLOAD_SHAPE = BoxShape(0.3, 0.3)


def _shape(entry: Mapping[str, Any]) -> PayloadShape:
    if entry.get("kind") == "bar":
        width = entry.get("width")
        return BarShape(float(entry["length"]), None if width is None else float(width))
    return BoxShape(float(entry["width"]), float(entry["depth"]))


@dataclass(frozen=True)
class Footprint:
    """A robot's body as the views draw it: a disk of ``radius`` with a heading stroke."""

    radius: float

    def to_meta(self) -> dict[str, Any]:
        return {"radius": self.radius}


# ---------------------------------------------------------------------- the scene
@dataclass(frozen=True)
class SceneDescription:
    """What the views draw of the world, as one component (or a whole run) describes it.

    ``obstacles`` is None where the component says nothing of obstacles, and a tuple
    (perhaps empty) where it tells all it knows of them; the other fields are empty when
    unknown. ``payloads`` maps each payload's pose series (a name in the trace's samples)
    to its shape, in declaration order; ``footprints`` maps agents to their bodies.
    """

    #: boundary walls (a corridor's): segments ``(x0, y0, x1, y1)``, drawn as thin black
    #: lines; obstacles a robot may hit are in ``obstacles``
    walls: tuple[tuple[float, float, float, float], ...] = ()
    regions: tuple[Region, ...] = ()
    obstacles: tuple[Obstacle, ...] | None = None
    #: the unit of the plane's axes (None: metres)
    units: str | None = None
    paths: tuple[GuidePath, ...] = ()
    collisions: tuple[CollisionMark, ...] = ()
    payloads: Mapping[str, PayloadShape] = field(default_factory=dict)
    footprints: Mapping[str, Footprint] = field(default_factory=dict)

    @property
    def unit(self) -> str:
        """The axes' unit as the views label it (``m`` unless the scene says)."""
        return "m" if self.units is None else self.units

    def paths_of(self, instance: int) -> tuple[GuidePath, ...]:
        """The guide paths drawn for ``instance``."""
        return tuple(p for p in self.paths if p.instance in (None, instance))

    def collisions_of(self, instance: int) -> tuple[CollisionMark, ...]:
        """The collisions marked in ``instance``."""
        return tuple(c for c in self.collisions if c.instance in (None, instance))

    # ------------------------------------------------------------------ trace form
    def to_meta(self) -> dict[str, Any]:
        """The trace's JSON form, the keys traces carry: ``world`` (``walls``, ``regions``,
        ``obstacles``, ``units``, ``paths``, ``collisions``: each only where the scene
        has it), ``payloads`` and ``payload_shapes``, ``footprints``."""
        world: dict[str, Any] = {}
        if self.walls:
            world["walls"] = [list(w) for w in self.walls]
        if self.regions:
            world["regions"] = [r.to_meta() for r in self.regions]
        if self.obstacles is not None:
            world["obstacles"] = [o.to_meta() for o in self.obstacles]
        if self.units is not None:
            world["units"] = self.units
        if self.paths:
            world["paths"] = [p.to_meta() for p in self.paths]
        if self.collisions:
            world["collisions"] = [c.to_meta() for c in self.collisions]
        out: dict[str, Any] = {"world": world} if world else {}
        if self.payloads:
            out["payloads"] = list(self.payloads)
            out["payload_shapes"] = {k: s.to_meta() for k, s in self.payloads.items()}
        if self.footprints:
            out["footprints"] = {k: f.to_meta() for k, f in self.footprints.items()}
        return out

    @classmethod
    def from_meta(cls, meta: Mapping[str, Any]) -> SceneDescription:
        """The scene a trace's metadata describes (what the views draw): its ``world``,
        its payloads and their shapes, and the footprints of its ``agents`` (a trace
        keeps each with its agent; :meth:`to_meta`'s ``footprints`` are read too). A
        payload without a shape gets :data:`DEFAULT_PAYLOAD_SHAPE`."""
        world = meta.get("world") or {}
        shapes = meta.get("payload_shapes") or {}
        names = [p["name"] if isinstance(p, dict) else str(p) for p in meta.get("payloads") or []]
        regions = tuple(
            Region(_points(r["points"]), r.get("label"))
            if isinstance(r, dict)
            else Region(_points(r))
            for r in world.get("regions") or []
        )
        obstacles = world.get("obstacles")
        return cls(
            walls=tuple(
                (a, b, c, d)
                for a, b, c, d in np.asarray(world.get("walls") or [], float)
                .reshape(-1, 4)
                .tolist()
            ),
            regions=regions,
            obstacles=None if obstacles is None else tuple(_obstacle(o) for o in obstacles),
            units=world.get("units"),
            paths=tuple(
                GuidePath(_instance(p), str(p.get("agent", "")), _points(p["points"]))
                for p in world.get("paths") or []
            ),
            collisions=tuple(
                CollisionMark(
                    _instance(c), str(c["who"]), float(c["t"]), float(c["x"]), float(c["y"])
                )
                for c in world.get("collisions") or []
            ),
            payloads={
                n: _shape(shapes[n]) if n in shapes else DEFAULT_PAYLOAD_SHAPE for n in names
            },
            footprints={
                name: Footprint(float(foot["radius"]))
                for name, foot in _footprints(meta).items()
                if (foot or {}).get("radius")
            },
        )


def _instance(entry: Mapping[str, Any]) -> int | None:
    i = entry.get("instance")
    return None if i is None else int(i)


def _footprints(meta: Mapping[str, Any]) -> dict[str, Any]:
    """Agent name -> footprint entry: a component's ``footprints``, then those a trace
    keeps with each of its ``agents``."""
    out = dict(meta.get("footprints") or {})
    out.update({a["name"]: a["footprint"] for a in meta.get("agents") or [] if "footprint" in a})
    return out
