"""A robot's clearance over its motion between two instants, exactly: the swept test.

Between two consecutive instants of a run a kinematic robot under a held input (a sampled
law, held ``inputs:``) moves on one closed-form path: a unicycle's centre on a circular arc
(its heading turning at a constant rate), a straight segment when it does not turn, a
holonomic base's centre on a straight segment. Its footprint is a disk, so what it sweeps
is that path grown by the radius, and the least gap to a post (a circle) or a wall (a
segment) over the whole motion has a closed form: the nearest point of an arc to a point
lies where the arc crosses the ray from its centre through the point, else at an end; an
arc and a segment are nearest at an end of either, at the arc's point whose tangent is
parallel to the segment, or where they cross. The first contact (the gap reaching 0) is a
root in closed form too: a quadratic along a segment, ``cos(phi - alpha) = k`` along an arc.
No sampling: what a robot grazes between two ticks is found however short the graze.

The path is rebuilt from the poses at the two instants (:func:`piece`): the heading's
change fixes the arc's angle, the chord its radius and centre, so nothing but the poses is
needed (no inputs, no plant) — which is why the robot must have moved under one held input
in between (:func:`holds_between_instants` says where a robot's model guarantees it).
A turn of half a revolution or more between two instants is not rebuilt (near a whole
turn the chord, and with it the radius, is lost in rounding; and a live robot's heading
is its odometry's yaw, wrapped, so a small turn across the wrap reads as nearly a whole
one: a turn ``T`` and ``T - 2 pi`` through the same two poses are the two complementary
arcs of one circle, which the poses cannot tell apart): :func:`piece` gives None and such
a piece is judged at its ends only, as before.

Everything here is on Python floats: the component asks only where a cheap bound cannot
rule a piece out (a piece of length ``L`` ending ``g`` from everything comes no nearer
than ``g - L``), a few pieces an instant at most.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import NamedTuple

from hybridteam.model.modes import Assign, Mode

#: The plant state a reset must not write for the swept test to hold (a robot moved by a
#: transition's ``x = ...`` jumps: no path joins its poses).
POSE = frozenset(("x", "y", "theta"))


class Piece(NamedTuple):
    """A robot centre's path between two instants ``t0`` and ``t1``: a segment from
    ``(x0, y0)`` to ``(x1, y1)`` when ``radius`` is 0, else an arc about ``(cx, cy)`` of
    ``radius`` from angle ``phi0`` turning by ``turn`` (signed, radians, ``|turn| < pi``);
    the position moves uniformly in time along it (a held input)."""

    t0: float
    t1: float
    x0: float
    y0: float
    x1: float
    y1: float
    cx: float = 0.0
    cy: float = 0.0
    radius: float = 0.0
    phi0: float = 0.0
    turn: float = 0.0

    @property
    def length(self) -> float:
        """The path's length (what bounds how much nearer than its end it comes)."""
        if self.radius:
            return self.radius * abs(self.turn)
        return math.hypot(self.x1 - self.x0, self.y1 - self.y0)

    def at(self, s: float) -> tuple[float, float]:
        """The position at fraction ``s`` of the piece (time ``t0 + s (t1 - t0)``)."""
        if self.radius:
            phi = self.phi0 + s * self.turn
            return self.cx + self.radius * math.cos(phi), self.cy + self.radius * math.sin(phi)
        return self.x0 + s * (self.x1 - self.x0), self.y0 + s * (self.y1 - self.y0)

    def time(self, s: float) -> float:
        return self.t0 + s * (self.t1 - self.t0)


def piece(
    t0: float, pose0: Iterable[float], t1: float, pose1: Iterable[float], turning: bool
) -> Piece | None:
    """The path from ``pose0`` (x, y, theta) at ``t0`` to ``pose1`` at ``t1`` under a held
    input: an arc where a unicycle (``turning``) changed heading, else a segment. None
    where the poses do not fix it (half a turn or more between them)."""
    x0, y0, th0 = pose0
    x1, y1, th1 = pose1
    turn = th1 - th0 if turning else 0.0
    cx, cy = x1 - x0, y1 - y0
    chord = math.hypot(cx, cy)
    if turn == 0.0 or chord == 0.0:  # straight, or turning on the spot: a segment (a point)
        return Piece(t0, t1, x0, y0, x1, y1)
    if not abs(turn) < math.pi:
        return None
    # rotating p0 about the centre by ``turn`` gives p1: the centre lies on the chord's
    # bisector, cot(turn / 2) half-chords to its left
    off = 0.5 / math.tan(0.5 * turn)
    ox, oy = 0.5 * (x0 + x1) - off * cy, 0.5 * (y0 + y1) + off * cx
    radius = chord / (2.0 * abs(math.sin(0.5 * turn)))
    return Piece(t0, t1, x0, y0, x1, y1, ox, oy, radius, math.atan2(y0 - oy, x0 - ox), turn)


def path_length(pose0: list[float], pose1: list[float], turning: bool) -> float:
    """The length of the held-input path from ``pose0`` (x, y, theta) to ``pose1``: the
    chord, times ``(turn / 2) / sin(turn / 2)`` along an arc; inf for a turn of half a
    revolution or more (no bound), as :func:`piece` rebuilds none."""
    gone = math.hypot(pose1[0] - pose0[0], pose1[1] - pose0[1])
    half = 0.5 * abs(pose1[2] - pose0[2]) if turning else 0.0
    if half >= 0.5 * math.pi:
        return math.inf
    if half > 0.0:
        gone *= half / math.sin(half)
    return gone


def _within(p: Piece, phi: float) -> float | None:
    """The fraction of arc ``p`` where its angle is ``phi`` (modulo a turn), or None."""
    delta = (phi - p.phi0) % math.tau if p.turn > 0 else (p.phi0 - phi) % math.tau
    s = delta / abs(p.turn)
    return s if s <= 1.0 else None


def _point_segment(px: float, py: float, seg: tuple[float, float, float, float]) -> float:
    ax, ay, bx, by = seg
    ex, ey = bx - ax, by - ay
    length2 = ex * ex + ey * ey
    s = 0.0 if length2 == 0.0 else min(1.0, max(0.0, ((px - ax) * ex + (py - ay) * ey) / length2))
    return math.hypot(ax + s * ex - px, ay + s * ey - py)


def point_distance(p: Piece, qx: float, qy: float) -> tuple[float, float]:
    """The least distance from the piece to point ``(qx, qy)`` and the fraction where it is
    reached (the earliest of equals)."""
    if p.radius:
        found = [(math.hypot(p.x0 - qx, p.y0 - qy), 0.0), (math.hypot(p.x1 - qx, p.y1 - qy), 1.0)]
        if qx != p.cx or qy != p.cy:  # (the centre is equally far from every point)
            s = _within(p, math.atan2(qy - p.cy, qx - p.cx))
            if s is not None:
                found.append((abs(math.hypot(qx - p.cx, qy - p.cy) - p.radius), s))
        return min(found, key=lambda f: (f[0], f[1]))
    ex, ey = p.x1 - p.x0, p.y1 - p.y0
    length2 = ex * ex + ey * ey
    s = (
        0.0
        if length2 == 0.0
        else min(1.0, max(0.0, ((qx - p.x0) * ex + (qy - p.y0) * ey) / length2))
    )
    x, y = p.at(s)
    return math.hypot(x - qx, y - qy), s


def segment_distance(p: Piece, seg: tuple[float, float, float, float]) -> tuple[float, float]:
    """The least distance from the piece to segment ``seg`` (x0, y0, x1, y1) and a fraction
    where it is reached."""
    ax, ay, bx, by = seg
    found = [(_point_segment(*p.at(s), seg), s) for s in (0.0, 1.0)]
    found += [(d, s) for d, s in (point_distance(p, ax, ay), point_distance(p, bx, by))]
    ex, ey = bx - ax, by - ay
    length = math.hypot(ex, ey)
    if length == 0.0:
        return min(found, key=lambda f: (f[0], f[1]))
    nx, ny = -ey / length, ex / length
    if p.radius:
        for sign in (1.0, -1.0):  # the arc's points whose tangent runs along the segment
            s = _within(p, math.atan2(sign * ny, sign * nx))
            if s is not None:
                found.append((_point_segment(*p.at(s), seg), s))
        for s in _arc_line_roots(p, nx, ny, nx * ax + ny * ay):
            found.append((_point_segment(*p.at(s), seg), s))
    else:
        dx, dy = p.x1 - p.x0, p.y1 - p.y0
        rate = nx * dx + ny * dy  # the signed distance to the line, linear in s
        if rate != 0.0:
            s = (nx * (ax - p.x0) + ny * (ay - p.y0)) / rate
            if 0.0 <= s <= 1.0:
                found.append((_point_segment(*p.at(s), seg), s))
    return min(found, key=lambda f: (f[0], f[1]))


def _arc_line_roots(p: Piece, nx: float, ny: float, level: float) -> list[float]:
    """Fractions of arc ``p`` where ``n . position = level`` (``n`` a unit vector):
    ``radius cos(phi - nu) = level - n . centre``, in closed form."""
    k = (level - (nx * p.cx + ny * p.cy)) / p.radius
    if not -1.0 <= k <= 1.0:
        return []
    nu, half = math.atan2(ny, nx), math.acos(k)
    found = (_within(p, nu + half), _within(p, nu - half))
    return [s for s in found if s is not None]


def _arc_circle_roots(p: Piece, qx: float, qy: float, reach: float) -> list[float]:
    """Fractions of arc ``p`` at distance ``reach`` from ``(qx, qy)``: with ``a = centre - q``,
    ``|a|^2 + radius^2 + 2 radius |a| cos(phi - alpha) = reach^2``."""
    ax, ay = p.cx - qx, p.cy - qy
    a = math.hypot(ax, ay)
    if a == 0.0:
        return []
    k = (reach * reach - a * a - p.radius * p.radius) / (2.0 * p.radius * a)
    if not -1.0 <= k <= 1.0:
        return []
    alpha, half = math.atan2(ay, ax), math.acos(k)
    found = (_within(p, alpha + half), _within(p, alpha - half))
    return [s for s in found if s is not None]


def line_circle_roots(p: Piece, qx: float, qy: float, reach: float) -> list[float]:
    """Fractions of segment ``p`` at distance ``reach`` from ``(qx, qy)`` (a quadratic)."""
    dx, dy = p.x1 - p.x0, p.y1 - p.y0
    fx, fy = p.x0 - qx, p.y0 - qy
    a = dx * dx + dy * dy
    if a == 0.0:
        return []
    b, c = fx * dx + fy * dy, fx * fx + fy * fy - reach * reach
    disc = b * b - a * c
    if disc < 0.0:
        return []
    root = math.sqrt(disc)
    return [s for s in ((-b - root) / a, (-b + root) / a) if 0.0 <= s <= 1.0]


def first_contact(
    p: Piece,
    reach: float,
    circles: Iterable[tuple[float, float, float]],
    segments: Iterable[tuple[float, float, float, float]],
) -> float | None:
    """The earliest fraction of the piece where a disk of radius ``reach`` about the
    centre touches a circle ``(x, y, r)`` or a segment, or None where it touches none.
    Called where the piece is known to touch something (its least gap is at most 0), so
    the start is free: the first root is the first contact."""
    found: list[float] = []
    roots = _arc_circle_roots if p.radius else line_circle_roots
    for qx, qy, r in circles:
        found += roots(p, qx, qy, reach + r)
    for seg in segments:
        ax, ay, bx, by = seg
        found += roots(p, ax, ay, reach) + roots(p, bx, by, reach)
        ex, ey = bx - ax, by - ay
        length = math.hypot(ex, ey)
        if length == 0.0:
            continue
        nx, ny = -ey / length, ex / length
        for level in (nx * ax + ny * ay + reach, nx * ax + ny * ay - reach):
            if p.radius:
                band = _arc_line_roots(p, nx, ny, level)
            else:
                rate = nx * (p.x1 - p.x0) + ny * (p.y1 - p.y0)
                s = (level - (nx * p.x0 + ny * p.y0)) / rate if rate != 0.0 else -1.0
                band = [s] if 0.0 <= s <= 1.0 else []
            for s in band:  # (on the band's line: a contact where it faces the segment)
                x, y = p.at(s)
                along = ((x - ax) * ex + (y - ay) * ey) / (length * length)
                if 0.0 <= along <= 1.0:
                    found.append(s)
    return min(found) if found else None


def least_gap(
    p: Piece,
    circles: Iterable[tuple[float, float, float]],
    segments: Iterable[tuple[float, float, float, float]],
) -> tuple[float, float]:
    """The least distance from the piece's path to the circles' edges (negative inside
    one) and the segments, and the fraction where it is reached: ``(inf, 0)`` with none.

    An obstacle farther from the piece's end than the best so far plus the piece's length
    cannot come nearer (the path is no longer than that): it is not looked at."""
    best = (math.inf, 0.0)
    reach = p.length
    for qx, qy, r in circles:
        if math.hypot(p.x1 - qx, p.y1 - qy) - r - reach > best[0]:
            continue
        d, s = point_distance(p, qx, qy)
        best = min(best, (d - r, s))
    for seg in segments:
        if _point_segment(p.x1, p.y1, seg) - reach > best[0]:
            continue
        best = min(best, segment_distance(p, seg))
    return best


def point_gap(
    x: float,
    y: float,
    circles: Iterable[tuple[float, float, float]],
    segments: Iterable[tuple[float, float, float, float]],
) -> float:
    """The distance from ``(x, y)`` to the nearest circle's edge (negative inside) or
    segment; inf with none."""
    out = math.inf
    for qx, qy, r in circles:
        out = min(out, math.hypot(x - qx, y - qy) - r)
    for seg in segments:
        out = min(out, _point_segment(x, y, seg))
    return out


def holds_between_instants(root: Mode) -> bool:
    """Whether an agent with mode tree ``root`` moves under one held input between any
    two instants, its pose changed by nothing but that motion: every mode's law sampled
    (a period) or absent, its ``inputs:`` held (``period``) or numbers or absent, no flow, and no
    action writing ``x``, ``y`` or ``theta`` (a reset jumps). A continuous law changes its
    input between instants: no single arc joins its poses."""
    modes = [root]
    while modes:
        mode = modes.pop()
        if mode.flow is not None or (mode.law is not None and mode.law.period is None):
            return False
        inputs = mode.inputs or {}
        held = mode.input_period is not None or all(
            isinstance(v, int | float) for v in inputs.values()
        )
        if not held:
            return False  # (constant inputs are held; expressions follow the state)
        actions = [*mode.on_entry, *mode.on_exit, *(a for t in mode.transitions for a in t.actions)]
        for action in actions:
            if isinstance(action, Assign) and action.text.split("=")[0].strip() in POSE:
                return False
        modes.extend(mode.children)
    return True
