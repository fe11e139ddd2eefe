"""Payloads held by compliant grasps: where a carried rigid body settles.

A payload is a rigid body with k grasp points ``b_i`` (body coordinates). Each grasp is
joined to a robot point ``r_i`` by a spring of constant ``sc_i`` (a force sensor that
gives a little, as on RIKEN's omni robots). The robots move much more slowly than the
springs settle, so we take the body to be in quasi-static equilibrium: its pose
``(p, R)`` minimizes the spring energy::

    E(p, R) = sum_i sc_i |R b_i + p - r_i|^2 ,

a weighted Procrustes problem with a closed form in 2-D: the weighted centroids coincide,
and the angle is the atan2 of the weighted cross-covariance of the centred point sets.
The *offset* of grasp i is ``r_i - (R b_i + p)``, the spring's stretch from the robot's
side; the body's link to robot i breaks when its offset exceeds that grasp's limit.

Sums over grasps are written out one grasp at a time, so an instance's result does not
depend on the size of the batch it is computed in.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np

from hybridteam.arrays import some
from hybridteam.floatpaths import Ops


class Equilibrium(NamedTuple):
    """Pose of n payloads and the offsets of their grasps."""

    x: np.ndarray  # (n,)
    y: np.ndarray  # (n,)
    theta: np.ndarray  # (n,) radians, body frame to world
    offsets: np.ndarray  # (n, k, 2): robot point minus world grasp point


def bar(length: float) -> np.ndarray:
    """Body points of a bar gripped at both ends, centred on its origin along x: ``(2, 2)``.

    Row 0 is the front end (+x), row 1 the back end, matching robots listed front first.
    """
    h = 0.5 * float(length)
    return np.array([[h, 0.0], [-h, 0.0]])


def weighted_sum(values: Sequence[Any], weights: Sequence[Any]) -> Any:
    """sum_i w_i v_i, left to right (no reduction whose order depends on shape), of one
    value per grasp: ``(n,)`` columns or one instance's floats alike."""
    acc = weights[0] * values[0]
    for w, v in zip(weights[1:], values[1:], strict=True):
        acc = acc + w * v
    return acc


def _weighted_sum(values: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """:func:`weighted_sum` of ``(n, k)`` arrays, column by column."""
    k = values.shape[1]
    return weighted_sum([values[:, i] for i in range(k)], [weights[:, i] for i in range(k)])


def equilibrium_pose(
    rx: Sequence[Any],
    ry: Sequence[Any],
    bx: Sequence[Any],
    by: Sequence[Any],
    w: Sequence[Any],
    ops: Ops = np,
) -> tuple[Any, Any, Any, Any, Any]:
    """:func:`equilibrium`'s pose ``(x, y, theta)`` and ``cos theta``, ``sin theta``, from
    one value per grasp of the robot points, body points and springs: ``(n,)`` columns with
    ``ops`` numpy, or one payload's floats in the float form
    (:func:`~hybridteam.floatpaths.float_form`, a single run's settling,
    :mod:`~hybridteam.world.settle_one`): the algorithm is written once."""
    total = w[0]
    for wi in w[1:]:
        total = total + wi
    rcx = weighted_sum(rx, w) / total
    rcy = weighted_sum(ry, w) / total
    bcx = weighted_sum(bx, w) / total
    bcy = weighted_sum(by, w) / total
    crx, cry = [v - rcx for v in rx], [v - rcy for v in ry]
    cbx, cby = [v - bcx for v in bx], [v - bcy for v in by]
    dot = weighted_sum([a * b + c * d for a, b, c, d in zip(cbx, crx, cby, cry, strict=True)], w)
    cross = weighted_sum([a * d - c * b for a, b, c, d in zip(cbx, crx, cby, cry, strict=True)], w)
    theta = ops.arctan2(cross, dot)
    c, s = ops.cos(theta), ops.sin(theta)
    return rcx - (c * bcx - s * bcy), rcy - (s * bcx + c * bcy), theta, c, s


def equilibrium(
    robot_points: np.ndarray, body_points: np.ndarray, springs: np.ndarray, offsets: bool = True
) -> Equilibrium:
    """Quasi-static pose of n payloads held at k grasps by springs.

    ``robot_points`` is ``(n, k, 2)``; ``body_points`` is ``(k, 2)`` (one body for all) or
    ``(n, k, 2)``; ``springs`` is ``(n, k)`` or ``(k,)``, all positive. When the body's
    orientation is undetermined (every cross-covariance term zero, e.g. all robots on one
    point) the angle is 0. With ``offsets`` false the result's offsets are an empty
    ``(n, 0, 2)`` array: a caller that places the body's points itself (the payload
    component, at every instant) does not pay for them twice.
    """
    r = np.asarray(robot_points, dtype=float)
    if r.ndim != 3 or r.shape[2] != 2:
        raise ValueError(f"robot_points must have shape (n, k, 2), got {r.shape}")
    n, k, _ = r.shape
    b = np.broadcast_to(np.asarray(body_points, dtype=float), (n, k, 2))
    w = np.broadcast_to(np.asarray(springs, dtype=float), (n, k))
    if some(w <= 0):
        raise ValueError("spring constants must be positive")
    x, y, theta, c, s = equilibrium_pose(
        *([a[:, i] for i in range(k)] for a in (r[..., 0], r[..., 1], b[..., 0], b[..., 1], w))
    )
    if not offsets:
        return Equilibrium(x, y, theta, np.empty((n, 0, 2)))
    gx = c[:, None] * b[..., 0] - s[:, None] * b[..., 1] + x[:, None]
    gy = s[:, None] * b[..., 0] + c[:, None] * b[..., 1] + y[:, None]
    held = np.empty((*gx.shape, 2))  # np.stack's values, without its checks
    held[..., 0], held[..., 1] = r[..., 0] - gx, r[..., 1] - gy
    return Equilibrium(x, y, theta, held)


def world_points(
    x: np.ndarray, y: np.ndarray, theta: np.ndarray, body_points: np.ndarray
) -> np.ndarray:
    """Body points placed at poses ``(x, y, theta)`` (each ``(n,)``): ``(n, k, 2)``."""
    b = np.asarray(body_points, dtype=float)
    c, s = np.cos(theta)[:, None], np.sin(theta)[:, None]
    bx, by = b[..., 0], b[..., 1]
    first = c * bx - s * by + np.asarray(x)[:, None]
    out = np.empty((*first.shape, 2))  # np.stack's values, without its checks
    out[..., 0], out[..., 1] = first, s * bx + c * by + np.asarray(y)[:, None]
    return out


def spring_energy(
    robot_points: np.ndarray,
    body_points: np.ndarray,
    springs: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    theta: np.ndarray,
) -> np.ndarray:
    """E(p, R) for given poses, ``(n,)``: what :func:`equilibrium` minimizes."""
    g = world_points(x, y, theta, np.broadcast_to(body_points, np.shape(robot_points)))
    d = np.asarray(robot_points, dtype=float) - g
    w = np.broadcast_to(np.asarray(springs, dtype=float), d.shape[:2])
    return _weighted_sum(d[..., 0] ** 2 + d[..., 1] ** 2, w)


def two_grasp_slack(limit_a: float, limit_b: float, spring_a: float, spring_b: float) -> float:
    """Largest ``|D - length|`` a bar held at both ends can take before a link breaks.

    With two grasps the bar lies on the line through the robots and the springs share the
    mismatch ``|D - length|`` in inverse proportion to their constants:
    ``|o_a| = sc_b / (sc_a + sc_b) * |D - length|``. Each offset must stay within its
    limit, so the mismatch is at most ``limit_a (sc_a + sc_b) / sc_b`` and at most
    ``limit_b (sc_a + sc_b) / sc_a``. This is how much longer than a rigid-grasp limit a
    compliantly held bar can be.
    """
    total = spring_a + spring_b
    return min(limit_a * total / spring_b, limit_b * total / spring_a)
