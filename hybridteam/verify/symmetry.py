"""Symmetry reduction: interchangeable agents explored once per arrangement.

Three identical followers that each ask once give the same behaviours whichever of them
asks first: a state and the state with two followers' parts swapped have successors that
are swapped the same way, and every property that names neither follower has the same
truth in both. Such states are one state up to *symmetry*; the explorer keeps one
representative of each class (the least of its permutations), so it stores a class once
instead of up to ``n!`` times, and every verdict is the same (the quotient is bisimilar to
the full skeleton for properties the permutations leave unchanged).

Agents are interchangeable when their compiled skeletons are the same up to their names
(modes, transitions, guards, actions, variables, ack policies, whether an operator or one
whose final modes end a run, the world events they get) and the parameters their discrete
logic reads are equal (plant state, streams and laws are abstracted away, so their
parameters may differ). The group is the permutations of interchangeable agents that fix
every agent

- a checked property names (``in_mode(b, ...)`` pins ``b``; ``count_in_role`` and
  ``deadlock`` name none),
- an expression names (``id_b``, ``to: b``),
- the scenario still names at its remaining entries (the group grows as the scenario
  goes on: agents it no longer names become free).

An agent index held in a variable or a message field (``leader = msg_sender``, a
``to:`` expression) would have to be permuted with the agents; such teams get no
symmetry reduction (said in :attr:`Symmetry.reason`).

Counterexamples stay concrete: :func:`lift` turns a path through representatives into a
path of the team's own states (re-deriving each step's permutation), which is what the
replay and the printed steps follow.
"""

from __future__ import annotations

import re
from array import array
from collections.abc import Iterator
from dataclasses import dataclass, field
from itertools import pairwise, permutations, product
from math import factorial
from typing import Any

from hybridteam.engine.compile.compiled import CAgent
from hybridteam.expr import Expression
from hybridteam.verify.abstraction import Skeleton
from hybridteam.verify.explore import NONE, Graph, other_answers
from hybridteam.verify.machine import Copy, Machine, OutboxEntry, State, _link
from hybridteam.verify.properties import Property
from hybridteam.verify.store import Edges, Store

#: A permutation of agents: ``p[a]`` is where agent ``a``'s part goes.
Perm = tuple[int, ...]

#: Orders of agents with equal parts tried per state, at most (:meth:`Symmetry.reduce`).
MAX_TIES = 720


@dataclass
class Symmetry:
    """The permutations a team's skeleton and properties allow, per scenario position."""

    agents: int
    classes: list[tuple[int, ...]]  # interchangeable agents (two or more), not pinned
    scenario: list[int]  # the agent of each scenario entry
    fifo: bool = False
    reason: str = ""  # why there is no reduction (empty when there is one)
    _free: dict[int, list[tuple[int, ...]]] = field(default_factory=dict, repr=False)

    @property
    def active(self) -> bool:
        """Whether some permutation besides the identity is allowed."""
        return bool(self.classes)

    def free(self, cursor: int) -> list[tuple[int, ...]]:
        """The classes once ``cursor`` scenario entries are raised, without the agents the
        remaining entries name (those stay fixed)."""
        found = self._free.get(cursor)
        if found is None:
            named = set(self.scenario[cursor:])
            found = [tuple(a for a in c if a not in named) for c in self.classes]
            found = self._free[cursor] = [c for c in found if len(c) > 1]
        return found

    def group(self, cursor: int) -> list[Perm]:
        """Every allowed permutation (the identity first) once ``cursor`` scenario entries
        are raised."""
        free = self.free(cursor)
        return [_perm(self.agents, free, images) for images in product(*map(permutations, free))]

    def representative(self, s: State) -> State:
        """The least state (a total order on states' tuples) among ``s``'s permutations."""
        return self.reduce(s)[0]

    def reduce(self, s: State) -> tuple[State, Perm]:
        """``s``'s representative and a permutation that maps ``s`` to it.

        The agents' parts come first in a state's tuple, so the least permutation puts
        each class's parts in ascending order; only agents with equal parts (the same
        modes and variables) are left to order, by the rest of the state. Where more than
        :data:`MAX_TIES` orders would remain, the agents' own order among equals is kept:
        a state of the class, not always the least (sound, less reduced)."""
        free = self.free(s.cursor)
        if not free:
            return s, tuple(range(self.agents))
        blocks: list[tuple[tuple[int, ...], tuple[int, ...]]] = []  # (agents, positions)
        count = 1
        for c in free:
            ranked = sorted(c, key=lambda a: s.agents[a])  # stable: equal parts by index
            k = 0
            while k < len(ranked):
                j = k + 1
                while j < len(ranked) and s.agents[ranked[j]] == s.agents[ranked[k]]:
                    j += 1
                blocks.append((tuple(ranked[k:j]), c[k:j]))
                count *= factorial(j - k)
                k = j
        ways = [
            permutations(positions) if count <= MAX_TIES else [positions] for _, positions in blocks
        ]
        best: State | None = None
        how: Perm = ()
        for images in product(*ways):
            p = _perm(self.agents, [agents for agents, _ in blocks], images)
            t = permute(s, p, self.fifo)
            if best is None or t < best:
                best, how = t, p
        assert best is not None  # (one arrangement at least)
        return best, how

    def size(self, cursor: int) -> int:
        """How many permutations are allowed once ``cursor`` scenario entries are raised."""
        n = 1
        for c in self.free(cursor):
            n *= factorial(len(c))
        return n

    def describe(self, names: list[str]) -> str:
        """The classes in words."""
        if not self.active:
            return f"none ({self.reason})"
        classes = "; ".join(", ".join(names[a] for a in c) for c in self.classes)
        return f"interchangeable agents {classes} ({self.size(0)} permutations at the start)"


def _perm(n: int, sources: list[tuple[int, ...]], images: tuple) -> Perm:
    """The permutation of ``n`` agents moving each ``sources[i][k]`` to ``images[i][k]``."""
    p = list(range(n))
    for c, img in zip(sources, images, strict=True):
        for a, b in zip(c, img, strict=True):
            p[a] = b
    return tuple(p)


def permute(s: State, p: Perm, fifo: bool = False) -> State:
    """``s`` with agent ``a``'s part moved to ``p[a]`` (copies, outbox, filters and id
    counters renamed with it), in canonical order. Message ids stay as they are: they are
    numbered per sender, which the permutation moves as a whole."""
    agents = [s.agents[0]] * len(p)
    for a, part in enumerate(s.agents):
        agents[p[a]] = part
    ids = list(s.next_ids)
    for a, k in enumerate(s.next_ids):
        ids[p[a]] = k
    inflight = [c._replace(sender=p[c.sender], receiver=p[c.receiver]) for c in s.inflight]
    return s._replace(
        agents=tuple(agents),
        inflight=tuple(sorted(inflight, key=_link if fifo else None)),
        outbox=tuple(
            sorted(
                e._replace(sender=p[e.sender], waiting=tuple(sorted(p[w] for w in e.waiting)))
                for e in s.outbox
            )
        ),
        seen=tuple(sorted((p[r], p[snd], k) for r, snd, k in s.seen)),
        next_ids=tuple(ids),
    )


def inverse(p: Perm) -> Perm:
    out = [0] * len(p)
    for a, b in enumerate(p):
        out[b] = a
    return tuple(out)


def symmetry(sk: Skeleton, props: list[Property], fifo: bool = False) -> Symmetry:
    """The symmetry of ``sk`` that keeps every property in ``props``."""
    agents = sk.original.agents
    n = len(agents)
    names = [ca.name for ca in agents]
    scenario = [a for _, a, _ in sk.original.scenario]
    none = Symmetry(n, [], scenario, fifo)
    pinned: set[int] = set()
    ids = {f"id_{name}": a for a, name in enumerate(names)}
    for ca in agents:
        for expr_names in _read(ca):
            for name in expr_names:
                if name in ids:
                    pinned.add(ids[name])
                elif name == "msg_sender":
                    none.reason = f"agent '{ca.name}' reads an agent index (msg_sender)"
                    return none
        for action in _actions(ca):
            if action.to_expr is not None:
                none.reason = f"agent '{ca.name}' sends to an agent computed from its variables"
                return none
            if action.to is not None and 0 <= action.to < n:
                pinned.add(action.to)
    for p in props:
        if p.kind in ("invariant", "response"):
            words = set(re.findall(r"[A-Za-z_][A-Za-z0-9_]*", p.text))
            pinned |= {a for a, name in enumerate(names) if name in words}
    by_sig: dict[tuple, list[int]] = {}
    for a in range(n):
        if a not in pinned:
            by_sig.setdefault(_signature(sk, a), []).append(a)
    classes = [tuple(c) for c in by_sig.values() if len(c) > 1]
    if not classes:
        none.reason = "no two agents are interchangeable where the properties allow it"
        return none
    return Symmetry(n, classes, scenario, fifo)


def _actions(ca: CAgent) -> Iterator[Any]:
    """Every action of the agent (on transitions, on entering and exiting modes)."""
    for tr in ca.transitions:
        yield from tr.actions
    for m in ca.modes:
        yield from m.on_entry
        yield from m.on_exit


def _read(ca: CAgent) -> list[frozenset[str]]:
    """The names each expression of the agent's discrete logic reads."""
    exprs: list[Expression | None] = list(ca.init_vars)
    for tr in ca.transitions:
        exprs += [tr.guard, tr.after]
    for action in _actions(ca):
        exprs += [action.expr, action.to_expr, *action.fields.values()]
    for pol in ca.policies.values():
        exprs += [pol.priority, pol.timeout, pol.retries]
    return [e.names for e in exprs if e is not None]


def _src(e: Expression | None) -> str | None:
    return None if e is None else e.source


def _action_sig(act: Any) -> tuple:
    return (
        act.kind,
        act.target,
        _src(act.expr),
        act.name,
        act.to,
        act.socket,
        tuple(sorted((k, _src(v)) for k, v in act.fields.items())),
    )


def _signature(sk: Skeleton, a: int) -> tuple:
    """What must be equal for agents to be interchangeable (no names, no plant)."""
    ca = sk.original.agents[a]
    read = {name for names in _read(ca) for name in names}
    params = tuple(
        (name, float(ca.param_defaults[k]))
        for name, k in sorted(ca.param_index.items())
        if name in read
    )
    modes = tuple(
        (
            m.path,
            m.parent,
            m.kind,
            tuple(m.children),
            m.initial,
            m.history,
            bool(m.final),
            m.role,
            tuple(_action_sig(x) for x in m.on_entry),
            tuple(_action_sig(x) for x in m.on_exit),
        )
        for m in ca.modes
    )
    transitions = tuple(
        (
            tr.source,
            tuple(tr.targets),
            tr.on,
            _src(tr.after),
            tr.guard_text,
            tr.priority,
            tr.internal,
            tuple(_action_sig(x) for x in tr.actions),
        )
        for tr in ca.transitions
    )
    policies = tuple(
        sorted(
            (k, _src(p.priority), _src(p.timeout), _src(p.retries), p.dedupe)
            for k, p in ca.policies.items()
        )
    )
    return (
        modes,
        transitions,
        tuple(sorted(ca.var_index.items())),
        tuple(_src(e) for e in ca.init_vars),
        tuple(sk.discrete_vars[a]),
        params,
        policies,
        bool(sk.original.team.agents[a].operator),
        a in sk.original.ending,  # its final modes end a run
        tuple(sorted(sk.inputs[a])),
        tuple(sorted(e for b, e in sk.world_events if b == a)),
        tuple(sk.time_driven[a]),
    )


# --------------------------------------------------------------------- counterexamples
def lift(sym: Symmetry, m: Machine, g: Graph, path: list[int]) -> tuple[Graph, list[int]]:
    """A path of the team's own states behind ``path`` (states of ``g``, representatives):
    a small graph holding it, and the path's states in it.

    Representative ``r_i`` stands for the concrete state ``c_i = tau_i^-1(r_i)``; the step
    ``r_i -> t`` (the edge's choice, the answers of its free comparisons re-found) with
    ``r_{i+1} = pi(t)`` is, permuted back, the concrete step ``c_i -> tau_i^-1(t)``, and
    ``tau_{i+1} = pi . tau_i``."""
    c = m.initial()
    rep, tau = sym.reduce(c)
    assert rep == g.states[path[0]], "the graph starts at the initial state's representative"
    states, choices = [c], []
    for a, b in pairwise(path):
        ra, rb = g.states[a], g.states[b]
        choice = g.edge_choice(a, b)
        assert choice is not None, "a path follows the graph's edges"
        t, pi = _step(sym, m, ra, choice, rb)
        back = inverse(tau)
        choices.append(_choice(choice, ra, back, states[-1]))
        states.append(permute(t, back, sym.fifo))
        tau = tuple(pi[tau[x]] for x in range(len(tau)))
    store = Store(len(states[0].agents))
    ids = []
    for s in states:
        key, k = store.find(s)
        ids.append(store.add(key) if k is None else k)
    edges = Edges()
    for (x, y), choice in zip(pairwise(ids), choices, strict=True):
        if x != y:
            edges.add(x, y, choice)
    edges.freeze(len(store))
    return Graph(store, array("I", [NONE] * len(store)), edges), ids


def _step(sym: Symmetry, m: Machine, ra: State, choice: tuple, rb: State) -> tuple[State, Perm]:
    """The successor of ``ra`` by ``choice`` whose representative is ``rb`` (its free
    comparisons' answers tried in the explorer's order), and the permutation to it."""
    tapes: list[tuple] = [()]
    while tapes:
        tape = tapes.pop(0)
        r = m.run([(ra, choice, tape)])[0]
        rep, pi = sym.reduce(r.state)
        if rep == rb:
            return r.state, pi
        tapes += other_answers(tape, r.reads)
    raise AssertionError(f"the step {choice} does not lead to its edge's state")  # a bug


def _choice(choice: tuple, rep: State, back: Perm, concrete: State) -> tuple:
    """``choice`` (on representative ``rep``) on the concrete state ``back(rep)``."""
    kind = choice[0]
    if kind in ("deliver", "lose", "dup"):
        c: Copy = rep.inflight[choice[1]]
        moved = c._replace(sender=back[c.sender], receiver=back[c.receiver])
        return (kind, concrete.inflight.index(moved))
    if kind == "timer":
        e: OutboxEntry = rep.outbox[choice[1]]
        entry = e._replace(sender=back[e.sender], waiting=tuple(sorted(back[w] for w in e.waiting)))
        return ("timer", concrete.outbox.index(entry))
    if kind in ("time", "world"):
        return (kind, back[choice[1]], *choice[2:])
    return choice
