"""Compile declared agents and teams into :mod:`.compiled` structures.

All name resolution happens here, so a model that compiles cannot fail on an unknown name
half-way through a run; every problem found is collected (with its document path) and
raised together as :class:`~hybridteam.errors.ModelErrors`.
"""

from __future__ import annotations

import numpy as np

from hybridteam.dynamics.plants import make_plant
from hybridteam.engine.bindings import check_parallel_drivers, compile_driver
from hybridteam.engine.compiled import (
    CONTINUOUS_NAMES,
    REPLY,
    RESERVED,
    CAction,
    CAgent,
    CMode,
    CTeam,
    CTransition,
    Driver,
    Watch,
)
from hybridteam.engine.protocols import attach, check_messages, team_symbols
from hybridteam.errors import DocPath, ModelError, ModelErrors, did_you_mean
from hybridteam.expr import (
    Expression,
    ExpressionError,
    compile_assignment,
    compile_expression,
    free_names,
)
from hybridteam.model import Agent, Assign, Mode, Raise, Send, Team, Transition


class _Collector:
    """Collects every error of a model instead of stopping at the first."""

    def __init__(self) -> None:
        self.errors: list[ModelError] = []

    def expr(self, text: str | float, symbols, where: DocPath, *, condition: bool = False
             ) -> Expression | None:
        try:
            return compile_expression(str(text), symbols, condition=condition)
        except ExpressionError as exc:
            self.errors.append(ModelError(where, exc.message, offset=exc.offset, hint=exc.hint))
            return None

    def fail(self, where: DocPath, message: str, hint: str | None = None) -> None:
        self.errors.append(ModelError(where, message, hint=hint))


def _symbols(state: dict[str, int], variables: dict[str, int], params: dict[str, int]):
    syms = {
        "t": lambda c: c.t,
        "t_in_mode": lambda c: c.t_in,
    }
    for name, j in state.items():
        syms[name] = lambda c, j=j: c.x[:, j]
    for name, j in variables.items():
        syms[name] = lambda c, j=j: c.v[:, j]
    for name, j in params.items():
        syms[name] = lambda c, j=j: c.p[:, j]
    return syms


def _message_symbols(fields: set[str]) -> dict:
    """Names a transition triggered by a message can read: ``msg_sender`` (the sending
    agent's index), ``msg_sent`` (its send time) and ``msg_<field>`` for each field."""
    syms = {"msg_sender": lambda c: c.m["sender"], "msg_sent": lambda c: c.m["t_send"]}
    for f in sorted(fields):
        syms[f"msg_{f}"] = lambda c, f=f: c.m[f]
    return syms


def message_fields(team: Team) -> dict[str, set[str]]:
    """The fields sent with each message type anywhere in the team (the receivers' view)."""
    out: dict[str, set[str]] = {name: set(spec.fields) for name, spec in team.messages.items()}
    for agent in team.agents:
        for _, mode in agent.root.walk():
            for tr in mode.transitions:
                for act in tr.actions:
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


def resolve_mode(name: str, paths: list[str], near: str | None = None
                 ) -> tuple[int | None, list[str]]:
    """Index of the mode called ``name`` (a unique name or dotted-path suffix), and matches.

    Of several matches, the one sharing the longest enclosing scope with ``near`` (the
    transition's source) wins if it alone does: a mode library copied under two protocol
    roles (``Lead.Avoid``, ``Offering.Avoid``) still says ``to: Avoid`` inside each copy.
    """
    matches = [i for i, p in enumerate(paths) if p and (p == name or p.endswith("." + name))]
    if len(matches) > 1 and near is not None:
        def scope(i: int) -> int:
            a, b = paths[i].split(".")[:-1], near.split(".")
            k = 0
            while k < min(len(a), len(b)) and a[k] == b[k]:
                k += 1
            return k
        best = max(scope(i) for i in matches)
        nearest = [i for i in matches if scope(i) == best]
        if len(nearest) == 1:
            return nearest[0], [paths[i] for i in matches]
    return (matches[0] if len(matches) == 1 else None), [paths[i] for i in matches]


# --------------------------------------------------------------------------- agents


def compile_agent(agent: Agent, index: int, team_params: dict[str, float],
                  agent_names: list[str],
                  message_fields: dict[str, set[str]] | None = None,
                  team: Team | None = None, extra_symbols: dict | None = None) -> CAgent:
    col = _Collector()
    where = agent.where
    try:
        plant = make_plant(agent.plant.kind, tuple(agent.plant.state))
    except KeyError:
        col.fail((*agent.plant.where, "kind"), f"unknown plant kind '{agent.plant.kind}'",
                 did_you_mean(agent.plant.kind, ["unicycle", "holonomic", "flow", "none"]))
        raise ModelErrors(col.errors) from None
    state_index = {n: j for j, n in enumerate(plant.state_names)}
    var_index = {n: j for j, n in enumerate(agent.variables)}
    params = {**team_params, **agent.parameters}
    param_index = {n: j for j, n in enumerate(params)}
    seen: dict[str, str] = {}
    for kind, names in (("state", state_index), ("variable", var_index),
                        ("parameter", agent.parameters)):
        for n in names:
            if n in RESERVED or n.startswith("__"):
                col.fail((*where, kind if kind != "state" else "plant", n),
                         f"'{n}' is a reserved name")
            elif n in seen and not (seen[n] == "parameter" and kind == "parameter"):
                col.fail((*where, n), f"name '{n}' is both a {seen[n]} and a {kind}")
            seen[n] = kind
    syms = {**(extra_symbols or {}), **_symbols(state_index, var_index, param_index)}
    param_syms = {**(extra_symbols or {}), **_symbols({}, {}, param_index)}

    missing = [n for n in plant.state_names if n not in agent.plant.state]
    if plant.kind != "flow" and (missing or set(agent.plant.state) - set(plant.state_names)):
        extra = sorted(set(agent.plant.state) - set(plant.state_names))
        for n in extra:
            col.fail((*agent.plant.where, "state", n),
                     f"a {plant.kind} plant has no state '{n}'",
                     f"its state is {', '.join(plant.state_names)}")
    init_state = []
    for n in plant.state_names:
        text = agent.plant.state.get(n, 0.0)
        init_state.append(col.expr(text, param_syms, (*agent.plant.where, "state", n)))
    init_vars = [col.expr(v, param_syms, (*where, "variables", n))
                 for n, v in agent.variables.items()]
    lower = np.full(len(plant.input_names), -np.inf)
    upper = np.full(len(plant.input_names), np.inf)
    for n, (lo, hi) in agent.plant.limits.items():
        if n not in plant.input_names:
            col.fail((*agent.plant.where, "limits", n), f"a {plant.kind} plant has no input '{n}'",
                     did_you_mean(n, plant.input_names))
            continue
        if lo > hi:
            col.fail((*agent.plant.where, "limits", n), f"lower limit {lo} exceeds upper {hi}")
        lower[plant.input_names.index(n)], upper[plant.input_names.index(n)] = lo, hi

    flat, children = _flatten(agent.root)
    paths = [p for p, _, _, _ in flat]
    modes: list[CMode] = []
    drivers: list[Driver] = [Driver("zero", -1)]
    for idx, (path, mode, parent, depth) in enumerate(flat):
        kind = "leaf" if not mode.children else ("and" if mode.parallel else "or")
        initial = -1
        if kind == "or":
            names = [c.name for c in mode.children]
            init_name = mode.initial or (names[0] if len(names) == 1 else None)
            if init_name is None:
                col.fail((*mode.where, "initial"), f"mode '{path or agent.name}' has "
                         f"{len(names)} children and no 'initial'")
            elif init_name not in names:
                col.fail((*mode.where, "initial"), f"unknown initial mode '{init_name}'",
                         did_you_mean(init_name, names))
            else:
                initial = children[idx][names.index(init_name)]
        elif mode.initial is not None and kind == "and":
            col.fail((*mode.where, "initial"), "a parallel mode enters all its regions; "
                     "it has no 'initial'")
        driver = compile_driver(mode, idx, plant, syms, col, params)
        if driver is not None:
            drivers.append(driver)
        inv = None
        if mode.invariant is not None:
            inv = col.expr(mode.invariant, syms, (*mode.where, "invariant"), condition=True)
        modes.append(CMode(idx, mode.name, path, parent, depth, kind, children[idx], initial,
                           mode.history, mode.final, len(drivers) - 1 if driver else -1, inv,
                           str(mode.invariant or ""), role=mode.role))
        if mode.final and mode.children:
            col.fail((*mode.where, "final"), "only leaf modes can be final")
    check_parallel_drivers(modes, col, flat)
    for m in reversed(modes):
        sub = [m.index]
        for c in m.children:
            sub.extend(modes[c].subtree.tolist())
        m.subtree = np.array(sorted(sub), dtype=np.intp)

    transitions: list[CTransition] = []
    decl: list[tuple[int, int, int, CTransition]] = []
    for idx, (_path, mode, _parent, depth) in enumerate(flat):
        for tr in mode.transitions:
            tsyms = syms
            if tr.on is not None and message_fields and tr.on in message_fields:
                tsyms = {**syms, **_message_symbols(message_fields[tr.on])}
            ct = _compile_transition(tr, idx, modes, paths, tsyms, state_index, var_index,
                                     agent_names, agent.name, col)
            if ct is not None:
                decl.append((-tr.priority, depth, len(decl), ct))
    decl.sort(key=lambda item: item[:3])
    for order, (_, _, _, ct) in enumerate(decl):
        ct.index = order
        transitions.append(ct)
    after_slot = 0
    for ct in transitions:
        sub_j = set(modes[ct.exit_root].subtree.tolist())
        ct.conflicts = np.array(
            [o.index for o in transitions[: ct.index]
             if sub_j & set(modes[o.exit_root].subtree.tolist())], dtype=np.intp)
        modes[ct.source].outgoing.append(ct.index)
        if ct.after is not None:
            ct.after_slot = after_slot
            after_slot += 1
    for ct in transitions:
        _role_carry(ct, modes, transitions)
    if col.errors:
        raise ModelErrors(col.errors)

    watches = _watches(modes, transitions, CONTINUOUS_NAMES | frozenset(state_index))
    m_count = len(modes)
    has_eventless = np.zeros(m_count, bool)
    has_triggered = np.zeros(m_count, bool)
    for ct in transitions:
        (has_triggered if ct.on else has_eventless)[ct.source] = True
    driver_modes = sorted((m.index for m in modes if m.driver >= 0),
                          key=lambda i: -modes[i].depth)
    ca = CAgent(
        index=index, name=agent.name, plant=plant, modes=modes, transitions=transitions,
        drivers=drivers, state_index=state_index, var_index=var_index,
        param_index=param_index,
        param_defaults=np.array([float(v) for v in params.values()], dtype=float),
        init_state=init_state, init_vars=init_vars, lower=lower, upper=upper,
        watches=watches,
        eventless=[ct.index for ct in transitions if ct.on is None],
        triggered=_group_triggered(transitions),
        after=[ct.index for ct in transitions if ct.after is not None],
        driver_modes=driver_modes, has_eventless=has_eventless, has_triggered=has_triggered,
        final=np.array([m.final for m in modes], bool),
        outcome=[mode.outcome for _p, mode, _q, _d in flat],
        leaves=np.array([m.index for m in modes if m.kind == "leaf"], dtype=np.intp),
    )
    if team is not None:
        attach(ca, team, syms, paths, col)
        if col.errors:
            raise ModelErrors(col.errors)
    return ca


def _role_carry(ct: CTransition, modes: list[CMode], transitions: list[CTransition]) -> None:
    """Fill ``ct.carry`` when it switches between two protocol states of one role.

    A protocol gives each of its states that plays a role a copy of the robot's role body
    (``Lead`` and ``Offering`` both lead). Which copy is active is bookkeeping of the
    handshake; what the robot does is the body. So a transition from one such state straight
    into another (a resignation: Lead -> Offering) resumes the body where it was, as a deep
    history would, instead of restarting the plan; its ``after:`` delays go on running
    (a plan's phase ends when it would have), while ``t_in_mode`` counts from the switch,
    when the copies' modes are entered.
    """
    if ct.internal or len(ct.entry_path) != 1:
        return
    s, t = modes[ct.exit_root], modes[ct.entry_path[0]]
    if s.role is None or s.role != t.role or not s.children:  # siblings: both under common
        return
    mapping = np.full(len(modes) + 1, -1, np.intp)

    def pair(a: int, b: int) -> None:
        mapping[a] = b
        if modes[a].kind == "or":
            ct.carry.append((a, b))
        names = {modes[c].name: c for c in modes[b].children}
        for c in modes[a].children:
            if modes[c].name in names:
                pair(c, names[modes[c].name])

    pair(s.index, t.index)
    ct.carry_map = mapping
    for a in np.flatnonzero(mapping[:-1] >= 0).tolist():
        b = int(mapping[a])
        timed = {transitions[j].origin: transitions[j].after_slot
                 for j in modes[b].outgoing if transitions[j].after is not None}
        ct.carry_timers += [(b, transitions[j].after_slot, timed[transitions[j].origin])
                            for j in modes[a].outgoing
                            if transitions[j].after is not None
                            and transitions[j].origin in timed]


def _group_triggered(transitions: list[CTransition]) -> dict[str, list[int]]:
    out: dict[str, list[int]] = {}
    for ct in transitions:
        if ct.on is not None:
            out.setdefault(ct.on, []).append(ct.index)
    return out


def _ancestors(modes: list[CMode], i: int) -> list[int]:
    """``i`` and its ancestors, innermost first."""
    out = [i]
    while modes[out[-1]].parent >= 0:
        out.append(modes[out[-1]].parent)
    return out


def _compile_transition(tr: Transition, src: int, modes: list[CMode], paths: list[str], syms,
                        state_index, var_index, agent_names, agent_name: str,
                        col: _Collector) -> CTransition | None:
    internal = tr.target is None
    tgt, matches = (src, []) if internal else resolve_mode(tr.target, paths, paths[src])
    if tgt is None:
        if matches:
            col.fail((*tr.where, "to"), f"mode name '{tr.target}' is ambiguous: "
                     f"{', '.join(matches)}; write its dotted path")
        else:
            col.fail((*tr.where, "to"), f"unknown mode '{tr.target}'",
                     did_you_mean(tr.target, [p.rsplit('.', 1)[-1] for p in paths if p]
                                   + [p for p in paths if p]))
        return None
    anc_s, anc_t = _ancestors(modes, src), _ancestors(modes, tgt)
    common = next(a for a in anc_s if a in anc_t)
    if common in (src, tgt):
        common = modes[common].parent
    if common < 0 and internal:
        col.fail(tr.where, "an internal transition (no 'to') needs a mode, not the agent root")
        return None
    if common < 0:
        col.fail((*tr.where, "to"), "a transition cannot leave the agent's root mode")
        return None
    if modes[common].kind == "and":
        col.fail((*tr.where, "to"), f"transition from '{modes[src].path}' to "
                 f"'{modes[tgt].path}' crosses parallel regions of '{modes[common].path}'")
        return None
    exit_root = anc_s[anc_s.index(common) - 1]
    entry_path = list(reversed(anc_t[: anc_t.index(common)]))
    guard = None
    if tr.guard is not None:
        guard = col.expr(tr.guard, syms, (*tr.where, "guard"), condition=True)
    after = None
    if tr.after is not None:
        after = col.expr(tr.after, syms, (*tr.where, "after"))
    actions: list[CAction] = []
    targets = list(state_index) + list(var_index)
    for k, act in enumerate(tr.actions):
        awhere = act.where or (*tr.where, "do", k)
        if isinstance(act, Assign):
            try:
                name, e = compile_assignment(act.text, syms, targets)
            except ExpressionError as exc:
                lhs = act.text.split("=")[0].strip(" +-*/%")
                if lhs in syms and lhs not in targets:
                    what = "time" if lhs in CONTINUOUS_NAMES else "a parameter"
                    col.errors.append(ModelError(awhere, f"'{lhs}' is {what} and cannot be "
                                                 "assigned; assign variables or plant state",
                                                 offset=exc.offset))
                else:
                    col.errors.append(ModelError(awhere, exc.message, offset=exc.offset,
                                                 hint=exc.hint))
                continue
            target = ("x", state_index[name]) if name in state_index else ("v", var_index[name])
            actions.append(CAction("assign", target=target, expr=e))
        elif isinstance(act, Raise):
            actions.append(CAction("raise", name=act.event))
        elif isinstance(act, Send):
            to, to_expr = None, None
            if act.to == "sender":
                if "msg_sender" not in syms:
                    col.fail((*awhere, "to"), "'to: sender' replies to the sender of the "
                             "message that triggered the transition; this transition has "
                             "no triggering message ('on:' a message type)")
                    continue
                to = REPLY
            elif act.to is not None and act.to in agent_names:
                to = agent_names.index(act.to)
            elif act.to is not None:
                # an expression giving an agent's index per instance (negative: everyone)
                try:
                    to_expr = compile_expression(act.to, syms)
                except ExpressionError as exc:
                    col.fail((*awhere, "to"), f"unknown agent '{act.to}'" if
                             act.to.isidentifier() else exc.message,
                             did_you_mean(act.to, agent_names) if act.to.isidentifier()
                             else exc.hint)
                    continue
            fields = {}
            for fname, text in act.fields.items():
                e = col.expr(text, syms, (*awhere, "fields", fname))
                if e is not None:
                    fields[fname] = e
            actions.append(CAction("send", name=act.message, to=to, socket=act.socket,
                                   fields=fields, to_expr=to_expr))
    return CTransition(
        index=-1, source=src, target=tgt, exit_root=exit_root, entry_path=entry_path,
        on=tr.on, after=after, guard=guard, actions=actions, priority=tr.priority,
        depth=modes[src].depth, text=f"{modes[src].path or agent_name} -> {modes[tgt].path}",
        guard_text=str(tr.guard or ""), internal=internal, origin=tuple(tr.where),
    )


def _watches(modes: list[CMode], transitions: list[CTransition],
             dynamic: frozenset[str]) -> list[Watch]:
    """Atoms to locate during flow: those of urgent guards and invariants that mention state
    or time (an atom over variables and parameters only cannot change while time flows)."""
    found: list[Watch] = []

    def add(expr: Expression | None, mode: int, invariant: bool) -> None:
        if expr is None:
            return
        for atom in expr.atoms:
            if free_names(atom.source, condition=True) & dynamic:
                found.append(Watch(atom, mode, expr, invariant))

    for ct in transitions:
        if ct.on is None:
            add(ct.guard, ct.source, False)
    for m in modes:
        add(m.invariant, m.index, True)
    return found


def compile_team(team: Team) -> CTeam:
    """Compile every agent; raise :class:`ModelErrors` with all problems found."""
    from hybridteam.engine.world import check_world
    from hybridteam.network import check_network

    errors: list[ModelError] = (check_network(team) + check_messages(team)
                                + check_world(team))
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
            errors.append(ModelError((*ev.where, "agent"), f"unknown agent '{ev.agent}'",
                                     hint=did_you_mean(ev.agent, names)))
            continue
        scenario.append((float(ev.at), names.index(ev.agent), ev.event))
    if errors:
        raise ModelErrors(errors)
    scenario.sort(key=lambda s: (s[0], s[1]))
    return CTeam(team, agents, scenario)
