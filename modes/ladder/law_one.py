"""One robot's control period on Python floats: :func:`.law.step`'s numbers for one row.

Through the engine the law runs for one instance at a time in a single run, and at that
size each of :func:`.law.step`'s numpy calls costs its dispatch (about a microsecond) for
one number: some 80 of them a period.

Every part of the law after the nearest-point search (the springs' offsets, the target
vector's normalization, the rotation, correction and arrival, the clamp, the wall rules,
the ladder's clearance) is written once in :mod:`.law`, over an operations namespace
``ops`` that is numpy for arrays, and its float form here is generated from that source
(:func:`hybridteam.library.float_form`: the same IEEE operations in the same order,
``np.minimum``/``np.maximum`` with numpy's ties and NaN, numpy's own ``arctan2``), so
every result has the array version's bits (``tests/modes/test_ladder_law_one.py`` checks that
on random rows). Written by hand here, and to be edited with :func:`.law.step`: the frame
changes (:meth:`.CornerFrame.to_frame` of one point), the nearest-point search (numpy's
own arithmetic and ``argmin`` on the window row) and the order :func:`.law.step` calls
the parts in. Where Python would raise and numpy would return inf or NaN (a division by
zero, a non-finite lookahead), :class:`Diverged` is raised and the caller takes the
array version for that row.
"""

from __future__ import annotations

from hybridteam.library import float_form

from . import law
from .frame import CornerFrame
from .law import Guide


class Diverged(ArithmeticError):
    """A row whose floats would raise where numpy's arrays return inf or NaN."""


def _max(a: float, b: float) -> float:
    """``np.maximum(a, b)``: ``b`` on ties, NaN if either is NaN (the corridor's largest
    offset, :mod:`.world_one`)."""
    return a if (a > b or a != a) else b


#: :func:`.law.spring_offsets` of one robot, generated from its source: its offset ``o``
#: and the robots' distance. Raises ZeroDivisionError where the robots coincide (numpy
#: gives inf and NaN).
spring_offsets = float_form(law.spring_offsets)
#: :func:`.law.ladder_clearance` of one ladder, generated from its source.
clearance = float_form(law.ladder_clearance)
#: The rest of :func:`.law.step`'s parts for one robot, generated from their sources (a
#: division by zero raises, where a robot centre is in the turn's inside: :class:`Diverged`)
arrival_factor = float_form(law.arrival_factor)
rotation_vector = float_form(law.rotation_vector)
norm = float_form(law.norm)
unit_vector = float_form(law.unit_vector)
correction_vector = float_form(law.correction_vector)
clamp_motion = float_form(law.clamp_motion)
avoid_ladder_collision = float_form(law.avoid_ladder_collision)
avoid_outer_walls = float_form(law.avoid_outer_walls)
inner_wall_distance = float_form(law.inner_wall_distance)
avoid_inner_walls = float_form(law.avoid_inner_walls)


def to_frame(frame: CornerFrame, x: float, y: float) -> tuple[float, float]:
    """:meth:`.CornerFrame.to_frame` of one point."""
    o0, o1, a0, a1, b0, b1 = frame.floats
    vx, vy = x - o0, y - o1
    return vx * a0 + vy * a1, vx * b0 + vy * b1


def to_world_vector(frame: CornerFrame, mx: float, my: float) -> tuple[float, float]:
    """:meth:`.CornerFrame.vectors_to_world` of one vector."""
    _, _, a0, a1, b0, b1 = frame.floats
    return mx * a0 + my * b0, mx * a1 + my * b1


def step_one(
    own: tuple[float, float],
    partner: tuple[float, float],
    guide: Guide,
    row: int,
    idx: int,
    p: dict[str, float],
    frame: CornerFrame,
    window: int,
    correction: str,
) -> tuple[float, float, int]:
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
    if not abs(p["lookahead"]) < 2.0**63:  # astype(np.int64) has no number for it
        raise ValueError("lookahead out of the int64 range")
    nearest, tx, ty, dgoal = _follow(x, y, guide, row, idx, int(p["lookahead"]), window)
    if p["kr"] != 0.0:
        _, _, a0, a1, b0, b1 = frame.floats  # (frame.vectors_to_frame of the goal heading)
        hx = p["hx"] * a0 + p["hy"] * a1
        hy = p["hx"] * b0 + p["hy"] * b1
        rx, ry = rotation_vector(x, y, px, py, dist, dgoal, hx, hy, p["kr"], 0.5 * p["length"])
        tx, ty = unit_vector(tx + rx, ty + ry)
    no = norm(ox, oy)
    gap = p["olim"] - p["orsp"]
    coef = p["kc"] / gap if gap > 0.0 else 0.0  # (law.correction_coefficient)
    cx, cy = correction_vector(ox, oy, no, p["orsp"], coef)
    mx, my = clamp_motion(tx, ty, arrival_factor(dgoal, v_max), cx, cy, v_max, correction)
    mx, my = avoid_ladder_collision(
        mx, my, clearance(x + ox, y + oy, px + pox, py + poy), p["ladder_margin"]
    )
    mx, my = avoid_outer_walls(x, y, mx, my, p["radius"], frame.width_in, frame.width_out)
    mx, my = avoid_inner_walls(x, y, mx, my, p["radius"], inner_wall_distance(x, y))
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
    tx, ty = unit_vector(guide.path_x.item(flat) - x, guide.path_y.item(flat) - y)
    dgoal = norm(guide.fpath.item(row, last, 0) - x, guide.fpath.item(row, last, 1) - y)
    return nearest, tx, ty, dgoal
