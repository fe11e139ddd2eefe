"""The roles view of a state diagram: what each robot does, without the protocol's machinery.

A protocol such as ``role_assignment`` gives a robot six states (Lead, Offering, Follow,
Requesting, Accepting, Operated), copies the robot's lead body into two of them and its
follow body into three, and adds some thirty transitions and as many message links. All of
it is right, and a full diagram shows it; but the figure a paper draws (the architecture
paper's Fig. 4) shows roles: Dock -> Transport, Transport = Lead | Follow. This module turns
the full diagram graph into that one, as a graph the same renderers draw:

- of the states playing one role, the first declared (``Lead``, ``Follow``, ``Operated``)
  stands for the role with its body; the others and their body copies are left out;
- the protocol's transitions become one edge per pair of roles, labelled with the handshakes
  that switch them: a trigger, prefixed by how the hidden state was reached
  (``want_lead … grant``: a follower that wanted to lead and was granted it);
- the protocol's messages become one dashed link per pair of robots, named by the protocol;
- an agent made only of protocol modes (the operator) is left out.

The robot's own modes, transitions and messages (Dock, ``docked``, ``ready``) are untouched,
so a team without protocols gives the full diagram unchanged.
"""

from __future__ import annotations

import networkx as nx

from hybridteam.export.diagram import agents, children, edges_of, parent, walk
from hybridteam.export.style import role_copies


def role_hosts(graph: nx.MultiDiGraph) -> list[str]:
    """Modes whose children are a protocol's role states (``Transport``)."""
    return [
        n
        for n, d in graph.nodes(data=True)
        if any(graph.nodes[c].get("role") for c in children(graph, n))
    ]


def _trigger(data: dict) -> str:
    """A protocol transition's trigger as a reader names it; ``x_undeliverable`` is one
    failure whatever message x was, so it reads ``undeliverable``."""
    on = data["trigger"]
    if on.endswith("_undeliverable"):
        return "undeliverable"
    return on or (f"after({data['after']})" if data["after"] else data["label"])


def _label(how: list[tuple[str, str]], width: int = 60) -> str:
    """``want_lead … grant, offer … confirm``; past ``width`` characters the triggers alone
    (``halt, after(answer_timeout), undeliverable``): a failure edge is read by its causes."""
    full = ", ".join(f"{a} … {b}" if a else b for a, b in how)
    return full if len(full) <= width else ", ".join(dict.fromkeys(b for _, b in how))


def roles_view(graph: nx.MultiDiGraph) -> nx.MultiDiGraph:
    """A copy of the diagram ``graph`` with each protocol region summarised by its roles."""
    out = graph.copy()
    hidden: set[str] = set()
    summary: list[tuple[str, str, str]] = []  # (source, target, label) per pair of roles
    hosts = role_hosts(graph)
    transitions = [(u, v, d) for u, v, d in edges_of(graph, "transition") if d["protocol"]]
    for host in hosts:
        states = [c for c in children(graph, host) if graph.nodes[c].get("role")]
        role = {c: graph.nodes[c]["role"] for c in states}
        copies = role_copies(role.items())  # node ids share the host's prefix, as paths do
        primary = {role[c]: c for c in states if c not in copies}
        hide = set(copies)
        reached: dict[str, list[str]] = {}  # hidden state -> triggers from its primary
        protocol_edges = [(u, v, d) for u, v, d in transitions if u in role and v in role]
        for u, v, d in protocol_edges:
            if u == primary[role[u]] and v in hide and role[v] == role[u]:
                reached.setdefault(v, []).append(_trigger(d))
        pairs: dict[tuple[str, str], list[tuple[str, str]]] = {}
        for u, v, d in protocol_edges:
            if role[u] == role[v]:
                continue
            how = (
                [("", _trigger(d))]
                if u not in hide
                else [(first, _trigger(d)) for first in reached.get(u, ["?"])]
            )
            have = pairs.setdefault((role[u], role[v]), [])
            have += [h for h in how if h not in have]
        summary += [(primary[a], primary[b], _label(how)) for (a, b), how in pairs.items()]
        hidden |= hide | {m for h in hide for m in walk(graph, h)}
    for agent in agents(graph):
        modes = list(walk(graph, agent))
        if modes and all(graph.nodes[m].get("protocol") for m in modes):
            hidden |= {agent, *modes}
    links = _protocol_links(graph, set(hosts), hidden)
    out.remove_nodes_from(hidden)
    out.remove_edges_from(
        [
            (u, v, k)
            for u, v, k, d in graph.edges(keys=True, data=True)
            if d["kind"] in ("transition", "message")
            and d.get("protocol")
            and u not in hidden
            and v not in hidden
        ]
    )
    for k, (u, v, label) in enumerate(summary):
        out.add_edge(
            u,
            v,
            order=graph.number_of_edges() + k,
            kind="transition",
            agent=graph.nodes[u]["agent"],
            trigger="",
            after="",
            guard="",
            actions=[],
            priority=0,
            label=label,
            index=-1,
            protocol="summary",
        )
    for k, (u, v, label) in enumerate(links):
        out.add_edge(
            u,
            v,
            order=2 * graph.number_of_edges() + k,
            kind="message",
            message=label,
            socket="control",
            label=label,
            protocol=label,
        )
    _renumber(out)
    return out


def _protocol_links(
    graph: nx.MultiDiGraph, hosts: set[str], hidden: set[str]
) -> list[tuple[str, str, str]]:
    """One (host, host, protocol) link per pair of visible robots exchanging its messages."""
    seen: dict[frozenset, tuple[str, str, str]] = {}
    for u, v, d in edges_of(graph, "message"):
        if not d.get("protocol"):
            continue
        a, b = _host(graph, u, hosts), _host(graph, v, hosts)
        if a is None or b is None or a in hidden or b in hidden:
            continue
        key = frozenset((graph.nodes[a]["agent"], graph.nodes[b]["agent"]))
        if len(key) == 2 and key not in seen:
            seen[key] = (a, b, f"{d['protocol']} ⇄")
    return list(seen.values())


def _host(graph: nx.MultiDiGraph, node: str | None, hosts: set[str]) -> str | None:
    while node is not None and node not in hosts:
        node = parent(graph, node)
    return node


def _renumber(graph: nx.MultiDiGraph) -> None:
    """Keep ``order`` a dense 0..n-1 sequence in the order edges were meant to be read."""
    edges = sorted(graph.edges(keys=True, data=True), key=lambda e: e[3]["order"])
    for k, (_u, _v, _key, d) in enumerate(edges):
        d["order"] = k
