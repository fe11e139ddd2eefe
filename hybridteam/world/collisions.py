"""Collisions, judged by the ``obstacles`` component: robots against static obstacles and
against each other (their footprint disks), payloads against static obstacles.

A robot that drives through a wall is a failed run, not an ``ok`` one with a negative
clearance in its statistics. At every instant the ``obstacles`` component measures the
gaps it already keeps statistics of; an overlap is a collision, handled by its
``on_collision`` setting:

- ``outcome`` (default): the instance ends with outcome ``collision`` and a message naming
  who hit what, when and by how much;
- ``warn``: the run goes on, and ``summary.json`` lists each robot's first collision
  (``collisions``); the trace records where and when (``meta.world.collisions``, also
  under ``outcome``) for the views to mark;
- ``ignore``: only the clearance statistics.

Like every judgment of a world component it is reported at the robot's sensing
instants (its law ticks), at most one control period late; a robot's footprint against
the static obstacles is judged over its motion between instants too
(:mod:`hybridteam.world.swept`), so one fast enough to cross a thin wall between two
ticks collides, at its first contact; two such robots are judged against each other over
it too (:mod:`hybridteam.world.swept_pair`), so robots crossing each other's paths between
ticks collide, and so is a payload held by one grasp of such a robot
(:mod:`hybridteam.world.swept_payload`).
"""

from __future__ import annotations

import functools

import numpy as np

MODES = ("outcome", "warn", "ignore")


def robot_overlaps(points: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """How far each pair of robots' footprints overlap: ``(m, R, R)``, > 0 where they do.

    ``points`` is ``(R, m, 2)``. Robots without a footprint (radius 0) collide with
    nobody: a point cannot be hit.
    """
    d = points[:, None] - points[None, :]  # (R, R, m, 2)
    dist = np.hypot(d[..., 0], d[..., 1])  # (R, R, m)
    reach = radius[:, None] + radius[None, :]
    overlap = (reach[..., None] - dist).transpose(2, 0, 1)  # (m, R, R)
    solid = (radius[:, None] > 0) & (radius[None, :] > 0) & _others(len(radius))
    return np.where(solid[None], overlap, -np.inf)


@functools.lru_cache(maxsize=16)
def _others(count: int) -> np.ndarray:
    """``(count, count)``: True off the diagonal (every pair of two different robots);
    read-only, built once per team size rather than at every instant."""
    out = ~np.eye(count, dtype=bool)
    out.flags.writeable = False
    return out


def box_sdf(points: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """Signed distance from each point ``(P, 2)`` to the nearest box ``[cx, cy, width,
    depth, theta_rad]``: ``(P,)``, < 0 inside."""
    dx = points[:, 0:1] - boxes[:, 0]
    dy = points[:, 1:2] - boxes[:, 1]
    c, s = np.cos(boxes[:, 4]), np.sin(boxes[:, 4])
    qx = np.abs(c * dx + s * dy) - boxes[:, 2] / 2.0
    qy = np.abs(-s * dx + c * dy) - boxes[:, 3] / 2.0
    outside = np.hypot(np.maximum(qx, 0.0), np.maximum(qy, 0.0))
    return np.minimum.reduce(outside + np.minimum(np.maximum(qx, qy), 0.0), axis=1)


def name_hit(point: np.ndarray, walls: np.ndarray, circles: np.ndarray, boxes: np.ndarray) -> str:
    """The static obstacle nearest to ``point`` (what a robot there has hit), as the team
    file lists it: ``walls[0]``, ``circles[2]``, ``boxes[1]``."""
    found: list[tuple[float, str]] = []
    for k, (x0, y0, x1, y1) in enumerate(walls):
        a, ab = np.array([x0, y0]), np.array([x1 - x0, y1 - y0])
        t = np.clip(np.dot(point - a, ab) / max(float(np.dot(ab, ab)), 1e-300), 0.0, 1.0)
        found.append((float(np.hypot(*(a + t * ab - point))), f"walls[{k}]"))
    for k, (x, y, r) in enumerate(circles):
        found.append((float(np.hypot(point[0] - x, point[1] - y) - r), f"circles[{k}]"))
    for k, box in enumerate(boxes):
        found.append((float(box_sdf(point[None], box[None])[0]), f"boxes[{k}]"))
    return min(found)[1] if found else "an obstacle"
