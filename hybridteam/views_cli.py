"""Command-line front ends of the views: ``diagram``, ``timeline``, ``plot``, ``animate``,
``sequence``, and the views ``run`` writes next to its trace.

Kept apart from :mod:`hybridteam.cli` so that plain ``validate``/``run --no-views`` never
import matplotlib. Every bad argument or unreadable trace is a one-line error, exit 2.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from hybridteam.cli import EXIT_OK, EXIT_USAGE, UsageError, load_team_or_report
from hybridteam.trace import Trace, write_atomic

IMAGE = (".png", ".svg")
DIAGRAM_FORMATS = {".dot": "dot", ".gv": "dot", ".mmd": "mermaid", ".mermaid": "mermaid",
                   ".puml": "plantuml", ".plantuml": "plantuml", ".svg": "svg", ".png": "png"}


def _load_trace(path: str, instance: int) -> Trace:
    """A trace file, or a one-line error naming it."""
    try:
        trace = Trace.load(path)
    except FileNotFoundError:
        raise UsageError(f"{path}: no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise UsageError(f"{path}: cannot read: {exc}") from None
    except json.JSONDecodeError as exc:
        raise UsageError(f"{path}:{exc.lineno}:{exc.colno}: not a JSON file: {exc.msg}") from None
    except (ValueError, KeyError, TypeError) as exc:
        raise UsageError(f"{path}: not a hybridteam trace ({exc})") from None
    if not 0 <= instance < trace.n:
        raise UsageError(f"--instance {instance}: the trace has instances 0..{trace.n - 1}")
    return trace


def _suffix(path: str, allowed: tuple[str, ...], what: str) -> str:
    suffix = Path(path).suffix.lower()
    if suffix not in allowed:
        raise UsageError(f"-o {path}: a {what} is written as {' or '.join(allowed)}")
    return suffix


def cmd_diagram(args: argparse.Namespace) -> int:
    from hybridteam.export.diagram import diagram_graph
    from hybridteam.export.render import RENDERERS, render

    fmt = args.format
    if fmt is None:
        fmt = DIAGRAM_FORMATS.get(Path(args.output).suffix.lower(), "dot") if args.output \
            else "dot"
    if fmt not in RENDERERS:
        from hybridteam.errors import did_you_mean

        hint = did_you_mean(fmt, RENDERERS)
        raise UsageError(f"unknown diagram format '{fmt}' (formats: {', '.join(RENDERERS)})"
                         + (f"; {hint}" if hint else ""))
    if fmt in ("svg", "png") and not args.output:
        raise UsageError(f"a {fmt} diagram needs -o FILE")
    team = load_team_or_report(args.model)
    if team is None:
        return EXIT_USAGE
    graph = diagram_graph(team)
    if args.detail == "roles":
        from hybridteam.export.roles import roles_view

        graph = roles_view(graph)
    out = render(graph, fmt)
    if args.output:
        write_atomic(Path(args.output), out)
    else:
        sys.stdout.write(out if isinstance(out, str) else out.decode())
    return EXIT_OK


def cmd_timeline(args: argparse.Namespace) -> int:
    from hybridteam.export.timeline import select_agents, write_timeline

    _suffix(args.output, IMAGE, "timeline")
    if args.data:
        _suffix(args.data, (".csv", ".json"), "timeline's data")
    if args.window and not args.window[0] < args.window[1]:
        raise UsageError(f"--window {args.window[0]:g} {args.window[1]:g}: T0 must be < T1")
    trace = _load_trace(args.trace, args.instance)
    agents = [a.strip() for a in args.agents.split(",") if a.strip()] if args.agents else None
    if args.agents is not None and not agents:
        raise UsageError("--agents: name at least one agent")
    try:
        select_agents(trace, agents)
    except ValueError as exc:
        raise UsageError(f"--agents: {exc}") from None
    write_timeline(trace, args.output, instance=args.instance,
                   window=tuple(args.window) if args.window else None, data_path=args.data,
                   agents=agents)
    print(f"wrote {args.output}" + (f" and {args.data}" if args.data else ""))
    return EXIT_OK


def cmd_plot(args: argparse.Namespace) -> int:
    from hybridteam.export.trajectories import write_trajectories

    _suffix(args.output, IMAGE, "trajectory plot")
    trace = _load_trace(args.trace, args.instance)
    write_trajectories(trace, args.output, instance=args.instance)
    print(f"wrote {args.output}")
    return EXIT_OK


def cmd_animate(args: argparse.Namespace) -> int:
    import shutil

    from hybridteam.export.animate import write_animation

    suffix = _suffix(args.output, (".gif", ".mp4"), "animation")
    if suffix == ".mp4" and shutil.which("ffmpeg") is None:
        raise UsageError("ffmpeg is not installed; write a .gif instead")
    if args.fps < 1:
        raise UsageError(f"--fps must be at least 1, got {args.fps}")
    trace = _load_trace(args.trace, args.instance)
    write_animation(trace, args.output, instance=args.instance, fps=args.fps)
    print(f"wrote {args.output}")
    return EXIT_OK


def cmd_sequence(args: argparse.Namespace) -> int:
    from hybridteam.export.sequence import sequence_chart

    trace = _load_trace(args.trace, args.instance)
    sockets = None if args.all_sockets else ("control",)
    text = sequence_chart(trace, args.format, instance=args.instance, sockets=sockets)
    if args.output:
        write_atomic(Path(args.output), text)
    else:
        sys.stdout.write(text)
    return EXIT_OK


VIEW_COMMANDS = {"diagram": cmd_diagram, "timeline": cmd_timeline, "plot": cmd_plot,
                 "animate": cmd_animate, "sequence": cmd_sequence}


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
