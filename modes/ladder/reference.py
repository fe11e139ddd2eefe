"""The same algorithm for one pair, as a plain scalar loop: the cross-check and the baseline.

Nothing here is vectorized: floats, ``math`` and one Python loop per control period, in
the order the paper describes. It shares only the inputs with the vectorized stepper
(the placements and guide paths of :mod:`.scene`, moved into the corner frame); the
per-step law, the outcome rules and the statistics are written again from the paper and
the README. Both use only ``+ - * /``, ``sqrt`` and comparisons in the same order, so
they agree bit for bit; the exception is the rotation vector (k_r != 0), whose
``np.arctan2`` and ``math.atan2`` may differ in the last bit.
"""

from __future__ import annotations

import math

import numpy as np

from hybridteam.world.geometry import Corridor, corridor_with_turn

from .frame import CornerFrame
from .kernel import LINK_BROKEN, STUCK, SUCCESS, Result
from .params import Pairs, Robot, Scenario, Settings
from .scene import build

TINY = 1e-300


def _norm(x: float, y: float) -> float:
    return math.sqrt(x * x + y * y)


def _nearest(
    px: list[float], py: list[float], x: float, y: float, idx: int, window: int, last: int
) -> int:
    best, best_k = math.inf, 0
    for k in range(2 * window + 1):
        j = min(max(idx - window + k, 0), last)
        dx, dy = px[j] - x, py[j] - y
        d = dx * dx + dy * dy
        if d < best:
            best, best_k = d, k
    return min(max(idx + best_k - window, 0), last)


def _motion(
    i: int,
    x: list[float],
    y: list[float],
    o: list,
    no: list[float],
    tips: list,
    dist: float,
    dgoal: list[float],
    nearest: list[int],
    paths: list,
    robots: tuple[Robot, Robot],
    length: float,
    heading: list,
    w_in: float,
    w_out: float,
    correction: str,
) -> tuple[float, float]:
    """Motion vector of robot i (0 front, 1 rear) for this period, in the corner frame."""
    j = 1 - i
    rb = robots[i]
    px, py = paths[i]
    last = len(px) - 1
    # Target vector (Sec. 3.2.1): toward the point `lookahead` past the nearest one.
    t = min(nearest[i] + max(rb.lookahead, 1), last)
    vx, vy = px[t] - x[i], py[t] - y[i]
    dq = max(_norm(vx, vy), TINY)
    tx, ty = vx / dq, vy / dq
    # Rotation vector: only when k_r != 0.
    if rb.kr != 0.0:
        ux, uy = (x[i] - x[j]) / dist, (y[i] - y[j]) / dist
        hx, hy = heading[i]
        dtheta = math.atan2(ux * hy - uy * hx, ux * hx + uy * hy)
        mag = rb.kr * (0.5 * length) * dtheta / max(dgoal[i], TINY)
        sx, sy = tx + -mag * uy, ty + mag * ux
        ns = max(_norm(sx, sy), TINY)
        tx, ty = sx / ns, sy / ns
    # Correction vector.
    gap = rb.olim - rb.orsp
    coef = rb.kc / gap if gap > 0.0 else 0.0
    k = coef * max(no[i] - rb.orsp, 0.0) / max(no[i], TINY)
    cx, cy = k * o[i][0], k * o[i][1]
    # Combine and clamp (Sec. 3.2.2), with the arrival factor.
    g = min(dgoal[i] / rb.v_max, 1.0)
    if correction == "scaled":  # the printed formula
        sx, sy = g * tx + cx, g * ty + cy
        cl = max(_norm(sx, sy), 1.0)
        mx, my = rb.v_max * (sx / cl), rb.v_max * (sy / cl)
    else:  # c a distance per step, or v_max only a cap
        scale = rb.v_max if correction == "distance" else 1.0
        sx, sy = scale * (g * tx) + cx, scale * (g * ty) + cy
        cl = max(_norm(sx, sy) / rb.v_max, 1.0)
        mx, my = sx / cl, sy / cl
    # Ladder-wall avoidance (Fig. 7b): the inside of the turn is x, y >= 0.
    (ax, ay), (bx, by) = tips[i], tips[j]
    da = _norm(min(ax, 0.0), min(ay, 0.0))
    db = _norm(min(bx, 0.0), min(by, 0.0))
    ux, uy = bx - ax, by - ay
    s = min(max(-(ax * ux + ay * uy) / max(ux * ux + uy * uy, TINY), 0.0), 1.0)
    clear = min(da, db, _norm(ax + s * ux, ay + s * uy))
    if (ax < 0.0) != (bx < 0.0) and (ax * by - ay * bx) * (ax - bx) >= 0.0:
        clear = 0.0
    if clear < rb.ladder_margin:
        mx, my = min(mx, 0.0), min(my, 0.0)
    # Robot-wall avoidance (Fig. 7a): outer walls, then the inner walls.
    if mx < 0.0 and x[i] + w_in + mx < rb.radius:
        mx = 0.0
    if my < 0.0 and y[i] + w_out + my < rb.radius:
        my = 0.0
    ex, ey = min(x[i], 0.0), min(y[i], 0.0)
    d = _norm(ex, ey)
    nx, ny = ex / d, ey / d
    p = mx * nx + my * ny
    if p < 0.0 and d + p < rb.radius:
        mx, my = mx - p * nx, my - p * ny
    return mx, my


def _ladder(
    x: list[float], y: list[float], share: list[float], length: float
) -> tuple[list, list[float], list, float]:
    """Offset vectors, their lengths, the ladder's ends and the robots' distance (Sec. 2)."""
    o, no, tips = [], [], []
    for i in range(2):
        dx, dy = x[i] - x[1 - i], y[i] - y[1 - i]
        dist = _norm(dx, dy)  # the same for both robots
        f = share[i] * ((length - dist) / dist)
        o.append((f * dx, f * dy))
        no.append(_norm(f * dx, f * dy))
        tips.append((x[i] + f * dx, y[i] + f * dy))
    return o, no, tips, dist


def _meets_corner(
    a: tuple[float, float], b: tuple[float, float], w_in: float, w_out: float
) -> bool:
    (ax, ay), (bx, by) = a, b
    if not (
        min(ax, bx) <= 0.0 and max(ax, bx) >= -w_in and min(ay, by) <= 0.0 and max(ay, by) >= -w_out
    ):
        return False
    dx, dy = bx - ax, by - ay
    s = dx * (-0.5 * w_out - ay) - dy * (-0.5 * w_in - ax)
    return abs(s) <= 0.5 * w_in * abs(dy) + 0.5 * w_out * abs(dx)


def run(
    scenario: Scenario,
    corridor: Corridor | None = None,
    settings: Settings | None = None,
    *,
    record: bool = False,
) -> Result:
    """Run one pair to success, stuck or a broken link; a :class:`Result` with n = 1."""
    corridor = corridor or corridor_with_turn()
    settings = settings or Settings()
    settings.check()
    scene = build(Pairs.of(scenario), corridor, settings)
    frame = CornerFrame.of(corridor)
    start = frame.to_frame(scene.start[:, 0]).tolist()
    goal = frame.to_frame(scene.goal[:, 0]).tolist()
    fpaths = frame.to_frame(scene.paths[:, 0])
    paths = [(fpaths[r, :, 0].tolist(), fpaths[r, :, 1].tolist()) for r in range(2)]
    robots = (scenario.front, scenario.rear)
    length = float(scenario.length)
    w_in, w_out = frame.width_in, frame.width_out
    heading = []
    for i in range(2):
        hx, hy = goal[i][0] - goal[1 - i][0], goal[i][1] - goal[1 - i][1]
        hn = _norm(hx, hy)
        heading.append((hx / hn, hy / hn))
    share = [robots[1 - i].sc / (robots[i].sc + robots[1 - i].sc) for i in range(2)]
    x = [start[0][0], start[1][0]]
    y = [start[0][1], start[1][1]]
    idx = [0, 0]
    path_len, corner_len, max_off = [0.0, 0.0], [0.0, 0.0], [0.0, 0.0]
    best, improved_at, corner_steps, step = math.inf, 0, 0, 0
    trajectory, tip_trace = [], []
    cracked = False  # a link broke between the two moves of a sequential step
    while True:
        o, no, tips, dist = _ladder(x, y, share, length)
        for i in range(2):
            max_off[i] = max(max_off[i], no[i])
        if record:
            trajectory.append([(x[0], y[0]), (x[1], y[1])])
            tip_trace.append(tips)
        dgoal = [_norm(goal[i][0] - x[i], goal[i][1] - y[i]) for i in range(2)]
        progress = dgoal[0] + dgoal[1]
        if progress < best - settings.stuck_tol:
            best, improved_at = progress, step
        if cracked or no[0] > robots[0].olim or no[1] > robots[1].olim:
            outcome = LINK_BROKEN
            break
        if dgoal[0] <= settings.arrive_tol and dgoal[1] <= settings.arrive_tol:
            outcome = SUCCESS
            break
        if improved_at <= step - settings.stuck_window or step >= settings.max_steps:
            outcome = STUCK
            break
        nearest = [
            _nearest(*paths[i], x[i], y[i], idx[i], settings.window, settings.path_points - 1)
            for i in range(2)
        ]
        move = [
            _motion(
                i,
                x,
                y,
                o,
                no,
                tips,
                dist,
                dgoal,
                nearest,
                paths,
                robots,
                length,
                heading,
                w_in,
                w_out,
                settings.correction,
            )
            for i in range(2)
        ]
        if settings.update != "synchronous":  # the second robot sees the first one moved
            first = 0 if settings.update == "front_first" else 1
            second = 1 - first
            x1, y1 = list(x), list(y)
            x1[first] += move[first][0]
            y1[first] += move[first][1]
            o1, no1, tips1, dist1 = _ladder(x1, y1, share, length)
            for i in range(2):
                max_off[i] = max(max_off[i], no1[i])
            cracked = no1[0] > robots[0].olim or no1[1] > robots[1].olim
            move[second] = _motion(
                second,
                x1,
                y1,
                o1,
                no1,
                tips1,
                dist1,
                dgoal,
                nearest,
                paths,
                robots,
                length,
                heading,
                w_in,
                w_out,
                settings.correction,
            )
        corner = _meets_corner(tips[0], tips[1], w_in, w_out)
        for i in range(2):
            moved = _norm(move[i][0], move[i][1])
            x[i] += move[i][0]
            y[i] += move[i][1]
            path_len[i] += moved
            if corner:
                corner_len[i] += moved
        idx = nearest
        corner_steps += corner
        step += 1
    position = frame.to_world(np.array([[x[0], y[0]], [x[1], y[1]]]))
    return Result(
        outcome=np.array([outcome], dtype=np.int8),
        steps=np.array([step]),
        corner_steps=np.array([corner_steps]),
        path=np.array([path_len]),
        corner_path=np.array([corner_len]),
        max_offset=np.array([max_off]),
        position=position[None],
        scene=scene,
        trajectory=frame.to_world(np.array(trajectory))[:, None] if record else None,
        tips=frame.to_world(np.array(tip_trace))[:, None] if record else None,
    )
