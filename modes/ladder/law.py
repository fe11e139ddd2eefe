"""The per-robot control law of the ladder paper (Sec. 3.2), as vectorized numpy kernels.

One evaluation is one control period of one robot of each of n pairs: from the robot's
and its partner's positions at the start of the period it finds the ladder's
equilibrium, the target, rotation and correction vectors, combines and clamps them
(3.2.2), and nullifies the components that would drive the robot or the ladder into a
wall (3.2.3, Fig. 7). Both robots evaluate the law on the same start-of-period state and
then move together (synchronous update).

Coordinates are in the corner frame (:mod:`.frame`), where the inside of the turn is the
quadrant ``x, y >= 0`` and the outer walls are ``x = -w_in``, ``y = -w_out``. The
functions take separate coordinate arrays of any common shape: the stepper passes
``(2, n)``, row 0 the front robots and row 1 the rear ones, the partner being the same
array upside down. :func:`step` is the same law for one robot of each pair in world
coordinates with ``(n, 2)`` points. Every formula is elementwise, with no reduction across
instances, so an instance's result does not depend on the batch; numpy ufuncs stand in
for np.where/np.clip where they are equivalent, because at small n the call count is
the cost.

Offsets follow the paper: ``o_i`` points from robot i's centre to its end of the ladder
(the negative of :func:`hybridteam.world.payload.equilibrium`'s robot-minus-grasp offset).
"""

from __future__ import annotations

import numpy as np

from hybridteam.library import Ops
from hybridteam.world.geometry import Corridor

from .frame import CornerFrame

#: Coordinates and parameters: float arrays of one common (broadcastable) shape.
Array = np.ndarray

#: Floor for divisors that are zero only when their numerators are.
TINY = 1e-300


def norm(x: Array, y: Array, ops: Ops = np) -> Array:
    """``sqrt(x^2 + y^2)``: plain arithmetic, so the scalar reference matches it bit for bit
    (and it is many times faster than ``np.hypot`` on large arrays)."""
    return ops.sqrt(x * x + y * y)


def unit_vector(vx: Array, vy: Array, ops: Ops = np) -> tuple[Array, Array]:
    """``v / max(|v|, TINY)``: a unit vector, or zero for a zero ``v``."""
    dq = ops.maximum(ops.sqrt(vx * vx + vy * vy), TINY)
    return vx / dq, vy / dq


def spring_offsets(
    x: Array, y: Array, px: Array, py: Array, length: Array, share: Array, ops: Ops = np
) -> tuple[Array, Array, Array]:
    """Offset vector ``o`` (robot centre to its ladder end) and the robots' distance D.

    With two grasps the ladder lies on the line through the robots, and the ends sit
    ``|o_i| = sc_partner / (sc_i + sc_partner) * |D - length|`` from the robots (Sec. 2);
    ``share`` is that spring ratio. ``o`` points toward the partner when stretched.
    Written once over ``ops`` (:func:`~hybridteam.floatpaths.float_form`: the float form
    of one robot, :mod:`.law_one`'s, raises ZeroDivisionError where robots coincide).
    """
    dx = x - px
    dy = y - py
    dist = ops.sqrt(dx * dx + dy * dy)  # (norm's arithmetic)
    f = share * ((length - dist) / dist)
    return f * dx, f * dy, dist


def pad_paths(paths: Array, window: int) -> tuple[Array, Array]:
    """Flattened x and y of guide paths ``(..., P, 2)``, each padded with ``window`` copies
    of its first and last point, so a search window never needs clipping."""
    p = np.asarray(paths, dtype=float)
    lead = np.repeat(p[..., :1, :], window, axis=-2)
    tail = np.repeat(p[..., -1:, :], window, axis=-2)
    padded = np.concatenate([lead, p, tail], axis=-2)
    return np.ascontiguousarray(padded[..., 0]).ravel(), np.ascontiguousarray(
        padded[..., 1]
    ).ravel()


def search_windows(path_x: Array, path_y: Array, window: int) -> tuple[Array, Array]:
    """Views of padded paths whose row ``base + i`` is points ``i - window .. i + window``."""
    size = 2 * window + 1
    return (
        np.lib.stride_tricks.sliding_window_view(path_x, size),
        np.lib.stride_tricks.sliding_window_view(path_y, size),
    )


class Guide:
    """One robot's guide paths for a batch, in the corner frame and padded for the search:
    the same for every period of a run, so a caller that keeps it (the engine law does)
    prepares them once instead of at every period, with the same values."""

    __slots__ = ("base", "fpath", "path_x", "path_y", "windows")

    def __init__(self, path: Array, frame: CornerFrame, window: int) -> None:
        self.fpath = frame.to_frame(path)
        n, count, _ = self.fpath.shape
        self.path_x, self.path_y = pad_paths(self.fpath, window)
        self.windows = search_windows(self.path_x, self.path_y, window)
        self.base = np.arange(n) * (count + 2 * window)


def nearest_on_path(
    x: Array,
    y: Array,
    windows: tuple[Array, Array],
    base: Array,
    idx: Array,
    window: int,
    last: int,
) -> Array:
    """Index of the guide-path point nearest the robot, searched within ``idx +- window``.

    ``windows`` come from :func:`search_windows`; ``base`` is where each robot's padded
    path starts. Searching near the previous nearest point makes progress along the path
    part of the robot's state (and the step cheap); of equally near points the first wins.
    """
    rows = base + idx
    ex = windows[0][rows] - x[..., None]
    ey = windows[1][rows] - y[..., None]
    ex *= ex
    ey *= ey
    ex += ey
    return np.minimum(np.maximum(idx + ex.argmin(axis=-1) - window, 0), last)


def target_vector(
    x: Array,
    y: Array,
    path_x: Array,
    path_y: Array,
    base: Array,
    nearest: Array,
    ahead: Array,
    last: int,
    window: int,
) -> tuple[Array, Array]:
    """Target vector: the unit vector to the point ``ahead`` points past the nearest one.

    ``ahead`` is the lookahead, at least 1 so that a robot standing on a path point still
    moves on (the paper's population includes lookahead 0).
    """
    flat = base + window + np.minimum(nearest + ahead, last)
    return unit_vector(path_x[flat] - x, path_y[flat] - y)


def arrival_factor(dgoal: Array, v_max: Array, ops: Ops = np) -> Array:
    """``min(1, distgoal / v_max)``: a robot takes no step past its goal.

    The paper does not say how a robot stops; this scales the target vector so the last
    step lands on the goal instead of oscillating around it.
    """
    return ops.minimum(dgoal / v_max, 1.0)


def rotation_vector(
    x: Array,
    y: Array,
    px: Array,
    py: Array,
    dist: Array,
    dgoal: Array,
    heading_x: Array,
    heading_y: Array,
    kr: Array,
    half_length: Array,
    ops: Ops = np,
) -> tuple[Array, Array]:
    """Rotation vector: perpendicular to the ladder, |r| = k_r * arclength / distgoal.

    ``arclength`` is the arc the ladder's end still has to sweep to reach the goal
    orientation (half the length times the remaining angle); ``heading`` is the unit vector
    from the partner's goal to this robot's goal, so the two robots of a pair get opposite
    vectors without knowing which of them is in front.
    """
    ux = (x - px) / dist
    uy = (y - py) / dist
    dtheta = ops.arctan2(ux * heading_y - uy * heading_x, ux * heading_x + uy * heading_y)
    mag = kr * half_length * dtheta / ops.maximum(dgoal, TINY)
    return -mag * uy, mag * ux


def correction_coefficient(kc: Array, olim: Array, orsp: Array) -> Array:
    """``k_c / (olim - orsp)``, or 0 when ``orsp >= olim`` (no correction before a break)."""
    kc, olim, orsp = (np.asarray(a, dtype=float) for a in (kc, olim, orsp))
    gap = olim - orsp
    return np.where(gap > 0.0, kc / np.where(gap > 0.0, gap, 1.0), 0.0)


def correction_vector(
    ox: Array, oy: Array, no: Array, orsp: Array, coef: Array, ops: Ops = np
) -> tuple[Array, Array]:
    """Correction vector toward the ladder end, growing linearly once |o| passes ``orsp``.

    ``no`` is |o|; ``coef`` is ``k_c / (olim - orsp)``, so |c| = k_c at the offset limit.
    """
    k = coef * ops.maximum(no - orsp, 0.0) / ops.maximum(no, TINY)
    return k * ox, k * oy


def combine(
    tx: Array,
    ty: Array,
    rx: Array | None,
    ry: Array | None,
    g: Array,
    cx: Array,
    cy: Array,
    v_max: Array,
    rotate: Array | None,
    correction: str = "scaled",
) -> tuple[Array, Array]:
    """Motion vector ``v_max * CLAMP(g * unit(t + r) + c)`` (Sec. 3.2.2).

    Where ``rotate`` is false (k_r = 0) the target vector, already a unit vector, is used
    as it is; ``rotate`` None means false everywhere. ``g`` is :func:`arrival_factor`.

    ``correction`` names the reading of how ``v_max`` enters (``ladder`` README, "Readings
    of Section 3"): ``scaled`` is the printed formula, where the correction vector is a
    fraction of the robot's speed (the paper's reason for normalizing ``t + r``: ``|c|``
    must be able to match it); ``distance`` takes ``c`` as a distance per step, added to
    the step ``v_max * unit(t + r)`` and the sum clamped at ``v_max`` (Fig. 6 draws ``c``
    as a displacement); ``capped`` takes ``v_max`` only as the cap "the largest distance it
    can cover in one step", the step being ``unit(t + r) + c`` clamped at ``v_max``.
    """
    if rotate is not None:
        sx, sy = unit_vector(tx + rx, ty + ry)
        tx = np.where(rotate, sx, tx)
        ty = np.where(rotate, sy, ty)
    return clamp_motion(tx, ty, g, cx, cy, v_max, correction)


def clamp_motion(
    tx: Array,
    ty: Array,
    g: Array,
    cx: Array,
    cy: Array,
    v_max: Array,
    correction: str,
    ops: Ops = np,
) -> tuple[Array, Array]:
    """:func:`combine` after the rotation: the motion vector from the (unit) direction
    ``t``, clamped as the ``correction`` reading says."""
    if correction == "scaled":
        sx = g * tx + cx
        sy = g * ty + cy
        cl = ops.maximum(ops.sqrt(sx * sx + sy * sy), 1.0)
        return v_max * (sx / cl), v_max * (sy / cl)
    if correction == "distance":
        sx = v_max * (g * tx) + cx
        sy = v_max * (g * ty) + cy
    elif correction == "capped":
        sx = g * tx + cx
        sy = g * ty + cy
    else:
        raise ValueError(f"unknown correction reading '{correction}'")
    cl = ops.maximum(ops.sqrt(sx * sx + sy * sy) / v_max, 1.0)
    return sx / cl, sy / cl


def ladder_clearance(ax: Array, ay: Array, bx: Array, by: Array, ops: Ops = np) -> Array:
    """Distance from the ladder ``a -> b`` to the inside of the turn; 0 if it enters it.

    The inside is the quadrant ``x, y >= 0``: the distance is the least of the ends'
    distances to it and the vertex's distance to the segment. A segment with both ends
    outside enters it only by crossing the line ``x = 0`` at some ``y >= 0``. Written once
    over ``ops`` (its float form is :mod:`.law_one`'s; norms as :func:`norm` computes them).
    """
    ex, ey = ops.minimum(ax, 0.0), ops.minimum(ay, 0.0)
    da = ops.sqrt(ex * ex + ey * ey)
    ex, ey = ops.minimum(bx, 0.0), ops.minimum(by, 0.0)
    db = ops.sqrt(ex * ex + ey * ey)
    ux = bx - ax
    uy = by - ay
    t = ops.minimum(
        ops.maximum(-(ax * ux + ay * uy) / ops.maximum(ux * ux + uy * uy, TINY), 0.0), 1.0
    )
    ex, ey = ax + t * ux, ay + t * uy
    dv = ops.sqrt(ex * ex + ey * ey)
    clear = ops.minimum(ops.minimum(da, db), dv)
    crossing = ((ax < 0.0) != (bx < 0.0)) & ((ax * by - ay * bx) * (ax - bx) >= 0.0)
    return ops.where(crossing, 0.0, clear)


def avoid_ladder_collision(
    mx: Array, my: Array, clearance: Array, margin: Array, ops: Ops = np
) -> tuple[Array, Array]:
    """Fig. 7(b): near the inner walls, drop components toward them or away from the corner.

    In the incoming leg "away from the corner" is the direction into the outgoing leg's
    inner wall and vice versa, so both rules are one: drop the positive frame components.
    Every point of the ladder then moves away from (or along) the inside of the turn and
    cannot enter it. Returns the new ``mx``, ``my``.
    """
    near = clearance < margin
    return ops.where(near, ops.minimum(mx, 0.0), mx), ops.where(near, ops.minimum(my, 0.0), my)


def avoid_walls(
    x: Array, y: Array, mx: Array, my: Array, radius: Array, width_in: float, width_out: float
) -> tuple[Array, Array]:
    """Fig. 7(a): drop the component toward a wall the robot would otherwise touch.

    A wall is about to be hit when the step would bring the centre closer than ``radius``
    to the wall's tangent line at the nearest wall point. The outer walls come first, then
    the inner walls (their nearest point, the vertex included). Returns the new ``mx``,
    ``my``.
    """
    mx, my = avoid_outer_walls(x, y, mx, my, radius, width_in, width_out)
    return avoid_inner_walls(x, y, mx, my, radius, inner_wall_distance(x, y))


def avoid_outer_walls(
    x: Array,
    y: Array,
    mx: Array,
    my: Array,
    radius: Array,
    width_in: float,
    width_out: float,
    ops: Ops = np,
) -> tuple[Array, Array]:
    """The outer-wall half of :func:`avoid_walls` (walls ``x = -w_in``, ``y = -w_out``)."""
    return (
        ops.where((mx < 0.0) & (x + width_in + mx < radius), 0.0, mx),
        ops.where((my < 0.0) & (y + width_out + my < radius), 0.0, my),
    )


def inner_wall_distance(x: Array, y: Array, ops: Ops = np) -> Array:
    """Distance from a robot centre outside the turn's inside to the inner walls."""
    ex, ey = ops.minimum(x, 0.0), ops.minimum(y, 0.0)
    return ops.sqrt(ex * ex + ey * ey)


def avoid_inner_walls(
    x: Array, y: Array, mx: Array, my: Array, radius: Array, d: Array, ops: Ops = np
) -> tuple[Array, Array]:
    """The inner-wall half of :func:`avoid_walls`; ``d`` is :func:`inner_wall_distance`.

    The vector from the nearest inner-wall point to the centre is ``(min(x, 0), min(y, 0))``:
    across the wall beside a leg, radial near the vertex.
    """
    nx = ops.minimum(x, 0.0) / d
    ny = ops.minimum(y, 0.0) / d
    p = mx * nx + my * ny
    p = ops.where((p >= 0.0) | (d + p >= radius), 0.0, p)
    return mx - p * nx, my - p * ny


def step(
    own: np.ndarray,
    partner: np.ndarray,
    path: np.ndarray,
    idx: np.ndarray,
    params: dict[str, np.ndarray],
    corridor: Corridor,
    *,
    window: int = 8,
    frame: CornerFrame | None = None,
    guide: Guide | None = None,
    correction: str = "scaled",
) -> tuple[np.ndarray, np.ndarray]:
    """One control period of one robot of each of n pairs: ``(displacement (n, 2), idx)``.

    World coordinates: ``own``/``partner`` are ``(n, 2)`` start-of-period positions,
    ``path`` the robot's guide paths ``(n, P, 2)`` (the goal last), ``idx`` its previous
    nearest path index ``(n,)``. ``params`` holds ``(n,)`` arrays ``length``, ``v_max``,
    ``lookahead``, ``olim``, ``orsp``, ``kc``, ``kr``, ``sc``, ``sc_partner``, ``radius``,
    ``ladder_margin`` and, if some ``kr`` is nonzero, ``goal_heading`` ``(n, 2)`` (unit,
    from the partner's goal to this robot's). Returns the displacement and the new index.
    ``guide``: ``path`` prepared (:class:`Guide`, same ``frame`` and ``window``), if kept.
    ``correction``: how ``v_max`` enters (:func:`combine`).
    """
    frame = frame or CornerFrame.of(corridor)
    prm = {k: np.asarray(v) for k, v in params.items()}
    count = path.shape[1]
    last = count - 1
    x, y = frame.to_frame(own).T
    px, py = frame.to_frame(partner).T
    guide = guide or Guide(path, frame, window)
    fpath, path_x, path_y = guide.fpath, guide.path_x, guide.path_y
    windows, base = guide.windows, guide.base
    share = prm["sc_partner"] / (prm["sc"] + prm["sc_partner"])
    pshare = prm["sc"] / (prm["sc"] + prm["sc_partner"])
    ox, oy, dist = spring_offsets(x, y, px, py, prm["length"], share)
    pox, poy, _ = spring_offsets(px, py, x, y, prm["length"], pshare)
    v_max = prm["v_max"]
    nearest = nearest_on_path(x, y, windows, base, np.asarray(idx), window, last)
    ahead = np.maximum(prm["lookahead"].astype(np.int64), 1)
    tx, ty = target_vector(x, y, path_x, path_y, base, nearest, ahead, last, window)
    dgoal = norm(fpath[:, last, 0] - x, fpath[:, last, 1] - y)
    rotate = prm["kr"] != 0.0
    rx = ry = None
    if rotate.any():
        heading = frame.vectors_to_frame(prm["goal_heading"])
        rx, ry = rotation_vector(
            x, y, px, py, dist, dgoal, heading[:, 0], heading[:, 1], prm["kr"], 0.5 * prm["length"]
        )
    else:
        rotate = None
    no = norm(ox, oy)
    cx, cy = correction_vector(
        ox, oy, no, prm["orsp"], correction_coefficient(prm["kc"], prm["olim"], prm["orsp"])
    )
    mx, my = combine(
        tx, ty, rx, ry, arrival_factor(dgoal, v_max), cx, cy, v_max, rotate, correction
    )
    clear = ladder_clearance(x + ox, y + oy, px + pox, py + poy)
    mx, my = avoid_ladder_collision(mx, my, clear, prm["ladder_margin"])
    mx, my = avoid_walls(x, y, mx, my, prm["radius"], frame.width_in, frame.width_out)
    move = np.empty((*mx.shape, 2))  # np.stack's values, without its checks
    move[..., 0], move[..., 1] = mx, my
    return frame.vectors_to_world(move), nearest
