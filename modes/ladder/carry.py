"""The ladder robots' law as an engine law: ``ladder.carry``, one control period per step.

Each robot runs :func:`.law.step` on what it senses through the ladder component
(``ladder.corridor``): its partner's position (the other end of the ladder it holds), its
guide path, the goal heading and the ladder's length and far spring. Its progress along
the path (the index of the nearest path point, searched near the previous one) is the
law's memory, kept from one period to the next. The output is the displacement of one
period as a velocity (the law's period is the time unit), so an omni-directional plant
moves exactly by it: ``x + m * 1``.
"""

from __future__ import annotations

from typing import cast

import numpy as np

from hybridteam.library import FLOAT_PATHS, LawContext
from hybridteam.library import law as register
from hybridteam.world.geometry import Corridor

from . import law, law_one

#: The robot's own parameters the law reads (the paper's table, Sec. 4).
ROBOT = ("v_max", "lookahead", "olim", "orsp", "kc", "kr", "sc", "radius", "ladder_margin")


@register("ladder.carry", plants=("holonomic",), params={"window": 16.0})
def carry(ctx: LawContext) -> np.ndarray:
    """Target, rotation and correction vectors, clamped, then the wall rules (Sec. 3.2)."""
    window = int(ctx["window"][0]) if ctx.size else 16
    if 0 < ctx.size <= FEW and FLOAT_PATHS.on:
        try:
            return _few(ctx, window)
        except law_one.Diverged:
            pass  # the arrays' inf and NaN, from the array version below
    partner, length, sc_partner, frame, correction = ctx.sense("period")
    path, guide, _ = _prepared(ctx, frame, window)
    table = ctx.table(ROBOT)
    own = ctx.state[:, :2]
    idx = ctx.recall("nearest", 0.0).astype(np.int64)
    u = np.zeros((ctx.size, 3))  # vx, vy and no turning: np.column_stack's values
    params = {k: table[:, j] for j, k in enumerate(ROBOT)}
    params.update(length=length, sc_partner=sc_partner)
    if (params["kr"] != 0.0).any():  # the goal heading matters only to the rotation vector
        params["goal_heading"] = ctx.sense("goal_heading")
    corridor = cast(Corridor, ctx.sense("corridor"))  # (the component senses its corridor)
    move, nearest = law.step(
        own,
        partner,
        path,
        idx,
        params,
        corridor,
        window=window,
        frame=frame,
        guide=guide,
        correction=correction,
    )
    ctx.keep("nearest", nearest)
    u[:, :2] = move
    return u


#: Up to this many instances the law runs on floats, row by row (:mod:`.law_one`).
FEW = 4


def _few(ctx: LawContext, window: int) -> np.ndarray:
    """:func:`.law.step` for a few rows on floats: the inputs ``(m, 3)`` (no turning);
    the new indices are kept. Every array is read once, as a list; nothing is kept where a
    row raises :class:`.law_one.Diverged` (the caller then takes the array version)."""
    partner, length, sc_partner, frame, correction = ctx.sense("period")
    _, guide, robots = _prepared(ctx, frame, window)
    heading = ctx.sense("goal_heading").tolist() if any(r["kr"] != 0.0 for r in robots) else None
    u, nearest = [], []
    for i, (robot, ell, scp, xy, pxy, k) in enumerate(
        zip(
            robots,
            length.tolist(),
            sc_partner.tolist(),
            ctx.state.tolist(),
            partner.tolist(),
            ctx.recall("nearest", 0.0).tolist(),
            strict=True,
        )
    ):
        p = dict(robot)
        p["length"], p["sc_partner"] = ell, scp
        if heading is not None:
            p["hx"], p["hy"] = heading[i]
        if not -_INDEX_RANGE < k < _INDEX_RANGE:  # (NaN too) astype's own conversion
            raise law_one.Diverged(f"kept index {k}")
        # the index kept as a float, toward zero as astype(np.int64) converts it
        dx, dy, near = law_one.step_one(
            (xy[0], xy[1]), tuple(pxy), guide, i, int(k), p, frame, window, correction
        )
        u.append((dx, dy, 0.0))
        nearest.append(near)
    ctx.keep("nearest", nearest)
    return np.array(u, dtype=float)


#: kept indices beyond this (or NaN) are left to the array version's conversion
_INDEX_RANGE = 2.0**62

#: Guides prepared lately: (frame, window, robot and instances, path, guide, robots),
#: newest last. A robot's guide paths are the corridor component's, built once at the start
#: of a run (whose frame is kept alive with its entry, so ``is`` cannot match a new one by
#: chance): the same robot and instances of the same run have the same paths, and the law
#: prepares them once instead of at every period. So are the robots' parameters (``robots``,
#: one dict of :data:`ROBOT` per instance, for the float version): an agent parameter is a
#: constant of its instance for the whole run.
_GUIDES: list[tuple] = []


def _prepared(
    ctx: LawContext, frame, window: int
) -> tuple[np.ndarray, law.Guide, list[dict[str, float]]]:
    """The guide paths of this robot's instances, their prepared guide, and the robot's
    parameters per instance."""
    key = (ctx.agent, ctx.instances.tobytes())
    for entry in reversed(_GUIDES):
        f, w, k, path, guide, robots = entry
        if f is frame and w == window and k == key:
            return path, guide, robots
    path = ctx.sense("path")
    guide = law.Guide(path, frame, window)
    robots = [dict(zip(ROBOT, row, strict=True)) for row in ctx.table(ROBOT).tolist()]
    _GUIDES.append((frame, window, key, path, guide, robots))
    del _GUIDES[:-8]
    return path, guide, robots
