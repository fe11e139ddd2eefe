"""The discrete skeleton of a team: what ``hybridteam verify`` keeps exact and what it
abstracts into nondeterministic choices.

Exact: each agent's mode configuration, the discrete variables (those only ever assigned
from parameters, agent indices, message senders, other discrete variables and the fields
of messages that carry such values), messages in flight, the acknowledged layer's outboxes
and duplicate filters. Abstracted: plant state, time, stream estimates, world readings —
and with them every variable or message field computed from them. A comparison in a guard
that reads an abstracted name is *free*: the explorer tries it both true and false, so
every timing and every continuous behaviour is covered (an over-approximation). A
transition that waits for time (``after:``) or for a free comparison to become true
without a trigger is *time-driven*: it may fire at any moment while its source is active.

The explorer does not re-interpret the model: it runs the engine's own compiled team,
whose guards are wrapped here (:class:`SkeletonGuard`) so that free comparisons read the
explorer's choices (:class:`Oracle`) and time-driven transitions fire only when chosen.
"""

from __future__ import annotations

import ast
import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from hybridteam.engine.compile.compiled import CAgent, CTeam, CTransition
from hybridteam.engine.compile.compiler import message_fields
from hybridteam.engine.compile.scope import message_symbols
from hybridteam.expr import compile_expression
from hybridteam.expr.compiler import free_names

INST = "__instance"  # hidden variable column: each row's instance index, for the oracle
UNDELIVERABLE = "_undeliverable"


class Oracle:
    """The explorer's answers to the questions the skeleton leaves open, per instance.

    ``chosen[i]``: the time-driven transition instance ``i`` fires (agent * 1e6 + index,
    -1 for none). ``tape[i]``: the truth values of free comparisons, read in order; a read
    past the tape's end answers False and is counted in ``reads[i]``, so the explorer
    knows which other answers it still has to try.
    """

    def __init__(self, n: int) -> None:
        self.chosen = np.full(n, -1, np.int64)
        self.tape: list[tuple[bool, ...]] = [()] * n
        self.reads = np.zeros(n, np.int64)

    def reset(self, n: int) -> None:
        """Room for ``n`` instances, nothing chosen, empty tapes."""
        self.chosen = np.full(n, -1, np.int64)
        self.tape = [()] * n
        self.reads = np.zeros(n, np.int64)

    def free(self, inst: np.ndarray) -> np.ndarray:
        out = np.zeros(inst.size, bool)
        for k, i in enumerate(inst.tolist()):
            r = int(self.reads[i])
            tape = self.tape[i]
            out[k] = tape[r] if r < len(tape) else False
            self.reads[i] = r + 1
        return out


class SkeletonGuard:
    """A transition's guard in the skeleton: exact comparisons are the engine's compiled
    ones, free comparisons read the oracle; a time-driven transition is enabled only in
    the instances that chose it (once)."""

    def __init__(self, source: str, tree, oracle: Oracle, inst_col: int, code: int | None) -> None:
        self.source, self.tree, self.oracle = source, tree, oracle
        self.inst_col, self.code = inst_col, code

    def __call__(self, ctx) -> np.ndarray:
        inst = ctx.v[:, self.inst_col].astype(np.int64)
        ok = np.ones(inst.size, bool)
        if self.code is not None:
            ok = self.oracle.chosen[inst] == self.code
            if not ok.any():
                return ok
        if self.tree is not None:
            before = self.oracle.reads[inst]  # (a copy)
            value = np.broadcast_to(self.tree(ctx, inst), inst.shape)
            if self.code is not None:
                # the tree is evaluated for every instance of the batch in the source mode;
                # only the ones that chose the transition have read their tapes (so an
                # instance's reads never depend on what its batch neighbours chose)
                self.oracle.reads[inst[~ok]] = before[~ok]
            ok = ok & value
        if self.code is not None:
            self.oracle.chosen[inst[ok]] = -1
        return ok


@dataclass
class Skeleton:
    """The abstraction of one team (see the module docstring)."""

    cteam: CTeam  # the explorer's copy of the compiled team (guards wrapped)
    original: CTeam
    oracle: Oracle
    discrete_vars: list[list[int]]  # per agent: the variable columns kept exact
    abstract_vars: list[list[str]]
    abstract_fields: set[tuple[str, str]]  # (message type, field) computed from state
    free: list[tuple[int, int, str]]  # (agent, transition, comparison text)
    time_driven: list[list[int]]  # per agent: transitions that fire when chosen
    world_events: list[tuple[int, str]]  # (agent, event) a world component may raise
    inputs: list[set[str]]  # per agent: events no action of its own raises (not messages)
    notes: list[str] = field(default_factory=list)

    @cached_property
    def hears(self) -> list[set[str]]:
        """Per agent: the message and event names some transition of it is triggered by."""
        return [set(ca.triggered) for ca in self.cteam.agents]

    @property
    def inst_col(self) -> list[int]:
        return [len(ca.var_index) - 1 for ca in self.cteam.agents]


def _discrete_names(ca: CAgent, abstract: set[str]) -> set[str]:
    names = set(ca.param_index) | {n for n in ca.symbols if n.startswith("id_")}
    return names | {v for v in ca.var_index if v not in abstract}


def _message_names(
    on: str | None, fields: dict[str, set[str]], abstract_fields: set[tuple[str, str]]
) -> set[str]:
    if on is None or on not in fields:
        return set()
    return {"msg_sender"} | {f"msg_{f}" for f in fields[on] if (on, f) not in abstract_fields}


def classify(cteam: CTeam) -> tuple[list[set[str]], set[tuple[str, str]]]:
    """Which variables and message fields are abstracted: a fixpoint, since a variable
    assigned from an abstracted one (or a field carrying one) is abstracted too."""
    fields = message_fields(cteam.team)
    abstract: list[set[str]] = [set() for _ in cteam.agents]
    afields: set[tuple[str, str]] = set()
    var_name = [{j: n for n, j in ca.var_index.items()} for ca in cteam.agents]
    changed = True
    while changed:
        changed = False
        for a, ca in enumerate(cteam.agents):
            # a transition's actions (which may read its message), then the modes' entry
            # and exit actions (which read no message)
            lists = [(tr.on, tr.actions) for tr in ca.transitions] + [
                (None, acts) for m in ca.modes for acts in (m.on_entry, m.on_exit) if acts
            ]
            for on, actions in lists:
                known = _discrete_names(ca, abstract[a]) | _message_names(on, fields, afields)
                for act in actions:  # (an assignment has its target and expression)
                    if act.kind == "assign" and act.target[0] == "v":  # type: ignore[index]
                        name = var_name[a][act.target[1]]  # type: ignore[index]
                        if name not in abstract[a] and not act.expr.names <= known:  # type: ignore[union-attr]
                            abstract[a].add(name)
                            changed = True
                    elif act.kind == "send":
                        for f, e in act.fields.items():
                            if (act.name, f) not in afields and not e.names <= known:
                                afields.add((act.name, f))
                                changed = True
    return abstract, afields


def _compile_tree(source: str, syms: Mapping, known: set[str], oracle: Oracle, free: list[str]):
    """The guard's Boolean structure over its comparisons: exact ones compiled by the
    expression compiler against the agent's own symbols, free ones read from the oracle.
    Returns None when the guard is exact as a whole (the engine's own guard is kept)."""
    if free_names(source, condition=True) <= known:
        return None
    root = ast.parse(source.strip(), mode="eval").body
    text = source.strip()

    def build(node):
        if isinstance(node, ast.BoolOp):
            parts = [build(v) for v in node.values]
            op = np.logical_and if isinstance(node.op, ast.And) else np.logical_or

            def both(ctx, inst, parts=parts, op=op):
                out = parts[0](ctx, inst)
                for p in parts[1:]:
                    out = op(out, p(ctx, inst))
                return out

            return both
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.Not):
            inner = build(node.operand)
            return lambda ctx, inst: np.logical_not(inner(ctx, inst))
        segment = ast.get_source_segment(text, node) or text
        if free_names(segment, condition=True) <= known:
            exact = compile_expression(segment, syms, condition=True)
            return lambda ctx, inst: np.broadcast_to(exact(ctx), inst.shape)
        free.append(segment)
        return lambda ctx, inst: oracle.free(inst)

    return build(root)


def _exact_tree(guard):
    """A whole guard that is exact, as a tree the skeleton guard can call."""
    return lambda ctx, inst: np.broadcast_to(guard(ctx), inst.shape)


def skeleton(cteam: CTeam, world_raises: tuple[str, ...] = ()) -> Skeleton:
    """Build the explorer's copy of ``cteam`` and describe what it abstracts."""
    abstract, afields = classify(cteam)
    fields = message_fields(cteam.team)
    messages = set(fields)
    oracle = Oracle(1)
    agents, free, timed, inputs, world_events = [], [], [], [], []
    for a, ca in enumerate(cteam.agents):
        inst_col = len(ca.var_index)
        base = _discrete_names(ca, abstract[a])
        new_transitions: list[CTransition] = []
        mine: list[int] = []
        raised = {  # by its transitions and by its modes' entry and exit actions
            act.name
            for actions in [tr.actions for tr in ca.transitions]
            + [m.on_entry for m in ca.modes]
            + [m.on_exit for m in ca.modes]
            for act in actions
            if act.kind == "raise"
        }
        for tr in ca.transitions:
            known = base | _message_names(tr.on, fields, afields)
            syms = (
                {**ca.symbols, **message_symbols(fields.get(tr.on, set()))}
                if tr.on in fields
                else ca.symbols
            )
            texts: list[str] = []
            tree = (
                None
                if tr.guard is None
                else _compile_tree(tr.guard.source, syms, known, oracle, texts)
            )
            free += [(a, tr.index, t) for t in texts]
            driven = tr.on is None and (tr.after is not None or tree is not None)
            if driven:
                mine.append(tr.index)
            if driven or tree is not None:
                if tree is None and tr.guard is not None:
                    tree = _exact_tree(tr.guard)
                guard = SkeletonGuard(
                    tr.guard.source if tr.guard else "",
                    tree,
                    oracle,
                    inst_col,
                    a * 1_000_000 + tr.index if driven else None,
                )
                tr = dataclasses.replace(tr, guard=guard)  # type: ignore[arg-type]  # (the skeleton's stand-in)
            new_transitions.append(tr)
        triggers = {tr.on for tr in ca.transitions if tr.on is not None}
        inputs.append(
            {
                e
                for e in triggers
                if e not in messages and e not in raised and not e.endswith(UNDELIVERABLE)
            }
        )
        world_events += [(a, e) for e in world_raises if e in triggers]
        timed.append(mine)
        agents.append(
            dataclasses.replace(
                ca,
                transitions=new_transitions,
                var_index={**ca.var_index, INST: inst_col},
                init_vars=[*ca.init_vars, compile_expression("0", {})],
            )
        )
    explorer = dataclasses.replace(cteam, agents=agents, scenario=[])
    sk = Skeleton(
        explorer,
        cteam,
        oracle,
        [
            [j for n, j in ca.var_index.items() if n not in abstract[a]]
            for a, ca in enumerate(cteam.agents)
        ],
        [sorted(s) for s in abstract],
        afields,
        free,
        timed,
        world_events,
        inputs,
    )
    sk.notes = _notes(sk)
    return sk


def _notes(sk: Skeleton) -> list[str]:
    """What the skeleton leaves out, in words (printed with every verdict)."""
    out = []
    names = [ca.name for ca in sk.original.agents]
    for a, vs in enumerate(sk.abstract_vars):
        if vs:
            out.append(
                f"agent '{names[a]}': variable(s) {', '.join(vs)} computed from time "
                "or state: abstracted"
            )
    if sk.abstract_fields:
        out.append(
            "message fields computed from time or state: "
            + ", ".join(sorted(f"{m}.{f}" for m, f in sk.abstract_fields))
            + ": abstracted"
        )
    for a, j, text in sk.free:
        tr = sk.original.agents[a].transitions[j]
        out.append(
            f"agent '{names[a]}' {tr.text}: '{text}' reads time or state: both outcomes explored"
        )
    streams = sorted({s.message for ca in sk.original.agents for s in ca.streams})
    if streams:
        out.append(
            f"data stream(s) {', '.join(streams)} left out (guards that read "
            "stream estimates are explored both ways)"
        )
    return out
