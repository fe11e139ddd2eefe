"""The core commands: ``validate``, ``run`` and ``schema``.

Outputs of ``run`` are written only after the run completes, each file atomically,
``summary.json`` last.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from hybridteam.cli.common import (
    EXIT_OK,
    EXIT_USAGE,
    UsageError,
    load_team_or_report,
    print_errors,
)


def register(sub) -> dict:
    """Add the core subcommands; returns their handlers by name."""
    v = sub.add_parser("validate", help="check files without running anything")
    v.add_argument("files", nargs="+", metavar="FILE")
    v.add_argument("--strict", action="store_true", help="treat warnings as errors")

    r = sub.add_parser("run", help="simulate a team and write its trace")
    r.add_argument("team", metavar="TEAM.yaml")
    r.add_argument("-o", "--output", required=True, metavar="OUT", help="output folder")
    r.add_argument("--seed", type=int, default=None, help="random seed (default: the file's)")
    r.add_argument("--duration", type=float, default=None, help="simulated seconds")
    r.add_argument("-n", type=int, default=None, help="ensemble size (default 1)")
    r.add_argument("--set", action="append", default=[], metavar="KEY=V[,V...]",
                   help="override a parameter (agent.param or team param); a list gives "
                        "one value per instance")
    r.add_argument("--quiet", action="store_true", help="no progress bar or summary")
    r.add_argument("--no-views", action="store_true",
                   help="skip the state diagram, timeline, trajectory and sequence views")

    s = sub.add_parser("schema", help="print the JSON Schema of a file kind")
    s.add_argument("kind", nargs="?", default=None, help="file kind (default: all)")
    return {"validate": cmd_validate, "run": cmd_run, "schema": cmd_schema}


def cmd_validate(args: argparse.Namespace) -> int:
    from hybridteam.io.filekind import InputErrors
    from hybridteam.kinds import load

    status = EXIT_OK
    for name in args.files:
        try:
            loaded = load(name)
        except InputErrors as exc:
            print_errors(exc)
            status = EXIT_USAGE
            continue
        for w in loaded.warnings:
            print(f"{w} (warning)", file=sys.stderr)
        if loaded.warnings and args.strict:
            status = EXIT_USAGE
        elif status == EXIT_OK:
            print(f"{name}: ok ({loaded.kind})")
    return status


def _overrides(items: list[str], n: int | None) -> tuple[dict[str, list[float]], int]:
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
                raise UsageError(f"--set {key}: {len(values)} values for an ensemble of "
                                 f"{size}")
            size = len(values)
        out[key.strip()] = values
    size = size or 1
    return {k: (v if len(v) > 1 else v * size) for k, v in out.items()}, size


def cmd_run(args: argparse.Namespace) -> int:
    from hybridteam.api import simulate
    from hybridteam.trace import write_atomic

    if args.n is not None and args.n < 1:
        raise UsageError(f"-n must be at least 1, got {args.n}")
    if args.duration is not None and not args.duration >= 0:
        raise UsageError(f"--duration must be >= 0, got {args.duration}")
    if args.seed is not None and args.seed < 0:
        raise UsageError(f"--seed must be >= 0, got {args.seed}")
    out = Path(args.output)
    if out.exists() and not out.is_dir():
        raise UsageError(f"output '{out}' exists and is not a folder")
    team = load_team_or_report(args.team)
    if team is None:
        return EXIT_USAGE
    overrides, n = _overrides(args.set, args.n)
    bar = None
    progress = None
    if not args.quiet and sys.stderr.isatty():
        from tqdm import tqdm

        bar = tqdm(total=100, unit="%", desc=team.name, leave=False,
                   bar_format="{desc}: {percentage:3.0f}%|{bar}| ETA {remaining}")

        def progress(frac: float) -> None:
            bar.n = round(100 * frac)
            bar.refresh()

    start = time.perf_counter()
    try:
        run = simulate(team, seed=args.seed, n=n, duration=args.duration,
                       overrides=overrides, progress=progress)
    except ValueError as exc:  # overrides naming no parameter, and the like
        raise UsageError(str(exc)) from None
    finally:
        if bar is not None:
            bar.close()
    wall = time.perf_counter() - start
    out.mkdir(parents=True, exist_ok=True)
    (out / "summary.json").unlink(missing_ok=True)
    run.to_json(out / "trace.json")
    run.write_csv(out)
    summary = run.summary()
    summary["wall_time_s"] = round(wall, 4)
    views: list[str] = []
    if not args.no_views:
        from hybridteam.export.runviews import write_run_views

        views = write_run_views(team, run, out)
    write_atomic(out / "summary.json", json.dumps(summary, indent=2) + "\n")
    if not args.quiet:
        _print_summary(summary, out, views)
    return EXIT_OK


_BASIC = frozenset({"instance", "outcome", "t_end", "message", "transitions", "messages"})


def _fmt(value) -> str:
    """A statistic for the terminal: numbers to 6 significant digits, lists joined by '/'."""
    if isinstance(value, list):
        return " / ".join(_fmt(v) for v in value)
    return f"{value:.6g}" if isinstance(value, float) else str(value)


def _print_summary(summary: dict, out: Path, views: list[str]) -> None:
    tally = ", ".join(f"{k}: {v}" for k, v in sorted(summary["outcomes"].items()))
    print(f"{summary['team']}: {summary['n']} instance(s), {summary['duration']:g} s simulated "
          f"in {summary['wall_time_s']:.3f} s wall — {tally}")
    for inst in summary["instances"][:10]:
        print(f"  [{inst['instance']}] {inst['outcome']} at t={inst['t_end']:.6g}: "
              f"{inst['transitions']} transitions, {inst['messages']} messages"
              + (f" — {inst['message']}" if inst["outcome"] != "ok" else ""))
        stats = {k: v for k, v in inst.items() if k not in _BASIC}
        if stats:
            print("      " + ", ".join(f"{k} {_fmt(v)}" for k, v in stats.items()))
    if summary["n"] > 10:
        print(f"  ... {summary['n'] - 10} more in summary.json")
    files = ["trace.json", "modes.csv", "transitions.csv", "messages.csv", "samples.csv",
             *views, "summary.json"]
    print(f"wrote {out}/ ({', '.join(files)})")


def cmd_schema(args: argparse.Namespace) -> int:
    from hybridteam.kinds import kinds

    known = kinds()
    if args.kind is not None and args.kind not in known:
        from hybridteam.errors import did_you_mean

        hint = did_you_mean(args.kind, known)
        raise UsageError(f"unknown file kind '{args.kind}' (kinds: {', '.join(known)})"
                         + (f"; {hint}" if hint else ""))
    names = [args.kind] if args.kind else list(known)
    schemas = {k: known[k].schema().model_json_schema(by_alias=True) for k in names}
    print(json.dumps(schemas[names[0]] if args.kind else schemas, indent=2))
    return EXIT_OK
