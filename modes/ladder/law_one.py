"""One robot's control period on Python floats: :func:`.law.step`'s numbers for one row.

Through the engine the law runs for one instance at a time in a single run, and at that
size each of :func:`.law.step`'s numpy calls costs its dispatch (about a microsecond) for
one number: some 80 of them a period. Here the same IEEE operations run in the same order
on floats, so every result has the array version's bits (``tests/test_ladder_law_one.py``
checks that on random rows). The rules that keep it so:

- ``+ - * /`` and :func:`math.sqrt` are the same correctly rounded operations in Python
  and numpy; sums and products keep the array version's grouping;
- ``np.minimum``/``np.maximum`` return their second argument on ties (``-0.0`` against
  ``0.0``) and propagate NaN; :func:`_min` and :func:`_max` do the same (Python's
  ``min``/``max`` do not);
- ``np.arctan2`` is called as it is (its result is not correctly rounded, so ``math.atan2``
  could differ);
- the nearest-point search runs numpy's own arithmetic and ``argmin`` on the window row;
- where Python would raise and numpy would return inf or NaN (a division by zero, a
  non-finite lookahead), :class:`Diverged` is raised and the caller takes the array
  version for that row.

:func:`.law.spring_offsets` and :func:`.law.ladder_clearance` are written once, over an
operations namespace, and their float forms here are generated from that source
(:func:`hybridteam.library.float_form`); anyone editing the rest of :func:`.law.step` or
the functions it calls must edit this twin too.
"""

from __future__ import annotations

import math

import numpy as np

from hybridteam.library import float_form

from . import law
from .frame import CornerFrame
from .law import TINY, Guide


class Diverged(ArithmeticError):
    """A row whose floats would raise where numpy's arrays return inf or NaN."""


def _min(a: float, b: float) -> float:
    """``np.minimum(a, b)``: ``b`` on ties, NaN if either is NaN."""
    return a if (a < b or a != a) else b


def _max(a: float, b: float) -> float:
    """``np.maximum(a, b)``: ``b`` on ties, NaN if either is NaN."""
    return a if (a > b or a != a) else b


def _norm(x: float, y: float) -> float:
    return math.sqrt(x * x + y * y)


#: :func:`.law.spring_offsets` of one robot, generated from its source: its offset ``o``
#: and the robots' distance. Raises ZeroDivisionError where the robots coincide (numpy
#: gives inf and NaN).
spring_offsets = float_form(law.spring_offsets)
#: :func:`.law.ladder_clearance` of one ladder, generated from its source.
clearance = float_form(law.ladder_clearance)


def to_frame(frame: CornerFrame, x: float, y: float) -> tuple[float, float]:
    """:meth:`.CornerFrame.to_frame` of one point."""
    o0, o1, a0, a1, b0, b1 = frame.floats
    vx, vy = x - o0, y - o1
    return vx * a0 + vy * a1, vx * b0 + vy * b1


def to_world_vector(frame: CornerFrame, mx: float, my: float) -> tuple[float, float]:
    """:meth:`.CornerFrame.vectors_to_world` of one vector."""
    _, _, a0, a1, b0, b1 = frame.floats
    return mx * a0 + my * b0, mx * a1 + my * b1


def step_one(own: tuple[float, float], partner: tuple[float, float], guide: Guide, row: int,
             idx: int, p: dict[str, float], frame: CornerFrame, window: int,
             correction: str) -> tuple[float, float, int]:
    """One control period of row ``row`` of ``guide``: ``(dx, dy, nearest)`` in world
    coordinates, as :func:`.law.step` computes them for that row.

    ``p`` holds the row's floats ``length``, ``v_max``, ``lookahead``, ``olim``, ``orsp``,
    ``kc``, ``kr``, ``sc``, ``sc_partner``, ``radius``, ``ladder_margin`` and, where ``kr``
    is nonzero, ``hx``, ``hy`` (the goal heading, world coordinates). Raises
    :class:`Diverged` where the array version would divide by zero or convert NaN.
    """
    try:
        return _step(own, partner, guide, row, idx, p, frame, window, correction)
    except (ZeroDivisionError, ValueError, OverflowError) as exc:
        raise Diverged(str(exc)) from None


def _step(own, partner, guide, row, idx, p, frame, window, correction):
    x, y = to_frame(frame, *own)
    px, py = to_frame(frame, *partner)
    sc, scp, length = p["sc"], p["sc_partner"], p["length"]
    share = scp / (sc + scp)
    pshare = sc / (sc + scp)
    ox, oy, dist = spring_offsets(x, y, px, py, length, share)
    pox, poy, _ = spring_offsets(px, py, x, y, length, pshare)
    v_max = p["v_max"]
    if not abs(p["lookahead"]) < 2.0 ** 63:  # astype(np.int64) has no number for it
        raise ValueError("lookahead out of the int64 range")
    nearest, tx, ty, dgoal = _follow(x, y, guide, row, idx, int(p["lookahead"]), window)
    if p["kr"] != 0.0:
        tx, ty = _rotate(x, y, px, py, dist, dgoal, tx, ty, p, frame)
    no = _norm(ox, oy)
    gap = p["olim"] - p["orsp"]
    coef = p["kc"] / gap if gap > 0.0 else 0.0
    k = coef * _max(no - p["orsp"], 0.0) / _max(no, TINY)
    cx, cy = k * ox, k * oy
    mx, my = _combine(tx, ty, _min(dgoal / v_max, 1.0), cx, cy, v_max, correction)
    if clearance(x + ox, y + oy, px + pox, py + poy) < p["ladder_margin"]:
        mx, my = _min(mx, 0.0), _min(my, 0.0)
    mx, my = _avoid_walls(x, y, mx, my, p["radius"], frame)
    wx, wy = to_world_vector(frame, mx, my)
    return wx, wy, nearest


def _follow(x, y, guide, row, idx, lookahead, window):
    """``nearest_on_path``, ``target_vector`` and the distance to the goal."""
    base = guide.base.item(row)  # (item: a Python number without a numpy scalar between)
    ex = guide.windows[0][base + idx] - x
    ey = guide.windows[1][base + idx] - y
    ex *= ex
    ey *= ey
    ex += ey
    last = guide.fpath.shape[1] - 1
    nearest = min(max(idx + int(ex.argmin()) - window, 0), last)
    flat = base + window + min(nearest + max(lookahead, 1), last)
    vx = guide.path_x.item(flat) - x
    vy = guide.path_y.item(flat) - y
    dq = _max(_norm(vx, vy), TINY)
    dgoal = _norm(guide.fpath.item(row, last, 0) - x, guide.fpath.item(row, last, 1) - y)
    return nearest, vx / dq, vy / dq, dgoal


def _rotate(x, y, px, py, dist, dgoal, tx, ty, p, frame):
    """``rotation_vector`` added to the target vector and normalized (``combine``)."""
    _, _, a0, a1, b0, b1 = frame.floats
    hx = p["hx"] * a0 + p["hy"] * a1
    hy = p["hx"] * b0 + p["hy"] * b1
    ux = (x - px) / dist
    uy = (y - py) / dist
    dtheta = float(np.arctan2(ux * hy - uy * hx, ux * hx + uy * hy))
    mag = p["kr"] * (0.5 * p["length"]) * dtheta / _max(dgoal, TINY)
    sx = tx + -mag * uy
    sy = ty + mag * ux
    ns = _max(_norm(sx, sy), TINY)
    return sx / ns, sy / ns


def _combine(tx, ty, g, cx, cy, v_max, correction):
    """``combine`` after the rotation: the motion vector, clamped."""
    if correction == "scaled":
        sx = g * tx + cx
        sy = g * ty + cy
        cl = _max(_norm(sx, sy), 1.0)
        return v_max * (sx / cl), v_max * (sy / cl)
    if correction == "distance":
        sx = v_max * (g * tx) + cx
        sy = v_max * (g * ty) + cy
    elif correction == "capped":
        sx = g * tx + cx
        sy = g * ty + cy
    else:
        raise Diverged(f"unknown correction reading '{correction}'")
    cl = _max(_norm(sx, sy) / v_max, 1.0)
    return sx / cl, sy / cl


def _avoid_walls(x, y, mx, my, radius, frame):
    """``avoid_walls``: the outer walls, then the inner ones."""
    if mx < 0.0 and x + frame.width_in + mx < radius:
        mx = 0.0
    if my < 0.0 and y + frame.width_out + my < radius:
        my = 0.0
    cx, cy = _min(x, 0.0), _min(y, 0.0)
    d = _norm(cx, cy)
    nx = cx / d
    ny = cy / d
    q = mx * nx + my * ny
    if q >= 0.0 or d + q >= radius:
        q = 0.0
    return mx - q * nx, my - q * ny
