"""One diagram model of a team: a networkx graph every renderer reads.

Renderers (DOT, Mermaid, PlantUML, images) never look at the declarations or the compiled
team themselves; they walk this graph. That keeps the drawing rules (what is a mode, which
transition goes where, which messages link agents) in one place, so the views cannot
disagree. The graph is built from the *compiled* team, because only compilation resolves a
transition's target (a unique name or a dotted path) to an actual mode.

Node ids are ``agent`` for agents and ``agent/Dotted.Path`` for modes; edges carry a
``kind``: ``contains`` (hierarchy), ``transition`` or ``message``.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import networkx as nx

from hybridteam.engine.compile.compiled import CAgent
from hybridteam.engine.compile.compiler import compile_team
from hybridteam.export.style import team_mode_colors
from hybridteam.io.protocols import InFile
from hybridteam.model import Assign, Mode, Raise, Send, Team, Transition


def protocol_of(where: tuple) -> str:
    """Name of the protocol file a declaration comes from ("" for the team's own)."""
    return Path(where[0]).stem if where and isinstance(where[0], InFile) else ""


def mode_id(agent: str, path: str) -> str:
    """Node id of a mode; the agent's root mode is the agent node itself."""
    return f"{agent}/{path}" if path else agent


def number(value: float | str) -> str:
    """Compact text of a number (``10``, ``0.25``) or an expression as written."""
    if isinstance(value, bool):
        return str(value)
    if isinstance(value, int | float):
        return f"{float(value):g}"
    return str(value)


def dynamics_text(mode: Mode) -> str:
    """One short line saying what moves the plant in ``mode``: a flow, a law or inputs."""
    if mode.flow:
        return "flow: " + ", ".join(f"{k}' = {number(v)}" for k, v in mode.flow.items())
    if mode.law is not None:
        rate = f" @{1.0 / mode.law.period:g} Hz" if mode.law.period else ""
        return f"law: {mode.law.name}{rate}"
    if mode.inputs:
        rate = f" @{1.0 / mode.input_period:g} Hz" if mode.input_period else ""
        return "inputs: " + ", ".join(f"{k} = {number(v)}" for k, v in mode.inputs.items()) + rate
    return ""


def action_text(action: Assign | Send | Raise, compact: bool = False) -> str:
    """An action as a reader would write it; ``compact`` drops a send's receiver."""
    if isinstance(action, Assign):
        return action.text
    if isinstance(action, Raise):
        return f"raise {action.event}"
    text = f"send {action.message}"
    if action.to is not None and not compact:
        text += f" -> {action.to}"
    if action.socket != "control" and not compact:
        text += f" on {action.socket}"
    return text


def behaviour_lines(mode: Mode) -> list[str]:
    """A mode's entry and exit actions as UML writes them: ``entry / a; b``, ``exit / c``."""
    return [
        f"{word} / " + "; ".join(action_text(a, compact=True) for a in acts)
        for word, acts in (("entry", mode.on_entry), ("exit", mode.on_exit))
        if acts
    ]


def transition_label(tr: Transition) -> str:
    """UML-style ``trigger after(d) [guard] / actions``, as short as the transition allows."""
    parts = []
    if tr.on:
        parts.append(tr.on)
    if tr.after is not None:
        parts.append(f"after({number(tr.after)})")
    if tr.guard:
        parts.append(f"[{tr.guard}]")
    text = " ".join(parts)
    if tr.actions:
        acts = "; ".join(action_text(a, compact=True) for a in tr.actions)
        text = f"{text} / {acts}" if text else f"/ {acts}"
    return text


def _link(graph: nx.MultiDiGraph, u: str, v: str, **attrs) -> None:
    """Add an edge numbered in insertion order (networkx itself groups edges by source)."""
    graph.add_edge(u, v, order=graph.number_of_edges(), **attrs)


def _declared(root: Mode) -> list[Mode]:
    """The declared modes in the compiler's pre-order (index i is compiled mode i)."""
    return [m for _, m in root.walk()]


def _precedence(agent: CAgent) -> list[int]:
    """Compiled index of each declared transition, in declaration order (the compiler
    sorts them by precedence, whose targets it resolves)."""
    rank = [0] * len(agent.transitions)
    for ct in agent.transitions:
        rank[ct.declared] = ct.index
    return rank


def _add_modes(
    graph: nx.MultiDiGraph, agent: CAgent, declared: list[Mode], colors: dict[str, str]
) -> None:
    modes = agent.modes
    for cm in modes[1:]:
        parent = modes[cm.parent]
        node = mode_id(agent.name, cm.path)
        graph.add_node(
            node,
            kind="mode",
            agent=agent.name,
            path=cm.path,
            name=cm.name,
            depth=cm.depth,
            mode_kind=cm.kind,
            region=parent.kind == "and",
            initial=parent.initial == cm.index,
            final=cm.final,
            history=cm.history,
            dynamics=dynamics_text(declared[cm.index]),
            invariant=cm.invariant_text,
            color=colors[cm.path],
            role=cm.role or "",
            behaviour=behaviour_lines(declared[cm.index]),
            protocol=protocol_of(declared[cm.index].where),
        )
        _link(graph, mode_id(agent.name, parent.path), node, kind="contains")


def _add_transitions(graph: nx.MultiDiGraph, agent: CAgent, declared: list[Mode]) -> None:
    rank = _precedence(agent)
    k = 0
    for idx, mode in enumerate(declared):
        for tr in mode.transitions:
            ct = agent.transitions[rank[k]]
            if ct.source != idx:  # the compiler's ordering rule changed: fail loudly
                raise RuntimeError("declared and compiled transitions disagree")
            for target in ct.targets or [ct.target]:  # several: one arrow to each
                _link(
                    graph,
                    mode_id(agent.name, agent.modes[ct.source].path),
                    mode_id(agent.name, agent.modes[target].path),
                    kind="transition",
                    agent=agent.name,
                    trigger=tr.on or "",
                    after="" if tr.after is None else number(tr.after),
                    guard=tr.guard or "",
                    actions=[action_text(a) for a in tr.actions],
                    priority=tr.priority,
                    label=transition_label(tr),
                    index=k,
                    protocol=protocol_of(tr.where),
                )
            k += 1


def _add_messages(graph: nx.MultiDiGraph, team: Team, agents: list[CAgent]) -> None:
    """A dashed link from each sending mode to each mode whose transition the message fires."""
    receivers: dict[str, list[tuple[str, str]]] = {}
    for agent in agents:
        for ct in sorted(agent.transitions, key=lambda c: c.source):
            if ct.on is not None:
                node = mode_id(agent.name, agent.modes[ct.source].path)
                if (agent.name, node) not in receivers.setdefault(ct.on, []):
                    receivers[ct.on].append((agent.name, node))
    seen: set[tuple[str, str, str]] = set()
    for agent, spec in zip(agents, team.agents, strict=True):
        declared = _declared(spec.root)
        for idx, mode in enumerate(declared):
            for tr in mode.transitions:
                for act in tr.actions:
                    if not isinstance(act, Send):
                        continue
                    source = mode_id(agent.name, agent.modes[idx].path)
                    for other, node in receivers.get(act.message, []):
                        if other == agent.name or (act.to is not None and other != act.to):
                            continue
                        if (source, node, act.message) in seen:
                            continue
                        seen.add((source, node, act.message))
                        _link(
                            graph,
                            source,
                            node,
                            kind="message",
                            message=act.message,
                            socket=act.socket,
                            label=act.message,
                            protocol=protocol_of(tr.where),
                        )


#: Longest text a state box or an edge shows without ``details`` (characters); longer
#: inputs, laws and labels end in "…" — a diagram is for the structure, the file has the rest
ELIDE = 44


def elide(text: str, limit: int = ELIDE) -> str:
    """``text`` cut to ``limit`` characters, ending in "…" when cut."""
    return text if len(text) <= limit else text[: limit - 1].rstrip() + "…"


def diagram_graph(
    team: Team, agents: list[str] | None = None, details: bool = False
) -> nx.MultiDiGraph:
    """The team as one graph: agents, their mode trees, transitions and message links.

    ``agents``: only these agents (messages between them only); ``details``: every input
    expression and transition label in full (by default each is cut to ``ELIDE``
    characters). Raises :class:`~hybridteam.errors.ModelErrors` if the team does not
    compile: a diagram of a model whose transitions cannot be resolved would silently be
    wrong; ValueError names an unknown agent.
    """
    graph = _whole_graph(team)
    if agents is not None:
        names = [a.name for a in team.agents]
        for name in agents:
            if name not in names:
                raise ValueError(
                    f"no agent '{name}' in team '{team.name}' (agents: {', '.join(names)})"
                )
        graph.remove_nodes_from(
            [n for n, d in list(graph.nodes(data=True)) if (d.get("agent") or n) not in agents]
        )
    if not details:
        for _n, d in graph.nodes(data=True):
            if d.get("dynamics"):
                d["dynamics"] = elide(d["dynamics"])
            if d.get("behaviour"):
                d["behaviour"] = [elide(line) for line in d["behaviour"]]
        for _u, _v, d in graph.edges(data=True):
            if d.get("kind") == "transition":
                d["label"] = elide(d["label"])
    return graph


def _whole_graph(team: Team) -> nx.MultiDiGraph:
    cteam = compile_team(team)
    graph: nx.MultiDiGraph = nx.MultiDiGraph(name=team.name)
    colors = team_mode_colors(
        [(m.path, m.final, m.role) for m in a.modes[1:]] for a in cteam.agents
    )
    for agent, spec in zip(cteam.agents, team.agents, strict=True):
        root = agent.modes[0]
        graph.add_node(
            agent.name, kind="agent", label=agent.name, plant=agent.plant.kind, history=root.history
        )
        declared = _declared(spec.root)
        _add_modes(graph, agent, declared, colors)
        _add_transitions(graph, agent, declared)
    _add_messages(graph, team, cteam.agents)
    return graph


# ------------------------------------------------------------------ reading the graph
# Small queries shared by the renderers, so each walks the hierarchy the same way.


def agents(graph: nx.MultiDiGraph) -> list[str]:
    """Agent nodes in team order."""
    return [n for n, d in graph.nodes(data=True) if d["kind"] == "agent"]


def children(graph: nx.MultiDiGraph, node: str) -> list[str]:
    """Direct children of an agent or composite mode, in declaration order."""
    return [v for _, v, d in graph.out_edges(node, data=True) if d["kind"] == "contains"]


def parent(graph: nx.MultiDiGraph, node: str) -> str | None:
    """The containing mode or agent (None for an agent)."""
    for u, _, d in graph.in_edges(node, data=True):
        if d["kind"] == "contains":
            return u
    return None


def ancestors(graph: nx.MultiDiGraph, node: str) -> list[str]:
    """``node`` and its containers up to the agent, innermost first."""
    out = [node]
    while (up := parent(graph, out[-1])) is not None:
        out.append(up)
    return out


def initial_child(graph: nx.MultiDiGraph, node: str) -> str | None:
    """The child entered by default (None for a parallel mode or a leaf)."""
    if graph.nodes[node].get("mode_kind") == "and":
        return None
    return next((c for c in children(graph, node) if graph.nodes[c]["initial"]), None)


def is_composite(graph: nx.MultiDiGraph, node: str) -> bool:
    """Agents count as composites: their root mode is drawn as the outermost box."""
    return graph.nodes[node]["kind"] == "agent" or graph.nodes[node]["mode_kind"] != "leaf"


def edges_of(graph: nx.MultiDiGraph, kind: str) -> list[tuple[str, str, dict]]:
    """``(source, target, attrs)`` of every edge of one kind, in the order they were added.

    networkx lists a multigraph's edges grouped by source node; the ``order`` attribute
    restores declaration order, which is what keeps rendered text stable and diffable.
    """
    found = [(u, v, d) for u, v, d in graph.edges(data=True) if d["kind"] == kind]
    return sorted(found, key=lambda e: e[2]["order"])


def walk(graph: nx.MultiDiGraph, node: str) -> Iterator[str]:
    """Pre-order walk below ``node`` (excluded)."""
    for child in children(graph, node):
        yield child
        yield from walk(graph, child)
