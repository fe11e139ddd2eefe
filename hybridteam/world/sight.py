"""Bounds on what a range ring reads of a box payload, without casting: a detect rule's
verdict where the bounds settle it, kept while the ring moves little relative to the box.

A ``detect`` rule asks one question of its ring at each sensing instant: does some beam
read below the threshold? The ``obstacles`` component answers it by casting the beams
(:func:`~hybridteam.world.raycast.cast_at`) against the static obstacles and every
payload's outline — about 60 numpy calls, most of a single run's sensing instant when the
robot carries a box its ring sees (experiment 2's XR4000 casts at every tick for verdicts
that change a handful of times in the run). The static obstacles are usually settled
without casting (the robot's clearance bounds every beam from below); a carried box never
was.

Here each ray meets two boxes in the payload's frame: the outline grown by a margin and
shrunk by it (:func:`box_reading_bounds`). Where the ray enters the grown box bounds the
cast's reading from below (the cast's own tolerances and the rounding of both
computations are far inside the margin), where it enters the shrunk box from above (a ray
that goes that deep has crossed the outline before). A beam whose upper bound is below a
threshold surely reads below it; one whose lower bound is at least the threshold (the
static obstacles beyond it too) surely does not. Only where a bound falls within the
margin of a threshold is a verdict open, and the component casts as before: the verdicts,
hence the events and the trace, are the cast's own.

A verdict proved with margin ``m`` still holds while every point of the rays up to the
threshold has moved less than ``m / 2`` relative to the box — a point at depth ``m``
inside the outline is still inside it, a segment ``m`` away from it still misses it — so
the component keeps its verdicts while the ring's pose in the box's frame has moved less
than :func:`kept_for` allows (:func:`motion`): a carried box moves a few micrometres
relative to its carrier between two ticks, and its verdicts cost a comparison on floats.
"""

from __future__ import annotations

import math

import numpy as np

from hybridteam.world.sensors import RangeRing

#: The margin of the grown and shrunk boxes, relative to the box's size (``1 +`` its half
#: extents): far above the cast's tolerances (``1e-9`` of a segment's length for
#: near-parallel rays, ``1e-10`` along it, ``1e-14`` of rounding) and below where
#: thresholds are set (a millimetre against the tenths of a metre of a detect rule).
MARGIN = 1e-3

#: A pose ``(x, y, theta)`` on Python floats
Pose = tuple[float, float, float]


def relative_pose(robot: Pose, box: Pose) -> Pose:
    """A robot's pose ``(x, y, theta)`` in the frame of a box at ``box`` (the heading
    difference not wrapped: :func:`motion` bounds a rotation by it either way)."""
    c, s = math.cos(box[2]), math.sin(box[2])
    dx, dy = robot[0] - box[0], robot[1] - box[1]
    return (c * dx + s * dy, c * dy - s * dx, robot[2] - box[2])


def motion(before: Pose, after: Pose, reach: float) -> float:
    """How far any point of a ray at most ``reach`` from the robot's centre (its mount
    radius plus the distance along the ray) moves in the box's frame when the robot's pose
    there goes from ``before`` to ``after``: at most the centre's displacement plus the
    arc ``reach |d theta|`` (a chord is no longer than its arc)."""
    return math.hypot(after[0] - before[0], after[1] - before[1]) + reach * abs(
        after[2] - before[2]
    )


def kept_for(half_width: float, half_depth: float) -> float:
    """How far (:func:`motion`) the rays may move relative to a box of these half extents
    and keep the verdicts its bounds proved: a quarter of the margin, so that what is left
    (a quarter of it) still dwarfs the cast's tolerances."""
    return MARGIN * (1.0 + half_width + half_depth) / 4.0


def box_reading_bounds(
    ring: RangeRing,
    beams: np.ndarray,
    pose: Pose,
    half_width: float,
    half_depth: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper bounds on where each of ``beams`` of ``ring``, on a robot at
    ``pose`` in the frame of a box with half extents ``half_width``, ``half_depth``
    (:func:`relative_pose`), meets the box's outline: two ``(len(beams),)`` arrays, inf
    where the beam surely misses it (lower) or may miss it (upper). A ray that starts
    within the grown box is left open (lower 0, upper inf): from inside, the cast reads
    where the ray leaves the box. A beam of several rays (a sonar cone) reads its nearest
    ray. Clipping to ``[min_range, max_range]`` is the caller's.
    """
    lx, ly, dx, dy = ring.local_rays(beams)  # (1, R) each, robot frame
    x, y, turn = pose
    ct, st = math.cos(turn), math.sin(turn)
    ox, oy = x + (ct * lx - st * ly), y + (st * lx + ct * ly)
    ux, uy = ct * dx - st * dy, st * dx + ct * dy
    margin = MARGIN * (1.0 + half_width + half_depth)
    outside = (np.abs(ox) > half_width + margin) | (np.abs(oy) > half_depth + margin)
    # the slabs of the grown box (row 0) and the shrunk one (row 1) at once: (2, R)
    wx = np.array([[half_width + margin], [half_width - margin]])
    wy = np.array([[half_depth + margin], [half_depth - margin]])
    with np.errstate(divide="ignore", invalid="ignore"):  # a ray along an axis of the box:
        inv_x, inv_y = 1.0 / ux, 1.0 / uy  # its slab is everything or nothing (+-inf) ...
        ax, bx = (-wx - ox) * inv_x, (wx - ox) * inv_x
        ay, by = (-wy - oy) * inv_y, (wy - oy) * inv_y
    enter = np.maximum(np.minimum(ax, bx), np.minimum(ay, by))
    leave = np.minimum(np.maximum(ax, bx), np.maximum(ay, by))
    meets = (enter <= leave) & (leave >= 0.0)
    # ... or NaN where it runs along a slab's edge: open
    sure = outside & ~np.isnan(enter[0] + leave[0])
    lower = np.where(sure, np.where(meets[0], enter[0], np.inf), 0.0)[0]
    shrunk = half_width > margin and half_depth > margin  # (else it proves nothing)
    upper = np.where(sure & meets[1] & shrunk, enter[1], np.inf)[0]
    if ring.rays_per_beam > 1:
        shape = (beams.size, ring.rays_per_beam)
        lower = np.minimum.reduce(lower.reshape(shape), axis=1)
        upper = np.minimum.reduce(upper.reshape(shape), axis=1)
    return lower, upper
