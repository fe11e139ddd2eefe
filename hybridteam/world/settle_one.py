"""One instance's payload settling on Python floats: a single run's instant.

:meth:`CarriedPayload._settle <hybridteam.world.carried.CarriedPayload._settle>` works on
``(m, k)`` arrays, about a hundred numpy operations an instant whatever ``m`` is. In a
single run ``m`` is 1, and each operation costs its dispatch (about 1 µs, several for the
broadcasting ones) for a handful of numbers: settling was a sixth of experiment 2's run.

Here the same IEEE operations run in the same order on Python floats (the array
version's evaluation order, written out: ``a + b * c - d * e`` is ``(a + b*c) - d*e``),
and the sines, cosines and arctangents are numpy's own (``np.sin`` of a float runs the
array loop), so every number equals the array version's bit for bit; the tests compare
the two.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from hybridteam.world.access import WorldAccess
    from hybridteam.world.carried import CarriedPayload


def _cos_sin(angle: float) -> tuple[float, float]:
    return float(np.cos(angle)), float(np.sin(angle))


def _weighted(values: list[float], weights: list[float]) -> float:
    """sum_i w_i v_i, left to right (payload._weighted_sum's order)."""
    acc = weights[0] * values[0]
    for w, v in zip(weights[1:], values[1:], strict=True):
        acc = acc + w * v
    return acc


def equilibrium_one(pts: list[tuple[float, float]], body: list[tuple[float, float]],
                    springs: list[float]) -> tuple[float, float, float]:
    """:func:`~hybridteam.world.payload.equilibrium` of one payload (no offsets):
    ``(x, y, theta)``."""
    total = springs[0]
    for w in springs[1:]:
        total = total + w
    rcx = _weighted([p[0] for p in pts], springs) / total
    rcy = _weighted([p[1] for p in pts], springs) / total
    bcx = _weighted([b[0] for b in body], springs) / total
    bcy = _weighted([b[1] for b in body], springs) / total
    rx, ry = [p[0] - rcx for p in pts], [p[1] - rcy for p in pts]
    bx, by = [b[0] - bcx for b in body], [b[1] - bcy for b in body]
    dot = _weighted([bx[i] * rx[i] + by[i] * ry[i] for i in range(len(pts))], springs)
    cross = _weighted([bx[i] * ry[i] - by[i] * rx[i] for i in range(len(pts))], springs)
    theta = float(np.arctan2(cross, dot))
    c, s = _cos_sin(theta)
    return rcx - (c * bcx - s * bcy), rcy - (s * bcx + c * bcy), theta


def settle_one(payload: CarriedPayload, world: WorldAccess, idx: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``payload._settle(world, idx)`` for one instance (``idx`` of size 1): updates the
    component's pose, rest, engagement, offsets and arm readings of that instance and
    returns the headings ``(1, k)``, offsets ``(1, k, 2)`` and engagement ``(1, k)``."""
    i = int(idx[0])
    agents = payload.agents
    mounts = payload.mount.tolist()
    body = payload.body.tolist()
    pts, heading = [], []
    for a, (mx, my) in zip(agents, mounts, strict=True):
        px, py, th = world.pose(a, idx)[0].tolist()
        c, s = _cos_sin(th)
        pts.append((px + c * mx - s * my, py + s * mx + c * my))
        heading.append(th)
    on = [True if name is None else bool(world.variable(a, name, idx)[0] > 0.5)
          for a, name in zip(agents, payload.engaged_by, strict=True)]
    held = payload._held(sum(1 << k for k, yes in enumerate(on) if yes)).tolist()
    x, y, theta = payload.rest[i].tolist()
    if len(held) == 1:  # no torque: keep the angle, follow the grasp point
        (j,) = held
        cs, sn = _cos_sin(theta)
        bx, by = body[j]
        x, y = pts[j][0] - (cs * bx - sn * by), pts[j][1] - (sn * bx + cs * by)
    elif len(held) > 1:
        springs = payload.spring.tolist()
        x, y, theta = equilibrium_one([pts[j] for j in held], [body[j] for j in held],
                                      [springs[j] for j in held])
    payload.pose[i] = payload.rest[i] = (x, y, theta)
    payload.engaged[i] = on
    c, s = _cos_sin(theta)
    offsets = [(p[0] - (c * bx - s * by + x), p[1] - (s * bx + c * by + y))
               for p, (bx, by) in zip(pts, body, strict=True)]
    arm = []
    for (ox, oy), th, r0 in zip(offsets, heading, payload.rel0[i].tolist(), strict=True):
        ch, sh = _cos_sin(th)
        rel = theta - th - r0
        arm.append((ch * ox + sh * oy, -sh * ox + ch * oy,
                    float(np.arctan2(np.sin(rel), np.cos(rel)))))
    payload.offset[i] = offsets
    payload.arm[i] = arm
    return np.array([heading]), np.array([offsets]), np.array([on])
