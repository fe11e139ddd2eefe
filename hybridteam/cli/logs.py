"""Robot logs: ``export`` (a run as a rosbag2), ``import`` (a rosbag2 as a trace) and
``check`` (a team's requirements on a log or a trace). See docs/logs.md.

They need ``rosbags`` (``pip install 'hybridteam[logs]'``); without it each says so in one
line, exit 2. A bad log, trace, team or mapping file is one located line, exit 2, and
nothing is written.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from hybridteam.cli.common import (
    EXIT_OK,
    EXIT_USAGE,
    UsageError,
    load_team_or_report,
    load_trace,
    print_errors,
    say,
)

#: ``check``'s exit status when a requirement is violated, or with ``--conformance`` the
#: run diverges from the model (0: all hold / conformant, 2: bad input)
EXIT_VIOLATED = 1


def register(sub) -> dict:
    """Add the log subcommands; returns their handlers by name."""
    e = sub.add_parser(
        "export",
        help="write a run as a rosbag2 (MCAP or SQLite) for "
        "Foxglove, PlotJuggler, RViz and ros2 bag",
    )
    e.add_argument("trace", metavar="TRACE", help="trace.json, or a run folder holding one")
    e.add_argument(
        "-o",
        "--output",
        required=True,
        metavar="OUT",
        help="run.mcap or run.db3 (one file), or a new folder (a rosbag2 folder)",
    )
    e.add_argument(
        "--format",
        choices=("mcap", "sqlite3"),
        default=None,
        help="storage (default: from OUT's extension; mcap for a folder)",
    )
    e.add_argument("--instance", type=int, default=0, help="ensemble instance (default 0)")

    i = sub.add_parser("import", help="read a rosbag2 recorded of a team as a trace")
    i.add_argument("log", metavar="LOG", help="a rosbag2 folder, or one .mcap or .db3 file")
    i.add_argument("--team", required=True, metavar="TEAM.yaml")
    i.add_argument("-o", "--output", required=True, metavar="trace.json")
    i.add_argument(
        "--map",
        default=None,
        metavar="MAPPING.yaml",
        help="which topic holds what, per agent (default: the names export "
        "writes, and a deployed robot's odom and cmd_vel from the team's "
        "deploy: section)",
    )

    c = sub.add_parser(
        "check",
        help="evaluate a team's requirements on a log or a trace "
        "(exit 0: all hold, 1: one is violated, 2: bad input)",
    )
    c.add_argument(
        "log", metavar="LOG_OR_TRACE", help="a rosbag2 (folder, .mcap, .db3) or a trace.json"
    )
    c.add_argument("--team", required=True, metavar="TEAM.yaml")
    c.add_argument(
        "--map",
        default=None,
        metavar="MAPPING.yaml",
        help="for a rosbag2: which topic holds what (see import)",
    )
    c.add_argument(
        "--conformance",
        action="store_true",
        help="instead of the requirements: replay what the log says arrived "
        "into the team and compare modes, transition times and poses (off "
        "the plant under the logged commands, and off the replay) (exit 0: "
        "conformant, 1: divergent)",
    )
    c.add_argument(
        "--tolerance",
        type=float,
        default=None,
        metavar="SECONDS",
        help="with --conformance: how far a transition may be from the model's time (default 0.1)",
    )
    return {"export": cmd_export, "import": cmd_import, "check": cmd_check}


def cmd_export(args: argparse.Namespace) -> int:
    from hybridteam.logs import LogError
    from hybridteam.logs.export import write_bag

    source = Path(args.trace)
    if source.is_dir() and (source / "trace.json").is_file():
        source = source / "trace.json"
    trace = load_trace(str(source), args.instance)
    try:
        out = write_bag(trace, args.output, args.format, args.instance)
    except LogError as exc:
        raise UsageError(str(exc)) from None
    except OSError as exc:
        raise UsageError(f"cannot write {args.output}: {exc.strerror or exc}") from None
    print(f"wrote {out}")
    return EXIT_OK


def _read_log(path: str, team, mapping: str | None):
    """The run a log records; None after printing a bad mapping file's located errors."""
    from hybridteam.io.filekind import InputErrors
    from hybridteam.logs import LogError
    from hybridteam.logs.bag import read_bag

    try:
        return read_bag(path, team, mapping)
    except InputErrors as exc:
        print_errors(exc)
        return None
    except LogError as exc:
        raise UsageError(str(exc)) from None


def read_recording(path: str, team, mapping: str | None, instance: int = 0):
    """The run a rosbag2 or a ``trace.json`` records of ``team`` (``check`` and the
    views' ``--against`` read it so); None after printing a bad mapping file's errors,
    a :class:`UsageError` for any other bad input."""
    if path.lower().endswith(".json") and not os.path.isdir(path):
        if mapping is not None:
            raise UsageError("--map names the topics of a rosbag2; a trace has no topics")
        run = load_trace(path, instance)
        if run.meta["team"] != team.name:
            raise UsageError(f"{path}: a run of team '{run.meta['team']}', not '{team.name}'")
        return run
    run = _read_log(path, team, mapping)
    if run is not None and not 0 <= instance < run.n:
        raise UsageError(f"--instance {instance}: the log has instances 0..{run.n - 1}")
    return run


def replayed(
    path: str, team_path: str, mapping: str | None, tolerance: float | None, instance: int = 0
):
    """The conformance of a recording to a team file (the views' ``--against``): None
    after printing a bad team or mapping file's errors."""
    team = load_team_or_report(team_path)
    if team is None:
        return None
    run = read_recording(path, team, mapping, instance)
    return None if run is None else conformance_of(path, run, team, tolerance, instance)


def conformance_of(path: str, run, team, tolerance: float | None, instance: int = 0):
    """The run replayed into its team and compared (``tolerance``: None for the default);
    a team a replay cannot run is a :class:`UsageError` naming ``path``."""
    from hybridteam.logs import LogError
    from hybridteam.logs.conformance import DEFAULT_TOLERANCE, conformance

    try:
        return conformance(
            run, team, instance, DEFAULT_TOLERANCE if tolerance is None else tolerance
        )
    except LogError as exc:
        raise UsageError(f"{path}: {exc}") from None


def cmd_import(args: argparse.Namespace) -> int:
    out = Path(args.output)
    if out.is_dir():
        raise UsageError(f"-o {out}: is a folder; name the trace file (trace.json)")
    team = load_team_or_report(args.team)
    if team is None:
        return EXIT_USAGE
    run = _read_log(args.log, team, args.map)
    if run is None:
        return EXIT_USAGE
    try:
        run.to_json(out)
    except OSError as exc:
        raise UsageError(f"cannot write {out}: {exc.strerror or exc}") from None
    print(
        f"wrote {out} ({len(run.sample_times)} sample times, {len(run.transitions)} "
        f"transitions, {len(run.messages)} messages)"
    )
    return EXIT_OK


def cmd_check(args: argparse.Namespace) -> int:
    from hybridteam.logs import LogError
    from hybridteam.logs.check import check_run
    from hybridteam.requirements.report import verdict_lines

    if args.tolerance is not None and not (args.conformance and args.tolerance >= 0):
        raise UsageError(
            f"--tolerance {args.tolerance}: a number of seconds >= 0, with --conformance"
        )
    team = load_team_or_report(args.team)
    if team is None:
        return EXIT_USAGE
    run = read_recording(args.log, team, args.map)
    if run is None:
        return EXIT_USAGE
    if args.conformance:
        return _conformance(args, run, team)
    try:
        verdicts = check_run(run, team)
    except LogError as exc:
        raise UsageError(f"{args.log}: {exc}") from None
    if not any(verdicts):
        say(f"hybridteam: note: team '{team.name}' has no requirements to check")
        return EXIT_OK
    for line in verdict_lines([{"requirements": v} for v in verdicts]):
        print(line)
    held = all(v["satisfied"] for per in verdicts for v in per.values())
    return EXIT_OK if held else EXIT_VIOLATED


def _conformance(args: argparse.Namespace, run, team) -> int:
    """``check --conformance``: the summary per agent and the first divergence."""
    result = conformance_of(args.log, run, team, args.tolerance)
    for line in result.lines():
        print(line)
    return EXIT_OK if result.conformant else EXIT_VIOLATED
