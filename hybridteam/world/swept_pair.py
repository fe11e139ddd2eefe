"""Two robots against each other over their motion between two instants: the swept pair.

Every instant ends every swept robot's piece of held motion (:mod:`.swept`), so two swept
robots' pieces span the same interval, and their centres' separation over it is
``D(s) = pa(s) - pb(s)`` for ``s`` in ``[0, 1]``; their footprints touch where ``|D(s)|``
reaches the sum of their radii.

Two segments (straight drives, a parked robot): ``D`` is linear in ``s``, the relative
motion a segment itself, and its least distance to the origin and its first crossing of a
circle are :mod:`.swept`'s closed forms (a quadratic). An arc with anything has no closed
form in general (the separation of two points on two circles turning at different rates),
so it is bounded instead, with a stated tolerance rather than by sampling more:

- ``D''`` is at most ``K = La |turn_a| + Lb |turn_b|`` long (an arc of radius ``r`` turning
  by ``turn`` over the unit interval accelerates by ``r turn^2``), so on ``[a, b]`` the
  motion stays within ``K (s - a)(b - s) / 2 <= K h^2 / 8`` of the chord between ``D(a)``
  and ``D(b)``: ``|D| >= dist(0, chord) - K h^2 / 8`` there. The least gap
  (:func:`least_separation`) is a branch and bound on that bound: the interval with the
  lowest bound is split until the least distance found (an attained one) is within
  :data:`GAP_TOLERANCE` of the lowest bound left (parts that cannot come within the
  contact distance are not split: only a contact's depth needs the tolerance). The
  bound's error shrinks with ``h^2``, so a minimum takes about a dozen halvings.
- ``f = |D|`` has ``f'' >= -K`` (``f + K s^2 / 2`` is convex), so
  ``f(s + tau) >= f(s) + tau f'(s) - K tau^2 / 2``: advancing ``s`` to that parabola's first
  reach of the contact distance (or by ``(f - reach) / (La + Lb)``, the Lipschitz step,
  whichever is longer) never passes a contact. :func:`first_touch` advances so until the
  gap is within :data:`CONTACT_TOLERANCE` of contact: no contact comes before the fraction
  it returns.

So a contact deeper than :data:`GAP_TOLERANCE` is never missed, a shallower graze may be,
and a reported first contact is at most ``CONTACT_TOLERANCE`` (in distance) short of the
exact one. Everything is on Python floats: the caller asks only where the end gaps leave
room for a contact (:func:`may_touch`), a rare instant.
"""

from __future__ import annotations

import heapq
import math

from hybridteam.world.swept import Piece, line_circle_roots, point_distance

#: Absolute tolerance (m) of an arc pair's least separation: the value returned is attained
#: and at most this above the true least one.
GAP_TOLERANCE = 1e-9
#: Absolute tolerance (m) of an arc pair's first contact: the separation there is at most
#: this above the contact distance, and nowhere before it is it at or below that distance.
CONTACT_TOLERANCE = 1e-10


def may_touch(d0: float, d1: float, length: float, reach: float) -> bool:
    """Whether two pieces whose centres are ``d0`` and ``d1`` apart at their ends and that
    are ``length`` long together may come within ``reach`` of each other in between: the
    separation changes no faster than ``length`` per unit ``s``, so it stays at least
    ``(d0 + d1 - length) / 2``."""
    return 0.5 * (d0 + d1 - length) - reach <= 0.0


def _velocity(p: Piece, s: float) -> tuple[float, float]:
    """The piece's derivative in ``s`` at ``s``."""
    if p.radius:
        phi = p.phi0 + s * p.turn
        rate = p.radius * p.turn
        return -rate * math.sin(phi), rate * math.cos(phi)
    return p.x1 - p.x0, p.y1 - p.y0


def _bend(p: Piece) -> float:
    """A bound on the length of the piece's second derivative in ``s``."""
    return p.radius * p.turn * p.turn if p.radius else 0.0


def _separation(pa: Piece, pb: Piece, s: float) -> tuple[float, float]:
    (xa, ya), (xb, yb) = pa.at(s), pb.at(s)
    return xa - xb, ya - yb


def _relative_segment(pa: Piece, pb: Piece) -> Piece:
    """Two segments' relative motion ``pa - pb``: a segment (``t0``, ``t1`` kept)."""
    return Piece(pa.t0, pa.t1, pa.x0 - pb.x0, pa.y0 - pb.y0, pa.x1 - pb.x1, pa.y1 - pb.y1)


def _chord_nearest(da: tuple[float, float], db: tuple[float, float]) -> tuple[float, float]:
    """The distance from the origin to the segment ``da``-``db`` and the fraction of it
    where it is reached."""
    ex, ey = db[0] - da[0], db[1] - da[1]
    length2 = ex * ex + ey * ey
    u = 0.0 if length2 == 0.0 else min(1.0, max(0.0, -(da[0] * ex + da[1] * ey) / length2))
    return math.hypot(da[0] + u * ex, da[1] + u * ey), u


def least_separation(pa: Piece, pb: Piece, below: float = math.inf) -> tuple[float, float]:
    """The least distance between the centres moving on ``pa`` and ``pb`` (the same
    interval) and the fraction where it is reached: exact for two segments, else attained
    and within :data:`GAP_TOLERANCE` of the least (module docstring) where that is below
    ``below``; where it is not, an attained distance, and none below ``below`` less the
    tolerance. (Parts of the motion that stay ``below`` apart are not refined: two robots
    turning side by side at a constant distance would otherwise be bisected to the
    tolerance all along.)"""
    if not pa.radius and not pb.radius:
        return point_distance(_relative_segment(pa, pb), 0.0, 0.0)
    bend = _bend(pa) + _bend(pb)
    d0, d1 = _separation(pa, pb, 0.0), _separation(pa, pb, 1.0)
    best = min((math.hypot(*d0), 0.0), (math.hypot(*d1), 1.0))
    heap = [(-math.inf, 0.0, 1.0, d0, d1)]
    while heap:
        lower, a, b, da, db = heapq.heappop(heap)
        if best[0] - lower <= GAP_TOLERANCE:
            break
        m = 0.5 * (a + b)
        dm = _separation(pa, pb, m)
        best = min(best, (math.hypot(*dm), m))
        for lo, hi, dlo, dhi in ((a, m, da, dm), (m, b, dm, db)):
            near, u = _chord_nearest(dlo, dhi)
            h = hi - lo
            s = lo + u * h
            best = min(best, (math.hypot(*_separation(pa, pb, s)), s))
            bound = near - bend * h * h / 8.0
            if bound < best[0] - GAP_TOLERANCE and bound < below:
                heapq.heappush(heap, (bound, lo, hi, dlo, dhi))
    return best


def first_touch(pa: Piece, pb: Piece, reach: float, before: float = 1.0) -> float:
    """The first fraction where the centres on ``pa`` and ``pb`` come within ``reach``,
    given that they do by ``before`` (a fraction where they are, such as
    :func:`least_separation`'s): 0 where they already are at the start; exact for two
    segments, else within :data:`CONTACT_TOLERANCE` of contact with none earlier."""
    d = _separation(pa, pb, 0.0)
    if math.hypot(*d) <= reach:
        return 0.0
    if not pa.radius and not pb.radius:
        roots = line_circle_roots(_relative_segment(pa, pb), 0.0, 0.0, reach)
        return min(roots, default=before)
    bend = _bend(pa) + _bend(pb)
    speed = pa.length + pb.length
    s = 0.0
    while True:
        dx, dy = _separation(pa, pb, s)
        f = math.hypot(dx, dy)
        gap = f - reach
        if gap <= CONTACT_TOLERANCE:
            return s
        (vax, vay), (vbx, vby) = _velocity(pa, s), _velocity(pb, s)
        slope = (dx * (vax - vbx) + dy * (vay - vby)) / f
        step = gap / speed  # (Lipschitz; the parabola's first root, below, is often longer)
        if bend > 0.0:
            step = max(step, 2.0 * gap / (math.sqrt(slope * slope + 2.0 * bend * gap) - slope))
        elif slope < 0.0:
            step = max(step, gap / -slope)
        if not s + step > s or s + step >= before:  # (rounding: no safe step left)
            return min(s + step, before)
        s += step
