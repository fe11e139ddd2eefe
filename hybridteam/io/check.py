"""Semantic checks that are not errors but usually are mistakes: warnings with locations.

Per agent, a directed graph over modes says what can become active: entering a mode enters
its initial child (or all regions of a parallel mode), an active mode keeps its ancestors
active, and a transition makes its target active. Modes not reachable from the root are
reported, and so are leaves that nothing can ever leave but are not marked ``final``.
Unknown names (modes, laws, variables) are errors and are caught by compiling the model.
"""

from __future__ import annotations

import networkx as nx

from hybridteam.engine.compile.compiled import CAgent, CTeam
from hybridteam.engine.compile.compiler import compile_team
from hybridteam.errors import ModelError
from hybridteam.io.protocols import InFile
from hybridteam.io.timing import timing_warnings
from hybridteam.model import Team


def mode_graph(ca: CAgent) -> nx.DiGraph:
    """What-can-become-active graph of one compiled agent (nodes are mode indices)."""
    g: nx.DiGraph[int] = nx.DiGraph()
    g.add_nodes_from(m.index for m in ca.modes)
    for m in ca.modes:
        if m.parent >= 0:
            g.add_edge(m.index, m.parent, kind="ancestor")
        if m.kind == "or":
            g.add_edge(m.index, m.initial, kind="initial")
            for entry in (m.default, m.history_default):  # a deeper initial or default
                if entry is not None:
                    g.add_edges_from(((m.index, k) for k in entry.marks), kind="initial")
            if m.history != "none":
                pass  # history only restores children that were reachable before
        elif m.kind == "and":
            for r in m.children:
                g.add_edge(m.index, r, kind="region")
    for tr in ca.transitions:
        g.add_edges_from(((tr.source, t) for t in tr.targets or [tr.target]), kind="transition")
    return g


def unreachable_modes(ca: CAgent) -> list[int]:
    g = mode_graph(ca)
    reach = nx.descendants(g, 0) | {0}
    return [m.index for m in ca.modes if m.index not in reach]


def dead_ends(ca: CAgent) -> list[int]:
    """Leaves with no outgoing transition on themselves or any ancestor, not final."""
    out = []
    for m in ca.modes:
        if m.kind != "leaf" or m.final:
            continue
        node, exits = m.index, False
        while node > 0:
            if ca.modes[node].outgoing:
                exits = True
                break
            node = ca.modes[node].parent
        if not exits:
            out.append(m.index)
    return out


def check_team(team: Team, cteam: CTeam | None = None) -> list[ModelError]:
    """Warnings for a team that compiles (``cteam``: its compiled form, when the caller
    has it already)."""
    cteam = cteam if cteam is not None else compile_team(team)
    warnings: list[ModelError] = []
    for agent, ca in zip(team.agents, cteam.agents, strict=True):
        # pre-order walks of the declaration and of the compiled tree visit modes alike
        where = [m.where for _, m in agent.root.walk()]
        for i in unreachable_modes(ca):
            warnings.append(
                ModelError(
                    where[i],
                    f"mode '{ca.modes[i].path}' is unreachable: "
                    "it is not an initial mode and no transition enters it",
                    at_key=True,
                )
            )
        if len(ca.modes) == 2:  # a single-mode agent: running forever is the point
            continue
        for i in dead_ends(ca):
            if where[i] and isinstance(where[i][0], InFile):
                continue  # a protocol's deliberate sink (Operated: the operator decides)
            warnings.append(
                ModelError(
                    where[i],
                    f"mode '{ca.modes[i].path}' has no way out and is not marked 'final: true'",
                    at_key=True,
                )
            )
    warnings += timing_warnings(team, cteam)
    return list({(w.path, str(w)): w for w in warnings}.values())  # once per place
