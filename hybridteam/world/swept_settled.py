"""A payload held by two or more grasps against the static obstacles over its motion
between two instants, with certified bounds: the swept settled payload.

With two or more engaged grasps the payload settles where the springs balance
(:func:`~hybridteam.world.payload.equilibrium`, a weighted Procrustes fit, in closed form
at every instant): its body centroid ``bc`` (of the grasps' body points, weighted by the
springs) lies on the robot points' weighted centroid ``rc``, and its angle is the argument
of ``z = sum_i w_i conj(cb_i) (r_i - rc)`` (complex numbers; ``cb_i = b_i - bc``). Between
two instants each robot point ``r_i`` moves in closed form (:class:`Grip`: the robot's
centre on its arc or segment, its heading turning at a constant rate), so the settled pose
is a closed-form function of the fraction ``s`` — but its gap to the obstacles has no
closed form (an angle ``arg z(s)`` of a sum of rotating vectors). It is bounded instead,
with stated tolerances rather than by sampling more:

- ``sum_i w_i cb_i = 0``, so ``z = sum_i w_i conj(cb_i) r_i``: ``|z'| <= sum_i w_i |cb_i|
  v_i`` and ``|z''| <= sum_i w_i |cb_i| a_i`` (``v_i``, ``a_i``: bounds on the robot
  point's speed and acceleration per unit ``s``), ``|rc'| <= sum_i w_i v_i / W`` and
  ``|rc''| <= sum_i w_i a_i / W``; and ``|z'| <= sum_i w_i |cb_i| |r_i' - rc'|`` (the
  same sum), so grasps moving alike turn the payload at no rate. On ``[a, b]``,
  ``|z| >= (|z(a)| + |z(b)| - h |z'|max) / 2``, so the angle's rates are bounded:
  ``|theta'| <= |z'| / |z|``, ``|theta''| <= |z''| / |z| + (|z'| / |z|)^2``.
- A corner ``q`` of the outline is at ``rc + R(theta) (q - bc)``; an obstacle's vertex
  ``V`` (a post's centre, a wall's end) is at ``R(-theta) (V - rc) + bc`` in the payload's
  frame. Both have bounded second derivatives from the rates above, so on ``[a, b]``
  each stays within ``K h^2 / 8`` of its chord. Two disjoint convex sets are nearest at
  a vertex of one of them, so the gap is the least of the corners' distances to the
  obstacles and the vertices' distances to the outline's edges (``F``), and ``F`` is
  bounded below on ``[a, b]`` by the chords' distances (:mod:`.swept`'s closed forms for
  segments) less those deviations. The bound's error shrinks with ``h^2``.
- :meth:`SettledCarry.least_gap` is a branch and bound on that bound: the least ``F``
  found (attained) is within :data:`GAP_TOLERANCE` of the least (parts that cannot come
  below a given level are not refined; a contact ends the search: its depth is not
  wanted). :meth:`SettledCarry.first_contact` splits from the start, leftmost first,
  discarding parts whose bound stays above :data:`CONTACT_TOLERANCE`: no part before
  the fraction it returns comes within that of contact, and it is within it of contact
  or within :data:`FRACTION_TOLERANCE` (of the piece) of a part that may be. A wall's
  distance is not signed (a corner crossing a wall takes ``F`` to 0 and up again), so a
  least ``F`` within :data:`GAP_TOLERANCE` of 0 is settled by that search: a contact,
  or none.

``F`` equals the gap while the outline and the obstacles are apart, and the two start
apart (:func:`~.swept_payload.overlapping` checks the start): to overlap later they first
touch, where ``F`` is 0. Where the orientation is nearly undetermined (``|z|`` not bounded
away from 0 on parts narrower than :data:`FRACTION_TOLERANCE`: the grasps' robot points
nearly on one point) the angle's rate has no bound and the piece is left to the instants
(:meth:`SettledCarry.least_gap` gives None). Everything is on Python floats: the caller
asks only where a cheap bound leaves room for a gap below the least so far.
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Sequence
from typing import NamedTuple

from hybridteam.world.settle_one import equilibrium_one
from hybridteam.world.swept import Piece, least_gap, piece, point_gap, segment_distance
from hybridteam.world.swept_payload import Point, Segment, outline, overlapping

#: Absolute tolerance (m) of the least gap: the value returned is attained and at most this
#: above the least one. (A payload riding at its least gap so far, a beam sliding past a
#: wall's end, must be bounded to the tolerance on every piece: 1e-6 m takes one chord
#: bound per piece where 1e-9 m took dozens of splits.)
GAP_TOLERANCE = 1e-6
#: Absolute tolerance (m) of the first contact: the gap there is at most this.
CONTACT_TOLERANCE = 1e-10
#: The narrowest part of a piece the searches split to (a fraction of the piece).
FRACTION_TOLERANCE = 1e-12


class Grip(NamedTuple):
    """A holding grasp's robot point over a piece: the robot's centre on ``path``, its
    heading turning from ``theta0`` to ``theta1`` (by ``turn``) at a constant rate, the
    point at ``mount`` in the robot's frame; the grasp's ``body`` point and ``spring``."""

    path: Piece
    theta0: float
    theta1: float
    turn: float
    mount: Point
    body: Point
    spring: float

    def at(self, s: float) -> Point:
        """The robot point at fraction ``s``: at the ends, from the poses themselves (so a
        piece's end is the next one's start to the bit, :class:`SettledCarry`'s ``first``;
        the path through them is the same to rounding)."""
        path = self.path
        if s == 0.0:
            x, y, th = path.x0, path.y0, self.theta0
        elif s == 1.0:
            x, y, th = path.x1, path.y1, self.theta1
        else:
            x, y = path.at(s)
            th = self.theta0 + s * self.turn
        c, sn = math.cos(th), math.sin(th)
        mx, my = self.mount
        return x + c * mx - sn * my, y + sn * mx + c * my

    def velocity(self, s: float) -> Point:
        """The robot point's derivative in ``s`` at ``s``."""
        path = self.path
        if path.radius:
            phi = path.phi0 + s * path.turn
            rate = path.radius * path.turn
            vx, vy = -rate * math.sin(phi), rate * math.cos(phi)
        else:
            vx, vy = path.x1 - path.x0, path.y1 - path.y0
        th = self.theta0 + s * self.turn
        c, sn = math.cos(th), math.sin(th)
        mx, my = self.mount
        return vx - self.turn * (sn * mx + c * my), vy + self.turn * (c * mx - sn * my)

    @property
    def speed(self) -> float:
        """A bound on the robot point's speed per unit ``s``."""
        return self.path.length + abs(self.turn) * math.hypot(*self.mount)

    @property
    def bend(self) -> float:
        """A bound on the length of the robot point's second derivative in ``s``."""
        arc = self.path.radius * self.path.turn * self.path.turn if self.path.radius else 0.0
        return arc + self.turn * self.turn * math.hypot(*self.mount)


def grip(
    t0: float,
    pose0: Sequence[float],
    t1: float,
    pose1: Sequence[float],
    turning: bool,
    mount: Point,
    body: Point,
    spring: float,
) -> Grip | None:
    """A grasp's robot point from robot pose ``pose0`` at ``t0`` to ``pose1`` at ``t1``
    under a held input (a unicycle ``turning``, else a holonomic base: its centre on a
    segment, its heading turning at a constant rate); None where that is not rebuilt (a
    turn of half a revolution or more)."""
    turn = pose1[2] - pose0[2]
    if not abs(turn) < math.pi:
        return None
    path = piece(t0, pose0, t1, pose1, turning)
    if path is None:
        return None
    return Grip(path, float(pose0[2]), float(pose1[2]), turn, mount, body, spring)


class State(NamedTuple):
    """The settled payload at fraction ``s``: its corners (world), the obstacles' vertices
    in its frame, ``|z|`` and the vertices' distances to the robot points' centroid, each
    feature's distance (the corners' to the obstacles, then the vertices' to the edges)
    and ``F``, their least (the gap while apart)."""

    s: float
    pose: tuple[float, float, float]
    corners: list[Point]
    vertices: list[Point]
    z: float
    spans: list[float]
    distances: list[float]
    gap: float


class Frame(NamedTuple):
    """What a :class:`SettledCarry` needs that does not change from piece to piece while
    the same grasps hold the same payload among the same obstacles: the grasps' body
    points and springs, their total, the body points about their weighted centroid and
    each one's lever ``w |cb|``, the outline's corners and edges in the payload's frame
    and the corners' distances from the centroid (``arms``), and the obstacles with their
    vertices (``fixed``: posts' centres with their radii, walls' ends with 0)."""

    body: list[Point]
    springs: list[float]
    total: float
    centred: list[Point]
    levers: list[float]
    local: list[Point]
    edges: list[Segment]
    arms: list[float]
    circles: list[tuple[float, float, float]]
    segments: list[Segment]
    fixed: list[tuple[float, float, float]]
    half_width: float
    half_depth: float

    @classmethod
    def of(
        cls,
        body: list[Point],
        springs: list[float],
        half_width: float,
        half_depth: float,
        circles: list[tuple[float, float, float]],
        segments: list[Segment],
    ) -> Frame:
        total = math.fsum(springs)
        bcx = math.fsum(w * b[0] for w, b in zip(springs, body, strict=True)) / total
        bcy = math.fsum(w * b[1] for w, b in zip(springs, body, strict=True)) / total
        centred = [(b[0] - bcx, b[1] - bcy) for b in body]
        levers = [w * math.hypot(*cb) for w, cb in zip(springs, centred, strict=True)]
        local, edges = outline(0.0, 0.0, 0.0, half_width, half_depth)
        arms = [math.hypot(u - bcx, v - bcy) for u, v in local]
        fixed = [(x, y, r) for x, y, r in circles]
        for ax, ay, bx, by in segments:
            fixed += [(ax, ay, 0.0), (bx, by, 0.0)]
        return cls(
            body, springs, total, centred, levers, local, edges, arms, circles, segments,
            fixed, half_width, half_depth,
        )  # fmt: skip


class SettledCarry:
    """A payload held by the grips ``grips`` over one piece (see the module docstring),
    an outline of half extents ``half_width`` and ``half_depth`` (a bar: depth 0), against
    ``circles`` (x, y, r) and ``segments``."""

    def __init__(
        self,
        grips: Sequence[Grip],
        half_width: float,
        half_depth: float,
        circles: list[tuple[float, float, float]],
        segments: list[Segment],
        first: State | None = None,
        frame: Frame | None = None,
    ) -> None:
        self.grips = list(grips)
        if frame is None:
            body, springs = [g.body for g in self.grips], [g.spring for g in self.grips]
            frame = Frame.of(body, springs, half_width, half_depth, circles, segments)
        #: what does not change from piece to piece (a caller may keep it for the next)
        self.frame = frame
        self.circles, self.segments = frame.circles, frame.segments
        self.body, self.springs, self.total = frame.body, frame.springs, frame.total
        self.centred, self.local, self.edges = frame.centred, frame.local, frame.edges
        self.arms, self.fixed = frame.arms, frame.fixed
        self.half_width, self.half_depth = frame.half_width, frame.half_depth
        total, lever = frame.total, frame.levers
        #: bounds per unit s: the centroid's speed and acceleration, |z'| and |z''|
        speeds, bends = [g.speed for g in self.grips], [g.bend for g in self.grips]
        self.drift = sum(w * v for w, v in zip(self.springs, speeds, strict=True)) / total
        self.sway = sum(w * a for w, a in zip(self.springs, bends, strict=True)) / total
        # |z'| <= sum_i w_i |cb_i| |r_i' - rc'| too (sum_i w_i cb_i = 0), and r_i' - rc'
        # drifts from its start by at most the two accelerations: grasps moving alike
        # (a translation) turn the payload at no rate
        starts = [g.velocity(0.0) for g in self.grips]
        ux = sum(w * v[0] for w, v in zip(self.springs, starts, strict=True)) / total
        uy = sum(w * v[1] for w, v in zip(self.springs, starts, strict=True)) / total
        self.dz = sum(
            m * min(speed, math.hypot(v[0] - ux, v[1] - uy) + bend + self.sway)
            for m, speed, bend, v in zip(lever, speeds, bends, starts, strict=True)
        )
        self.ddz = sum(m * a for m, a in zip(lever, bends, strict=True))
        #: the payload at the start: ``first`` where the caller kept the previous piece's
        #: end (the same robot points, springs and obstacles: the same numbers)
        self.first = self.state(0.0) if first is None else first._replace(s=0.0)
        self._last: State | None = None

    @property
    def last(self) -> State:
        """The payload at the end (what the next piece may start from)."""
        if self._last is None:
            self._last = self.state(1.0)
        return self._last

    def state(self, s: float) -> State:
        """The settled payload at fraction ``s`` (the run's own settling arithmetic)."""
        pts = [g.at(s) for g in self.grips]
        x, y, theta = equilibrium_one(pts, self.body, self.springs)
        w, total = self.springs, self.total
        rcx = sum(wi * p[0] for wi, p in zip(w, pts, strict=True)) / total
        rcy = sum(wi * p[1] for wi, p in zip(w, pts, strict=True)) / total
        dot = cross = 0.0
        for wi, (cx, cy), (px, py) in zip(w, self.centred, pts, strict=True):
            dot += wi * (cx * (px - rcx) + cy * (py - rcy))
            cross += wi * (cx * (py - rcy) - cy * (px - rcx))
        c, sn = math.cos(theta), math.sin(theta)
        corners = [(x + c * u - sn * v, y + sn * u + c * v) for u, v in self.local]
        vertices = []
        for qx, qy, _ in self.fixed:
            dx, dy = qx - x, qy - y
            vertices.append((c * dx + sn * dy, -sn * dx + c * dy))
        spans = [math.hypot(qx - rcx, qy - rcy) for qx, qy, _ in self.fixed]
        distances = [point_gap(px, py, self.circles, self.segments) for px, py in corners]
        for (vx, vy), (_, _, r) in zip(vertices, self.fixed, strict=True):
            distances.append(point_gap(vx, vy, (), self.edges) - r)
        gap = min(distances, default=math.inf)
        z = math.hypot(dot, cross)
        return State(s, (x, y, theta), corners, vertices, z, spans, distances, gap)

    def lower(self, a: State, b: State) -> float:
        """A lower bound on ``F`` over ``[a.s, b.s]`` (-inf where ``|z|`` has none)."""
        h = b.s - a.s
        zmin = 0.5 * (a.z + b.z - h * self.dz)
        if not zmin > 0.0:
            return -math.inf
        rate = self.dz / zmin
        turning = self.ddz / zmin + 2.0 * rate * rate  # |theta''| + theta'^2
        shrink = h * h / 8.0
        # each feature: its chord's ends, its bend allowance, and its distance at both ends
        # less half the chord (no nearer in between, the chord being that long): the
        # chord's exact distance only where that leaves it below the least so far
        features = []
        for arm, p, q in zip(self.arms, a.corners, b.corners, strict=True):
            features.append((p, q, (self.sway + turning * arm) * shrink, 0.0, -1))
        for k, ((_, _, r), p, q, sa, sb) in enumerate(
            zip(self.fixed, a.vertices, b.vertices, a.spans, b.spans, strict=True)
        ):
            span = 0.5 * (sa + sb + h * self.drift)  # (|V - rc| on the part)
            bend = self.sway + 2.0 * rate * self.drift + turning * span
            features.append((p, q, bend * shrink, r, k))
        rough = []
        for (p, q, allow, _, _), da, db in zip(features, a.distances, b.distances, strict=True):
            rough.append(0.5 * (da + db - math.hypot(q[0] - p[0], q[1] - p[1])) - allow)
        out = math.inf
        ranked = sorted(zip(rough, features, strict=True), key=lambda f: f[0])
        for low, (p, q, allow, r, k) in ranked:
            if not low < out:
                break
            chord = Piece(0.0, 0.0, p[0], p[1], q[0], q[1])
            if k < 0:
                near = least_gap(chord, self.circles, self.segments)[0]
            else:
                near = min(segment_distance(chord, edge)[0] for edge in self.edges) - r
            out = min(out, near - allow)
        return out

    def overlapping_at_start(self) -> bool:
        """Whether the outline already meets an obstacle at the start where ``F`` does not
        say so (:func:`~.swept_payload.overlapping`)."""
        _, edges = outline(*self.first.pose, self.half_width, self.half_depth)
        return overlapping(edges, self.circles, self.segments)

    def least_gap(self, below: float = math.inf, apart: bool = False) -> tuple[float, float] | None:
        """The least gap over the piece (0 where they meet) and the fraction where it is
        reached: attained, and within :data:`GAP_TOLERANCE` of the least where that is
        below ``below`` less the tolerance (elsewhere: none is). None where
        the orientation's rate has no bound (module docstring). With ``apart`` the caller
        knows the outline starts clear of the obstacles (no overlap to check)."""
        if not apart and self.overlapping_at_start():
            return 0.0, 0.0
        first, last = self.first, self.last
        best = min((first.gap, 0.0), (last.gap, 1.0))
        bound = self.lower(first, last)
        heap = [(bound, 0.0, first, last)]
        if not (bound < best[0] - GAP_TOLERANCE and bound < below - GAP_TOLERANCE):
            heap = []  # (a piece whose chords keep it clear: nearly every one)
        while heap and best[0] > 0.0:
            low, _, a, b = heapq.heappop(heap)
            if best[0] - low <= GAP_TOLERANCE:
                break
            if b.s - a.s <= FRACTION_TOLERANCE:
                return None
            mid = self.state(0.5 * (a.s + b.s))
            best = min(best, (mid.gap, mid.s))
            for lo, hi in ((a, mid), (mid, b)):
                bound = self.lower(lo, hi)
                if bound < best[0] - GAP_TOLERANCE and bound < below - GAP_TOLERANCE:
                    heapq.heappush(heap, (bound, lo.s, lo, hi))
        if 0.0 < best[0] <= GAP_TOLERANCE:  # (a wall's distance is not signed: F touches
            found = self._touch(last)  # 0 where a corner crosses it; is there a contact?)
            if found is not None:
                return 0.0, found
        return max(best[0], 0.0), best[1]

    def first_contact(self, before: float) -> float:
        """The first fraction where the outline touches an obstacle, given that it does by
        ``before`` (where :meth:`least_gap` found it): no contact comes earlier."""
        if self.overlapping_at_start():
            return 0.0
        found = self._touch(self.last if before == 1.0 else self.state(before))
        return before if found is None else found

    def _touch(self, end: State) -> float | None:
        """The first fraction up to ``end`` within :data:`CONTACT_TOLERANCE` of contact,
        or at the start of a part narrower than :data:`FRACTION_TOLERANCE` the bound
        cannot keep that far apart; None where the bound keeps every part so: split from
        the start, leftmost first, so every part before the fraction returned was kept
        apart. (A corner passing a wall's end exactly, into the box, comes within
        rounding of contact, not to a sign change: a tolerance is what catches it.)"""
        stack = [(self.first, end)]
        while stack:
            a, b = stack.pop()
            if a.gap <= CONTACT_TOLERANCE:
                return a.s
            if self.lower(a, b) > CONTACT_TOLERANCE:  # (a part that stays clear)
                continue
            if b.s - a.s <= FRACTION_TOLERANCE:
                return a.s
            mid = self.state(0.5 * (a.s + b.s))
            stack += [(mid, b), (a, mid)]  # (the earlier part first)
        return end.s if end.gap <= CONTACT_TOLERANCE else None
