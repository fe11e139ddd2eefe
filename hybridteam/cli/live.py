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
import os
import signal
import sys
from collections.abc import Callable

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
                       "wall clock, simulated plants or robots over ROS 2 (docs/live.md)")
    p.add_argument("team", metavar="TEAM.yaml")
    p.add_argument("--agent", action="append", default=[], metavar="NAME",
                   help="an agent this process runs (repeat for several)")
    p.add_argument("--world", action="store_true",
                   help="this process is the team's world process: it hosts no agent and "
                        "runs the world components on the poses the agents send")
    p.add_argument("-o", "--output", required=True, metavar="OUT", help="output folder")
    p.add_argument("--transport", choices=TRANSPORTS, default="udp",
                   help="how datagrams travel (udp: one port per process; ros2: ROS 2 "
                        "topics, with the [ros] extra)")
    p.add_argument("--plant", choices=PLANTS, default="sim",
                   help="what moves the hosted agents (sim: their plants integrated here; "
                        "ros2: their robots, through the team file's deploy: topics)")
    p.add_argument("--domain-id", type=int, default=None, metavar="N",
                   help="(ros2) the ROS domain (default: ROS_DOMAIN_ID, else 0)")
    p.add_argument("--ros-peers", type=int, default=0, metavar="N",
                   help="(ros2) before starting, wait until N other processes' transports "
                        "are matched (ROS discovery is asynchronous; 'launch' sets it)")
    p.add_argument("--listen", default="127.0.0.1:47000", metavar="HOST:PORT",
                   help="this process's UDP address (default 127.0.0.1:47000)")
    p.add_argument("--peer", action="append", default=[], metavar="HOST:PORT",
                   help="another process's UDP address (repeat for several)")
    p.add_argument("--duration", type=float, default=None,
                   help="run seconds (default: the team's simulation.duration)")
    p.add_argument("--time-scale", type=float, default=1.0, metavar="K",
                   help="run time passes K times faster than the wall clock (simulated "
                        "plants only; default 1)")
    p.add_argument("--log-level", choices=LEVELS, default="info",
                   help="what is logged to stderr (default info)")
    add_faults(p)
    p.add_argument("--ready", action="store_true",
                   help="(for 'launch') once the port is bound and the team compiled, print "
                        "'ready HOST:PORT' and start the run when stdin says 'go'")

    la = sub.add_parser("launch", help="run every agent of a team live on this machine, "
                        "one process each over loopback UDP, and merge their traces")
    la.add_argument("team", metavar="TEAM.yaml")
    la.add_argument("-o", "--output", required=True, metavar="OUT", help="output folder")
    la.add_argument("--transport", choices=TRANSPORTS, default="udp",
                    help="how datagrams travel (udp: one loopback port per process; ros2: "
                         "ROS 2 topics, with the [ros] extra)")
    la.add_argument("--domain-id", type=int, default=None, metavar="N",
                    help="(ros2) the ROS domain the processes share (default: one chosen "
                         "from this process's id, so launches do not hear each other)")
    la.add_argument("--duration", type=float, default=None,
                    help="run seconds (default: the team's simulation.duration)")
    la.add_argument("--time-scale", type=float, default=1.0, metavar="K",
                    help="run time passes K times faster than the wall clock (default 1)")
    la.add_argument("--log-level", choices=LEVELS, default="info",
                    help="what the processes log to OUT/agents/NAME/live.log (default info)")
    add_faults(la)
    return {"live": cmd_live, "launch": cmd_launch}


LEVELS = ("debug", "info", "warning", "error")
TRANSPORTS = ("udp", "ros2")
PLANTS = ("sim", "ros2")


def add_faults(parser) -> None:
    """``--drop``, ``--delay`` and ``--seed``: injected faults at the receiving socket."""
    parser.add_argument("--drop", type=float, default=0.0, metavar="P",
                        help="test aid: drop each arriving datagram with probability P")
    parser.add_argument("--delay", type=float, default=0.0, metavar="D",
                        help="test aid: hold each arriving datagram D run seconds more")
    parser.add_argument("--seed", type=int, default=0,
                        help="the --drop draws' seed (default 0)")
    parser.add_argument("--drop-copy", action="append", default=[], metavar="TYPE[:N]",
                        help="test aid: drop the N-th copy (default 1st) of message TYPE "
                             "that arrives for an agent here (repeat for several)")


def fault_args(args: argparse.Namespace, k: int) -> list[str]:
    """The fault options as ``live`` takes them, for ``launch``'s ``k``-th process (its
    seed: ``--seed`` + k, so the processes' draws differ)."""
    return ["--drop", repr(args.drop), "--delay", repr(args.delay), "--seed",
            str(args.seed + k), *(a for c in args.drop_copy for a in ("--drop-copy", c))]


def drop_copies(items: list[str]) -> dict[str, set[int]]:
    """``--drop-copy TYPE[:N]`` options as ``{type: {n, ...}}``, or UsageError."""
    out: dict[str, set[int]] = {}
    for item in items:
        name, sep, count = item.partition(":")
        if not name.isidentifier() or (sep and not (count.isdigit() and int(count) >= 1)):
            raise UsageError(f"--drop-copy must be TYPE or TYPE:N with N >= 1, got '{item}'")
        out.setdefault(name, set()).add(int(count) if sep else 1)
    return out


def address(text: str, flag: str) -> tuple[str, int]:
    """``HOST:PORT`` as a socket address, or UsageError naming the flag."""
    host, sep, port = text.rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 <= int(port) <= 65535:
        raise UsageError(f"{flag} must be HOST:PORT with a port from 0 to 65535, got "
                         f"'{text}'")
    return host, int(port)


def check_clock(args: argparse.Namespace) -> None:
    """UsageError for a ``--duration`` or ``--time-scale`` that is no clock setting."""
    if args.duration is not None and not 0 <= args.duration < math.inf:
        raise UsageError(f"--duration must be a finite number >= 0, got {args.duration}")
    if not 0 < args.time_scale < math.inf:
        raise UsageError(f"--time-scale must be a finite number > 0, got {args.time_scale}")
    if not 0 <= args.drop <= 1:
        raise UsageError(f"--drop must be a probability from 0 to 1, got {args.drop}")
    if not 0 <= args.delay < math.inf:
        raise UsageError(f"--delay must be a finite number >= 0, got {args.delay}")
    drop_copies(args.drop_copy)


def cmd_live(args: argparse.Namespace) -> int:
    from hybridteam.errors import ModelError
    from hybridteam.live.hosting import HostingError
    from hybridteam.live.run import LiveRun

    check_clock(args)
    if bool(args.agent) == args.world:
        raise UsageError("give the agents this process runs (--agent NAME) or --world, "
                         "not both")
    listen = address(args.listen, "--listen")
    peers = [address(p, "--peer") for p in args.peer]
    out = output_folder(args.output)
    logging.basicConfig(level=args.log_level.upper(), stream=sys.stderr,
                        format="%(asctime)s %(name)s %(levelname)s: %(message)s")
    team = load_team_or_report(args.team)
    if team is None:
        return EXIT_USAGE
    agents = list(dict.fromkeys(args.agent))
    if args.world and args.plant != "sim":
        raise UsageError("--world hosts no agent: --plant is for the agents' processes")
    stopped: list[str] = []

    def on_signal(signum: int, _frame) -> None:
        stopped.append(signal.Signals(signum).name)

    transport = open_transport(args, team.name, agents or ["world"], listen, peers)
    try:
        plants = open_plants(args, team, agents, on_silent=stopped.append)
    except BaseException:
        transport.close()
        raise
    previous = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        live = LiveRun(team, agents, transport, transport_name=args.transport,
                       time_scale=args.time_scale, duration=args.duration,
                       stop=lambda: stopped[0] if stopped else None, drop=args.drop,
                       delay=args.delay, seed=args.seed,
                       drop_copies=drop_copies(args.drop_copy), plants=plants,
                       plant_name=args.plant, world=args.world)
        if args.transport == "ros2":
            wait_for_peers(transport, args.ros_peers)
        if args.ready:
            print("ready " + ("ros2" if args.transport == "ros2" else
                              "{}:{}".format(*transport.address)), flush=True)
            if sys.stdin.readline().strip() != "go":
                raise UsageError("not started: stdin did not say 'go' (--ready)")
        trace = live.run()
    except HostingError as exc:
        raise UsageError(str(exc)) from None
    except ModelError as exc:  # a value out of range as the run goes: at its line
        from hybridteam.io.loader import locate_in_file

        say(locate_in_file(exc, args.team))
        return EXIT_USAGE
    finally:
        for plant in plants.values():  # (each robot is stopped: a zero Twist)
            plant.robot.close()
        transport.close()
        for s, handler in previous.items():
            signal.signal(s, handler)
    outcome = trace.outcomes[0]
    summary = {"team": team.name, "agents": agents, "outcome": outcome["outcome"],
               "t_end": outcome["t"], "message": outcome["message"],
               "transitions": len(trace.transitions), "messages": len(trace.messages),
               "live": trace.meta["live"]}
    write_folder(out, trace, summary)
    say(f"{team.name}: {', '.join(agents) or 'the world'} {outcome['outcome']} at "
        f"t={outcome['t']:.6g}: "
        f"{outcome['message']}; wrote {out}/ (trace.json, summary.json)")
    return EXIT_OK


def open_transport(args: argparse.Namespace, team: str, agents: list[str],
                   listen: tuple[str, int], peers: list[tuple[str, int]]):
    """The transport ``--transport`` names, or a one-line error: a taken port, a ROS 2
    transport without rclpy (the [ros] extra), a bad domain."""
    from hybridteam.live.transport import TransportError, UdpTransport

    if args.transport == "udp":
        try:
            return UdpTransport(listen, peers)
        except TransportError as exc:
            raise UsageError(str(exc)) from None
    try:
        from hybridteam.live.ros2 import Ros2Transport

        return Ros2Transport(team, "_".join(agents), ("data", "control"),
                             domain_id=args.domain_id)
    except (ImportError, ValueError) as exc:
        raise UsageError(f"--transport ros2: {exc}") from None


#: Wall seconds ``--plant ros2`` waits at least for a robot's first odometry (ROS
#: discovery: the robot's driver is found asynchronously, within a second or two).
FIRST_ODOMETRY = 10.0


def open_plants(args: argparse.Namespace, team, agents: list[str],
                on_silent: Callable[[str], None]) -> dict:
    """The hosted agents' external plants ``--plant`` names, by agent: none for ``sim``
    (the engine integrates them); for ``ros2`` each agent's robot through its ``deploy:``
    entry, once its first odometry has arrived (``on_silent``: told why when a robot's
    odometry falls silent later, to stop the run). A one-line UsageError for an agent with
    no entry or not a unicycle, a time scale (a robot keeps the wall clock's pace),
    rclpy missing, or a robot that says nothing at the start (within its timeout, and
    at least FIRST_ODOMETRY)."""
    if args.plant == "sim":
        return {}
    if args.time_scale != 1:
        raise UsageError(f"--plant ros2: a robot moves on the wall clock; --time-scale "
                         f"must be 1, got {args.time_scale:g}")
    from hybridteam.live.ros2_plant import PlantSilent, RobotPlant, Ros2Plant

    for name in agents:
        if name not in team.deploy:
            raise UsageError(f"--plant ros2: agent '{name}' has no entry in the team file's "
                             "deploy: section (its robot's cmd_vel and odom topics)")
        try:
            RobotPlant.check(name, team.agent(name).plant.kind)
        except ValueError as exc:
            raise UsageError(f"--plant ros2: {exc}") from None
    plants: dict = {}
    try:
        for name in agents:
            robot = Ros2Plant(name, team.deploy[name], domain_id=args.domain_id,
                              team=team.name)
            plants[name] = RobotPlant(robot, team.agent(name).plant.kind, on_silent)
            # the first odometry, before the clock starts (finding the robot's driver on
            # the domain can take longer than the silence its timeout allows later)
            robot.pose(max(robot.deploy.timeout, FIRST_ODOMETRY))
            plants[name].state(0.0)
    except BaseException as exc:
        for plant in plants.values():
            plant.robot.close()
        if isinstance(exc, ImportError | ValueError | PlantSilent):
            raise UsageError(f"--plant ros2: {exc}") from None
        raise
    return plants


def wait_for_peers(transport, count: int) -> None:
    """Block until the ROS 2 transport is matched with ``count`` others on both sockets:
    until a reader has matched a writer it drops that writer's datagrams, so agents that
    started talking before discovery ended would lose their first messages."""
    import time

    end = time.monotonic() + START_TIMEOUT
    while any(transport.peers(s) < count for s in ("data", "control")):
        if time.monotonic() > end:
            raise UsageError(f"--ros-peers {count}: only "
                             f"{min(transport.peers(s) for s in ('data', 'control'))} "
                             f"found within {START_TIMEOUT:g} s (same --domain-id?)")
        time.sleep(0.02)


#: The world process's folder under ``OUT/agents/`` (no agent can be named so: names
#: are identifiers).
WORLD_PROCESS = "@world"

#: Wall seconds a launched process may take to start (import, compile, bind) and to end
#: after its run's duration is up, however loaded the machine.
START_TIMEOUT, END_MARGIN = 60.0, 30.0


def cmd_launch(args: argparse.Namespace) -> int:
    """Every agent of the team as a ``hybridteam live`` process on loopback: ports chosen
    free, every process's clock started together (``--ready``), the end rule's processes
    awaited and the others (operators) then stopped, the traces merged."""
    import subprocess
    import time

    from hybridteam.engine.compile.compiler import compile_team
    from hybridteam.live.hosting import HostingError, hosted_team
    from hybridteam.live.merge import merge_traces
    from hybridteam.live.run import check_drop_copies
    from hybridteam.trace import Trace

    check_clock(args)
    out = output_folder(args.output)
    team = load_team_or_report(args.team)
    if team is None:
        return EXIT_USAGE
    full = compile_team(team)
    names = [ca.name for ca in full.agents]
    try:
        hosted_team(full, names)
        check_drop_copies(full, drop_copies(args.drop_copy))
    except HostingError as exc:
        raise UsageError(str(exc)) from None
    ending = [names[a] for a in full.ending]
    # the processes: one per agent, and the world process when the team has components
    hosts = [*names, *([WORLD_PROCESS] if team.world else [])]
    # (summary.json is written last: an older one must not make a failed launch's folder
    # look complete)
    (out / "summary.json").unlink(missing_ok=True)
    ports = free_ports(len(hosts)) if args.transport == "udp" else [0] * len(hosts)
    domain = args.domain_id if args.domain_id is not None else 1 + os.getpid() % 100
    stopped: list[str] = []

    def on_signal(signum: int, _frame) -> None:
        stopped.append(signal.Signals(signum).name)

    previous = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    procs: dict[str, subprocess.Popen] = {}
    try:
        for k, (name, port) in enumerate(zip(hosts, ports, strict=True)):
            folder = out / "agents" / name
            folder.mkdir(parents=True, exist_ok=True)
            command = [sys.executable, "-m", "hybridteam.cli", "live", args.team,
                       *(["--world"] if name == WORLD_PROCESS else ["--agent", name]),
                       "--time-scale", repr(args.time_scale), "--log-level",
                       args.log_level, "--ready", *fault_args(args, k), "-o", str(folder),
                       "--transport", args.transport]
            if args.transport == "udp":
                command += ["--listen", f"127.0.0.1:{port}"]
                command += [a for p in ports if p != port
                            for a in ("--peer", f"127.0.0.1:{p}")]
            else:  # every process in one domain, each waiting for all the others
                command += ["--domain-id", str(domain), "--ros-peers", str(len(hosts) - 1)]
            if args.duration is not None:
                command += ["--duration", repr(args.duration)]
            with open(folder / "live.log", "wb") as logfile:
                procs[name] = subprocess.Popen(command, stdin=subprocess.PIPE,
                                               stdout=subprocess.PIPE, stderr=logfile)
        for name, proc in procs.items():
            if not _ready(proc, START_TIMEOUT):
                raise UsageError(f"agent '{name}' did not start: "
                                 f"{_last_line(out / 'agents' / name / 'live.log')}")
        for proc in procs.values():  # every clock starts now
            assert proc.stdin is not None
            proc.stdin.write(b"go\n")
            proc.stdin.close()
        duration = full.team.simulation.duration if args.duration is None else args.duration
        deadline = time.monotonic() + duration / args.time_scale + END_MARGIN
        while any(p.poll() is None for p in procs.values()):
            rule_done = all(procs[n].poll() is not None for n in ending) if ending else False
            if stopped or rule_done or time.monotonic() > deadline:
                for p in procs.values():
                    if p.poll() is None:
                        p.terminate()  # (SIGTERM: the run stops, its trace is written)
                for p in procs.values():
                    p.wait(timeout=END_MARGIN)
                break
            time.sleep(0.05)
    finally:
        for proc in procs.values():
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        for s, handler in previous.items():
            signal.signal(s, handler)
    # a process that died (killed, crashed) left no trace: the team's trace is the others'
    # (what its teammates did about its silence), and says which are missing and why
    missing = {n: _exit_text(p.returncode, out / "agents" / n / "live.log")
               for n, p in procs.items()
               if p.returncode != 0 or not (out / "agents" / n / "trace.json").exists()}
    for name, why in missing.items():
        say(f"hybridteam: agent '{name}' left no trace: {why}")
    if all(n in missing for n in names):
        raise UsageError("no agent's process left a trace")
    traces = [Trace.load(out / "agents" / n / "trace.json") for n in hosts
              if n not in missing]
    merged = merge_traces(traces, ending)
    merged.meta["live"]["missing"] = missing
    merged.outcomes[0]["message"] += "".join(f"; {n}: no trace ({why})"
                                             for n, why in missing.items())
    outcome = merged.outcomes[0]
    summary = {"team": team.name, "outcome": outcome["outcome"], "t_end": outcome["t"],
               "message": outcome["message"], "transitions": len(merged.transitions),
               "messages": len(merged.messages), "live": merged.meta["live"]}
    write_folder(out, merged, summary)
    say(f"{team.name}: {outcome['outcome']} at t={outcome['t']:.6g}; wrote {out}/ "
        "(trace.json, summary.json, agents/NAME/)")
    return EXIT_OK


def write_folder(out, trace, summary: dict) -> None:
    """A live run's ``trace.json``, then its ``summary.json`` (last, and any older one
    removed first: a folder without it is not complete), or one line naming what could
    not be written. ``live`` and ``launch`` both end so."""
    from hybridteam.trace import write_atomic

    try:
        out.mkdir(parents=True, exist_ok=True)
        (out / "summary.json").unlink(missing_ok=True)
        trace.to_json(out / "trace.json")
        write_atomic(out / "summary.json", json.dumps(summary, indent=2) + "\n")
    except OSError as exc:
        raise UsageError(f"cannot write {exc.filename or out}: {exc.strerror or exc}") \
            from None


def free_ports(count: int) -> list[int]:
    """``count`` distinct free UDP ports on loopback (bound together, then released)."""
    import socket

    held = []
    try:
        for _ in range(count):
            s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            held.append(s)
            s.bind(("127.0.0.1", 0))
        return [s.getsockname()[1] for s in held]
    finally:
        for s in held:
            s.close()


def _ready(proc, timeout: float) -> bool:
    """Whether ``proc`` printed its ready line within ``timeout`` wall seconds."""
    import select
    import time

    end = time.monotonic() + timeout
    while time.monotonic() < end and proc.poll() is None:
        ready, _, _ = select.select([proc.stdout], [], [], 0.2)
        if ready:
            return proc.stdout.readline().startswith(b"ready ")
    return False


def _exit_text(code: int | None, log) -> str:
    """Why a launched process ended without its trace: its signal or status, last log line."""
    if code is not None and code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exit status {code}: {_last_line(log)}"


def _last_line(log) -> str:
    """The last line a launched process logged (its error), for one-line messages."""
    try:
        lines = log.read_text(errors="replace").strip().splitlines()
    except OSError:
        return "no log"
    return lines[-1] if lines else "nothing logged"
