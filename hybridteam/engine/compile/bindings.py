"""What drives a mode's plant: a sampled or continuous law, ``inputs:`` expressions, a flow.

A mode declares at most one of ``law``, ``inputs`` and ``flow``; a leaf without one inherits
its nearest ancestor's, and an agent with none anywhere stands still (the "zero" driver).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import TYPE_CHECKING

from hybridteam.dynamics.plants import Plant
from hybridteam.engine.compile.compiled import CMode, Driver
from hybridteam.errors import did_you_mean
from hybridteam.expr import Expression, compile_expression
from hybridteam.laws import LawNotFound, asked_names, resolve
from hybridteam.model import Mode

if TYPE_CHECKING:
    from hybridteam.engine.compile.scope import Collector


def compile_driver(
    mode: Mode,
    idx: int,
    plant: Plant,
    syms,
    col: Collector,
    parameters: Mapping[str, float | str],
    folder: str | None = None,
    variables: Iterable[str] = (),
) -> Driver | None:
    """The driver a mode declares (None: it declares none); ``folder`` is where the team
    file lives, where ``module:function`` laws are looked for first.

    ``parameters`` are the agent's (team ones included); a law binding's ``with:`` values
    and the law's defaults are its *binding parameters* (``params`` of the binding, the
    law and the driver)."""
    declared = [k for k in ("law", "inputs", "flow") if getattr(mode, k) is not None]
    at = mode.body or mode.where  # a role's body, where a protocol's mode plays the role
    if len(declared) > 1:
        col.fail(
            at,
            f"mode '{mode.name}' declares both '{declared[0]}' and "
            f"'{declared[1]}'; a mode has one way to drive its plant",
        )
        return None
    if mode.flow is not None:
        if plant.kind != "flow":
            col.fail(
                (*at, "flow"),
                f"'flow' needs a flow plant; this agent is a "
                f"{plant.kind} (give 'law' or 'inputs' instead)",
            )
            return None
        exprs: list[Expression | None] = [None] * len(plant.state_names)
        for name, text in mode.flow.items():
            if name not in plant.state_names:
                col.fail(
                    (*at, "flow", name),
                    f"unknown state '{name}'",
                    did_you_mean(name, plant.state_names),
                )
                continue
            exprs[plant.state_names.index(name)] = col.expr(text, syms, (*at, "flow", name))
        return Driver("flow", idx, flow=exprs)
    if mode.inputs is not None:
        if plant.kind == "flow":
            col.fail((*at, "inputs"), "a flow plant has no inputs; use 'flow'")
            return None
        exprs_in: list[Expression] = []
        for name in mode.inputs:
            if name not in plant.input_names:
                col.fail(
                    (*at, "inputs", name),
                    f"a {plant.kind} plant has no input '{name}'",
                    did_you_mean(name, plant.input_names),
                )
        for name in plant.input_names:
            text = mode.inputs.get(name, 0.0)
            e = col.expr(text, syms, (*at, "inputs", name))
            exprs_in.append(e)  # type: ignore[arg-type]  # (None: col has the error; no run)
        period = mode.input_period
        held = bool(period) and all(
            e is not None and e.names <= parameters.keys() for e in exprs_in
        )
        return Driver(
            "sampled" if period else "continuous",
            idx,
            period=period or 0.0,
            inputs=exprs_in,
            held=held,
        )
    if mode.law is not None:
        b = mode.law
        if plant.kind == "flow":
            col.fail((*b.where,), "a flow plant has no inputs for a law to drive; use 'flow'")
            return None
        try:
            spec = resolve(b.name, folder)
        except LawNotFound as exc:
            col.fail(
                (*b.where, "use") if b.where else mode.where,
                str(exc),
                did_you_mean(b.name.rpartition(":")[2], exc.candidates),
            )
            return None
        if spec.plants and plant.kind not in spec.plants:
            col.fail(
                (*b.where, "use"),
                f"law '{b.name}' drives {'/'.join(spec.plants)} plants, not {plant.kind}",
            )
        pexprs: dict[str, Expression] = {}
        for name, default in spec.params.items():
            pexprs[name] = compile_expression(repr(float(default)), syms)
        for name, text in b.params.items():
            if spec.params and name not in spec.params:
                col.fail(
                    (*b.where, "with", name),
                    f"law '{b.name}' has no parameter '{name}'",
                    did_you_mean(name, spec.params),
                )
                continue
            e = col.expr(text, syms, (*b.where, "with", name))
            if e is not None:
                pexprs[name] = e
        for name in sorted(pexprs.keys() & set(plant.state_names)):
            # ctx[name] reads a binding parameter first: the law would never see the state
            given = name in b.params
            col.fail(
                (*b.where, "with", name) if given else (*b.where, "use"),
                f"binding parameter '{name}' of law '{spec.name}' has the name of a "
                "state of this agent, so the law would read the parameter, never the "
                "state; "
                + ("rename the parameter" if given else "the law cannot be bound to this plant"),
            )
        known = {*pexprs, *plant.state_names, *parameters, *variables}
        for name in sorted(asked_names(spec.fn) - known):
            col.fail(
                (*b.where, "use"),
                f"law '{spec.name}' reads ctx[{name!r}], which is no "
                "binding parameter, state, parameter or variable of this agent; give "
                "the agent that parameter",
                did_you_mean(name, known),
            )
        return Driver(
            "sampled" if b.period else "continuous",
            idx,
            period=b.period or 0.0,
            law=spec,
            params=pexprs,
            where=b.where or mode.where,
        )
    return None


def check_parallel_drivers(modes: list[CMode], col: Collector, flat) -> None:
    """At most one region of a parallel mode may drive the plant: inputs must be unambiguous."""
    for m in modes:
        if m.kind != "and":
            continue
        driving = [
            modes[c].name
            for c in m.children
            if any(modes[i].driver >= 0 for i in _subtree_indices(modes, c))
        ]
        if len(driving) > 1:
            col.fail(
                (*flat[m.index][1].where,),
                f"regions {', '.join(driving)} of parallel "
                f"mode '{m.path}' both drive the plant; only one region may",
            )


def _subtree_indices(modes: list[CMode], root: int) -> list[int]:
    out, stack = [], [root]
    while stack:
        i = stack.pop()
        out.append(i)
        stack.extend(modes[i].children)
    return out
