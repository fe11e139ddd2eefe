"""What every command shares: exit codes, usage errors, the parser class, error printing.

Bad input of any kind — YAML, schema, model, arguments — prints located messages to stderr
and exits with status 2, never a traceback, and writes nothing.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

EXIT_OK, EXIT_USAGE, EXIT_INTERRUPTED = 0, 2, 130


class UsageError(Exception):
    """A bad argument: printed as one line, exit status 2."""


class Parser(argparse.ArgumentParser):
    """argparse, with its error exit routed through our exit code."""

    def error(self, message: str) -> None:  # argparse would print usage + exit 2 too
        self.print_usage(sys.stderr)
        print(f"{self.prog}: error: {message}", file=sys.stderr)
        raise SystemExit(EXIT_USAGE)


def output_folder(name: str) -> Path:
    """``-o``'s folder: new, or an existing folder (a file there is a usage error)."""
    out = Path(name)
    if out.exists() and not out.is_dir():
        raise UsageError(f"output '{out}' exists and is not a folder")
    return out


def print_errors(exc) -> None:
    """Each located error of an :class:`~hybridteam.io.filekind.InputErrors`, one a line."""
    for err in exc.errors:
        print(err, file=sys.stderr)


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
        print(f"{w} (warning)", file=sys.stderr)
    return loaded.model
