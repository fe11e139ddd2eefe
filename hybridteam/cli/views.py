"""The view commands: ``diagram``, ``timeline``, ``plot``, ``animate``, ``sequence``.

Kept apart from the core commands so that plain ``validate``/``run --no-views`` never
import matplotlib. Every bad argument or unreadable trace is a one-line error, exit 2.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from hybridteam.cli.common import (
    EXIT_OK,
    EXIT_USAGE,
    UsageError,
    load_team_or_report,
    read_json,
)
from hybridteam.cli.common import load_trace as _load_trace
from hybridteam.trace import write_atomic


def register(sub) -> dict:
    """Add the view subcommands; returns their handlers by name."""
    d = sub.add_parser("diagram", help="draw a model's state diagram")
    d.add_argument("model", metavar="MODEL.yaml")
    d.add_argument(
        "-f",
        "--format",
        default=None,
        help="dot, mermaid, plantuml, svg, png or pdf (default: from -o, else dot)",
    )
    d.add_argument(
        "-o",
        "--output",
        default=None,
        metavar="FILE",
        help="output file (default: text to standard output)",
    )
    d.add_argument(
        "--detail",
        choices=("roles", "full"),
        default="roles",
        help="roles: a protocol's states summarised by the roles they play (Lead, "
        "Follow), as a paper draws them; full: every protocol state, "
        "transition and message (default: roles)",
    )
    d.add_argument(
        "--agent",
        action="append",
        default=None,
        metavar="NAME",
        help="only this agent (repeat for more; default: the whole team)",
    )
    d.add_argument(
        "--details",
        action="store_true",
        help="inputs, laws and transition labels in full (default: cut to 44 characters)",
    )

    tl = _trace_parser(sub, "timeline", "draw the mode timeline of a run")
    tl.add_argument(
        "--window",
        nargs=2,
        type=float,
        metavar=("T0", "T1"),
        help="close-up between two times, with message arrows",
    )
    tl.add_argument(
        "-f",
        "--format",
        choices=("png", "svg", "pdf"),
        default=None,
        help="png, svg or pdf (default: from -o, else png)",
    )
    tl.add_argument(
        "-o",
        "--output",
        default=None,
        metavar="FILE",
        help=".png, .svg or .pdf (default timeline.<format>)",
    )
    tl.add_argument(
        "--data", default=None, metavar="FILE", help="also write the drawn data as .csv or .json"
    )
    tl.add_argument(
        "--agents",
        default=None,
        metavar="A,B",
        help="lanes of these agents only, in team order (default: all)",
    )
    top = tl.add_mutually_exclusive_group()
    top.add_argument(
        "--top",
        dest="top",
        action="store_true",
        default=None,
        help="a row of top-level modes above every agent with nested modes "
        "(default: only for agents with more than one top-level mode)",
    )
    top.add_argument(
        "--no-top", dest="top", action="store_false", help="no rows of top-level modes"
    )
    _against_parser(tl, "its mode bars under the log's, per agent, the first divergence marked")

    pl = _trace_parser(sub, "plot", "draw the trajectories of a run")
    pl.add_argument(
        "-f",
        "--format",
        choices=("png", "svg", "pdf"),
        default=None,
        help="png, svg or pdf (default: from -o, else png)",
    )
    pl.add_argument(
        "-o",
        "--output",
        default=None,
        metavar="FILE",
        help=".png, .svg or .pdf (default trajectories.<format>)",
    )
    pl.add_argument(
        "--xlim",
        nargs=2,
        type=float,
        metavar=("X0", "X1"),
        help="x range of the plane (default: the scene, walls and paths)",
    )
    pl.add_argument(
        "--ylim",
        nargs=2,
        type=float,
        metavar=("Y0", "Y1"),
        help="y range of the plane (default: the scene)",
    )
    pl.add_argument(
        "--size",
        nargs=2,
        type=float,
        metavar=("W", "H"),
        help="figure width and height in inches (default: 8 wide, as tall as the scene asks)",
    )
    _against_parser(
        pl,
        "its replay's paths dashed over the log's and the plant under the "
        "logged commands dotted, both largest deviations marked",
    )

    an = _trace_parser(sub, "animate", "animate a run (GIF; MP4 when ffmpeg is installed)")
    an.add_argument("--fps", type=int, default=20, help="frames per second (default 20)")
    an.add_argument(
        "--speed",
        type=float,
        default=None,
        metavar="X",
        help="simulated seconds per second of playback (default: a frame per "
        "sample, at most 300 frames)",
    )
    an.add_argument(
        "--size",
        nargs=2,
        type=float,
        metavar=("W", "H"),
        help="frame size in inches (default: 9 wide, as tall as the scene asks)",
    )
    an.add_argument(
        "--dpi", type=float, default=100.0, help="pixels per inch (default 100: 900 pixels wide)"
    )
    an.add_argument(
        "-o", "--output", default="run.gif", metavar="FILE", help=".gif or .mp4 (default run.gif)"
    )

    sq = _trace_parser(sub, "sequence", "message sequence chart of a run")
    sq.add_argument("-f", "--format", default="mermaid", choices=["mermaid", "plantuml"])
    sq.add_argument(
        "--all-sockets",
        action="store_true",
        help="include data messages, not only control messages",
    )
    sq.add_argument(
        "-o",
        "--output",
        default=None,
        metavar="FILE",
        help="output file (default: standard output)",
    )

    return {
        "diagram": cmd_diagram,
        "timeline": cmd_timeline,
        "plot": cmd_plot,
        "animate": cmd_animate,
        "sequence": cmd_sequence,
    }


def _trace_parser(sub, name: str, help: str):
    """A view of a run: its trace file and which instance of an ensemble."""
    p = sub.add_parser(name, help=help)
    p.add_argument("trace", metavar="trace.json")
    p.add_argument("--instance", type=int, default=0, help="ensemble instance (default 0)")
    return p


def _against_parser(p, what: str) -> None:
    """``--against TEAM.yaml`` (with ``--map`` and ``--tolerance`` as ``check`` takes
    them): the view of a recording with its model's replay drawn over it."""
    p.add_argument(
        "--against",
        default=None,
        metavar="TEAM.yaml",
        help=f"replay the recording into this team, as check --conformance does, "
        f"and draw the model's replay: {what} (the recording may then be a "
        "rosbag2: folder, .mcap or .db3)",
    )
    p.add_argument(
        "--map",
        default=None,
        metavar="MAPPING.yaml",
        help="with --against, for a rosbag2: which topic holds what (see import)",
    )
    p.add_argument(
        "--tolerance",
        type=float,
        default=None,
        metavar="SECONDS",
        help="with --against: how far a transition may be from the model's time (default 0.1)",
    )


def _replay(args: argparse.Namespace):
    """The conformance of the recording to ``--against``'s team; None when the team or
    mapping file was bad (its errors printed)."""
    from hybridteam.cli.logs import replayed

    return replayed(args.trace, args.against, args.map, args.tolerance, args.instance)


def _check_against(args: argparse.Namespace) -> None:
    """``--map`` and ``--tolerance`` only with ``--against``; a tolerance of seconds >= 0."""
    for name in ("map", "tolerance"):
        if getattr(args, name) is not None and args.against is None:
            raise UsageError(
                f"--{name} goes with --against TEAM.yaml (the model to draw over the recording)"
            )
    if args.tolerance is not None and not (math.isfinite(args.tolerance) and args.tolerance >= 0):
        raise UsageError(f"--tolerance {args.tolerance:g}: a number of seconds >= 0")


IMAGE = (".png", ".svg", ".pdf")
DIAGRAM_FORMATS = {
    ".dot": "dot",
    ".gv": "dot",
    ".mmd": "mermaid",
    ".mermaid": "mermaid",
    ".puml": "plantuml",
    ".plantuml": "plantuml",
    ".svg": "svg",
    ".png": "png",
    ".pdf": "pdf",
}


def _check_size(size: list[float] | None) -> None:
    """``--size W H`` of a figure view: inches, each between 1 and 50."""
    if size and not all(math.isfinite(v) and 1.0 <= v <= 50.0 for v in size):
        raise UsageError(
            f"--size {size[0]:g} {size[1]:g}: width and height must be between 1 and 50 inches"
        )


def _figure_output(path: str | None, fmt: str | None, stem: str) -> str:
    """The file a figure view writes: ``-o`` as given (its extension must be a figure's and
    agree with ``--format``), else ``<stem>.<format>`` (png by default)."""
    if path is None:
        return f"{stem}.{fmt or 'png'}"
    suffix = _suffix(path, IMAGE, f"{stem} figure")
    if fmt is not None and suffix != f".{fmt}":
        raise UsageError(
            f"-o {path} says {suffix[1:]} but --format says {fmt}; name the "
            f"file .{fmt} or drop --format"
        )
    return path


def _suffix(path: str, allowed: tuple[str, ...], what: str) -> str:
    suffix = Path(path).suffix.lower()
    if suffix not in allowed:
        raise UsageError(f"-o {path}: a {what} is written as {' or '.join(allowed)}")
    return suffix


def cmd_diagram(args: argparse.Namespace) -> int:
    from hybridteam.export.diagram import diagram_graph
    from hybridteam.export.render import RENDERERS, render

    fmt = args.format
    suffix = Path(args.output).suffix.lower() if args.output else ""
    if fmt is not None and DIAGRAM_FORMATS.get(suffix, fmt) != fmt:  # no Mermaid in a .png
        names = " or ".join(s for s, f in DIAGRAM_FORMATS.items() if f == fmt) or "for it"
        raise UsageError(
            f"-o {args.output} says {DIAGRAM_FORMATS[suffix]} but -f says {fmt}; "
            f"name the file {names}, or drop -f (the format is then taken from "
            "the file's name)"
        )
    if fmt is None and args.output:
        if suffix not in DIAGRAM_FORMATS:  # never DOT text in a file named otherwise
            raise UsageError(
                f"-o {args.output}: cannot tell the format from "
                f"'{suffix or '(no extension)'}'; name the file "
                f"{', '.join(sorted(set(DIAGRAM_FORMATS)))} or give -f"
            )
        fmt = DIAGRAM_FORMATS[suffix]
    fmt = fmt or "dot"
    if fmt not in RENDERERS:
        from hybridteam.errors import did_you_mean

        hint = did_you_mean(fmt, RENDERERS)
        raise UsageError(
            f"unknown diagram format '{fmt}' (formats: {', '.join(RENDERERS)})"
            + (f"; {hint}" if hint else "")
        )
    if fmt in ("svg", "png", "pdf") and not args.output:
        raise UsageError(f"a {fmt} diagram needs -o FILE")
    team = load_team_or_report(args.model)
    if team is None:
        return EXIT_USAGE
    try:
        graph = diagram_graph(team, args.agent, details=args.details)
    except ValueError as exc:
        raise UsageError(f"--agent: {exc}") from None
    if args.detail == "roles":
        from hybridteam.export.roles import roles_view

        graph = roles_view(graph)
    out = render(graph, fmt)
    if args.output:
        write_atomic(Path(args.output), out)
        print(f"wrote {args.output}")
    else:
        sys.stdout.write(out if isinstance(out, str) else out.decode())
    return EXIT_OK


def cmd_timeline(args: argparse.Namespace) -> int:
    from hybridteam.export.runviews import MAX_VIEW_AGENTS
    from hybridteam.export.timeline import select_agents, write_timeline

    args.output = _figure_output(args.output, args.format, "timeline")
    if args.data:
        _suffix(args.data, (".csv", ".json"), "timeline's data")
    if args.window and not all(math.isfinite(w) for w in args.window):
        raise UsageError(
            f"--window {args.window[0]:g} {args.window[1]:g}: times must be finite numbers"
        )
    if args.window and not args.window[0] < args.window[1]:
        raise UsageError(f"--window {args.window[0]:g} {args.window[1]:g}: T0 must be < T1")
    _check_against(args)
    if args.against is not None and args.data:
        raise UsageError("--data writes a run's own timeline; drop it with --against")
    result = None
    if args.against is not None:
        result = _replay(args)
        if result is None:
            return EXIT_USAGE
    trace = _load_trace(args.trace, args.instance) if result is None else result.log
    agents = [a.strip() for a in args.agents.split(",") if a.strip()] if args.agents else None
    if args.agents is not None and not agents:
        raise UsageError("--agents: name at least one agent")
    try:
        lanes = len(select_agents(trace, agents))
    except ValueError as exc:
        raise UsageError(f"--agents: {exc}") from None
    if lanes > MAX_VIEW_AGENTS:  # an image too tall to draw in reasonable time, or at all
        raise UsageError(
            f"{args.trace}: a timeline draws up to {MAX_VIEW_AGENTS} agents' "
            f"lanes, and {'--agents names' if agents else 'this trace has'} "
            f"{lanes:,}; choose some with --agents A,B"
        )
    window = tuple(args.window) if args.window else None
    if result is not None:
        result.write_timeline(args.output, window=window, agents=agents, top=args.top)
        print(f"wrote {args.output}")
        return EXIT_OK
    write_timeline(
        trace,
        args.output,
        instance=args.instance,
        window=window,
        data_path=args.data,
        agents=agents,
        top=args.top,
    )
    print(f"wrote {args.output}" + (f" and {args.data}" if args.data else ""))
    return EXIT_OK


def cmd_plot(args: argparse.Namespace) -> int:
    from hybridteam.export.trajectories import write_trajectories

    args.output = _figure_output(args.output, args.format, "trajectories")
    for name in ("xlim", "ylim"):
        lo_hi = getattr(args, name)
        if lo_hi and not (all(math.isfinite(v) for v in lo_hi) and lo_hi[0] < lo_hi[1]):
            raise UsageError(
                f"--{name} {lo_hi[0]:g} {lo_hi[1]:g}: need two finite numbers, the first smaller"
            )
    _check_size(args.size)
    _check_against(args)
    limits = {
        "xlim": tuple(args.xlim) if args.xlim else None,
        "ylim": tuple(args.ylim) if args.ylim else None,
        "size": tuple(args.size) if args.size else None,
    }
    if args.against is not None:
        result = _replay(args)
        if result is None:
            return EXIT_USAGE
        result.write_plot(args.output, **limits)
    else:
        trace = _load_trace(args.trace, args.instance)
        write_trajectories(trace, args.output, instance=args.instance, **limits)
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
    if args.speed is not None and not (math.isfinite(args.speed) and args.speed > 0):
        raise UsageError(f"--speed must be a positive number, got {args.speed:g}")
    _check_size(args.size)
    if not (math.isfinite(args.dpi) and 20 <= args.dpi <= 600):
        raise UsageError(f"--dpi must be between 20 and 600, got {args.dpi:g}")
    trace = _load_trace(args.trace, args.instance)
    write_animation(
        trace,
        args.output,
        instance=args.instance,
        fps=args.fps,
        speed=args.speed,
        size=tuple(args.size) if args.size else None,
        dpi=args.dpi,
    )
    print(f"wrote {args.output}")
    return EXIT_OK


def cmd_sequence(args: argparse.Namespace) -> int:
    from hybridteam.export.sequence import sequence_chart

    trace = _load_trace(args.trace, args.instance)
    sockets = None if args.all_sockets else ("control",)
    text = sequence_chart(trace, args.format, instance=args.instance, sockets=sockets)
    if args.output:
        write_atomic(Path(args.output), text)
        print(f"wrote {args.output}")
    else:
        sys.stdout.write(text)
    return EXIT_OK


def _load_summary(path: Path) -> dict:
    """A run folder's ``summary.json``, checked against its format; or a one-line error at
    the file, line and column of its first bad field (a file anyone can hand over)."""
    from hybridteam.summary_schema import check_summary

    text, summary = read_json(path, "files of a run folder", "a run summary")
    problem = check_summary(summary)
    if problem is None:
        return summary
    where, message = problem
    raise UsageError(f"{path}{_json_position(text, where)}: not a run summary: {message}")


def _json_position(text: str, where: tuple) -> str:
    """``:line:column`` of the value at ``where`` in a JSON document (JSON is YAML, whose
    reader keeps positions), or nothing when the text cannot be read that way."""
    from hybridteam.io.yamlpos import SourceError, load_yaml

    try:
        _, positions = load_yaml(text)
    except (SourceError, RecursionError):
        return ""
    mark = positions.value(where) or positions.nearest(where)[1]
    return f":{mark.line}:{mark.column}"


def cmd_run_report(args: argparse.Namespace) -> int:
    """``hybridteam report RUN_FOLDER``: the HTML page of a run, for a folder that holds a
    ``trace.json`` (others get the study's report, see :mod:`~hybridteam.cli.sweep`)."""
    from hybridteam.export.report import NotAnImage, write_report

    folder = Path(args.folder)
    if args.output is not None:
        _suffix(args.output, (".html", ".htm"), "report")
    if not (folder / "summary.json").is_file():
        raise UsageError(
            f"{folder}: no summary.json; is it a folder written by 'hybridteam run -o FOLDER'?"
        )
    trace = _load_trace(str(folder / "trace.json"), args.instance)
    summary = _load_summary(folder / "summary.json")
    try:
        out = write_report(
            folder,
            trace,
            summary,
            args.output,
            instance=args.instance,
            animation=not args.no_animation,
        )
    except NotAnImage as exc:
        raise UsageError(str(exc)) from None
    print(f"wrote {out}")
    return EXIT_OK
