"""What every command shares: exit codes, usage errors, the parser class, error printing.

Bad input of any kind — YAML, schema, model, arguments — prints located messages to stderr
and exits with status 2, never a traceback, and writes nothing. Every message and warning
goes to the terminal through :func:`say` (libraries' warnings through :func:`show_warning`),
which shows control characters as escapes: a message quotes names from files anyone can
hand over, and a name must not recolour, retitle or rewrite the terminal.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import sys
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn, TextIO

from hybridteam.errors import printable

if TYPE_CHECKING:
    from hybridteam.trace import Trace

EXIT_OK, EXIT_USAGE, EXIT_INTERRUPTED = 0, 2, 130


class UsageError(Exception):
    """A bad argument: printed as one line, exit status 2."""


def say(message: object) -> None:
    """Print an error, a warning or a note to stderr, its control characters escaped."""
    print(printable(str(message)), file=sys.stderr)


def show_warning(
    message: Warning | str,
    category: type[Warning],
    filename: str,
    lineno: int,
    file: TextIO | None = None,
    line: str | None = None,
) -> None:
    """:func:`warnings.showwarning` for the command line: a library's warning (matplotlib's
    "Glyph 27 (\\x1b) missing from font", quoting a name) printed with :func:`say`'s
    escapes."""
    text = warnings.formatwarning(message, category, filename, lineno, line)
    (file or sys.stderr).write(printable(text))


class _Stderr(logging.Handler):
    """Records printed on the standard error of the moment (a test's capture included),
    their control characters escaped as :func:`say` escapes them. Without a formatter a
    record reads as the command line's own messages do: ``hybridteam: warning: ...``."""

    def emit(self, record: logging.LogRecord) -> None:
        try:
            text = (
                self.format(record)
                if self.formatter is not None
                else f"hybridteam: {record.levelname.lower()}: {record.getMessage()}"
            )
            print(printable(text), file=sys.stderr)
        except Exception:
            self.handleError(record)  # logging's rule: a handler never raises


@contextmanager
def library_logging(level: str | None) -> Iterator[None]:
    """The command line's one logging setup, for the duration of a command: what the
    library logs (the ``hybridteam`` loggers) is printed on stderr. A command with a
    ``--log-level`` (a live process) prints every record from that level with its time and
    module; every other command prints warnings and errors as its own messages
    (``hybridteam: warning: ...``). Undone when the command returns, so a program (or a
    test) calling :func:`hybridteam.cli.main` keeps its own logging."""
    logger = logging.getLogger("hybridteam")
    handler = _Stderr()
    if level is not None:
        handler.setFormatter(logging.Formatter("%(asctime)s %(name)s %(levelname)s: %(message)s"))
    old = logger.level
    logger.setLevel(logging.WARNING if level is None else level.upper())
    logger.addHandler(handler)
    try:
        yield
    finally:
        logger.removeHandler(handler)
        logger.setLevel(old)


class Parser(argparse.ArgumentParser):
    """argparse, with its error exit routed through our exit code."""

    def error(self, message: str) -> NoReturn:  # argparse would print usage + exit 2 too
        self.print_usage(sys.stderr)
        say(f"{self.prog}: error: {message}")
        raise SystemExit(EXIT_USAGE)


def add_workers(parser) -> None:
    """``--workers N`` or ``--scheduler ADDRESS`` (one of them), then ``--connect-timeout``:
    where a study's runs go (``sweep``, ``falsify``)."""
    where = parser.add_mutually_exclusive_group()
    where.add_argument(
        "--workers",
        type=int,
        default=None,
        metavar="N",
        help="local worker processes (default 1: this process)",
    )
    where.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="run on a Dask distributed cluster, e.g. tcp://host:8786 (needs hybridteam[dask])",
    )
    add_connect_timeout(parser)


def check_workers(workers: int | None) -> None:
    """UsageError unless ``--workers`` is absent or at least 1."""
    if workers is not None and workers < 1:
        raise UsageError(f"--workers must be at least 1, got {workers}")


def add_connect_timeout(parser) -> None:
    """``--connect-timeout S`` beside ``--scheduler`` (``sweep``, ``falsify``)."""
    from hybridteam.sweep.cluster import DEFAULT_CONNECT_TIMEOUT

    parser.add_argument(
        "--connect-timeout",
        type=float,
        default=DEFAULT_CONNECT_TIMEOUT,
        metavar="S",
        help="seconds to reach the --scheduler and hear it "
        f"answer as a Dask scheduler (default {DEFAULT_CONNECT_TIMEOUT:g})",
    )


def check_connect_timeout(seconds: float) -> None:
    """UsageError unless ``--connect-timeout`` is a finite number of seconds > 0."""
    if not 0 < seconds < float("inf"):
        raise UsageError(f"--connect-timeout must be a finite number > 0, got {seconds}")


def output_folder(name: str) -> Path:
    """``-o``'s folder: new, or an existing folder (a file there is a usage error)."""
    out = Path(name)
    if out.exists() and not out.is_dir():
        raise UsageError(f"output '{out}' exists and is not a folder")
    return out


def print_errors(exc) -> None:
    """Each located error of an :class:`~hybridteam.io.filekind.InputErrors`, one a line."""
    for err in exc.errors:
        say(err)


def load_team_or_report(path: str, warnings: bool = False):
    """The team in ``path``, or None after printing its located errors to stderr; with
    ``warnings``, its warnings are printed too (``run`` warns as ``validate`` does)."""
    from hybridteam.io.loader import InputErrors, load_team_file

    try:
        loaded = load_team_file(path)
    except InputErrors as exc:
        print_errors(exc)
        return None
    for w in loaded.warnings if warnings else ():
        say(f"{w} (warning)")
    return loaded.model


INCOMPLETE = "INCOMPLETE"


def write_run_folder(out: Path, team, run, summary: dict, views: bool) -> list[str]:
    """Write a run's folder; ``summary.json`` last. Until it is written the folder holds an
    ``INCOMPLETE`` file saying so, which stays if writing fails or is interrupted, or if a
    view cannot be drawn (``summary.json`` is then written too, with ``views_error``): a
    folder is complete (``summary.json``, no ``INCOMPLETE``) or says it is not."""
    from hybridteam.trace import write_atomic

    marker = out / INCOMPLETE
    try:
        out.mkdir(parents=True, exist_ok=True)
        (out / "summary.json").unlink(missing_ok=True)
        write_atomic(
            marker,
            "hybridteam run was writing this folder and did not finish: "
            "its files may be partial or stale (summary.json is written last)\n",
        )
        run.to_json(out / "trace.json")
        run.write_csv(out)
        written: list[str] = []
        failed = None
        skipped = None
        if views:
            from hybridteam.export.runviews import views_skipped, write_run_views

            skipped = views_skipped(team)
            if skipped is not None:
                summary["views_skipped"] = skipped
            else:
                try:
                    written = write_run_views(team, run, out)
                except OSError:
                    raise
                except Exception as exc:  # a view that cannot be drawn: the data stands
                    failed = f"{type(exc).__name__}: {exc}"
                    summary["views_error"] = failed
        write_atomic(out / "summary.json", json.dumps(summary, indent=2) + "\n")
        if failed is None:
            marker.unlink()
        else:  # the data stands, the views do not: the folder still says it is incomplete
            write_atomic(
                marker,
                f"drawing the views failed ({failed}): the trace, the tables "
                "and summary.json are complete, the views are not\n",
            )
        if skipped is not None:
            print(f"hybridteam: note: {skipped}", file=sys.stderr)
        if failed is not None:
            raise UsageError(
                f"drawing the views failed ({failed}); {out}/ has the trace, "
                f"the tables and summary.json, not the views ({INCOMPLETE} says "
                "so; --no-views skips the views)"
            )
        return written
    except OSError as exc:
        target = getattr(exc, "filename2", None) or exc.filename  # a rename's target
        where = f" {target}" if target else ""
        raise UsageError(
            f"cannot write{where}: {exc.strerror or exc}"
            + ("" if not marker.exists() else f"; {out}/ is incomplete ({INCOMPLETE} marks it)")
        ) from None
    except MemoryError:
        raise UsageError(
            f"ran out of memory writing {out}/: it is incomplete ({INCOMPLETE} "
            "marks it); raise simulation.sample_period or shorten the run"
        ) from None
    except KeyboardInterrupt:
        print(
            f"hybridteam: interrupted while writing {out}/: it is incomplete (no "
            f"summary.json; {INCOMPLETE} marks it)",
            file=sys.stderr,
        )
        raise SystemExit(EXIT_INTERRUPTED) from None


def read_json(path: str | os.PathLike[str], files: str, kind: str) -> tuple[str, Any]:
    """The text and the data of a JSON file handed over (a trace, a run's summary), or one
    :class:`UsageError` naming it: only a regular file of a bounded size is read (not a
    FIFO, not ``/dev/zero``; ``HYBRIDTEAM_MAX_TRACE_MB``), as UTF-8, as JSON. ``files``
    names such files in the size message ("traces"), ``kind`` the document ("a run
    summary")."""
    from hybridteam.io.files import MAX_TRACE_MB, read_regular
    from hybridteam.io.yamlpos import SourceError

    try:
        text = read_regular(
            path, str(path), limit_mb=MAX_TRACE_MB, env="HYBRIDTEAM_MAX_TRACE_MB", what=files
        ).decode("utf-8")
        return text, json.loads(text)
    except SourceError as exc:
        raise UsageError(str(exc)) from None
    except UnicodeDecodeError as exc:
        raise UsageError(f"{path}: cannot read: {exc}") from None
    except json.JSONDecodeError as exc:
        raise UsageError(f"{path}:{exc.lineno}:{exc.colno}: not a JSON file: {exc.msg}") from None
    except RecursionError:
        raise UsageError(f"{path}: not {kind} (nested too deeply)") from None


def load_trace(path: str, instance: int = 0) -> Trace:
    """A trace file, checked against the trace format; or a one-line error naming it
    (:class:`UsageError`). The views and ``check`` read traces through this."""
    from hybridteam.trace import Trace
    from hybridteam.trace_schema import check_trace

    if os.path.isdir(path):
        raise UsageError(f"{path}: is a directory, not a trace file")
    if not os.path.lexists(path):
        raise UsageError(f"{path}: no such file")
    _text, data = read_json(path, "traces", "a hybridteam trace")
    problem = check_trace(data)
    if problem is not None:
        raise UsageError(f"{path}: not a valid hybridteam trace: {problem}")
    trace = Trace.from_dict(data)
    if not 0 <= instance < trace.n:
        raise UsageError(f"--instance {instance}: the trace has instances 0..{trace.n - 1}")
    return trace
