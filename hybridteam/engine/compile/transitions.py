"""Compiling transitions: targets, exit and entry paths, guards, actions, precedence.

A transition is compiled once into a :class:`~.compiled.CTransition` whose mode indices,
exit root and entry path are resolved, whose guard, delay and actions are numpy
callables, and whose conflicts with higher-precedence transitions are precomputed, so the
discrete phase (:mod:`hybridteam.engine.run.discrete`) only evaluates and fires. The atoms
of urgent guards and invariants that can change while time flows are collected as watches
(:mod:`hybridteam.engine.run.crossing` locates their sign changes).
"""

from __future__ import annotations

import dataclasses
from collections import ChainMap
from collections.abc import Mapping

import numpy as np

from hybridteam.engine.compile.compiled import (
    CONTINUOUS_NAMES,
    REPLY,
    CAction,
    CMode,
    CTransition,
    Entry,
    Watch,
)
from hybridteam.engine.compile.scope import Collector, message_symbols, resolve_mode
from hybridteam.errors import DocPath, ModelError, did_you_mean
from hybridteam.expr import (
    Expression,
    ExpressionError,
    ModeTest,
    compile_assignment,
    compile_expression,
    free_names,
)
from hybridteam.model import Action, Assign, Mode, Raise, Send, Transition


def compile_transitions(
    flat: list[tuple[str, Mode, int, int]],
    modes: list[CMode],
    paths: list[str],
    syms: Mapping,
    state_index: dict[str, int],
    var_index: dict[str, int],
    agent_names: list[str],
    agent_name: str,
    message_fields: dict[str, set[str]] | None,
    col: Collector,
    inner_first: bool = False,
) -> list[CTransition]:
    """Every transition of an agent, in precedence order: higher ``priority`` first, then
    outer before inner (``inner_first``: inner before outer, SCXML's rule), then
    declaration order; with conflicts, ``after`` slots, the modes' ``outgoing`` lists and
    role carries filled in.

    Inner first orders sources in post-order (a mode after every mode inside it, disjoint
    subtrees in document order), so between regions the one written first wins, and a
    transition is also blocked by one that fired from inside its source, as SCXML selects
    at most one transition per active leaf, the innermost.
    """
    decl: list[tuple[int, tuple[int, int], int, CTransition]] = []
    syms = {**syms, "in_mode": mode_test(paths, agent_name)}  # what guards read
    for idx, (_path, mode, _parent, depth) in enumerate(flat):
        for tr in mode.transitions:
            tsyms: Mapping = syms
            if tr.on is not None and message_fields and tr.on in message_fields:
                tsyms = ChainMap(message_symbols(message_fields[tr.on]), syms)
            ct = _compile_transition(
                tr, idx, modes, paths, tsyms, state_index, var_index, agent_names, agent_name, col
            )
            if ct is not None:
                ct.declared = len(decl)
                level = (int(modes[idx].subtree[-1]), -depth) if inner_first else (depth, 0)
                decl.append((-tr.priority, level, len(decl), ct))
    decl.sort(key=lambda item: item[:3])
    transitions: list[CTransition] = []
    for order, (_, _, _, ct) in enumerate(decl):
        ct.index = order
        transitions.append(ct)
    after_slot = 0
    exits = [
        frozenset(() if ct.internal else modes[ct.exit_root].subtree.tolist())
        - ({ct.exit_root} if ct.exit_inside else set())
        for ct in transitions
    ]
    inside = (
        [frozenset(modes[ct.source].subtree.tolist()) for ct in transitions]
        if inner_first
        else None
    )
    for ct in transitions:
        ct.conflicts = np.array(
            [
                o.index
                for o in transitions[: ct.index]
                if conflict(ct, exits[ct.index], o, exits[o.index])
                or (
                    inside is not None
                    and (o.source in inside[ct.index] or ct.source in inside[o.index])
                )
            ],
            dtype=np.intp,
        )
        modes[ct.source].outgoing.append(ct.index)
        if ct.after is not None:
            ct.after_slot = after_slot
            after_slot += 1
    for ct in transitions:
        _role_carry(ct, modes, transitions)
    return transitions


def mode_test(paths: list[str], agent_name: str) -> ModeTest:
    """``in_mode(Name)`` in a guard: whether a mode of the same agent is active, named as a
    transition's target is (a unique name or a dotted path). Another agent's modes are not
    readable: agents learn of each other through messages."""

    def resolve(name: str):
        m, matches = resolve_mode(name, paths)
        if m is None:
            if matches:
                raise ExpressionError(
                    f"mode name '{name}' is ambiguous: {', '.join(matches)}; write its dotted path"
                )
            raise ExpressionError(
                f"agent '{agent_name}' has no mode '{name}'",
                hint=did_you_mean(
                    name, [p.rsplit(".", 1)[-1] for p in paths if p] + [p for p in paths if p]
                )
                or "in_mode reads the agent's own modes; another agent's are known only "
                "through its messages",
            )
        return lambda c, m=m: c.in_mode(m)

    return ModeTest(resolve)


def conflict(
    a: CTransition, exit_a: frozenset[int], b: CTransition, exit_b: frozenset[int]
) -> bool:
    """Whether ``a`` and ``b`` cannot both fire in one micro-step (the one of higher
    precedence blocks the other): they are declared on the same mode (at most one
    transition per source), their exit sets overlap, or one exits the other's source. A
    transition without a target exits nothing, so it is blocked only by a transition that
    leaves its source (or one on the same source), never by one elsewhere inside it."""
    return a.source == b.source or bool(exit_a & exit_b) or a.source in exit_b or b.source in exit_a


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
        timed = {
            transitions[j].origin: transitions[j].after_slot
            for j in modes[b].outgoing
            if transitions[j].after is not None
        }
        ct.carry_timers += [
            (b, transitions[j].after_slot, timed[transitions[j].origin])
            for j in modes[a].outgoing
            if transitions[j].after is not None and transitions[j].origin in timed
        ]


def group_triggered(transitions: list[CTransition]) -> dict[str, list[int]]:
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


def domain(modes: list[CMode], ends: list[int]) -> int:
    """The mode a transition stays inside (its domain): the innermost mode that properly
    contains its source and targets (``ends``: the source first), -1 if only leaving the
    root would do. Unlike the W3C recommendation's, it may be a parallel mode, as SCION's
    fixtures have it (``more-parallel/test10b``).

    The source is left even when a target is inside it (a self-transition exits and
    re-enters). A parallel domain — a transition between two of its regions, or from a
    region to itself or one of its descendants — stays active: every one of its regions
    is left and entered again (those without a target by default), the parallel mode's
    own entry and exit actions do not run.
    """
    chains = [_ancestors(modes, e) for e in ends]
    common = next(a for a in chains[0] if all(a in c for c in chains[1:]))
    if common in ends:
        common = modes[common].parent
    return common


def entry_to(modes: list[CMode], top: int, targets: list[int]) -> Entry:
    """How to enter ``targets`` from inside ``top`` (a transition's domain, or a mode
    whose ``initial`` or history default names a descendant): the modes on the way,
    entered outermost first, parallel modes on the way entering their other regions by
    default."""
    marks: set[int] = set()
    first = -1
    for t in targets:
        m = t
        while m != top:
            marks.add(m)
            first, m = m, modes[m].parent
    return Entry(first, frozenset(marks), frozenset(targets))


def _apart(modes: list[CMode], targets: list[int], tr: Transition, col: Collector) -> bool:
    """Several targets must lie in different regions of a parallel mode (each region
    gets at most one), as SCXML requires of a legal configuration."""
    for k, b in enumerate(targets):
        for a in targets[:k]:
            chain_a, chain_b = _ancestors(modes, a), _ancestors(modes, b)
            common = next(m for m in chain_a if m in chain_b)
            if common in (a, b) or modes[common].kind != "and":
                col.fail(
                    (*tr.where, "to", k),
                    f"targets '{modes[a].path}' and "
                    f"'{modes[b].path}' are not in different regions of a parallel "
                    "mode; a transition enters one mode per region",
                )
                return False
    return True


def _compile_transition(
    tr: Transition,
    src: int,
    modes: list[CMode],
    paths: list[str],
    syms,
    state_index,
    var_index,
    agent_names,
    agent_name: str,
    col: Collector,
) -> CTransition | None:
    internal = tr.target is None
    if internal and src == 0:
        col.fail(tr.where, "an internal transition (no 'to') needs a mode, not the agent root")
        return None
    targets: list[int] = []
    for k, name in enumerate(tr.targets):
        where = (*tr.where, "to", k) if tr.more_targets else (*tr.where, "to")
        tgt, matches = resolve_mode(name, paths, paths[src])
        if tgt is None:
            if matches:
                col.fail(
                    where,
                    f"mode name '{name}' is ambiguous: {', '.join(matches)}; write its dotted path",
                )
            else:
                col.fail(
                    where,
                    f"unknown mode '{name}'",
                    did_you_mean(
                        name, [p.rsplit(".", 1)[-1] for p in paths if p] + [p for p in paths if p]
                    ),
                )
            return None
        targets.append(tgt)
    if not _apart(modes, targets, tr, col):
        return None
    tgt = targets[0] if targets else src
    exit_root, entry_path, entry, inside = src, [src], None, False
    if tr.local and (
        internal or not all(t != src and src in _ancestors(modes, t) for t in targets)
    ):
        col.fail(
            (*tr.where, "local"),
            "a local transition stays inside its source: its "
            f"targets must be modes inside '{modes[src].path}'",
        )
        return None
    if not internal:
        common = src if tr.local else domain(modes, [src, *targets])
        if common < 0:
            col.fail((*tr.where, "to"), "a transition cannot leave the agent's root mode")
            return None
        anc_s, anc_t = _ancestors(modes, src), _ancestors(modes, tgt)
        entry_path = list(reversed(anc_t[: anc_t.index(common)]))
        if tr.local or modes[common].kind == "and":  # the domain stays; below it is left
            exit_root, inside = common, True
            entry = dataclasses.replace(
                entry_to(modes, modes[common].parent, targets), active_first=True
            )
        else:
            exit_root = anc_s[anc_s.index(common) - 1]
            entry = entry_to(modes, common, targets)
    guard = None
    if tr.guard is not None:
        guard = col.expr(tr.guard, syms, (*tr.where, "guard"), condition=True)
    after = None
    if tr.after is not None:
        after = col.expr(tr.after, syms, (*tr.where, "after"))
    actions = compile_actions(
        tr.actions, (*tr.where, "do"), syms, state_index, var_index, agent_names, col
    )
    return CTransition(
        index=-1,
        source=src,
        target=tgt,
        exit_root=exit_root,
        entry_path=entry_path,
        entry=entry,
        targets=targets,
        exit_inside=inside,
        on=tr.on,
        after=after,
        guard=guard,
        actions=actions,
        priority=tr.priority,
        depth=modes[src].depth,
        text=f"{modes[src].path or agent_name} -> "
        f"{', '.join(modes[t].path for t in targets) or modes[src].path}",
        guard_text=str(tr.guard or ""),
        internal=internal,
        origin=tuple(tr.where),
    )


def compile_actions(
    declared: tuple[Action, ...],
    where: DocPath,
    syms: Mapping,
    state_index: dict[str, int],
    var_index: dict[str, int],
    agent_names: list[str],
    col: Collector,
) -> list[CAction]:
    """A transition's ``do:`` list, or a mode's ``entry:`` or ``exit:`` list (``where``):
    assignments (to variables or plant state: a reset), raised local events and sends."""
    actions: list[CAction] = []
    targets = list(state_index) + list(var_index)
    for k, act in enumerate(declared):
        awhere = act.where or (*where, k)
        if isinstance(act, Assign):
            try:
                name, e = compile_assignment(act.text, syms, targets)
            except ExpressionError as exc:
                lhs = act.text.split("=")[0].strip(" +-*/%")
                if lhs in syms and lhs not in targets:
                    what = "time" if lhs in CONTINUOUS_NAMES else "a parameter"
                    col.add(
                        ModelError(
                            awhere,
                            f"'{lhs}' is {what} and cannot be "
                            "assigned; assign variables or plant state",
                            offset=exc.offset,
                        )
                    )
                else:
                    col.add(ModelError(awhere, exc.message, offset=exc.offset, hint=exc.hint))
                continue
            target = ("x", state_index[name]) if name in state_index else ("v", var_index[name])
            actions.append(CAction("assign", target=target, expr=e))
        elif isinstance(act, Raise):
            actions.append(CAction("raise", name=act.event))
        elif isinstance(act, Send):
            send = _compile_send(act, awhere, syms, agent_names, col)
            if send is not None:
                actions.append(send)
    return actions


def _compile_send(
    act: Send, awhere: tuple, syms: Mapping, agent_names: list[str], col: Collector
) -> CAction | None:
    """A ``send`` action: to everyone, to a named agent, back to the triggering message's
    sender, or to an agent index given by an expression (negative: everyone)."""
    to, to_expr = None, None
    if act.to == "sender":
        if "msg_sender" not in syms:
            col.fail(
                (*awhere, "to"),
                "'to: sender' replies to the sender of the "
                "message that triggered the transition; this transition has "
                "no triggering message ('on:' a message type)",
            )
            return None
        to = REPLY
    elif act.to is not None and act.to in agent_names:
        to = agent_names.index(act.to)
    elif act.to is not None:
        try:
            to_expr = compile_expression(act.to, syms)
        except ExpressionError as exc:
            col.fail(
                (*awhere, "to"),
                f"unknown agent '{act.to}'" if act.to.isidentifier() else exc.message,
                did_you_mean(act.to, agent_names) if act.to.isidentifier() else exc.hint,
            )
            return None
    fields = {}
    for fname, text in act.fields.items():
        e = col.expr(text, syms, (*awhere, "fields", fname))
        if e is not None:
            fields[fname] = e
    return CAction(
        "send", name=act.message, to=to, socket=act.socket, fields=fields, to_expr=to_expr
    )


def watches(
    modes: list[CMode], transitions: list[CTransition], dynamic: frozenset[str]
) -> list[Watch]:
    """Atoms to locate during flow: those of urgent guards and invariants that mention state
    or time (an atom over variables and parameters only cannot change while time flows)."""
    found: list[Watch] = []

    def add(expr: Expression | None, mode: int, invariant: bool) -> None:
        if expr is None:
            return
        for atom in expr.atoms:
            if free_names(atom.source, condition=True) & dynamic:
                found.append(
                    Watch(
                        atom, mode, expr, invariant, conjunct=any(atom is c for c in expr.conjuncts)
                    )
                )

    for ct in transitions:
        if ct.on is None:
            add(ct.guard, ct.source, False)
    for m in modes:
        add(m.invariant, m.index, True)
    return found
