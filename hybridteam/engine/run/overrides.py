"""Per-instance parameter values: the agents' defaults with an ensemble's overrides applied.

Shared by the simulator and by libraries' batch simulators (which must see exactly the
parameters the engine would), so the rules live in one place: ``"agent.param"`` sets one
agent's parameter, a bare ``"param"`` every agent that has it (team parameters are copied
into every agent); a value is one number or one per instance. ``"network.jitter"`` (and
``latency``, ``loss``) sets the network's default link, ``"network.links.a->b.jitter"`` a
link the team declares: what the ``network:`` block says, replaced per instance, so a
setting the file gives as a number can be varied without making it a team parameter.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from hybridteam.engine.compile.compiled import CAgent, Ctx
from hybridteam.errors import did_you_mean
from hybridteam.model import NetworkSpec

#: what a link sets, in the order the network reads them
LINK_SETTINGS = ("latency", "jitter", "loss")
NETWORK = "network."  # the prefix of the network's override keys

Link = tuple[str, str] | None  # (sender, receiver), or None: the default link


def parameter_matrices(
    agents: Sequence[CAgent], n: int, overrides: Mapping[str, float | Sequence[float]]
) -> list[np.ndarray]:
    """One ``(n, P)`` parameter matrix per agent, defaults tiled, then overrides applied."""
    mats = [np.tile(ca.param_defaults, (n, 1)) for ca in agents]
    apply_overrides(agents, mats, n, overrides)
    return mats


def apply_overrides(
    agents: Sequence[CAgent],
    mats: Sequence[np.ndarray],
    n: int,
    overrides: Mapping[str, float | Sequence[float]],
    network: NetworkSpec | None = None,
) -> None:
    """Write ``overrides`` into the agents' ``(n, P)`` matrices; ValueError names a bad key
    (with the team's ``network``, its settings are among the keys it suggests).

    Parameters an agent writes as expressions (``ack_timeout: 2 * latency``) are then
    re-evaluated per instance from the overridden values, except those overridden
    themselves: an explicit value wins over the formula.
    """
    if not overrides:
        return  # the defaults already hold every derived value
    fixed: list[set[int]] = [set() for _ in agents]
    for key, value in overrides.items():
        values = override_values(key, value, n)
        problem = key_problem(agents, key, network)
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


def override_values(key: str, value: Any, n: int) -> np.ndarray:
    """An override's value as a number or ``n`` numbers, all finite; ValueError says why
    not."""
    values = np.asarray(value, dtype=float)
    if values.ndim > 1 or (values.ndim == 1 and values.size != n):
        raise ValueError(
            f"override '{key}': expected a number or {n} values, got shape {values.shape}"
        )
    if not np.isfinite(values).all():
        bad = np.flatnonzero(~np.isfinite(np.atleast_1d(values)))[0]
        raise ValueError(
            f"override '{key}': {np.atleast_1d(values)[bad]} (instance "
            f"{bad}) is not a finite number"
        )
    return values


def network_targets(network: NetworkSpec) -> dict[str, tuple[Link, str]]:
    """Each network override key and the link and setting it replaces."""
    out: dict[str, tuple[Link, str]] = {f"{NETWORK}{what}": (None, what) for what in LINK_SETTINGS}
    for link in network.links:
        out.update(
            {f"{NETWORK}links.{link[0]}->{link[1]}.{what}": (link, what) for what in LINK_SETTINGS}
        )
    return out


def sets_network(agents: Sequence[CAgent], key: str) -> bool:
    """Whether ``key`` is one of the network's settings (an agent called ``network`` keeps
    its own parameters)."""
    return key.startswith(NETWORK) and not any(ca.name == "network" for ca in agents)


def split_overrides(
    agents: Sequence[CAgent], overrides: Mapping[str, Any]
) -> tuple[dict[str, Any], dict[str, Any]]:
    """(the agents' parameter overrides, the network's setting overrides)."""
    medium = {k: v for k, v in overrides.items() if sets_network(agents, k)}
    return {k: v for k, v in overrides.items() if k not in medium}, medium


def key_problem(
    agents: Sequence[CAgent], key: str, network: NetworkSpec | None = None
) -> str | None:
    """Why ``key`` names no parameter of the agents (``"override 'x' names no parameter;
    did you mean 'speed'?"``) nor, given the team's ``network``, a network setting; or
    None when it names one."""
    targets = {} if network is None else network_targets(network)
    if targets and sets_network(agents, key):
        if key in targets:
            return None
        return f"override '{key}' names no network setting" + (
            f"; {hint}"
            if (hint := did_you_mean(key, list(targets)))
            else f" (settings: {', '.join(targets)})"
        )
    agent, _, name = key.rpartition(".")
    if any((not agent or ca.name == agent) and name in ca.param_index for ca in agents):
        return None
    known = sorted(
        {f"{ca.name}.{p}" for ca in agents for p in ca.param_index}
        | {p for ca in agents for p in ca.param_index}
        | set(targets)
    )
    return f"override '{key}' names no parameter" + (
        f"; {hint}" if (hint := did_you_mean(key, known)) else ""
    )
