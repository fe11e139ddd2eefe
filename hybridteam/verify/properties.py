"""What ``hybridteam verify`` checks, and the checks on an explored state graph.

Properties come from the team's ``requirements:`` (the requirements language) where their
shape has a meaning without a clock:

- ``always(phi)``, phi without temporal operators: an *invariant*, checked on every
  reachable state (``always(count_in_role(lead) <= 1)``);
- ``always(implies(phi, eventually(psi)))``: a *response* (phi leads to psi): from every
  reachable state where phi holds, every path reaches psi — no path ends, and no cycle
  runs, through states where psi is false;

plus the built-in ``deadlock``: a state where nothing can happen any more (no copy in
flight, no timer, no time-driven transition) while some agent waits for a message (it is
not final, not an operator, and only a message or an event of its own could move it), not
every agent is final (whatever the team's end rule says: a run that ends while a robot
still waits for its partner's message is the handshake's deadlock), and no operator has
taken command.

Other formulas (timed windows, nested operators, states or time) are listed as not
checkable, with the reason. Formulas are evaluated with the requirements' own compiled
trees (:mod:`hybridteam.requirements.nodes`) on the states' modes and discrete variables.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field

import networkx as nx
import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

from hybridteam.errors import ModelErrors
from hybridteam.requirements import nodes as N
from hybridteam.requirements.check import compile_requirements
from hybridteam.verify.abstraction import Skeleton
from hybridteam.verify.explore import Graph
from hybridteam.verify.store import UINT, Grouped


class Unsupported(Exception):
    """A formula reads a signal the skeleton does not keep."""


@dataclass
class Property:
    name: str
    kind: str  # "invariant" | "response" | "deadlock" | "skipped"
    text: str
    phi: N.Node | None = None
    psi: N.Node | None = None
    reason: str = ""


@dataclass
class Verdict:
    prop: Property
    holds: bool | None  # None: not checked
    state: int = -1  # the violating state (invariant, deadlock) or the response's trigger
    lasso: list[int] | None = None  # response: from the trigger through psi-false states
    loops: bool = False  # the lasso ends in a cycle (else in a dead end)
    message: str = ""
    others: list[int] = field(default_factory=list)  # more violations, one per configuration


#: Every state (:class:`States` rows).
_ALL = slice(None)
#: States whose signals are spread at once when formulas are evaluated (the default
#: ``block`` of :func:`check` and :func:`truths`): the arrays of a block, not of millions
#: of states, are held at a time. The verdicts do not depend on it.
BLOCK = 1 << 20


class States:
    """The signals a formula reads, over explored states (shape ``(S, 1)``)."""

    def __init__(self, sk: Skeleton, g: Graph, rows: slice | np.ndarray = _ALL) -> None:
        """Explored states' (``rows``: these) active modes and discrete variables, per
        agent: from the few distinct agent parts the store keeps, spread over the states
        when a formula first reads that agent (an agent no formula reads costs nothing)."""
        self.sk = sk
        count = len(sk.cteam.agents)
        parts = g.states.agent_parts
        if isinstance(parts, Grouped):  # (the packed store's: made for these rows only)
            self._nums = parts[rows]
        else:
            flat = parts if isinstance(parts, np.ndarray) else np.frombuffer(parts, UINT)
            self._nums = flat.reshape(len(g.states), count)[rows]
        self.shape = (self._nums.shape[0], 1)
        self.memo: dict = {}
        self._values = g.states.parts.values
        self._agents: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self.names = {ca.name: a for a, ca in enumerate(sk.cteam.agents)}

    def _agent(self, a: int) -> tuple[np.ndarray, np.ndarray]:
        """Agent ``a``'s active modes ``(states, modes)`` and discrete variables
        ``(states, kept columns)``, made at the first read."""
        if a not in self._agents:
            m = len(self.sk.cteam.agents[a].modes)
            values = self._values
            used, inverse = np.unique(self._nums[:, a], return_inverse=True)
            act = np.array([np.frombuffer(values[u][0][:m], np.uint8) for u in used.tolist()])
            cols = self.sk.discrete_vars[a]
            var = np.array([values[u][1] for u in used.tolist()], float)
            self._agents[a] = (
                act.astype(bool).reshape(used.size, m)[inverse],
                var.reshape(used.size, len(cols))[inverse],
            )
        return self._agents[a]

    @property
    def t(self):
        raise Unsupported("it reads time")

    def in_modes(self, agent: str, modes: list[int]) -> np.ndarray:
        return np.logical_or.reduce(self.active(self.names[agent])[:, modes], axis=1)[:, None]

    def active(self, a: int) -> np.ndarray:
        """Agent ``a``'s active modes in each state ``(states, modes)``, as booleans."""
        return self._agent(a)[0]

    def variable(self, agent: str, j: int) -> np.ndarray:
        a = self.names[agent]
        cols = self.sk.discrete_vars[a]
        if j not in cols:
            raise Unsupported(
                f"it reads {agent}.{self._var_name(a, j)}, which is computed from time or state"
            )
        return self._agent(a)[1][:, cols.index(j)][:, None]

    def _var_name(self, a: int, j: int) -> str:
        return next(n for n, k in self.sk.original.agents[a].var_index.items() if k == j)

    def param(self, agent: str, name: str) -> np.ndarray:
        ca = self.sk.original.agents[self.names[agent]]
        return np.full(self.shape, ca.param_defaults[ca.param_index[name]])

    def team_param(self, name: str) -> np.ndarray:
        ca = self.sk.original.agents[0]
        return np.full(self.shape, ca.param_defaults[ca.param_index[name]])

    def state(self, agent: str, j: int):
        raise Unsupported(f"it reads {agent}'s plant state")

    def series(self, name: str, j: int):
        raise Unsupported(f"it reads the world series '{name}'")

    def event(self, kind: str, agent: str | None, message: str):
        raise Unsupported(f"it reads {kind}() message events")


_OPS = {
    "<": np.less,
    "<=": np.less_equal,
    ">": np.greater,
    ">=": np.greater_equal,
    "==": np.equal,
    "!=": np.not_equal,
}


def truth(node: N.Node, sig: States) -> np.ndarray:
    """Whether a temporal-free formula holds in each state (exact, not robustness: a
    strict comparison at its boundary is false)."""
    n = sig.shape[0]
    if isinstance(node, N.Const):
        return np.full(n, bool(node.value))
    # (a Flag is built with its getter, a Predicate with both sides)
    if isinstance(node, N.Flag):
        return np.broadcast_to(node.get(sig), sig.shape)[:, 0].astype(bool)  # type: ignore[misc]
    if isinstance(node, N.Predicate):
        a = np.broadcast_to(np.asarray(node.lhs(sig), float), sig.shape)  # type: ignore[misc, type-var]
        b = np.broadcast_to(np.asarray(node.rhs(sig), float), sig.shape)  # type: ignore[misc, type-var]
        return _OPS[node.op](a, b)[:, 0]
    if isinstance(node, N.Not):
        return ~truth(node.children[0], sig)
    if isinstance(node, N.And):
        return np.logical_and.reduce([truth(c, sig) for c in node.children])
    if isinstance(node, N.Or):
        return np.logical_or.reduce([truth(c, sig) for c in node.children])
    if isinstance(node, N.Implies):
        return ~truth(node.children[0], sig) | truth(node.children[1], sig)
    raise Unsupported("it has a temporal operator inside")


def _temporal_free(node: N.Node) -> bool:
    return not isinstance(node, N.Temporal) and all(_temporal_free(c) for c in node.children)


def _unbounded(node: N.Temporal) -> bool:
    return node.lo == 0 and math.isinf(node.hi)


def properties(sk: Skeleton) -> list[Property]:
    """The team's requirements, classified, then ``deadlock``."""
    try:
        reqs = compile_requirements(sk.original).requirements
    except ModelErrors:  # the loader reports these; a team that loads compiles them
        reqs = []
    out = []
    for r in reqs:
        f = r.formula
        p = Property(r.name, "skipped", r.text)
        if isinstance(f, N.Always) and _unbounded(f):
            body = f.children[0]
            if _temporal_free(body):
                p.kind, p.phi = "invariant", body
            elif (
                isinstance(body, N.Implies)
                and _temporal_free(body.children[0])
                and isinstance(body.children[1], N.Eventually)
                and _unbounded(body.children[1])
                and _temporal_free(body.children[1].children[0])
            ):
                p.kind, p.phi, p.psi = "response", body.children[0], body.children[1].children[0]
        if p.kind == "skipped":
            p.reason = (
                "verify checks always(phi) and always(implies(phi, eventually(psi))) "
                "with phi, psi free of temporal operators; timed windows need a clock"
            )
        out.append(p)
    out.append(
        Property("deadlock", "deadlock", "nothing can happen while an agent waits for a message")
    )
    return out


#: Why a partial search leaves responses unchecked.
PARTIAL_LIVENESS = (
    "partial search: a response needs the whole state graph (its cycles), which a "
    "partial search does not keep; it checks invariants and deadlock (use --storage exact)"
)


def check(props: list[Property], sk: Skeleton, g: Graph, block: int = BLOCK) -> list[Verdict]:
    """Each property's verdict over the explored graph, its formulas evaluated ``block``
    states at a time."""
    out = []
    for p in props:
        try:
            if p.kind == "invariant":
                assert p.phi is not None  # (an invariant has its formula)
                out.append(_invariant(p, truths(p.phi, sk, g, block)))
            elif p.kind == "response" and g.coverage is not None:
                out.append(Verdict(p, None, message=PARTIAL_LIVENESS))
            elif p.kind == "response":
                assert p.phi is not None and p.psi is not None  # (a response has both)
                out.append(
                    _response(p, g, truths(p.phi, sk, g, block), truths(p.psi, sk, g, block))
                )
            elif p.kind == "deadlock":
                out.append(_deadlock(p, sk, g))
            else:
                out.append(Verdict(p, None, message=p.reason))
        except Unsupported as exc:
            out.append(Verdict(p, None, message=f"not checkable: {exc}"))
    return out


def truths(node: N.Node, sk: Skeleton, g: Graph, block: int = BLOCK) -> np.ndarray:
    """:func:`truth` in every explored state, evaluated ``block`` states at a time."""
    n = len(g.states)
    return np.concatenate(
        [truth(node, States(sk, g, slice(k, min(k + block, n)))) for k in range(0, n, block)]
        or [np.zeros(0, bool)]
    )


def _invariant(p: Property, ok: np.ndarray) -> Verdict:
    bad = np.flatnonzero(~ok)
    if not bad.size:
        return Verdict(p, True)
    return Verdict(p, False, int(bad[0]), others=bad[1:].tolist())  # breadth-first: shortest


def _response(p: Property, g: Graph, phi: np.ndarray, psi: np.ndarray) -> Verdict:
    """phi leads to psi: no phi state starts a psi-free path into a dead end or a cycle.

    The whole graph is searched with sparse arrays (the psi-free subgraph's reverse, then
    what reaches a dead end or a cycle); only a violation's lasso is traced with networkx,
    on the states that reach a bad one. The arrays over every edge are the check's peak of
    memory: the subgraph is cut from the edges' own sparse-row view in 32-bit indices, and
    a property that holds needs no strongly connected components (scipy's take a float64
    copy of every edge), only the reverse graph."""
    waiting = ~psi
    dead = waiting & g.terminal()
    if compiled():  # (the same peeling in the memory of the reverse alone: peel.py)
        from hybridteam.verify.peel import reaching

        row, dst = g.edges.csr()
        reach, (rev_ptr, rev_idx) = reaching(row, dst, waiting, dead)
        starts = np.flatnonzero(reach & phi)
        if not starts.size:
            return Verdict(p, True)
        n = len(waiting)
        marks = np.ones(rev_idx.size, np.int8)
        back = csr_matrix((marks, rev_idx, rev_ptr), shape=(n, n), copy=False)
    else:
        back, out = _reverse(g, waiting)
        reach = _reaching(back, out, waiting, dead)
        starts = np.flatnonzero(reach & phi)
        if not starts.size:
            return Verdict(p, True)
    # a violation: which states lie on a psi-free cycle (those that reach one do too)
    _, label = connected_components(back, directed=True, connection="strong")
    del back
    size = np.bincount(label, minlength=1)
    cyclic = waiting & (size[label] > 1)
    return _lasso(
        p,
        g,
        psi,
        reach,
        set(np.flatnonzero(dead).tolist()),
        set(np.flatnonzero(cyclic).tolist()),
        int(starts[0]),
    )


def compiled() -> bool:
    """Whether responses are peeled by the compiled loop (:mod:`.peel`): where numba is
    importable and not switched off (``HYBRIDTEAM_NUMBA=0``, as for exploring)."""
    from hybridteam.verify.kernel import numba_available

    return numba_available()


def _reverse(g: Graph, free: np.ndarray) -> tuple[csr_matrix, np.ndarray]:
    """The subgraph of the edges between ``free`` states, reversed (row k: the sources of
    k's edges, duplicates possible), and each state's out-degree in the subgraph."""
    n = len(free)
    indptr, indices = _psi_free(g, free)
    out = np.diff(indptr)
    marks = np.ones(indices.size, np.int8)
    # csc's columns are the reverse's rows: its transpose is the reverse, not a copy
    back = csr_matrix((marks, indices, indptr), shape=(n, n), copy=False).tocsc().T
    return back, out


def _psi_free(g: Graph, free: np.ndarray, block: int = BLOCK) -> tuple[np.ndarray, np.ndarray]:
    """``(indptr, indices)`` of the edges between ``free`` states (duplicates possible),
    in the narrowest index type that holds them (int32 below 2**31 edges). The edges are
    sifted ``block`` states at a time, twice (count, then place): no array over every
    edge but the result."""
    indptr, indices = g.edges.csr()
    n = len(free)
    wide = np.int64 if indices.size >= 2**31 or n >= 2**31 else np.int32
    sub_indptr = np.zeros(n + 1, wide)
    for a, b, lo, keep in _sifted(indptr, indices, free, block):
        before = np.zeros(keep.size + 1, wide)  # kept edges before each of the block's
        np.cumsum(keep, dtype=wide, out=before[1:])
        sub_indptr[a + 1 : b + 1] = before[indptr[a + 1 : b + 1] - lo] + sub_indptr[a]
    sub_indices = np.zeros(int(sub_indptr[-1]), wide)
    for a, b, lo, keep in _sifted(indptr, indices, free, block):
        sub_indices[sub_indptr[a] : sub_indptr[b]] = indices[lo : lo + keep.size][keep]
    return sub_indptr, sub_indices


def _sifted(
    indptr: np.ndarray, indices: np.ndarray, free: np.ndarray, block: int
) -> Iterator[tuple[int, int, int, np.ndarray]]:
    """Per ``block`` states ``a..b``: their first edge's number and which of their edges
    join two free states."""
    for a in range(0, len(free), block):
        b = min(a + block, len(free))
        lo, hi = int(indptr[a]), int(indptr[b])
        keep = np.repeat(free[a:b], np.diff(indptr[a : b + 1]))  # the source is free
        keep &= free[indices[lo:hi]]  # and so is the destination
        yield a, b, lo, keep


def _reaching(back: csr_matrix, out: np.ndarray, free: np.ndarray, dead: np.ndarray) -> np.ndarray:
    """The ``free`` states with a path among free states to a ``dead`` one or into a
    cycle (those included). The others are peeled off backwards: a free state that is not
    dead and has no free successor left cannot reach either, nor can a state all of whose
    free successors were peeled (``out``, the free out-degrees, counts them down; ``back``:
    the free subgraph's reverse). What remains has a successor that remains, or is dead:
    following those it meets a dead end or comes round a cycle."""
    out = out.copy()
    gone = free & (out == 0) & ~dead
    frontier = np.flatnonzero(gone)
    while frontier.size:
        preds, times = np.unique(back[frontier].indices, return_counts=True)
        out[preds] -= times.astype(out.dtype)
        frontier = preds[out[preds] == 0]
        gone[frontier] = True
    return free & ~gone


def _lasso(
    p: Property,
    g: Graph,
    psi: np.ndarray,
    reach: np.ndarray,
    dead: set[int],
    cyclic: set[int],
    start: int,
) -> Verdict:
    """The shortest psi-free path from ``start`` into a dead end or a cycle (``reach``
    holds every dead and cyclic state: the backward search starts from them)."""
    sub: nx.DiGraph[int] = nx.DiGraph()
    nodes = np.flatnonzero(reach).tolist()
    sub.add_nodes_from(nodes)
    sub.add_edges_from((k, j) for k in nodes for j in g.succ(k) if reach[j] and not psi[j])
    targets = {k for k in dead | cyclic if k == start or nx.has_path(sub, start, k)}
    lengths = nx.single_source_shortest_path(sub, start)
    end = min(targets, key=lambda k: (len(lengths[k]), k))
    lasso = lengths[end]
    loops = end in cyclic
    if loops:
        back = next(iter(nx.find_cycle(sub.subgraph(cyclic), end)))
        lasso = [*lasso, back[1]] if back[1] != end else lasso
    return Verdict(p, False, start, lasso, loops)


def _deadlock(p: Property, sk: Skeleton, g: Graph) -> Verdict:
    rows = np.flatnonzero(g.terminal())
    if not rows.size:
        return Verdict(p, True)
    team = sk.original.team
    agents = sk.cteam.agents
    sig = States(sk, g, rows)
    blocked = np.zeros(rows.size, bool)
    all_final = np.ones(rows.size, bool)
    commanded = np.zeros(rows.size, bool)
    for a, ca in enumerate(agents):
        act = sig.active(a)
        final = (~act[:, ca.leaves] | ca.final[ca.leaves]).all(axis=1)
        if team.agents[a].operator:
            initial = np.zeros(len(ca.modes), bool)
            m = 0
            while True:
                initial[m] = True
                if ca.modes[m].kind != "or":
                    break
                m = ca.modes[m].initial
            commanded |= (act[:, ca.leaves] != initial[ca.leaves]).any(axis=1)
            continue
        all_final &= final
        for r in range(rows.size):
            if final[r]:
                continue
            waits = {
                ca.transitions[j].on
                for m in np.flatnonzero(act[r])
                for j in ca.modes[m].outgoing
                if ca.transitions[j].on
            }
            if waits and not waits & (sk.inputs[a] | {e for b, e in sk.world_events if b == a}):
                blocked[r] = True
    bad = rows[blocked & ~all_final & ~commanded]
    if not bad.size:
        return Verdict(p, True)
    return Verdict(p, False, int(bad[0]), others=bad[1:].tolist())
