"""Plane geometry for worlds: wall segments, polygons, and a corridor with one turn.

Everything here is domain-neutral (no robots, no ladders) and vectorized with numpy over
a leading axis, because callers check an ensemble of bodies against the same walls at
every step. Segments are rows ``[x0, y0, x1, y1]`` in arrays of shape ``(m, 4)``: that is
also how a :class:`~hybridteam.world.scene.SceneDescription` holds walls (and a trace
stores them, under ``meta["world"]["walls"]``), so a world is drawn without translation.

Only ``+ - * /``, ``sqrt`` and comparisons are used in the distance and intersection
kernels, in the same order for every element, so a result never depends on how many
other points are in the batch.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from hybridteam.world.scene import Region, SceneDescription

#: Relative tolerance of "touching" in the intersection tests (parallel, collinear).
_EPS = 1e-12


def relative_pose(
    x: np.ndarray,
    y: np.ndarray,
    theta: np.ndarray,
    ref_x: np.ndarray,
    ref_y: np.ndarray,
    ref_theta: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A pose in a reference pose's frame: how far ahead of and left of the reference the
    point is, and the heading difference in [-pi, pi) (a follower's place relative to its
    leader, say)."""
    c, s = np.cos(ref_theta), np.sin(ref_theta)
    dx, dy = x - ref_x, y - ref_y
    return c * dx + s * dy, -s * dx + c * dy, (theta - ref_theta + np.pi) % (2 * np.pi) - np.pi


def as_segments(segments: np.ndarray | list) -> np.ndarray:
    """Walls as a float array of shape (m, 4); one segment may be given as (4,)."""
    seg = np.asarray(segments, dtype=float)
    if seg.ndim == 1:
        seg = seg[None, :]
    if seg.ndim != 2 or seg.shape[1] != 4:
        raise ValueError(f"segments must have shape (m, 4), got {seg.shape}")
    return seg


def point_segment_distances(
    points: np.ndarray, segments: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Distance from every point to every segment: ``(n, m)`` and closest points ``(n, m, 2)``.

    The closest point is the projection clamped to the segment; a degenerate segment
    (both ends equal) is treated as a point.
    """
    dist, cx, cy = _closest(np.asarray(points, dtype=float).reshape(-1, 2), as_segments(segments))
    return dist, np.stack([cx, cy], axis=-1)


def _closest(p: np.ndarray, seg: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`point_segment_distances` of float points ``(n, 2)`` and segments ``(m, 4)``:
    distances and the closest points' coordinates, each ``(n, m)``. Elementwise, so a
    point's distances are the same whichever other points are given with it."""
    ax, ay = seg[:, 0], seg[:, 1]
    dx, dy = seg[:, 2] - ax, seg[:, 3] - ay
    dd = dx * dx + dy * dy
    safe = np.where(dd > 0.0, dd, 1.0)
    rx = p[:, 0:1] - ax
    ry = p[:, 1:2] - ay
    t = np.clip((rx * dx + ry * dy) / safe, 0.0, 1.0)
    t = np.where(dd > 0.0, t, 0.0)
    cx = ax + t * dx
    cy = ay + t * dy
    ex = p[:, 0:1] - cx
    ey = p[:, 1:2] - cy
    return np.sqrt(ex * ex + ey * ey), cx, cy


def point_segment_distance(
    points: np.ndarray, segments: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Distance from each of n points to the nearest of m segments, and that closest point.

    Returns ``(distance (n,), closest (n, 2))``: what a robot needs to know about the
    wall it is about to touch.
    """
    dist, closest = point_segment_distances(points, segments)
    k = np.argmin(dist, axis=1)
    rows = np.arange(dist.shape[0])
    return dist[rows, k], closest[rows, k]


def _orient(ax, ay, bx, by, cx, cy):
    """Twice the signed area of triangle abc (> 0: counter-clockwise)."""
    return (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)


def segments_intersect(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Whether each of n segments ``a`` meets each of m segments ``b`` (touching counts).

    Returns a boolean array ``(n, m)``. Used to assert that a body never crosses a wall,
    so the test is closed: a segment ending exactly on a wall intersects it.
    """
    a = as_segments(a)[:, None, :]
    b = as_segments(b)[None, :, :]
    p0x, p0y, p1x, p1y = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    q0x, q0y, q1x, q1y = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    scale = np.abs(p1x - p0x) + np.abs(p1y - p0y) + np.abs(q1x - q0x) + np.abs(q1y - q0y)
    tol = _EPS * scale * scale
    d1 = _orient(q0x, q0y, q1x, q1y, p0x, p0y)
    d2 = _orient(q0x, q0y, q1x, q1y, p1x, p1y)
    d3 = _orient(p0x, p0y, p1x, p1y, q0x, q0y)
    d4 = _orient(p0x, p0y, p1x, p1y, q1x, q1y)
    proper = (((d1 > tol) & (d2 < -tol)) | ((d1 < -tol) & (d2 > tol))) & (
        ((d3 > tol) & (d4 < -tol)) | ((d3 < -tol) & (d4 > tol))
    )

    def on(sx0, sy0, sx1, sy1, px, py, d):
        inside_x = (np.minimum(sx0, sx1) - tol <= px) & (px <= np.maximum(sx0, sx1) + tol)
        inside_y = (np.minimum(sy0, sy1) - tol <= py) & (py <= np.maximum(sy0, sy1) + tol)
        return (np.abs(d) <= tol) & inside_x & inside_y

    touching = (
        on(q0x, q0y, q1x, q1y, p0x, p0y, d1)
        | on(q0x, q0y, q1x, q1y, p1x, p1y, d2)
        | on(p0x, p0y, p1x, p1y, q0x, q0y, d3)
        | on(p0x, p0y, p1x, p1y, q1x, q1y, d4)
    )
    return proper | touching


def segment_segment_distances(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance between each of n segments and each of m segments, ``(n, m)``.

    Zero when they meet; otherwise the smallest of the four end-to-segment distances
    (two non-crossing segments are closest at an end of one of them).
    """
    a = as_segments(a)
    b = as_segments(b)
    n, m = len(a), len(b)
    # each segment's two ends against the other set, in one call per side (elementwise:
    # the distances :func:`point_segment_distances` gives each end alone)
    da = _closest(np.concatenate([a[:, 0:2], a[:, 2:4]]), b)[0]
    db = _closest(np.concatenate([b[:, 0:2], b[:, 2:4]]), a)[0]
    dist = np.minimum(np.minimum(da[:n], da[n:]), np.minimum(db[:m].T, db[m:].T))
    return np.where(segments_intersect(a, b), 0.0, dist)


def points_in_polygon(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Even-odd test of n points against one simple polygon ``(k, 2)``; boundary counts in.

    Points on an edge are reported inside, so "touches the corner region" is never missed
    by a ladder that ends exactly on the region's border.
    """
    p = np.asarray(points, dtype=float).reshape(-1, 2)
    poly = np.asarray(polygon, dtype=float)
    x, y = p[:, 0:1], p[:, 1:2]
    x0, y0 = poly[:, 0], poly[:, 1]
    x1, y1 = np.roll(x0, -1), np.roll(y0, -1)
    straddle = (y0 > y) != (y1 > y)
    dy = np.where(y1 != y0, y1 - y0, 1.0)
    xcross = x0 + (y - y0) * (x1 - x0) / dy
    inside = np.logical_xor.reduce(straddle & (x < xcross), axis=1)
    edges = np.stack([x0, y0, x1, y1], axis=1)
    dist, _ = point_segment_distances(p, edges)
    return inside | (dist.min(axis=1) <= _EPS * (1.0 + np.abs(p).max(axis=1)))


def polygon_edges(polygon: np.ndarray) -> np.ndarray:
    """The closed boundary of a polygon ``(k, 2)`` as segments ``(k, 4)``."""
    poly = np.asarray(polygon, dtype=float)
    return np.concatenate([poly, np.roll(poly, -1, axis=0)], axis=1)


def segments_intersect_polygon(segments: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Whether each of n segments meets a polygon (crosses its boundary or lies inside)."""
    seg = as_segments(segments)
    crosses = segments_intersect(seg, polygon_edges(polygon)).any(axis=1)
    return crosses | points_in_polygon(seg[:, 0:2], polygon)


def rectangle(x0: float, y0: float, x1: float, y1: float) -> np.ndarray:
    """Counter-clockwise corners of an axis-aligned rectangle, ``(4, 2)``."""
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=float)


@dataclass(frozen=True, eq=False)
class Corridor:
    """A corridor of two straight legs joined by one 90° turn.

    The incoming leg runs along +y from its entrance; the outgoing leg leaves the turn
    along +x (``turn="right"``) or -x (``"left"``). The corner region is the rectangle
    where the two legs overlap (the paper's shaded 200 x 200 square). Ends are open: a
    corridor is what the walls say, and nothing stops a body at the entrance or exit.
    """

    width_in: float
    width_out: float
    turn: Literal["right", "left"]
    outer_walls: np.ndarray  # (2, 4): incoming leg's outer wall, then outgoing leg's
    inner_walls: np.ndarray  # (2, 4): incoming leg's inner wall (ends at the vertex), outgoing
    corner: np.ndarray  # (4, 2) polygon of the corner region
    inner_vertex: np.ndarray  # (2,) where the inner walls meet
    outer_vertex: np.ndarray  # (2,) where the outer walls meet
    entrance: np.ndarray  # (2, 2): [outer end, inner end] of the open entrance
    exit: np.ndarray  # (2, 2): [outer end, inner end] of the open exit
    direction_in: np.ndarray  # (2,) unit direction of travel along the incoming leg
    direction_out: np.ndarray  # (2,) unit direction of travel along the outgoing leg

    @property
    def walls(self) -> np.ndarray:
        """All walls, ``(4, 4)``: outer walls first, then inner walls."""
        return np.concatenate([self.outer_walls, self.inner_walls])

    @property
    def inner_normals(self) -> np.ndarray:
        """Unit normals of the inner walls pointing *into* the walls, ``(2, 2)``.

        A displacement with a positive component along one of these moves toward the
        inside of the turn; in the incoming leg the second one is "back, away from the
        corner", in the outgoing leg the first one is "forward, away from the corner".
        """
        return np.stack([self.direction_out, -self.direction_in])

    def corner_entry_point(self, across: np.ndarray | float) -> np.ndarray:
        """Point on the corner's entry edge: ``across`` 0 at the inner vertex, 1 outer wall."""
        a = np.asarray(across, dtype=float)[..., None]
        return self.inner_vertex - a * self.width_in * self.direction_out

    def corner_exit_point(self, across: np.ndarray | float) -> np.ndarray:
        """Point on the corner's exit edge: ``across`` 0 at the inner vertex, 1 outer wall."""
        a = np.asarray(across, dtype=float)[..., None]
        return self.inner_vertex + a * self.width_out * self.direction_in

    def leg_point(
        self, leg: Literal["in", "out"], along: np.ndarray | float, across: np.ndarray | float = 0.5
    ) -> np.ndarray:
        """A point ``along`` from the open end of a leg, ``across`` 0 inner .. 1 outer wall.

        ``leg_point("in", d)`` is on the centre line ``d`` after the entrance;
        ``leg_point("out", d)`` is on the centre line ``d`` before the exit.
        """
        a = np.asarray(along, dtype=float)[..., None]
        c = np.asarray(across, dtype=float)[..., None]
        if leg == "in":
            inner = self.entrance[1]
            return inner + a * self.direction_in - c * self.width_in * self.direction_out
        inner = self.exit[1]
        return inner - a * self.direction_out + c * self.width_out * self.direction_in

    def describe(self) -> SceneDescription:
        """What the views draw of the corridor: its walls, and its corner as a region
        labelled ``corner``; it has no obstacles besides its walls."""
        return SceneDescription(
            walls=tuple((a, b, c, d) for a, b, c, d in self.walls.tolist()),
            regions=(Region(tuple((x, y) for x, y in self.corner.tolist()), "corner"),),
            obstacles=(),
        )


def corridor_with_turn(
    width_in: float = 200.0,
    width_out: float = 200.0,
    outer_leg_in: float = 1200.0,
    outer_leg_out: float = 1200.0,
    inner_leg_in: float | None = None,
    inner_leg_out: float | None = None,
    turn: Literal["right", "left"] = "right",
) -> Corridor:
    """A corridor with one 90° turn; the defaults are the ladder paper's (Fig. 3).

    The paper gives 200 units of width, 2400 along the outer wall and 2000 along the inner
    wall; with square-cut ends that is 1200 + 1200 outer and 1000 + 1000 inner. Outer legs
    are measured from an open end to the outer vertex; inner legs from an open end to the
    inner vertex and default to the square-cut length (outer leg minus the other leg's
    width). The entrance is on y = 0 with the outer wall of the incoming leg on x = 0, so
    a right turn draws as an upside-down L going up and then right.
    """
    if turn not in ("right", "left"):
        raise ValueError(f"turn must be 'right' or 'left', got {turn!r}")
    if min(width_in, width_out) <= 0:
        raise ValueError("corridor widths must be positive")
    if inner_leg_in is None:
        inner_leg_in = outer_leg_in - width_out
    if inner_leg_out is None:
        inner_leg_out = outer_leg_out - width_in
    if min(inner_leg_in, inner_leg_out) < 0 or outer_leg_in < width_out or outer_leg_out < width_in:
        raise ValueError("corridor legs are shorter than the corner they lead to")
    s = 1.0 if turn == "right" else -1.0
    # Right turn: outer wall of the incoming leg on x = 0, inner wall on x = width_in.
    ox, ix = 0.0, s * width_in
    top = outer_leg_in  # outer wall of the outgoing leg
    vy = top - width_out  # inner wall of the outgoing leg
    outer_v = np.array([ox, top])
    inner_v = np.array([ix, vy])
    exit_x_outer = ox + s * outer_leg_out
    exit_x_inner = ix + s * inner_leg_out
    outer = np.array([[ox, 0.0, ox, top], [ox, top, exit_x_outer, top]])
    inner = np.array([[ix, vy - inner_leg_in, ix, vy], [ix, vy, exit_x_inner, vy]])
    corner = rectangle(min(ox, ix), vy, max(ox, ix), top)
    return Corridor(
        width_in=float(width_in),
        width_out=float(width_out),
        turn=turn,
        outer_walls=outer,
        inner_walls=inner,
        corner=corner,
        inner_vertex=inner_v,
        outer_vertex=outer_v,
        entrance=np.array([[ox, 0.0], [ix, vy - inner_leg_in]]),
        exit=np.array([[exit_x_outer, top], [exit_x_inner, vy]]),
        direction_in=np.array([0.0, 1.0]),
        direction_out=np.array([s, 0.0]),
    )
