"""A payload carried by one grasp against the static obstacles over its motion between
two instants, exactly: the swept payload.

With a single engaged grasp a payload keeps its angle and follows the grasp's robot point
(:mod:`hybridteam.world.carried`: a point spring transmits no torque), so between two
instants it *translates*, every point of it by the mount point's displacement. A unicycle
under a held input turns rigidly about one fixed centre (or translates), so its mount
point runs on an arc about that centre, and every point of the payload on a congruent arc
(:class:`Carry`): a corner on an arc about ``corner - mount + centre``; a fixed point seen
from the payload (a post's centre, a wall's end) on the reversed arc. Both are
:class:`~hybridteam.world.swept.Piece` s, and the least gap and first contact of a convex
outline against a post or a wall reduce to :mod:`.swept`'s closed forms: two disjoint
convex sets are nearest at a vertex of one of them, so the outline's corners against the
posts and walls, and the posts' centres and the walls' ends against the outline's edges
(in the payload's frame at the first instant, which only translates) cover every case.

Exact where the carrier's motion is rebuilt (:func:`carry`): a unicycle under a held input
turning by less than half a revolution, or a holonomic base that does not turn or carries
the grasp at its centre (a holonomic base turning while it translates moves an off-centre
mount on no arc). Two or more engaged grasps settle at the springs' equilibrium, whose
angle has no closed form over the motion: those payloads are bounded instead
(:mod:`.swept_settled`).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import NamedTuple

from hybridteam.world.swept import Piece, first_contact, least_gap, piece, segment_distance

Point = tuple[float, float]
Segment = tuple[float, float, float, float]


class Carry(NamedTuple):
    """A translation of the payload between instants ``t0`` and ``t1``: every point moves
    by ``M(s) - M0``, where the mount point ``M`` turns by ``turn`` about ``(cx, cy)``
    (``turn`` 0: moves by ``s (dx, dy)``)."""

    t0: float
    t1: float
    mx: float
    my: float
    cx: float = 0.0
    cy: float = 0.0
    turn: float = 0.0
    dx: float = 0.0
    dy: float = 0.0

    def moving(self, qx: float, qy: float, sign: float = 1.0) -> Piece:
        """The path of the payload's point at ``(qx, qy)`` at the start (``sign`` 1), or
        of a fixed point ``(qx, qy)`` relative to the payload (``sign`` -1: it moves by
        ``M0 - M(s)`` in the payload's frame at the start)."""
        if not self.turn:
            x1, y1 = qx + sign * self.dx, qy + sign * self.dy
            return Piece(self.t0, self.t1, qx, qy, x1, y1)
        rx, ry = self.mx - self.cx, self.my - self.cy
        radius = math.hypot(rx, ry)
        if radius == 0.0:  # (the mount on the turning centre: nothing moves)
            return Piece(self.t0, self.t1, qx, qy, qx, qy)
        ox, oy = qx - sign * rx, qy - sign * ry
        phi0 = math.atan2(sign * ry, sign * rx)
        end = phi0 + self.turn
        x1, y1 = ox + radius * math.cos(end), oy + radius * math.sin(end)
        return Piece(self.t0, self.t1, qx, qy, x1, y1, ox, oy, radius, phi0, self.turn)


def carry(
    t0: float,
    pose0: Sequence[float],
    t1: float,
    pose1: Sequence[float],
    mount: Point,
    turning: bool,
) -> Carry | None:
    """The mount point's motion from robot pose ``pose0`` at ``t0`` to ``pose1`` at ``t1``
    (``mount`` in the robot's frame) under a held input: a unicycle (``turning``) turns
    about the centre of its arc (its own centre where it turns on the spot); None where it
    is not rebuilt (half a turn or more; a holonomic base turning with the mount off its
    centre)."""
    x0, y0, th0 = pose0
    x1, y1, th1 = pose1
    c, s = math.cos(th0), math.sin(th0)
    mx, my = x0 + c * mount[0] - s * mount[1], y0 + s * mount[0] + c * mount[1]
    if th1 == th0 or not (turning or mount[0] or mount[1]):  # a translation
        return Carry(t0, t1, mx, my, dx=x1 - x0, dy=y1 - y0)
    if not turning:
        return None
    path = piece(t0, pose0, t1, pose1, turning)
    if path is None:
        return None
    centre = (path.cx, path.cy) if path.radius else (x0, y0)
    return Carry(t0, t1, mx, my, centre[0], centre[1], th1 - th0)


def outline(
    x: float, y: float, theta: float, half_width: float, half_depth: float
) -> tuple[list[Point], list[Segment]]:
    """The corners and edges of a payload's outline at pose ``(x, y, theta)``: a box's
    four, a bar's two ends and one edge (``half_depth`` 0)."""
    c, s = math.cos(theta), math.sin(theta)
    local = (
        [(-half_width, 0.0), (half_width, 0.0)]
        if half_depth == 0.0
        else [
            (-half_width, -half_depth),
            (half_width, -half_depth),
            (half_width, half_depth),
            (-half_width, half_depth),
        ]
    )
    corners = [(x + c * u - s * v, y + s * u + c * v) for u, v in local]
    if len(corners) == 2:
        return corners, [(*corners[0], *corners[1])]
    return corners, [(*corners[k], *corners[(k + 1) % 4]) for k in range(4)]


def _fixed_points(
    circles: Iterable[tuple[float, float, float]], segments: Iterable[Segment]
) -> list[tuple[float, float, float]]:
    """The obstacles' vertices as seen by the outline's edges: each post's centre with its
    radius, each wall's ends with 0."""
    out = list(circles)
    for ax, ay, bx, by in segments:
        out += [(ax, ay, 0.0), (bx, by, 0.0)]
    return out


def _side(ax: float, ay: float, bx: float, by: float, px: float, py: float) -> float:
    """Twice the signed area of ``a, b, p``: > 0 where ``p`` is left of ``a -> b``."""
    return (bx - ax) * (py - ay) - (by - ay) * (px - ax)


def _crossing(e: Segment, f: Segment) -> bool:
    """Whether segments ``e`` and ``f`` cross (touching counts; not collinear overlaps,
    where an end of one lies on the other and the distances see it)."""
    d1, d2 = _side(*e, f[0], f[1]), _side(*e, f[2], f[3])
    d3, d4 = _side(*f, e[0], e[1]), _side(*f, e[2], e[3])
    return d1 * d2 <= 0.0 and d3 * d4 <= 0.0 and (d1, d2) != (0.0, 0.0)


def overlapping(
    edges: list[Segment],
    circles: list[tuple[float, float, float]],
    segments: list[Segment],
) -> bool:
    """Whether the outline already meets an obstacle where the distances of its vertices
    do not say so: a post's centre or a wall's end inside a box, or a wall crossing an
    edge (two disjoint convex sets are nearest at a vertex; overlapping ones need not
    be). Asked at the start of a motion only: to come to overlap later, the two must
    first touch, vertex to edge."""
    for e in edges:
        if any(_crossing(e, f) for f in segments):
            return True
    if len(edges) < 4:  # (a bar has no inside)
        return False
    for qx, qy, _ in _fixed_points(circles, segments):
        if all(_side(*e, qx, qy) >= 0.0 for e in edges):  # (the corners run anticlockwise)
            return True
    return False


def payload_least_gap(
    motion: Carry,
    corners: list[Point],
    edges: list[Segment],
    circles: list[tuple[float, float, float]],
    segments: list[Segment],
) -> tuple[float, float]:
    """The least gap between the outline (``corners`` and ``edges`` at the start) carried
    by ``motion`` and the posts and walls, 0 where they meet, and the fraction where it
    is reached: ``(inf, 0)`` with no obstacle."""
    if overlapping(edges, circles, segments):
        return 0.0, 0.0
    best = (math.inf, 0.0)
    for qx, qy in corners:
        best = min(best, least_gap(motion.moving(qx, qy), circles, segments))
    for qx, qy, r in _fixed_points(circles, segments):
        seen = motion.moving(qx, qy, -1.0)
        for edge in edges:
            d, s = segment_distance(seen, edge)
            best = min(best, (d - r, s))
    return max(best[0], 0.0), best[1]


def payload_first_contact(
    motion: Carry,
    corners: list[Point],
    edges: list[Segment],
    circles: list[tuple[float, float, float]],
    segments: list[Segment],
) -> float | None:
    """The earliest fraction where the carried outline touches a post or a wall (a corner
    reaching one, or a post's edge or a wall's end reaching an edge), or None."""
    if overlapping(edges, circles, segments):
        return 0.0
    found = []
    for qx, qy in corners:
        s = first_contact(motion.moving(qx, qy), 0.0, circles, segments)
        if s is not None:
            found.append(s)
    for qx, qy, r in _fixed_points(circles, segments):
        s = first_contact(motion.moving(qx, qy, -1.0), r, [], edges)
        if s is not None:
            found.append(s)
    return min(found, default=None)
