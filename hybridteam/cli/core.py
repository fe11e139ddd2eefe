"""The core commands: ``validate``, ``run`` and ``schema``.

Outputs of ``run`` are written only after the run completes, each file atomically,
``summary.json`` last.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

from hybridteam.cli.common import (
    EXIT_OK,
    EXIT_USAGE,
    UsageError,
    load_team_or_report,
    output_folder,
    print_errors,
    say,
    write_run_folder,
)
from hybridteam.errors import ModelError, printable
from hybridteam.progress import MODES, reporter


def register(sub) -> dict:
    """Add the core subcommands; returns their handlers by name."""
    v = sub.add_parser(
        "validate",
        help="check files without running a simulation (Python "
        "modules beside a team file are imported: they are part of it)",
    )
    v.add_argument("files", nargs="+", metavar="FILE")
    v.add_argument("--strict", action="store_true", help="treat warnings as errors")

    r = sub.add_parser("run", help="simulate a team and write its trace")
    r.add_argument("team", metavar="TEAM.yaml")
    r.add_argument("-o", "--output", required=True, metavar="OUT", help="output folder")
    r.add_argument("--seed", type=int, default=None, help="random seed (default: the file's)")
    r.add_argument("--duration", type=float, default=None, help="simulated seconds")
    r.add_argument("-n", type=int, default=None, help="ensemble size (default 1)")
    r.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=V[,V...]",
        help="override a parameter (agent.param or team param) or a network "
        "setting (network.latency, network.jitter, network.loss, "
        "network.links.A->B.loss); a list gives one value per instance",
    )
    r.add_argument("--quiet", action="store_true", help="no progress or summary")
    r.add_argument(
        "--progress",
        choices=MODES,
        default="auto",
        help="auto (a bar on a terminal, lines otherwise), bar, log or none",
    )
    r.add_argument(
        "--no-views",
        action="store_true",
        help="skip the state diagram, timeline, trajectory and sequence views",
    )
    r.add_argument(
        "--report",
        action="store_true",
        help="also write report.html: every view and the summary on one "
        "self-contained page (see 'hybridteam report')",
    )
    r.add_argument(
        "--no-animation",
        action="store_true",
        help="with --report: leave the animation out (most of the report's time)",
    )
    r.add_argument(
        "--max-memory",
        type=float,
        default=None,
        metavar="GB",
        help="refuse runs needing more memory (default 4 GB)",
    )
    r.add_argument(
        "--max-periods",
        type=float,
        default=None,
        metavar="N",
        help="refuse runs of more control periods per instance (default 1e8)",
    )
    r.add_argument(
        "--max-wall",
        type=float,
        default=None,
        metavar="HOURS",
        help="stop a run whose pace projects more wall time (default 24)",
    )

    lw = sub.add_parser("laws", help="list the registered laws: parameters and what they do")
    lw.add_argument(
        "prefix",
        nargs="?",
        default=None,
        help="only laws whose name starts with this (e.g. transport)",
    )

    s = sub.add_parser("schema", help="print the JSON Schema of a file kind")
    s.add_argument("kind", nargs="?", default=None, help="file kind (default: all)")
    return {"validate": cmd_validate, "run": cmd_run, "schema": cmd_schema, "laws": cmd_laws}


def cmd_validate(args: argparse.Namespace) -> int:
    from hybridteam.io.filekind import InputErrors
    from hybridteam.kinds import load_any

    status = EXIT_OK
    for name in args.files:
        try:
            loaded = load_any(name)
        except InputErrors as exc:
            print_errors(exc)
            status = EXIT_USAGE
            continue
        for w in loaded.warnings:
            say(f"{w} (warning)")
        if loaded.warnings and args.strict:
            status = EXIT_USAGE
        else:  # every file gets its verdict, also after a failing one
            print(printable(f"{name}: ok ({loaded.kind})"))  # a name a glob may have found
    return status


def _overrides(items: list[str], n: int | None) -> tuple[dict[str, list[float] | float], int]:
    out: dict[str, list[float]] = {}
    size = n
    for item in items:
        key, sep, text = item.partition("=")
        if not sep or not key.strip():
            raise UsageError(f"--set {item!r}: expected KEY=VALUE or KEY=V1,V2,...")
        try:
            values = [float(v) for v in text.split(",")]
        except ValueError:
            raise UsageError(f"--set {item!r}: values must be numbers") from None
        if len(values) > 1:
            if size is not None and size != len(values):
                raise UsageError(f"--set {key}: {len(values)} values for an ensemble of {size}")
            size = len(values)
        out[key.strip()] = values
    # one value stays one number (the engine broadcasts it): no list of -n copies
    return {k: (v if len(v) > 1 else v[0]) for k, v in out.items()}, size or 1


def cmd_run(args: argparse.Namespace) -> int:
    from hybridteam.api import simulate

    if args.n is not None and args.n < 1:
        raise UsageError(f"-n must be at least 1, got {args.n}")
    if args.duration is not None and not 0 <= args.duration < math.inf:
        raise UsageError(f"--duration must be a finite number >= 0, got {args.duration}")
    for flag, value in (
        ("--max-memory", args.max_memory),
        ("--max-periods", args.max_periods),
        ("--max-wall", args.max_wall),
    ):
        if value is not None and not 0 < value < math.inf:
            raise UsageError(f"{flag} must be a finite number > 0, got {value}")
    if args.seed is not None and args.seed < 0:
        raise UsageError(f"--seed must be >= 0, got {args.seed}")
    if args.no_animation and not args.report:
        raise UsageError(
            "--no-animation leaves the animation out of the report: give it with --report"
        )
    out = output_folder(args.output)
    if (out / "study.json").exists():
        raise UsageError(
            f"output '{out}' holds a study's results; give the run a folder of its own"
        )
    team = load_team_or_report(args.team, warnings=not args.quiet)
    if team is None:
        return EXIT_USAGE
    overrides, n = _overrides(args.set, args.n)
    shown = reporter("none" if args.quiet else args.progress, 100, team.name, "%")

    def progress(frac: float) -> None:
        assert shown is not None
        shown.update(round(100 * frac) - shown.n)

    start = time.perf_counter()
    try:
        run = simulate(
            team,
            seed=args.seed,
            n=n,
            duration=args.duration,
            overrides=overrides,
            progress=None if shown is None else progress,
            max_memory=None if args.max_memory is None else args.max_memory * 1e9,
            max_periods=args.max_periods,
            max_wall=None if args.max_wall is None else args.max_wall * 3600,
            written=True,
        )
    except ModelError as exc:  # a value out of range in some instance: at its line
        from hybridteam.io.loader import locate_in_file

        say(locate_in_file(exc, args.team))
        return EXIT_USAGE
    except ValueError as exc:  # overrides naming no parameter, and the like
        raise UsageError(str(exc)) from None
    except MemoryError:  # within --max-memory by the estimate, beyond what the machine has
        raise UsageError(
            "the run ran out of memory (the machine has less than the memory "
            "limit the estimate was checked against): lower --max-memory GB, "
            "shorten the run or the ensemble"
        ) from None
    finally:
        if shown is not None:
            shown.close()
    summary = run.summary()
    summary["wall_time_s"] = round(time.perf_counter() - start, 4)
    views = write_run_folder(out, team, run, summary, views=not args.no_views)
    if args.report:
        from hybridteam.export.report import write_report
        from hybridteam.export.runviews import MAX_VIEW_AGENTS

        if len(team.agents) > MAX_VIEW_AGENTS:  # the report draws the run's views too
            say(
                f"hybridteam: note: no report.html: the team has {len(team.agents):,} agents "
                f"and a report draws its views for up to {MAX_VIEW_AGENTS}"
            )
        else:
            write_report(out, run, summary, animation=not args.no_animation)
            views.append("report.html")
    if not args.quiet:
        _print_summary(summary, out, views)
    return EXIT_OK


_BASIC = frozenset(
    {"instance", "outcome", "t_end", "message", "transitions", "messages", "requirements"}
)


def _fmt(value) -> str:
    """A statistic for the terminal: numbers to 6 significant digits, lists joined by '/'
    ('none' for an empty one)."""
    if isinstance(value, list):  # an empty one (no collisions) says so
        return " / ".join(_fmt(v) for v in value) if value else "none"
    return f"{value:.6g}" if isinstance(value, float) else str(value)


def _print_summary(summary: dict, out: Path, views: list[str]) -> None:
    tally = ", ".join(f"{k}: {v}" for k, v in sorted(summary["outcomes"].items()))
    ended = max(inst["t_end"] for inst in summary["instances"])
    simulated = (
        f"{summary['duration']:g} s simulated"
        if ended >= summary["duration"]
        else f"{ended:g} of {summary['duration']:g} s simulated"
    )
    print(
        f"{summary['team']}: {summary['n']} instance(s), {simulated} in "
        f"{summary['wall_time_s']:.3f} s wall — {tally}"
    )
    for inst in summary["instances"][:10]:
        print(
            f"  [{inst['instance']}] {inst['outcome']} at t={inst['t_end']:.6g}: "
            f"{inst['transitions']} transitions, {inst['messages']} messages"
            + (f" — {inst['message']}" if inst["outcome"] != "ok" else "")
        )
        stats = {k: v for k, v in inst.items() if k not in _BASIC}
        if stats:
            print("      " + ", ".join(f"{k} {_fmt(v)}" for k, v in stats.items()))
    if summary["n"] > 10:
        print(f"  ... {summary['n'] - 10} more in summary.json")
    from hybridteam.requirements.report import verdict_lines

    for line in verdict_lines(summary["instances"]):
        print(line)
    files = [
        "trace.json",
        "modes.csv",
        "transitions.csv",
        "messages.csv",
        "samples.csv",
        *views,
        "summary.json",
    ]
    print(f"wrote {out}/ ({', '.join(files)})")


def cmd_schema(args: argparse.Namespace) -> int:
    from hybridteam.kinds import kinds

    known = kinds()
    if args.kind is not None and args.kind not in known:
        from hybridteam.errors import did_you_mean

        hint = did_you_mean(args.kind, known)
        raise UsageError(
            f"unknown file kind '{args.kind}' (kinds: {', '.join(known)})"
            + (f"; {hint}" if hint else "")
        )
    names = [args.kind] if args.kind else list(known)
    schemas = {k: known[k].schema().model_json_schema(by_alias=True) for k in names}
    print(json.dumps(schemas[names[0]] if args.kind else schemas, indent=2))
    return EXIT_OK


def cmd_laws(args: argparse.Namespace) -> int:
    """Every registered law (installed libraries included): plants, parameters with their
    defaults, the names it reads from the agent, and its docstring's first paragraph."""
    import textwrap

    from hybridteam.discovery import broken_note
    from hybridteam.laws import asked_names, registered, resolve

    names = [n for n in registered() if args.prefix is None or n.startswith(args.prefix)]
    if not names:
        from hybridteam.errors import did_you_mean

        hint = did_you_mean(args.prefix, registered())
        raise UsageError(f"no law starts with '{args.prefix}'" + (f"; {hint}" if hint else ""))
    for name in names:
        spec = resolve(name)
        plants = "/".join(spec.plants) if spec.plants else "any plant"
        print(f"{name}  ({plants})")
        if spec.summary:
            print(textwrap.fill(spec.summary, 92, initial_indent="    ", subsequent_indent="    "))
        if spec.params:
            print("    with: " + ", ".join(f"{k}={v:g}" for k, v in spec.params.items()))
        reads = sorted(asked_names(spec.fn) - set(spec.params))
        if reads:
            print("    reads from the agent: " + ", ".join(reads))
    if (note := broken_note()) is not None:
        say(f"hybridteam: warning: {note}")
    return EXIT_OK
