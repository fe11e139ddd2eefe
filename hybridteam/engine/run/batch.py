"""Building :class:`~hybridteam.world.request.BatchRequest` s from a compiled team.

Everything in a request is resolved here exactly as :class:`~.ensemble.Ensemble` resolves
it for a run — parameter overrides (:mod:`.overrides`), component settings
(:func:`~hybridteam.engine.compile.settings.component_values`), initial states from their
expressions — so a fast path starts from the values the engine would have used. The
team's shape is copied out of the compiled structures into plain frozen values; nothing of
the engine leaks through.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from hybridteam.engine.compile.compiled import CAgent, CTeam, Ctx
from hybridteam.engine.compile.settings import component_values
from hybridteam.engine.run.overrides import parameter_matrices, split_overrides
from hybridteam.engine.run.randomness import seed_value
from hybridteam.world.component import WorldComponent, lookup
from hybridteam.world.request import AgentShape, BatchRequest, ModeShape, TransitionShape


def offers_batch(cls: type[WorldComponent]) -> bool:
    """Whether a component class has a batch fast path at all (saves building requests)."""
    # (a classmethod read off its class is a bound method: ``__func__`` is the function)
    base = getattr(WorldComponent.batch, "__func__", None)
    return getattr(cls.batch, "__func__", None) is not base


def batch_rows(
    cteam: CTeam, n: int, overrides: Mapping[str, Any], seed: int | Sequence[int]
) -> list[dict[str, Any]] | None:
    """Rows from the first world component whose fast path accepts the team, else None."""
    classes = [lookup(spec.use) for spec in cteam.team.world]
    if not any(offers_batch(cls) for cls in classes):
        return None
    if split_overrides(cteam.agents, overrides)[1]:  # a request carries no network settings
        return None
    mats = parameter_matrices(cteam.agents, n, overrides)
    shapes = tuple(_shape(ca, p, n) for ca, p in zip(cteam.agents, mats, strict=True))
    first = cteam.agents[0] if cteam.agents else None
    team_params = (
        {k: mats[0][:, first.param_index[k]].copy() for k in cteam.team.parameters}
        if first is not None
        else {}
    )
    for k, (cls, spec) in enumerate(zip(classes, cteam.team.world, strict=True)):
        if not offers_batch(cls):
            continue
        request = BatchRequest(
            team=cteam.team,
            n=n,
            seed=seed_value(seed, n),
            duration=float(cteam.team.simulation.duration),
            component=k,
            settings=component_values(cls, spec.values, team_params, n, spec.where),
            agents=shapes,
            team_params=team_params,
        )
        rows = cls.batch(request)
        if rows is not None:
            return rows
    return None


def _shape(ca: CAgent, p: np.ndarray, n: int) -> AgentShape:
    x0, v0 = ca.initial_values(p)
    start = Ctx(x0, v0, p, np.zeros(n))  # law bindings see the initial state
    modes, law_params = [], {}
    for m in ca.modes:
        drv = ca.drivers[m.driver] if m.driver >= 0 else None
        spec = drv.law if drv is not None and drv.inputs is None else None
        law = spec.name if spec is not None else None
        if drv is not None and spec is not None:
            values = {k: np.full(n, float(v)) for k, v in spec.params.items()}
            values.update(
                {
                    k: np.broadcast_to(np.asarray(e(start), float), (n,)).copy()
                    for k, e in drv.params.items()
                }
            )
            law_params[m.path] = values
        modes.append(
            ModeShape(
                path=m.path,
                kind=m.kind,
                parent=ca.modes[m.parent].path if m.parent >= 0 else None,
                initial=ca.modes[m.initial].path if m.initial >= 0 else None,
                final=m.final,
                outcome=ca.outcome[m.index],
                law=law,
                period=float(drv.period) if drv is not None else 0.0,
                bound=tuple(drv.params) if drv is not None else (),
                inputs=drv is not None and drv.inputs is not None,
                flow=drv is not None and drv.kind == "flow",
                invariant=m.invariant_text,
            )
        )
    transitions = tuple(
        TransitionShape(
            source=ca.modes[tr.source].path,
            target=ca.modes[tr.target].path,
            on=tr.on,
            guard=tr.guard_text,
            after=tr.after is not None,
            actions=len(tr.actions),
            internal=tr.internal,
        )
        for tr in ca.transitions
    )
    names = ca.plant.input_names
    return AgentShape(
        name=ca.name,
        index=ca.index,
        plant=ca.plant.kind,
        state_names=tuple(ca.plant.state_names),
        input_names=tuple(names),
        limits={k: (float(ca.lower[j]), float(ca.upper[j])) for j, k in enumerate(names)},
        params={k: p[:, j].copy() for k, j in ca.param_index.items()},
        initial={k: x0[:, j].copy() for j, k in enumerate(ca.plant.state_names)},
        variables=tuple(ca.var_index),
        modes=tuple(modes),
        transitions=transitions,
        law_params=law_params,
    )
