"""``hybridteam live``: agents of a team as one process over real datagrams, on the wall
clock (docs/live.md).

The process writes its folder's ``trace.json`` and ``summary.json`` (last) when its run
ends: by the end rule, at ``--duration``, or on SIGINT/SIGTERM, which stop the run at its
next wait (the trace is complete up to there). Logs go through :mod:`logging` to stderr.
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import signal
import sys

from hybridteam.cli.common import (
    EXIT_OK,
    EXIT_USAGE,
    UsageError,
    load_team_or_report,
    output_folder,
    say,
)


def register(sub) -> dict:
    """Add the ``live`` subcommand; returns its handler by name."""
    p = sub.add_parser("live", help="run agents of a team live: real UDP datagrams, the "
                       "wall clock, simulated plants (docs/live.md)")
    p.add_argument("team", metavar="TEAM.yaml")
    p.add_argument("--agent", action="append", required=True, metavar="NAME",
                   help="an agent this process runs (repeat for several)")
    p.add_argument("-o", "--output", required=True, metavar="OUT", help="output folder")
    p.add_argument("--transport", choices=("udp",), default="udp",
                   help="how datagrams travel (udp: one port per process)")
    p.add_argument("--listen", default="127.0.0.1:47000", metavar="HOST:PORT",
                   help="this process's UDP address (default 127.0.0.1:47000)")
    p.add_argument("--peer", action="append", default=[], metavar="HOST:PORT",
                   help="another process's UDP address (repeat for several)")
    p.add_argument("--broadcast", action="store_true",
                   help="allow a LAN broadcast address among the peers")
    p.add_argument("--duration", type=float, default=None,
                   help="run seconds (default: the team's simulation.duration)")
    p.add_argument("--time-scale", type=float, default=1.0, metavar="K",
                   help="run time passes K times faster than the wall clock (simulated "
                        "plants only; default 1)")
    p.add_argument("--log-level", choices=("debug", "info", "warning", "error"),
                   default="info", help="what is logged to stderr (default info)")
    return {"live": cmd_live}


def address(text: str, flag: str) -> tuple[str, int]:
    """``HOST:PORT`` as a socket address, or UsageError naming the flag."""
    host, sep, port = text.rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 <= int(port) <= 65535:
        raise UsageError(f"{flag} must be HOST:PORT with a port from 0 to 65535, got "
                         f"'{text}'")
    return host, int(port)


def cmd_live(args: argparse.Namespace) -> int:
    from hybridteam.live.hosting import HostingError
    from hybridteam.live.run import run_live
    from hybridteam.live.transport import TransportError, UdpTransport
    from hybridteam.trace import write_atomic

    if args.duration is not None and not 0 <= args.duration < math.inf:
        raise UsageError(f"--duration must be a finite number >= 0, got {args.duration}")
    if not 0 < args.time_scale < math.inf:
        raise UsageError(f"--time-scale must be a finite number > 0, got {args.time_scale}")
    listen = address(args.listen, "--listen")
    peers = [address(p, "--peer") for p in args.peer]
    out = output_folder(args.output)
    logging.basicConfig(level=args.log_level.upper(), stream=sys.stderr,
                        format="%(asctime)s %(name)s %(levelname)s: %(message)s")
    team = load_team_or_report(args.team)
    if team is None:
        return EXIT_USAGE
    agents = list(dict.fromkeys(args.agent))
    stopped: list[str] = []

    def on_signal(signum: int, _frame) -> None:
        stopped.append(signal.Signals(signum).name)

    try:
        transport = UdpTransport(listen, peers, broadcast=args.broadcast)
    except TransportError as exc:
        raise UsageError(str(exc)) from None
    previous = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        trace = run_live(team, agents, transport, transport_name=args.transport,
                         time_scale=args.time_scale, duration=args.duration,
                         stop=lambda: stopped[0] if stopped else None)
    except HostingError as exc:
        raise UsageError(str(exc)) from None
    finally:
        transport.close()
        for s, handler in previous.items():
            signal.signal(s, handler)
    outcome = trace.outcomes[0]
    summary = {"team": team.name, "agents": agents, "outcome": outcome["outcome"],
               "t_end": outcome["t"], "message": outcome["message"],
               "transitions": len(trace.transitions), "messages": len(trace.messages),
               "live": trace.meta["live"]}
    try:
        out.mkdir(parents=True, exist_ok=True)
        (out / "summary.json").unlink(missing_ok=True)
        trace.to_json(out / "trace.json")
        write_atomic(out / "summary.json", json.dumps(summary, indent=2) + "\n")
    except OSError as exc:
        raise UsageError(f"cannot write {exc.filename or out}: {exc.strerror or exc}") \
            from None
    say(f"{team.name}: {', '.join(agents)} {outcome['outcome']} at t={outcome['t']:.6g}: "
        f"{outcome['message']}; wrote {out}/ (trace.json, summary.json)")
    return EXIT_OK
