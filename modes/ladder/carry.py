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

import numpy as np

from hybridteam.library import LawContext
from hybridteam.library import law as register

from . import law

#: The robot's own parameters the law reads (the paper's table, Sec. 4).
ROBOT = ("v_max", "lookahead", "olim", "orsp", "kc", "kr", "sc", "radius", "ladder_margin")


@register("ladder.carry", plants=("holonomic",), params={"window": 16.0})
def carry(ctx: LawContext) -> np.ndarray:
    """Target, rotation and correction vectors, clamped, then the wall rules (Sec. 3.2)."""
    params = {k: np.asarray(ctx[k], dtype=float) for k in ROBOT}
    params.update(length=ctx.sense("length"), sc_partner=ctx.sense("sc_partner"),
                  goal_heading=ctx.sense("goal_heading"))
    own = ctx.state[:, :2]
    window = int(ctx["window"][0]) if ctx.size else 16
    path, frame = ctx.sense("path"), ctx.sense("frame")
    move, nearest = law.step(own, ctx.sense("partner"), path,
                             ctx.recall("nearest", 0.0).astype(np.int64), params,
                             ctx.sense("corridor"), window=window, frame=frame,
                             guide=_guide(path, frame, window),
                             correction=ctx.sense("correction"))
    ctx.keep("nearest", nearest)
    u = np.zeros((ctx.size, 3))  # vx, vy and no turning: np.column_stack's values
    u[:, :2] = move
    return u


#: Guides prepared lately: (frame, window, path, guide), newest last. A run's robots ask
#: for the same few paths at every period; comparing a path costs far less than preparing
#: it (the frame is kept alive with its entry, so ``is`` cannot match a new one by chance).
_GUIDES: list[tuple] = []


def _guide(path: np.ndarray, frame, window: int) -> law.Guide:
    """The prepared guide of ``path`` (equal paths, frame and window: the same guide)."""
    for entry in reversed(_GUIDES):
        f, w, p, guide = entry
        if f is frame and w == window and p.shape == path.shape and np.array_equal(p, path):
            return guide
    guide = law.Guide(path, frame, window)
    _GUIDES.append((frame, window, path.copy(), guide))
    del _GUIDES[:-8]
    return guide
