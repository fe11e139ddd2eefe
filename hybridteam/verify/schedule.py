"""Moments for a path's steps: a simple temporal network solved with networkx.

A skeleton path fixes the order of its steps, and some steps fix their distance to an
earlier one: an ack timeout expires exactly its timeout after the message was (re)sent,
an ``after:`` timeout exactly its delay after its mode was entered; and an ack timeout or
``after:`` that the path does not take must not expire while it is armed. Each is a bound
``lo <= T_j - T_i <= hi`` on two steps' moments. With an edge ``i -> j`` of weight ``hi``
and ``j -> i`` of weight ``-lo`` per bound, the bounds can be met iff the graph has no
negative cycle, and ``T_j = -dist(j, 0)`` is the earliest schedule (Dechter, Meiri and
Pearl's simple temporal networks). A negative cycle names the bounds that contradict
each other: the reason a path is spurious. Weights are whole nanoseconds: an equality
(an ack timeout of 0.1 s both ways) must cancel exactly, which floats do not promise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from itertools import pairwise

import networkx as nx

#: the time between two steps that happen one after the other (seconds): a millisecond
#: (as long as a message on a LAN takes; runs are readable), else a microsecond when a
#: path must fit more steps into a timeout than milliseconds allow
GAPS = (1e-3, 1e-6)
_NS = 1e9


@dataclass(frozen=True)
class Bound:
    i: int
    j: int
    lo: float
    hi: float
    why: str


def solve(n: int, bounds: list[Bound]) -> list[float] | str:
    """The earliest moments ``T_0 = 0, ..., T_n`` meeting ``bounds``, or why none do."""
    g: nx.DiGraph[int] = nx.DiGraph()
    g.add_nodes_from(range(n + 1))

    def edge(u: int, v: int, w: float, why: str) -> None:
        w = round(w * _NS)
        if not g.has_edge(u, v) or g[u][v]["weight"] > w:
            g.add_edge(u, v, weight=w, why=why)

    for b in bounds:
        if b.hi < math.inf:
            edge(b.i, b.j, b.hi, b.why)
        if b.lo > -math.inf:
            edge(b.j, b.i, -b.lo, b.why)
    try:
        dist = nx.single_source_bellman_ford_path_length(g.reverse(copy=False), 0)
    except nx.NetworkXUnbounded:
        return "no moments meet all of: " + "; ".join(_contradiction(g))
    return [-dist[k] / _NS for k in range(n + 1)]


def _contradiction(g: nx.DiGraph) -> list[str]:
    """The bounds along one negative cycle (networkx's search may miss from one source:
    every node is tried)."""
    for source in g.nodes:
        try:
            cycle = nx.find_negative_cycle(g, source)
        except nx.NetworkXError:
            continue
        whys: list[str] = []
        for u, v in pairwise(cycle):
            if g[u][v]["why"] not in whys:
                whys.append(g[u][v]["why"])
        return whys
    return ["bounds that contradict each other"]
