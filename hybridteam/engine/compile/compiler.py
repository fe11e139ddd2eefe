"""Compile declared agents and teams into :mod:`.compiled` structures.

All name resolution happens here, so a model that compiles cannot fail on an unknown name
half-way through a run; every problem found is collected (with its document path) and
raised together as :class:`~hybridteam.errors.ModelErrors`. An agent is compiled in four
steps, one function each: its names (plant, state, variables, parameters), its initial
values and limits, its mode tree with drivers (:mod:`.bindings`), and its transitions
(:mod:`.transitions`).
"""

from __future__ import annotations

from collections import ChainMap
from collections.abc import Mapping, MutableMapping
from dataclasses import dataclass

import numpy as np

from hybridteam.dynamics.plants import Plant, make_plant
from hybridteam.engine.compile.bindings import check_parallel_drivers, compile_driver
from hybridteam.engine.compile.compiled import (
    CONTINUOUS_NAMES,
    RESERVED,
    CAgent,
    CMode,
    CTeam,
    CTransition,
    Ctx,
    Driver,
)
from hybridteam.engine.compile.protocols import attach, check_messages, team_symbols
from hybridteam.engine.compile.scope import Collector, resolve_mode, symbols
from hybridteam.engine.compile.settings import check_network, check_world
from hybridteam.engine.compile.transitions import (
    compile_actions,
    compile_transitions,
    entry_to,
    group_triggered,
    watches,
)
from hybridteam.engine.compile.values import transition_delay
from hybridteam.errors import ModelError, ModelErrors, did_you_mean
from hybridteam.expr import Expression
from hybridteam.model import Agent, Mode, Send, Team

__all__ = ["compile_agent", "compile_team", "message_fields", "resolve_mode"]


def message_fields(team: Team) -> dict[str, set[str]]:
    """The fields sent with each message type anywhere in the team (the receivers' view):
    by transitions' actions and by modes' entry and exit actions."""
    out: dict[str, set[str]] = {name: set(spec.fields) for name, spec in team.messages.items()}
    for agent in team.agents:
        for _, mode in agent.root.walk():
            lists = [tr.actions for tr in mode.transitions] + [mode.on_entry, mode.on_exit]
            for actions in lists:
                for act in actions:
                    if isinstance(act, Send):
                        out.setdefault(act.message, set()).update(act.fields)
    return out


def _flatten(root: Mode) -> tuple[list[tuple[str, Mode, int, int]], dict[int, list[int]]]:
    """Pre-order list of (path, mode, parent, depth); paths exclude the root's name."""
    out: list[tuple[str, Mode, int, int]] = []
    children: dict[int, list[int]] = {}

    def visit(mode: Mode, path: str, parent: int, depth: int) -> None:
        idx = len(out)
        out.append((path, mode, parent, depth))
        children[idx] = []
        if parent >= 0:
            children[parent].append(idx)
        for child in mode.children:
            visit(child, f"{path}.{child.name}" if path else child.name, idx, depth + 1)

    visit(root, "", -1, 0)
    return out, children


# --------------------------------------------------------------------------- agents


@dataclass
class _Names:
    """An agent's plant and the columns of its names: what its expressions can read."""

    plant: Plant
    state: dict[str, int]
    variables: dict[str, int]
    parameters: dict[str, float | str]  # team parameters, then the agent's (overriding them)
    param_index: dict[str, int]
    syms: MutableMapping  # every name an expression of the agent may use
    param_syms: Mapping  # parameters only (initial values are evaluated before anything runs)
    defaults: np.ndarray  # every parameter's value, derived ones evaluated on the defaults
    derived: tuple[tuple[int, Expression], ...]  # (column, expression) of derived ones


def _names(
    agent: Agent, team_params: dict[str, float], extra_symbols: dict | None, col: Collector
) -> _Names:
    try:
        plant = make_plant(agent.plant.kind, tuple(agent.plant.state))
    except KeyError:
        col.fail(
            (*agent.plant.where, "kind"),
            f"unknown plant kind '{agent.plant.kind}'",
            did_you_mean(agent.plant.kind, ["unicycle", "holonomic", "flow", "none"]),
        )
        raise ModelErrors(col.errors) from None
    state_index = {n: j for j, n in enumerate(plant.state_names)}
    var_index = {n: j for j, n in enumerate(agent.variables)}
    parameters = {**team_params, **agent.parameters}
    param_index = {n: j for j, n in enumerate(parameters)}
    seen: dict[str, str] = {}
    for kind, names in (
        ("state", state_index),
        ("variable", var_index),
        ("parameter", agent.parameters),
    ):
        for n in names:
            if n in RESERVED or n.startswith("__"):
                col.fail(
                    (*agent.where, kind if kind != "state" else "plant", n),
                    f"'{n}' is a reserved name",
                )
            elif n in seen and not (seen[n] == "parameter" and kind == "parameter"):
                col.fail((*agent.where, n), f"name '{n}' is both a {seen[n]} and a {kind}")
            seen[n] = kind
    # the agent's own names over the team's (``id_<agent>``: one per agent), chained, not
    # copied: a copy per agent made a team of thousands quadratic to compile
    extra = extra_symbols or {}
    param_syms = ChainMap(symbols({}, {}, param_index), extra)
    defaults, derived = _derived(agent, parameters, param_index, param_syms, col)
    return _Names(
        plant,
        state_index,
        var_index,
        parameters,
        param_index,
        ChainMap(symbols(state_index, var_index, param_index), extra),
        param_syms,
        defaults,
        derived,
    )


def _derived(
    agent: Agent,
    parameters: dict[str, float | str],
    param_index: dict[str, int],
    param_syms: Mapping,
    col: Collector,
) -> tuple[np.ndarray, tuple[tuple[int, Expression], ...]]:
    """Default values of every parameter, and the agent's parameters written as
    expressions (``ack_timeout: 2 * latency + 0.05``).

    A derived parameter reads the team's parameters and the agent's own parameters declared
    above it (so there is an order and no cycle); it is re-evaluated per instance after an
    ensemble's overrides (see :func:`.overrides.apply_overrides`), unless it is overridden
    itself. Its default is the expression on the defaults.
    """
    values = np.zeros((1, len(parameters)))
    derived: list[tuple[int, Expression]] = []
    readable: set[str] = set()  # the parameters declared so far
    ctx = Ctx(np.zeros((1, 0)), np.zeros((1, 0)), values, np.zeros(1))
    for name, value in parameters.items():
        j = param_index[name]
        if isinstance(value, str):
            where = (*agent.where, "parameters", name)
            expr = col.expr(value, param_syms, where)
            later = sorted((expr.names - readable) & set(parameters)) if expr else []
            if later:
                col.fail(
                    where,
                    f"parameter '{name}' reads '{later[0]}', which is not declared above it",
                    "a parameter may read the team's parameters "
                    "and the agent's own parameters declared before it",
                )
            elif expr is not None:
                values[0, j] = float(np.asarray(expr(ctx), float).reshape(-1)[0])
                derived.append((j, expr))
        else:
            values[0, j] = float(value)
        readable.add(name)
    return values[0], tuple(derived)


def _initial_values(
    agent: Agent, names: _Names, col: Collector
) -> tuple[list[Expression], list[Expression], np.ndarray, np.ndarray]:
    """Initial state and variable expressions, and the inputs' lower and upper limits."""
    plant, where = names.plant, agent.plant.where
    missing = [n for n in plant.state_names if n not in agent.plant.state]
    if plant.kind != "flow" and (missing or set(agent.plant.state) - set(plant.state_names)):
        for n in sorted(set(agent.plant.state) - set(plant.state_names)):
            col.fail(
                (*where, "state", n),
                f"a {plant.kind} plant has no state '{n}'",
                f"its state is {', '.join(plant.state_names)}",
            )
    init_state = [
        col.expr(agent.plant.state.get(n, 0.0), names.param_syms, (*where, "state", n))
        for n in plant.state_names
    ]
    init_vars = [
        col.expr(v, names.param_syms, (*agent.where, "variables", n))
        for n, v in agent.variables.items()
    ]
    lower = np.full(len(plant.input_names), -np.inf)
    upper = np.full(len(plant.input_names), np.inf)
    for n, (lo, hi) in agent.plant.limits.items():
        if n not in plant.input_names:
            col.fail(
                (*where, "limits", n),
                f"a {plant.kind} plant has no input '{n}'",
                did_you_mean(n, plant.input_names),
            )
            continue
        if lo > hi:
            col.fail((*where, "limits", n), f"lower limit {lo} exceeds upper {hi}")
        lower[plant.input_names.index(n)], upper[plant.input_names.index(n)] = lo, hi
    return init_state, init_vars, lower, upper  # type: ignore[return-value]  # (None only beside an error in col)


def _modes(
    agent: Agent,
    flat: list[tuple[str, Mode, int, int]],
    children: dict[int, list[int]],
    names: _Names,
    col: Collector,
    folder: str | None,
) -> tuple[list[CMode], list[Driver]]:
    """The mode tree in pre-order with initial children, drivers and invariants."""
    modes: list[CMode] = []
    drivers: list[Driver] = [Driver("zero", -1)]
    deeper: dict[int, int] = {}  # an 'initial' naming a deeper descendant, by mode
    history_default: dict[int, int] = {}
    for idx, (path, mode, parent, depth) in enumerate(flat):
        kind = "leaf" if not mode.children else ("and" if mode.parallel else "or")
        initial = -1
        at = mode.body or mode.where  # a role's body gives a protocol mode its submodes
        if kind == "or":
            kids = [c.name for c in mode.children]
            init_name = mode.initial or (kids[0] if len(kids) == 1 else None)
            if init_name is None:
                col.fail(
                    (*at, "initial"),
                    f"mode '{path or agent.name}' has {len(kids)} children and no 'initial'",
                )
            elif init_name in kids:
                initial = children[idx][kids.index(init_name)]
            else:
                deeper[idx] = _descendant(
                    init_name, idx, flat, (*at, "initial"), "initial mode", col
                )
            if mode.history_default is not None:
                history_default[idx] = _descendant(
                    mode.history_default,
                    idx,
                    flat,
                    (*mode.where, "history", "default"),
                    "history default",
                    col,
                )
        elif mode.initial is not None and kind == "and":
            col.fail(
                (*at, "initial"), "a parallel mode enters all its regions; it has no 'initial'"
            )
        if mode.history_default is not None and kind != "or":
            col.fail(
                (*mode.where, "history", "default"),
                "a history default is where a "
                "composite enters one of its children while nothing is remembered; "
                + (
                    "a parallel mode enters all its regions: give it to a region"
                    if kind == "and"
                    else "this mode has no children"
                ),
            )
        driver = compile_driver(
            mode, idx, names.plant, names.syms, col, names.parameters, folder, names.variables
        )
        if driver is not None:
            drivers.append(driver)
        inv = None
        if mode.invariant is not None:
            inv = col.expr(mode.invariant, names.syms, (*mode.where, "invariant"), condition=True)
        modes.append(
            CMode(
                idx,
                mode.name,
                path,
                parent,
                depth,
                kind,
                children[idx],
                initial,
                mode.history,
                mode.final,
                len(drivers) - 1 if driver else -1,
                inv,
                str(mode.invariant or ""),
                role=mode.role,
            )
        )
        if mode.final and mode.children:
            col.fail((*mode.where, "final"), "only leaf modes can be final")
        if kind == "leaf" and mode.history != "none":
            col.fail(
                (*mode.where, "history"),
                f"mode '{path or agent.name}' has no modes to "
                "remember: 'history' restores a composite mode's last active child; "
                "remove it, or give the mode 'modes'",
            )
    for m in modes:
        target = deeper.get(m.index, m.initial)
        if target >= 0:
            m.default = entry_to(modes, m.index, [target])
            m.initial = m.default.first
        if history_default.get(m.index, -1) >= 0:
            m.history_default = entry_to(modes, m.index, [history_default[m.index]])
    check_parallel_drivers(modes, col, flat)
    for m in reversed(modes):
        sub = [m.index]
        for c in m.children:
            sub.extend(modes[c].subtree.tolist())
        m.subtree = np.array(sorted(sub), dtype=np.intp)
    return modes, drivers


def _check_delays(transitions: list[CTransition], names: _Names, col: Collector) -> None:
    """``after:`` delays of parameters alone, checked on the agent's own values as entering
    the mode checks them (a delay reading the state or the time is checked there only)."""
    ctx = Ctx(
        np.zeros((1, len(names.state))),
        np.zeros((1, len(names.variables))),
        names.defaults[None, :],
        np.zeros(1),
    )
    for ct in transitions:
        if ct.after is None or not ct.after.names <= names.param_index.keys():
            continue
        try:
            transition_delay(ct, ctx, np.zeros(1, np.intp))
        except ModelError as exc:
            col.errors.append(ModelError(exc.path, exc.message.replace(" in instance 0", "")))


def _descendant(
    name: str,
    idx: int,
    flat: list[tuple[str, Mode, int, int]],
    where: tuple,
    what: str,
    col: Collector,
) -> int:
    """The descendant of mode ``idx`` that ``name`` names (a unique name or a dotted path
    below the mode), -1 with an error collected if none or several do."""
    path = flat[idx][0]
    prefix = f"{path}." if path else ""
    below = [
        p[len(prefix) :] if i != idx and p.startswith(prefix) else ""
        for i, (p, _m, _q, _d) in enumerate(flat)
    ]
    found, matches = resolve_mode(name, below)
    if found is None:
        col.fail(
            where,
            f"mode name '{name}' is ambiguous: {', '.join(matches)}; write its dotted path"
            if matches
            else f"unknown {what} '{name}'",
            None
            if matches
            else did_you_mean(
                name, [p.rsplit(".", 1)[-1] for p in below if p] + [p for p in below if p]
            ),
        )
        return -1
    return found


def compile_agent(
    agent: Agent,
    index: int,
    team_params: dict[str, float],
    agent_names: list[str],
    message_fields: dict[str, set[str]] | None = None,
    team: Team | None = None,
    extra_symbols: dict | None = None,
) -> CAgent:
    """One agent, compiled; :class:`ModelErrors` with every problem found."""
    col = Collector()
    names = _names(agent, team_params, extra_symbols, col)
    init_state, init_vars, lower, upper = _initial_values(agent, names, col)
    flat, children = _flatten(agent.root)
    paths = [p for p, _, _, _ in flat]
    modes, drivers = _modes(
        agent, flat, children, names, col, team.folder if team is not None else None
    )
    transitions = compile_transitions(
        flat,
        modes,
        paths,
        names.syms,
        names.state,
        names.variables,
        agent_names,
        agent.name,
        message_fields,
        col,
        inner_first=team is not None and team.priority_rule == "inner_first",
    )
    for (_p, mode, _q, _d), cm in zip(flat, modes, strict=True):
        cm.on_entry = compile_actions(
            mode.on_entry,
            (*mode.where, "entry"),
            names.syms,
            names.state,
            names.variables,
            agent_names,
            col,
        )
        cm.on_exit = compile_actions(
            mode.on_exit,
            (*mode.where, "exit"),
            names.syms,
            names.state,
            names.variables,
            agent_names,
            col,
        )
    _check_delays(transitions, names, col)
    if col.errors:
        raise ModelErrors(col.errors)
    has_eventless = np.zeros(len(modes), bool)
    has_triggered = np.zeros(len(modes), bool)
    for ct in transitions:
        (has_triggered if ct.on else has_eventless)[ct.source] = True
    ca = CAgent(
        index=index,
        name=agent.name,
        plant=names.plant,
        modes=modes,
        transitions=transitions,
        drivers=drivers,
        state_index=names.state,
        var_index=names.variables,
        param_index=names.param_index,
        param_defaults=names.defaults,
        derived_params=names.derived,
        transition_sources=np.array([ct.source for ct in transitions], np.intp),
        symbols=names.syms,
        init_state=init_state,
        init_vars=init_vars,
        lower=lower,
        upper=upper,
        watches=watches(modes, transitions, CONTINUOUS_NAMES | frozenset(names.state)),
        eventless=[ct.index for ct in transitions if ct.on is None],
        triggered=group_triggered(transitions),
        after=[ct.index for ct in transitions if ct.after is not None],
        driver_modes=sorted(
            (m.index for m in modes if m.driver >= 0), key=lambda i: -modes[i].depth
        ),
        has_eventless=has_eventless,
        has_triggered=has_triggered,
        final=np.array([m.final for m in modes], bool),
        outcome=[mode.outcome for _p, mode, _q, _d in flat],
        leaves=np.array([m.index for m in modes if m.kind == "leaf"], dtype=np.intp),
        mode_actions=any(m.on_entry or m.on_exit for m in modes),
    )
    if team is not None:
        attach(ca, team, names.syms, paths, col)
        if col.errors:
            raise ModelErrors(col.errors)
    return ca


# --------------------------------------------------------------------------- teams


def compile_team(team: Team) -> CTeam:
    """Compile every agent; raise :class:`ModelErrors` with all problems found."""
    errors: list[ModelError] = check_network(team) + check_messages(team) + check_world(team)
    fields = message_fields(team)
    extra = team_symbols(team)
    agents: list[CAgent] = []
    names = [a.name for a in team.agents]
    for i, agent in enumerate(team.agents):
        try:
            agents.append(compile_agent(agent, i, team.parameters, names, fields, team, extra))
        except ModelErrors as exc:
            errors.extend(exc.errors)
    scenario = []
    for ev in team.scenario:
        if ev.agent not in names:
            errors.append(
                ModelError(
                    (*ev.where, "agent"),
                    f"unknown agent '{ev.agent}'",
                    hint=did_you_mean(ev.agent, names),
                )
            )
            continue
        scenario.append((float(ev.at), names.index(ev.agent), ev.event))
    ending = _ending(team, names, errors)
    if errors:
        raise ModelErrors(errors)
    scenario.sort(key=lambda s: (s[0], s[1]))
    return CTeam(team, agents, scenario, ending, team.end.when == "any")


def _ending(team: Team, names: list[str], errors: list[ModelError]) -> list[int]:
    """Indices of the agents whose final modes end a run: those ``end.agents`` names, else
    every agent but operators (a protocol's operator stands by forever; waiting for it
    would keep every run going to its duration)."""
    if team.end.agents is None:
        chosen = [i for i, a in enumerate(team.agents) if not a.operator]
        return chosen or list(range(len(team.agents)))
    out = []
    for k, name in enumerate(team.end.agents):
        if name not in names:
            errors.append(
                ModelError(
                    (*team.end.where, "agents", k),
                    f"unknown agent '{name}'",
                    hint=did_you_mean(name, names),
                )
            )
        else:
            out.append(names.index(name))
    return out
