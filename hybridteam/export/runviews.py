"""The views ``hybridteam run`` writes beside a trace: state diagrams, timeline,
trajectories and the sequence chart."""

from __future__ import annotations

from pathlib import Path

from hybridteam.trace import write_atomic

#: ``hybridteam run`` draws its views for teams of up to this many agents, and
#: ``hybridteam timeline`` as many lanes. A timeline draws a lane per agent (a thousand
#: lanes took 45 s of CPU for one image, and past some thousands the image is too tall to
#: allocate) and no reader follows a hundred.
MAX_VIEW_AGENTS = 100


def views_skipped(team) -> str | None:
    """Why ``hybridteam run`` draws no views of ``team`` (too many agents), or None."""
    n = len(team.agents)
    if n <= MAX_VIEW_AGENTS:
        return None
    return (
        f"no views drawn: the team has {n:,} agents and views are drawn for up to "
        f"{MAX_VIEW_AGENTS}; draw some of them with 'hybridteam timeline TRACE --agents "
        "A,B' or 'hybridteam diagram MODEL --agent A'"
    )


def write_run_views(team, run, out: Path) -> list[str]:
    """The views ``hybridteam run`` writes beside the trace (instance 0 of an ensemble)."""
    from hybridteam.export.diagram import diagram_graph
    from hybridteam.export.render import render
    from hybridteam.export.roles import role_hosts, roles_view
    from hybridteam.export.sequence import sequence_chart
    from hybridteam.export.timeline import write_timeline
    from hybridteam.export.trajectories import write_trajectories

    full = diagram_graph(team)
    graph = roles_view(full)
    written = []
    for name, fmt in (("modes.dot", "dot"), ("modes.mmd", "mermaid"), ("modes.svg", "svg")):
        write_atomic(out / name, render(graph, fmt))
        written.append(name)
    if role_hosts(full):  # the protocol's own states too, for whoever debugs a handshake
        write_atomic(out / "modes-full.svg", render(full, "svg"))
        written.append("modes-full.svg")
    trace = run.instance(0) if run.n > 1 else run
    for name in ("timeline.png", "timeline.svg"):
        write_timeline(trace, out / name)
        written.append(name)
    for name in ("trajectories.png", "trajectories.svg"):
        write_trajectories(trace, out / name)
        written.append(name)
    write_atomic(out / "sequence.mmd", sequence_chart(trace, "mermaid"))
    written.append("sequence.mmd")
    return written
