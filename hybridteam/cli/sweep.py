"""The study commands: ``sweep STUDY.yaml -o OUT`` and ``report OUT``.

Bad input (the study, its team, the arguments, an output folder holding another study) is
one located line per problem on stderr and exit status 2, before anything is written. An
interruption keeps the finished chunks and says how to resume.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from hybridteam.cli.common import (
    EXIT_INTERRUPTED,
    EXIT_OK,
    EXIT_USAGE,
    UsageError,
    add_workers,
    check_connect_timeout,
    check_workers,
    output_folder,
    print_errors,
)
from hybridteam.progress import MODES


def register(sub) -> dict:
    """Add the ``sweep`` and ``report`` subcommands; returns their handlers by name."""
    sw = sub.add_parser("sweep", help="run a parameter study (resumes an interrupted one)")
    sw.add_argument("study", metavar="STUDY.yaml")
    sw.add_argument("-o", "--output", required=True, metavar="OUT", help="output folder")
    add_workers(sw)
    sw.add_argument(
        "--chunk",
        type=int,
        default=None,
        metavar="K",
        help="runs per ensemble chunk (default: the one an interrupted study "
        "was run with, else the study's (500 unless it says), made smaller "
        "where that leaves some of --workers N without a chunk)",
    )
    sw.add_argument("--quiet", action="store_true", help="no progress or summary")
    sw.add_argument(
        "--progress",
        choices=MODES,
        default="auto",
        help="auto (a bar on a terminal, lines otherwise), bar, log or none",
    )

    rp = sub.add_parser(
        "report",
        help="a run folder's HTML page, or a study's plots and report.md",
        description="For a folder written by 'hybridteam run "
        "-o FOLDER': one self-contained HTML page (summary, state diagram, "
        "timeline, trajectories, animation, sequence chart). For a study's "
        "output folder: its plots and report.md.",
    )
    rp.add_argument("folder", metavar="FOLDER", help="a run folder or a study's output folder")
    rp.add_argument(
        "-o",
        "--output",
        default=None,
        metavar="FILE",
        help="run folders: the page (default FOLDER/report.html)",
    )
    rp.add_argument(
        "--instance", type=int, default=0, help="run folders: which instance (default 0)"
    )
    rp.add_argument(
        "--no-animation",
        action="store_true",
        help="run folders: leave the animation out (drawn unless FOLDER has run.gif)",
    )
    return {"sweep": cmd_sweep, "report": cmd_report}


def cmd_sweep(args: argparse.Namespace) -> int:
    from hybridteam.io.filekind import InputErrors
    from hybridteam.sweep.run import run_study
    from hybridteam.sweep.store import StudyError
    from hybridteam.sweep.study import load_study

    check_workers(args.workers)
    if args.chunk is not None and args.chunk < 1:
        raise UsageError(f"--chunk must be at least 1, got {args.chunk}")
    check_connect_timeout(args.connect_timeout)
    out = output_folder(args.output)
    try:
        study = load_study(args.study)
    except InputErrors as exc:
        print_errors(exc)
        return EXIT_USAGE
    show = "none" if args.quiet else args.progress
    try:
        result = run_study(
            study,
            out,
            workers=args.workers,
            scheduler=args.scheduler,
            chunk=args.chunk,
            progress=show,
            connect_timeout=args.connect_timeout,
        )
    except StudyError as exc:
        raise UsageError(str(exc)) from None
    except KeyboardInterrupt:
        print(
            f"hybridteam: interrupted; the finished chunks are kept in {out}/chunks — "
            "run the same command to resume",
            file=sys.stderr,
        )
        return EXIT_INTERRUPTED
    # result.warnings were logged as they arose, printed by main's library_logging
    if not args.quiet:
        plan = result.plan
        tally: dict[str, int] = {}
        assert result.table is not None
        for row in result.table.rows:
            for name in result.table.columns[
                result.table.columns.index("runs") + 1 : result.table.columns.index("success_rate")
            ]:
                tally[name] = tally.get(name, 0) + row[name]
        reused = f", {len(result.reused)} found done" if result.reused else ""
        print(
            f"{study.name}: {plan.runs} runs in {len(plan.chunks)} chunks "
            f"({len(result.computed)} computed{reused}"
            + (f", {result.executor}" if result.computed else "")
            + f") in {result.wall_s:.2f} s — "
            + ", ".join(f"{k}: {v}" for k, v in tally.items())
        )
        print(
            f"wrote {out}/ (results.csv, results.md, runs.csv, study.json, chunks/); "
            f"'hybridteam report {out}' draws the plots"
        )
    return EXIT_OK


def cmd_report(args: argparse.Namespace) -> int:
    from hybridteam.sweep.report import write_report
    from hybridteam.sweep.store import StudyError

    if (Path(args.folder) / "trace.json").is_file():  # a run's folder
        from hybridteam.cli.views import cmd_run_report

        return cmd_run_report(args)
    try:
        path = write_report(args.folder)
    except StudyError as exc:
        raise UsageError(str(exc)) from None
    print(f"wrote {path} (plots in {Path(args.folder) / 'plots'})")
    return EXIT_OK
