"""Per-instance parameter values: the agents' defaults with an ensemble's overrides applied.

Shared by the simulator and by libraries' batch simulators (which must see exactly the
parameters the engine would), so the rules live in one place: ``"agent.param"`` sets one
agent's parameter, a bare ``"param"`` every agent that has it (team parameters are copied
into every agent); a value is one number or one per instance.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from hybridteam.engine.compiled import CAgent, Ctx
from hybridteam.errors import did_you_mean


def parameter_matrices(agents: Sequence[CAgent], n: int,
                       overrides: Mapping[str, float | Sequence[float]]) -> list[np.ndarray]:
    """One ``(n, P)`` parameter matrix per agent, defaults tiled, then overrides applied."""
    mats = [np.tile(ca.param_defaults, (n, 1)) for ca in agents]
    apply_overrides(agents, mats, n, overrides)
    return mats


def apply_overrides(agents: Sequence[CAgent], mats: Sequence[np.ndarray], n: int,
                    overrides: Mapping[str, float | Sequence[float]]) -> None:
    """Write ``overrides`` into the agents' ``(n, P)`` matrices; ValueError names a bad key.

    Parameters an agent writes as expressions (``ack_timeout: 2 * latency``) are then
    re-evaluated per instance from the overridden values, except those overridden
    themselves: an explicit value wins over the formula.
    """
    if not overrides:
        return  # the defaults already hold every derived value
    fixed: list[set[int]] = [set() for _ in agents]
    for key, value in overrides.items():
        values = np.asarray(value, dtype=float)
        if values.ndim > 1 or (values.ndim == 1 and values.size != n):
            raise ValueError(f"override '{key}': expected a number or {n} values, "
                             f"got shape {values.shape}")
        if not np.isfinite(values).all():
            bad = np.flatnonzero(~np.isfinite(np.atleast_1d(values)))[0]
            raise ValueError(f"override '{key}': {np.atleast_1d(values)[bad]} (instance "
                             f"{bad}) is not a finite number")
        problem = key_problem(agents, key)
        if problem is not None:
            raise ValueError(problem)
        agent, _, name = key.rpartition(".")
        for ca, p, own in zip(agents, mats, fixed, strict=True):
            if (not agent or ca.name == agent) and name in ca.param_index:
                p[:, ca.param_index[name]] = values
                own.add(ca.param_index[name])
    for ca, p, own in zip(agents, mats, fixed, strict=True):
        if ca.derived_params:
            ctx = Ctx(np.zeros((n, 0)), np.zeros((n, 0)), p, np.zeros(n))
            for j, expr in ca.derived_params:
                if j not in own:
                    p[:, j] = np.broadcast_to(expr(ctx), (n,))


def key_problem(agents: Sequence[CAgent], key: str) -> str | None:
    """Why ``key`` names no parameter of the agents (``"override 'x' names no parameter;
    did you mean 'speed'?"``), or None when it names one."""
    agent, _, name = key.rpartition(".")
    if any((not agent or ca.name == agent) and name in ca.param_index for ca in agents):
        return None
    known = sorted({f"{ca.name}.{p}" for ca in agents for p in ca.param_index}
                   | {p for ca in agents for p in ca.param_index})
    return f"override '{key}' names no parameter" + \
        (f"; {hint}" if (hint := did_you_mean(key, known)) else "")
