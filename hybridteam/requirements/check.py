"""Compile a team's requirements and check them on a run: one verdict per instance.

A verdict says whether the requirement holds, its robustness (how far from failing: the
margin by which the worst case stays inside, negative when violated), and for a violation
the first time it is violated and the sub-formula that failed there.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from hybridteam.errors import ModelError, ModelErrors
from hybridteam.expr import ExpressionError
from hybridteam.requirements.catalog import Catalog
from hybridteam.requirements.formula import compile_formula
from hybridteam.requirements.nodes import Node
from hybridteam.requirements.signals import Signals


@dataclass
class CompiledRequirement:
    name: str
    formula: Node
    text: str
    description: str | None


@dataclass
class RequirementSet:
    """A team's compiled requirements and the message types they read."""

    requirements: list[CompiledRequirement]
    events: frozenset[str]
    catalog: Catalog | None = None

    def __bool__(self) -> bool:
        return bool(self.requirements)

    def observers(self, cteam: Any) -> dict[int, list[Any]]:
        """The engine watches for the comparisons it can locate exactly (:mod:`.observe`)."""
        from hybridteam.requirements.observe import observers

        if not self.requirements or self.catalog is None:
            return {}
        return observers([r.formula for r in self.requirements], cteam, self.catalog)

    def check(
        self,
        run: Any,
        params: Mapping[str, tuple[list[str], np.ndarray]],
        snapshots: Mapping[str, Any] | None = None,
    ) -> list[dict[str, dict]]:
        """Per instance of ``run``: ``{name: verdict}`` (see :func:`verdict`)."""
        if not self.requirements:
            return [{} for _ in range(run.n)]
        sig = Signals(run, params, self.events, snapshots)
        out: list[dict[str, dict]] = [{} for _ in range(run.n)]
        for req in self.requirements:
            rho = req.formula.rho0(sig)
            for i in range(run.n):
                out[i][req.name] = verdict(req.formula, sig, i, float(rho[i]))
        return out


def verdict(formula: Node, sig: Signals, i: int, rho: float) -> dict[str, Any]:
    """``satisfied``, ``robustness`` (``"inf"``/``"-inf"`` where a Boolean decided it, as
    JSON has no infinities; ``"nan"`` where a signal was not a number, as ``sqrt(-1)``
    is not, which satisfies nothing), and for a violation ``violated_at`` and
    ``failed``."""
    out: dict[str, Any] = {"satisfied": rho >= 0, "robustness": json_number(rho)}
    if rho < 0:
        t, failed = formula.blame(sig, i, 0)
        out["violated_at"], out["failed"] = t, failed
    return out


def json_number(x: float) -> float | str:
    """``x`` as JSON can hold it: the infinities and NaN as the strings ``"inf"``,
    ``"-inf"`` and ``"nan"`` (JSON has no such numbers)."""
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    if math.isnan(x):
        return "nan"
    return x


def compile_requirements(cteam: Any) -> RequirementSet:
    """The team's requirements compiled against its signals; every problem is collected
    and raised as :class:`ModelErrors` (located by the loader)."""
    team = cteam.team
    if not team.requirements:
        return RequirementSet([], frozenset())
    catalog = Catalog.of(cteam, _series(team))
    errors, done = [], []
    for req in team.requirements:
        try:
            node = compile_formula(req.formula, catalog)
        except ExpressionError as exc:
            errors.append(ModelError(req.where, exc.message, offset=exc.offset, hint=exc.hint))
            continue
        done.append(CompiledRequirement(req.name, node, req.formula, req.description))
    if errors:
        raise ModelErrors(errors)
    return RequirementSet(done, frozenset(catalog.used_events), catalog)


def _series(team: Any) -> dict[str, tuple[str, ...]]:
    """The world's sampled series (a payload's pose), from a one-instance world."""
    if not team.world:
        return {}
    from hybridteam.engine.run.world import World

    params = {k: np.array([float(v)]) for k, v in team.parameters.items()}
    try:
        return World(team, 1, params).sample_series()
    except Exception:  # a world that cannot be built fails the run with its own message
        return {}
