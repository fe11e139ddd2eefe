"""One instance's clearances on Python floats, where the static obstacles are circles: a
single run's sensing instant.

:meth:`Obstacles._measure <hybridteam.world.obstacles.Obstacles._measure>` measures every
planar robot's centre clearance, the robots' footprint overlaps and every payload's gap
on ``(R, m)`` arrays: about ninety numpy operations an instant whatever ``m`` is, for a
handful of numbers in a single run — after the rule verdicts stopped casting, the largest
part of a transport experiment's world. A scene of posts (circles, no walls or boxes) has
gaps simple enough to take here on floats: the same IEEE operations in the same order,
numpy's own ``hypot``, ``cos`` and ``sin`` on each number, and numpy's ``minimum`` and
``maximum`` (NaN first, the later operand on a tie), so every number equals the array
version's; the tests compare the two. Where a gap shows a collision this path records
nothing and the array version measures again and reports it (a rare instant, whose
message and mark it alone writes). Anyone editing ``_measure``, ``clearance``,
``robot_overlaps`` or ``CarriedPayload.gap`` for circles must edit this twin too.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from hybridteam.world.access import WorldAccess

if TYPE_CHECKING:
    from hybridteam.world.obstacles import Obstacles, Scene


def _min(a: float, b: float) -> float:
    """``np.minimum`` of two floats: ``a`` if it is smaller or NaN, else ``b``."""
    return a if a < b or a != a else b


def _max(a: float, b: float) -> float:
    """``np.maximum`` of two floats."""
    return a if a > b or a != a else b


def _cos_sin(angle: float) -> tuple[float, float]:
    return float(np.cos(angle)), float(np.sin(angle))


def measure_one(
    obs: Obstacles,
    world: WorldAccess,
    idx: np.ndarray,
    scene: Scene,
    sensing: dict[int, np.ndarray] | None,
) -> dict[int, np.ndarray] | None:
    """``obs._measure(world, idx, scene, sensing)`` for one instance (``idx`` of size 1) of
    a scene of circles only, without ``clearance`` series: updates the running minima and
    returns each planar robot's centre clearance ``(1,)``; None, having changed nothing,
    where some judged gap is a collision (the array version reports it)."""
    i = idx.item(0)
    circles = scene.circles.tolist()
    robots = obs.planar
    radius = obs.radius.tolist()
    senses = [True if sensing is None else bool(sensing[a].item(0)) for a in robots]
    points = [world.pose(a, idx)[0].tolist() for a in robots]
    centre = []
    for x, y, _ in points:  # sensors.clearance: the nearest circle's edge, NaN none
        gap = math.inf
        for cx, cy, r in circles:
            dx, dy = x - cx, y - cy
            d = math.sqrt(dx * dx + dy * dy) - r
            gap = _min(gap, math.inf if d != d else d)
        centre.append(_min(math.inf, gap) - 0.0)
    judged = [g - r if own else math.inf for g, r, own in zip(centre, radius, senses, strict=True)]
    if any(j < 0 for j in judged):
        return None
    for r1 in range(len(robots)):  # collisions.robot_overlaps, pairs where either senses
        for r2 in range(r1 + 1, len(robots)):
            if radius[r1] > 0 and radius[r2] > 0 and (senses[r1] or senses[r2]):
                (x1, y1, _), (x2, y2, _) = points[r1], points[r2]
                dist = float(np.hypot(x1 - x2, y1 - y2))
                if (radius[r1] + radius[r2]) - dist > 0:
                    return None
    payload, measured = [], []  # (judged: inf where no carrier senses)
    for p in obs.payloads:  # CarriedPayload.gap against circles (no segments)
        carried = sensing is None or any(sensing[a].item(0) for a in p.agents)
        if not carried:
            payload.append(math.inf)
            continue
        measured.append(p)
        px, py, th = p.pose[i].tolist()
        hw, hd = (float(h[0]) for h in p.half_extents(idx))
        c, s = _cos_sin(th)
        gap = math.inf
        for cx, cy, r in circles:
            dx, dy = cx - px, cy - py
            bx, by = c * dx + s * dy, -s * dx + c * dy
            box = float(np.hypot(_max(abs(bx) - hw, 0.0), _max(abs(by) - hd, 0.0)))
            gap = _min(gap, _max(box - r, 0.0))
        gap = _min(math.inf, gap)
        if gap <= 0:
            return None
        payload.append(gap)
    for r, j in enumerate(judged):
        obs.min_clear[r, i] = _min(obs.min_clear[r, i].item(), j)
    for k, gap in enumerate(payload):
        obs.payload_clear[i] = _min(obs.payload_clear[i].item(), gap)
        if obs.settled_last and gap < math.inf:
            obs.note_settled_gap(k, i, world.t.item(i), gap)
    for p in measured:  # (its counter: a gap measured)
        p.work.gaps += 1
    return {a: np.array([g]) for a, g in zip(robots, centre, strict=True)}
