"""Command line: ``hybridteam COMMAND ...``.

Each command group registers its own parsers and handlers — :mod:`.core` (validate, run,
schema), :mod:`.views` (diagram, timeline, plot, animate, sequence), :mod:`.sweep` (sweep,
report), :mod:`.falsify` (falsify), :mod:`.verify` (verify), :mod:`.convert`
(convert: SCXML in and out), :mod:`.live` (live, launch, merge), :mod:`.logs` (export, import,
check: rosbag2 logs) — and shares exit codes, errors and run folders through
:mod:`.common`. Groups never import each other.
"""

from __future__ import annotations

import sys
import warnings
from collections.abc import Sequence

from hybridteam.cli import convert, core, falsify, live, logs, sweep, verify, views
from hybridteam.cli.common import (
    EXIT_INTERRUPTED,
    EXIT_OK,
    EXIT_USAGE,
    Parser,
    UsageError,
    library_logging,
    say,
    show_warning,
)

__all__ = ["main"]


def _parser() -> tuple[Parser, dict]:
    p = Parser(prog="hybridteam", description="Teams of robots as hybrid systems.")
    sub = p.add_subparsers(dest="command", required=True, parser_class=Parser)
    commands: dict = {}
    for group in (core, views, sweep, falsify, verify, convert, live, logs):
        commands.update(group.register(sub))
    return p, commands


def main(argv: Sequence[str] | None = None) -> int:
    with warnings.catch_warnings():  # restores the caller's showwarning (tests call main)
        warnings.showwarning = show_warning
        return _main(argv)


def _main(argv: Sequence[str] | None) -> int:
    parser, commands = _parser()
    args = parser.parse_args(argv)
    try:
        # a live process logs at its --log-level (launch's is its processes', not its own)
        with library_logging(args.log_level if args.command == "live" else None):
            return commands[args.command](args)
    except UsageError as exc:
        say(f"hybridteam: error: {exc}")
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("hybridteam: interrupted; nothing written", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:  # output piped into `head`: not an error of ours
        sys.stderr.close()
        return EXIT_OK
    except OSError as exc:  # standard output full or closed, and the like: one line
        say(f"hybridteam: error: cannot write: {exc.strerror or exc}")
        return EXIT_USAGE
