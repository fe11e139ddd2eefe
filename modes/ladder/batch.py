"""The vectorized stepper standing in for the engine on plain ladder teams (studies).

A parameter study runs thousands of ladder pairs; through the engine each period costs the
general machinery (event queue, mode trees, a law call per robot), through
:func:`.kernel.simulate` a few fused array operations. For a team that is exactly what the
kernel computes — two omni robots each running ``ladder.carry`` with a period of one step
from the start, whose ``arrived`` and ``stuck`` events lead to final modes, in one
``ladder.corridor`` world and nothing else — :func:`rows` gives the engine's per-instance
results from the kernel. Any other team returns None and runs through the engine. The
tests compare both paths instance by instance (outcomes and step counts equal, lengths to
rounding).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from hybridteam.library import AgentShape, BatchRequest, OneLaw
from hybridteam.world.geometry import corridor_with_turn

from .kernel import OUTCOMES, simulate
from .params import ROBOT_FIELDS, Pairs, Settings

_UNIFORM = (
    "width_in",
    "width_out",
    "outer_leg_in",
    "outer_leg_out",
    "goal_gap",
    "path_points",
    "tension",
    "approach",
    "alpha_inset",
    "arrive_tol",
    "stuck_window",
    "stuck_tol",
)


def _carrier(shape: AgentShape) -> OneLaw | None:
    """The robot's plan if it only carries the ladder (the kernel's robot), else None."""
    plan = shape.one_law()
    if (
        plan is None
        or shape.plant != "holonomic"
        or plan.law != "ladder.carry"
        or plan.period != 1.0
        or set(plan.bound) - {"window"}
        or set(plan.ends) != {"arrived", "stuck"}
    ):
        return None
    if any(k not in shape.params for k in ROBOT_FIELDS):
        return None
    return plan


def rows(request: BatchRequest) -> list[dict[str, Any]] | None:
    """The engine's per-instance rows for a plain ladder team, from the kernel; else None."""
    if len(request.components) != 1 or not request.quiet or len(request.agents) != 2:
        return None
    v = request.settings
    names = sorted(a.name for a in request.agents)
    if names != sorted([v["front"], v["rear"]]):
        return None
    robots = [request.agent(v["front"]), request.agent(v["rear"])]
    front, rear = (_carrier(r) for r in robots)
    if front is None or rear is None or front.ends != rear.ends:
        return None
    plans = [front, rear]
    windows = np.concatenate([p.params.get("window", np.full(request.n, 16.0)) for p in plans])
    uniform = {k: request.uniform(k) for k in _UNIFORM}
    if np.ptp(windows) != 0 or None in uniform.values():
        return None
    one = {k: x for k, x in uniform.items() if x is not None}  # (all of them, now)
    corridor = corridor_with_turn(
        one["width_in"], one["width_out"], one["outer_leg_in"], one["outer_leg_out"], turn=v["turn"]
    )
    settings = Settings(
        goal_gap=one["goal_gap"],
        path_points=int(one["path_points"]),
        tension=one["tension"],
        approach=one["approach"] if one["approach"] > 0 else None,
        alpha_inset=one["alpha_inset"],
        window=int(windows[0]),
        arrive_tol=one["arrive_tol"],
        stuck_window=int(one["stuck_window"]),
        stuck_tol=one["stuck_tol"],
        max_steps=int(np.floor(request.duration)),
        correction=str(v["correction"]),
        update=str(v["update"]),
    )
    start = np.stack([np.stack([r.initial["x"], r.initial["y"]], axis=-1) for r in robots])
    pairs = Pairs(
        np.asarray(v["length"], float).copy(),
        {k: np.stack([r.params[k] for r in robots]) for k in ROBOT_FIELDS},
    )
    result = simulate(pairs, corridor, settings, start=start)
    ends = plans[0].ends
    names_of = {"success": ends["arrived"], "stuck": ends["stuck"], "link_broken": "link_broken"}
    out = []
    for i in range(request.n):
        outcome = names_of[OUTCOMES[int(result.outcome[i])]]
        if result.steps[i] >= settings.max_steps and outcome == ends["stuck"]:
            outcome = "ok"  # the engine's run ends at its duration, the kernel's at max_steps
        out.append(
            {
                "instance": i,
                "outcome": outcome,
                "t_end": float(result.steps[i]),
                "steps": int(result.steps[i]),
                "steps_in_corner": int(result.corner_steps[i]),
                "path_length": [float(x) for x in result.path[i]],
                "corner_path_length": [float(x) for x in result.corner_path[i]],
                "max_offset": [float(x) for x in result.max_offset[i]],
            }
        )
    return out
