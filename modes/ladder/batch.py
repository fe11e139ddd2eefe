"""The vectorized stepper standing in for the engine on plain ladder teams (studies).

A parameter study runs thousands of ladder pairs; through the engine each period costs the
general machinery (event queue, mode trees, a law call per robot), through
:func:`.kernel.simulate` a few fused array operations. For a team that is exactly what the
kernel computes — two omni robots under ``ladder.carry`` with a period of one step, whose
``arrived`` and ``stuck`` events lead to final modes, in one ``ladder.corridor`` world and
nothing else — :func:`rows` gives the engine's per-instance results from the kernel. Any
other team returns None and runs through the engine. The tests compare both paths
instance by instance (outcomes and step counts equal, lengths to rounding).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from hybridteam.engine.compiled import CAgent, Ctx, Driver
from hybridteam.engine.compiler import compile_team
from hybridteam.engine.overrides import parameter_matrices
from hybridteam.engine.world import component_values
from hybridteam.errors import ModelErrors
from hybridteam.world.geometry import corridor_with_turn

from .kernel import OUTCOMES, simulate
from .params import ROBOT_FIELDS, Pairs, Settings

if TYPE_CHECKING:
    from hybridteam.model import Team
    from hybridteam.world.component import WorldComponent

_UNIFORM = ("width_in", "width_out", "outer_leg_in", "outer_leg_out", "goal_gap",
            "path_points", "tension", "approach", "alpha_inset", "arrive_tol", "stuck_window",
            "stuck_tol")


def _carrier(ca: CAgent) -> tuple[Driver, dict[str, str]] | None:
    """(its driver, {event: outcome}) if the agent only carries the ladder, else None."""
    drivers = [d for d in ca.drivers if d.kind != "zero"]
    if ca.plant.kind != "holonomic" or len(drivers) != 1:
        return None
    drv = drivers[0]
    if drv.kind != "sampled" or drv.law is None or drv.law.name != "ladder.carry" \
            or drv.period != 1.0 or set(drv.params) - {"window"}:
        return None
    carry = ca.modes[drv.owner]
    root = ca.modes[0]
    if carry.kind != "leaf" or root.initial != carry.index or carry.parent != 0:
        return None
    ends: dict[str, str] = {}
    for tr in ca.transitions:
        if tr.source != carry.index or tr.on not in ("arrived", "stuck") or tr.guard \
                or tr.after is not None or tr.actions or tr.internal:
            return None
        target = ca.modes[tr.target]
        if not target.final:
            return None
        ends[tr.on] = ca.outcome[tr.target] or "ok"
    if set(ends) != {"arrived", "stuck"}:
        return None
    return drv, ends


def rows(cls: type[WorldComponent], team: Team, n: int, overrides: Mapping[str, Any],
         seed: int | Any) -> list[dict[str, Any]] | None:
    """The engine's per-instance rows for a plain ladder team, from the kernel; else None."""
    if len(team.world) != 1 or team.scenario or team.messages or any(
            a.streams for a in team.agents) or len(team.agents) != 2:
        return None
    try:
        cteam = compile_team(team)
    except ModelErrors:
        return None
    spec = team.world[0]
    names = [a.name for a in team.agents]
    front, rear = (spec.values.get(k, cls.params[k]) for k in ("front", "rear"))
    if sorted(names) != sorted([front, rear]):
        return None
    agents = [cteam.agents[names.index(front)], cteam.agents[names.index(rear)]]
    plans = [_carrier(ca) for ca in agents]
    if None in plans or plans[0][1] != plans[1][1]:  # type: ignore[index]
        return None
    ends = plans[0][1]  # type: ignore[index]
    mats = parameter_matrices(cteam.agents, n, overrides)
    p = [mats[names.index(front)], mats[names.index(rear)]]
    windows = np.concatenate([_window(plan[0], ca, m, n) for plan, ca, m  # type: ignore[index]
                              in zip(plans, agents, p, strict=True)])
    if np.ptp(windows) != 0:
        return None
    window = float(windows[0])
    first = p[0]
    team_params = {k: first[:, agents[0].param_index[k]] for k in team.parameters}
    v = component_values(cls, spec.values, team_params, n)
    if any(np.ptp(v[k]) != 0 for k in _UNIFORM) or any(
            k not in ca.param_index for k in ROBOT_FIELDS for ca in agents):
        return None
    one = {k: float(v[k][0]) for k in _UNIFORM}
    corridor = corridor_with_turn(one["width_in"], one["width_out"], one["outer_leg_in"],
                                  one["outer_leg_out"], turn=v["turn"])
    settings = Settings(
        goal_gap=one["goal_gap"], path_points=int(one["path_points"]), tension=one["tension"],
        approach=one["approach"] if one["approach"] > 0 else None,
        alpha_inset=one["alpha_inset"], window=int(window), arrive_tol=one["arrive_tol"],
        stuck_window=int(one["stuck_window"]), stuck_tol=one["stuck_tol"],
        max_steps=int(np.floor(team.simulation.duration)))
    start = np.stack([_initial_xy(ca, m, n) for ca, m in zip(agents, p, strict=True)])
    pairs = Pairs(v["length"].copy(), {k: np.stack([m[:, ca.param_index[k]] for ca, m
                                                    in zip(agents, p, strict=True)])
                                       for k in ROBOT_FIELDS})
    result = simulate(pairs, corridor, settings, start=start)
    out = []
    names_of = {"success": ends["arrived"], "stuck": ends["stuck"], "link_broken": "link_broken"}
    for i in range(n):
        outcome = names_of[OUTCOMES[int(result.outcome[i])]]
        if result.steps[i] >= settings.max_steps and outcome == ends["stuck"]:
            outcome = "ok"  # the engine's run ends at its duration, the kernel's at max_steps
        out.append({"instance": i, "outcome": outcome, "t_end": float(result.steps[i]),
                    "steps": int(result.steps[i]),
                    "steps_in_corner": int(result.corner_steps[i]),
                    "path_length": [float(x) for x in result.path[i]],
                    "corner_path_length": [float(x) for x in result.corner_path[i]],
                    "max_offset": [float(x) for x in result.max_offset[i]]})
    return out


def _window(drv: Driver, ca: CAgent, p: np.ndarray, n: int) -> np.ndarray:
    """The law binding's search window per instance (the law's default is 16)."""
    if "window" not in drv.params:
        return np.full(n, 16.0)
    return np.broadcast_to(np.asarray(drv.params["window"](_start_ctx(ca, p, n)), float), (n,))


def _start_ctx(ca: CAgent, p: np.ndarray, n: int) -> Ctx:
    """A context in which expressions of parameters (initial states, bindings) evaluate."""
    return Ctx(np.zeros((n, len(ca.plant.state_names))), np.zeros((n, len(ca.var_index))), p,
               np.zeros(n))


def _initial_xy(ca: CAgent, p: np.ndarray, n: int) -> np.ndarray:
    """The agent's initial (x, y) per instance, from its plant's state expressions."""
    ctx = _start_ctx(ca, p, n)
    cols = [np.broadcast_to(e(ctx), (n,)) for e in ca.init_state[:2]]
    return np.stack(cols, axis=-1).astype(float)
