"""One instance's payload settling on Python floats: a single run's instant.

:meth:`CarriedPayload._settle <hybridteam.world.carried.CarriedPayload._settle>` works on
``(m, k)`` arrays, about a hundred numpy operations an instant whatever ``m`` is. In a
single run ``m`` is 1, and each operation costs its dispatch (about 1 µs, several for the
broadcasting ones) for a handful of numbers: settling was a sixth of experiment 2's run.

Here the same IEEE operations run in the same order on Python floats (the array
version's evaluation order, written out: ``a + b * c - d * e`` is ``(a + b*c) - d*e``),
and the sines, cosines and arctangents are numpy's own (``np.sin`` of a float runs the
array loop), so every number equals the array version's bit for bit; the tests compare
the two. The spring equilibrium is not written here: its float form is generated from
:func:`~hybridteam.world.payload.equilibrium_pose`, the array version's own source.
Anyone editing the rest of ``_settle`` must edit this twin too.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from hybridteam.floatpaths import float_form
from hybridteam.world.payload import equilibrium_pose

if TYPE_CHECKING:
    from hybridteam.world.access import WorldAccess
    from hybridteam.world.carried import CarriedPayload


def _cos_sin(angle: float) -> tuple[float, float]:
    return float(np.cos(angle)), float(np.sin(angle))


#: :func:`~hybridteam.world.payload.equilibrium_pose` of one payload, generated from its
#: source (:func:`~hybridteam.floatpaths.float_form`)
_pose_on_floats = float_form(equilibrium_pose)


def equilibrium_one(
    pts: list[tuple[float, float]], body: list[tuple[float, float]], springs: list[float]
) -> tuple[float, float, float]:
    """:func:`~hybridteam.world.payload.equilibrium` of one payload (no offsets):
    ``(x, y, theta)``."""
    x, y, theta, _, _ = _pose_on_floats(
        [p[0] for p in pts],
        [p[1] for p in pts],
        [b[0] for b in body],
        [b[1] for b in body],
        springs,
    )
    return x, y, theta


def settle_one(
    payload: CarriedPayload, world: WorldAccess, idx: np.ndarray
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
    on = [
        True if name is None else bool(world.variable(a, name, idx)[0] > 0.5)
        for a, name in zip(agents, payload.engaged_by, strict=True)
    ]
    held = payload._held(sum(1 << k for k, yes in enumerate(on) if yes)).tolist()
    x, y, theta = payload.rest[i].tolist()
    if len(held) == 1:  # no torque: keep the angle, follow the grasp point
        (j,) = held
        cs, sn = _cos_sin(theta)
        bx, by = body[j]
        x, y = pts[j][0] - (cs * bx - sn * by), pts[j][1] - (sn * bx + cs * by)
    elif len(held) > 1:
        springs = payload.spring.tolist()
        x, y, theta = equilibrium_one(
            [pts[j] for j in held], [body[j] for j in held], [springs[j] for j in held]
        )
    payload.pose[i] = payload.rest[i] = (x, y, theta)
    payload.engaged[i] = on
    c, s = _cos_sin(theta)
    offsets = [
        (p[0] - (c * bx - s * by + x), p[1] - (s * bx + c * by + y))
        for p, (bx, by) in zip(pts, body, strict=True)
    ]
    arm = []
    for (ox, oy), th, r0 in zip(offsets, heading, payload.rel0[i].tolist(), strict=True):
        ch, sh = _cos_sin(th)
        rel = theta - th - r0
        arm.append(
            (ch * ox + sh * oy, -sh * ox + ch * oy, float(np.arctan2(np.sin(rel), np.cos(rel))))
        )
    payload.offset[i] = offsets
    payload.arm[i] = arm
    return np.array([heading]), np.array([offsets]), np.array([on])
