"""Requirement comparisons the engine can watch, so their crossings are exact.

A trace is sampled; a violation that starts between two samples would only be known to
within a sample period. A comparison that reads one agent's states (with parameters, team
parameters, ``t`` and constants) is handed to the engine as an *observer* watch: the
engine locates its zero crossings like a guard's (to ``event_tol``) and stops there, and
the state snapshot taken at that instant puts the crossing on the requirement's grid.
Comparisons over several agents, world series or counts are not located; their failures
start at the grid point where the sampled margin first turns negative (or where linear
interpolation puts the zero, see :meth:`~.nodes.Always.blame`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from hybridteam.engine.compile.compiled import Watch
from hybridteam.expr import Atom, ExpressionError
from hybridteam.requirements import nodes as N
from hybridteam.requirements.catalog import Catalog, Getter, Problem
from hybridteam.requirements.formula import compile_formula

_UFUNCS = {"<": np.less, "<=": np.less_equal, ">": np.greater, ">=": np.greater_equal}


class _AgentCatalog(Catalog):
    """Names of one agent, read from the engine's context instead of a run's signals."""

    def __init__(self, base: Catalog, agent: str, ca: Any) -> None:
        super().__init__(base.agents, base.team_params, {}, set())
        self.agent, self.ca = agent, ca

    def bare_symbols(self) -> dict[str, Getter]:
        syms: dict[str, Getter] = {"t": lambda c: c.t}
        for p, j in self.ca.param_index.items():
            if p in self.team_params or self.single() == self.agent:
                syms[p] = lambda c, j=j: c.p[:, j]  # type: ignore[misc]  # default-bound lambda
        if self.single() == self.agent:
            for x, j in self.ca.state_index.items():
                syms[x] = lambda c, j=j: c.x[:, j]  # type: ignore[misc]  # default-bound lambda
        return syms

    def dotted(self, text: str) -> tuple[Getter | None, Problem]:
        head, _, tail = text.partition(".")
        if head == self.agent and tail in self.ca.state_index:
            j = self.ca.state_index[tail]
            return (lambda c: c.x[:, j]), ("", None)
        if head == self.agent and tail in self.ca.param_index:
            j = self.ca.param_index[tail]
            return (lambda c: c.p[:, j]), ("", None)
        return None, ("not this agent's", None)

    def function(self, name: str, args: list) -> tuple[None, tuple[int, int, str, None]]:
        return None, (0, 0, "not a state", None)


def _predicates(node: N.Node) -> list[N.Predicate]:
    out = [node] if isinstance(node, N.Predicate) and node.continuous and node.op in _UFUNCS else []
    for child in node.children:
        out += _predicates(child)
    return out


def _atom(pred: N.Predicate) -> Atom:
    lhs, rhs, op = pred.lhs, pred.rhs, pred.op
    ufunc, less = _UFUNCS[op], op in ("<", "<=")
    assert lhs is not None and rhs is not None

    def margin(c: Any) -> Any:
        return np.subtract(rhs(c), lhs(c)) if less else np.subtract(lhs(c), rhs(c))

    def both(c: Any) -> tuple[Any, Any]:
        a, b = lhs(c), rhs(c)
        return ufunc(a, b), (np.subtract(b, a) if less else np.subtract(a, b))

    return Atom(pred.source, op, margin, lambda c: ufunc(lhs(c), rhs(c)), both)


def observers(formulas: list[N.Node], cteam: Any, catalog: Catalog) -> dict[int, list[Watch]]:
    """Per agent index, the watches of the formulas' single-agent state comparisons."""
    catalogs = [(ca, _AgentCatalog(catalog, ca.name, ca)) for ca in cteam.agents]
    out: dict[int, list[Watch]] = {}
    seen: set[tuple[str, str]] = set()
    for formula in formulas:
        for pred in _predicates(formula):
            for ca, cat in catalogs:
                if (ca.name, pred.source) in seen:
                    break
                try:
                    twin = compile_formula(pred.source, cat)
                except ExpressionError:
                    continue
                if isinstance(twin, N.Predicate) and twin.op in _UFUNCS:
                    seen.add((ca.name, pred.source))
                    out.setdefault(ca.index, []).append(
                        Watch(_atom(twin), 0, None, False, observer=True)
                    )
                break
    return out
