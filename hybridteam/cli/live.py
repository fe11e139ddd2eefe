"""``hybridteam live``: agents of a team as one process over real datagrams, on the wall
clock (docs/live.md); ``launch``: every process of a team on this machine; ``merge``: the
processes' traces as one team trace.

The process writes its folder's ``trace.json`` and ``summary.json`` (last) when its run
ends: by the end rule, at ``--duration``, or on SIGINT/SIGTERM, which stop the run at its
next wait (the trace is complete up to there). Logs go through :mod:`logging` to stderr.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import signal
import sys
import time
from collections.abc import Callable

from hybridteam.cli.common import (
    EXIT_OK,
    EXIT_USAGE,
    UsageError,
    load_team_or_report,
    output_folder,
    say,
)
from hybridteam.cli.udp import add_udp_options, check_udp_flags, udp_settings


def register(sub) -> dict:
    """Add the ``live`` subcommand; returns its handler by name."""
    p = sub.add_parser(
        "live",
        help="run agents of a team live: real UDP datagrams, the "
        "wall clock, simulated plants or robots over ROS 2 (docs/live.md)",
    )
    p.add_argument("team", metavar="TEAM.yaml")
    p.add_argument(
        "--agent",
        action="append",
        default=[],
        metavar="NAME",
        help="an agent this process runs (repeat for several)",
    )
    p.add_argument(
        "--world",
        action="store_true",
        help="this process is the team's world process: it hosts no agent and "
        "runs the world components on the poses the agents send",
    )
    p.add_argument("-o", "--output", required=True, metavar="OUT", help="output folder")
    p.add_argument(
        "--transport",
        choices=TRANSPORTS,
        default="udp",
        help="how datagrams travel (udp: one port per process; ros2: ROS 2 "
        "topics, with the [ros] extra)",
    )
    p.add_argument(
        "--plant",
        choices=PLANTS,
        default="sim",
        help="what moves the hosted agents (sim: their plants integrated here; "
        "ros2: their robots, through the team file's deploy: topics)",
    )
    p.add_argument(
        "--domain-id",
        type=int,
        default=None,
        metavar="N",
        help="(ros2) the ROS domain (default: ROS_DOMAIN_ID, else 0)",
    )
    p.add_argument(
        "--ros-peers",
        type=int,
        default=0,
        metavar="N",
        help="(ros2) before starting, wait until N other processes' transports "
        "are matched (ROS discovery is asynchronous; 'launch' sets it)",
    )
    add_udp_options(p)
    p.add_argument(
        "--duration",
        type=float,
        default=None,
        help="run seconds (default: the team's simulation.duration)",
    )
    p.add_argument(
        "--time-scale",
        type=float,
        default=1.0,
        metavar="K",
        help="run time passes K times faster than the wall clock (simulated "
        "plants only; default 1)",
    )
    p.add_argument(
        "--log-level",
        choices=LEVELS,
        default="info",
        help="what is logged to stderr (default info)",
    )
    p.add_argument(
        "--world-timeout",
        type=float,
        default=None,
        metavar="S",
        help="wall seconds of silence after which an agent's process stops (no "
        "reading from the world process for a pose) and the world process "
        "logs an agent's (no pose; it holds the last). Default 5",
    )
    add_faults(p)
    p.add_argument(
        "--wire-team",
        default=None,
        metavar="TEAM.yaml",
        help="test aid: speak this team file's wire identity while running "
        "TEAM.yaml, a drifted copy of it (same name, agents and messages): "
        "a robot whose code differs from the model",
    )
    p.add_argument(
        "--ready",
        action="store_true",
        help="(for 'launch') once the port is bound and the team compiled, print "
        "'ready HOST:PORT' and start the run when stdin says 'go' (or "
        "'go WALL': run time 0 at that time.time(), every process's)",
    )

    la = sub.add_parser(
        "launch",
        help="run every agent of a team live on this machine, "
        "one process each over loopback UDP, and merge their traces",
    )
    la.add_argument("team", metavar="TEAM.yaml")
    la.add_argument("-o", "--output", required=True, metavar="OUT", help="output folder")
    la.add_argument(
        "--transport",
        choices=TRANSPORTS,
        default="udp",
        help="how datagrams travel (udp: one loopback port per process; ros2: "
        "ROS 2 topics, with the [ros] extra)",
    )
    la.add_argument(
        "--domain-id",
        type=int,
        default=None,
        metavar="N",
        help="(ros2) the ROS domain the processes share (default: with "
        "--plant ros2 ROS_DOMAIN_ID, the robots'; else one chosen from "
        "this process's id, so launches do not hear each other)",
    )
    la.add_argument(
        "--duration",
        type=float,
        default=None,
        help="run seconds (default: the team's simulation.duration)",
    )
    la.add_argument(
        "--time-scale",
        type=float,
        default=1.0,
        metavar="K",
        help="run time passes K times faster than the wall clock (default 1)",
    )
    la.add_argument(
        "--plant",
        choices=PLANTS,
        default="sim",
        help="what moves the agents (sim: their plants integrated in their "
        "processes; ros2: the robots of the team file's deploy: section, "
        "at time scale 1; the other agents simulated)",
    )
    la.add_argument(
        "--log-level",
        choices=LEVELS,
        default="info",
        help="what the processes log to OUT/agents/NAME/live.log (default info)",
    )
    add_faults(la)
    la.add_argument(
        "--agent-team",
        action="append",
        default=[],
        metavar="NAME=FILE.yaml",
        help="test aid: agent NAME's process runs FILE.yaml (a drifted copy of "
        "the team) while speaking the team's wire (live --wire-team); "
        "repeat for several",
    )

    me = sub.add_parser(
        "merge",
        help="merge the traces of one live run's processes "
        "(their folders, or trace files) into the team's trace, as launch "
        "does",
    )
    me.add_argument(
        "traces",
        nargs="+",
        metavar="FOLDER_OR_TRACE",
        help="a process's output folder (its trace.json) or trace file",
    )
    me.add_argument("-o", "--output", required=True, metavar="OUT", help="output folder")
    me.add_argument(
        "--align",
        choices=("messages", "wall"),
        default="messages",
        help="how the processes' clocks are aligned (messages: each clock's "
        "offset estimated from the messages' send and receive times, "
        "assuming latencies alike both ways, for processes on several "
        "machines; wall: one machine's wall clock, as launch does). Default "
        "messages",
    )
    return {"live": cmd_live, "launch": cmd_launch, "merge": cmd_merge}


def agent_teams(items: list[str], names: list[str]) -> dict[str, str]:
    """``--agent-team NAME=FILE.yaml`` options as ``{agent: file}``, or UsageError."""
    out: dict[str, str] = {}
    for item in items:
        name, sep, path = item.partition("=")
        if not sep or not path:
            raise UsageError(f"--agent-team must be NAME=FILE.yaml, got '{item}'")
        if name not in names:
            raise UsageError(
                f"--agent-team {item}: no agent '{name}' in the team (agents: {', '.join(names)})"
            )
        if name in out:
            raise UsageError(f"--agent-team: agent '{name}' is given twice")
        out[name] = path
    return out


LEVELS = ("debug", "info", "warning", "error")
TRANSPORTS = ("udp", "ros2")
PLANTS = ("sim", "ros2")


def add_faults(parser) -> None:
    """``--drop``, ``--delay`` and ``--seed``: injected faults at the receiving socket."""
    parser.add_argument(
        "--drop",
        type=float,
        default=0.0,
        metavar="P",
        help="test aid: drop each arriving datagram with probability P",
    )
    parser.add_argument(
        "--delay",
        type=float,
        default=0.0,
        metavar="D",
        help="test aid: hold each arriving datagram D run seconds more",
    )
    parser.add_argument("--seed", type=int, default=0, help="the --drop draws' seed (default 0)")
    parser.add_argument(
        "--drop-copy",
        action="append",
        default=[],
        metavar="TYPE[:N]",
        help="test aid: drop the N-th copy (default 1st) of message TYPE "
        "that arrives for an agent here (repeat for several)",
    )
    parser.add_argument(
        "--losses-from",
        default=None,
        metavar="COUNTEREXAMPLE",
        help="test aid: lose live the copies a 'hybridteam verify' "
        "counterexample loses (its folder, VERIFY_OUT/PROPERTY), each "
        "dropped at its receiver's process as --drop-copy TYPE:N",
    )


def fault_args(args: argparse.Namespace, k: int) -> list[str]:
    """The fault options as ``live`` takes them, for ``launch``'s ``k``-th process (its
    seed: ``--seed`` + k, so the processes' draws differ; ``--losses-from`` becomes each
    process's own ``--drop-copy`` options)."""
    return [
        "--drop",
        repr(args.drop),
        "--delay",
        repr(args.delay),
        "--seed",
        str(args.seed + k),
        *(a for c in args.drop_copy for a in ("--drop-copy", c)),
    ]


def drop_copies(items: list[str]) -> dict[str, set[int]]:
    """``--drop-copy TYPE[:N]`` options as ``{type: {n, ...}}``, or UsageError."""
    out: dict[str, set[int]] = {}
    for item in items:
        name, sep, count = item.partition(":")
        if not name.isidentifier() or (sep and not (count.isdigit() and int(count) >= 1)):
            raise UsageError(f"--drop-copy must be TYPE or TYPE:N with N >= 1, got '{item}'")
        out.setdefault(name, set()).add(int(count) if sep else 1)
    return out


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
    """:func:`live_process`, the caller's SIGINT and SIGTERM handlers restored once it has
    ended: only after its folder is written, so that a SIGTERM after its run ends (launch
    stopping the processes still running once the end rule's have ended, as this one
    closes its transport and writes) stops nothing but is noted."""
    previous = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        return live_process(args)
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)


def live_process(args: argparse.Namespace) -> int:
    """``hybridteam live``: its handlers of SIGINT and SIGTERM stop the run at its next
    wait (:func:`cmd_live` restores the caller's)."""
    from hybridteam.errors import ModelError
    from hybridteam.live.hosting import HostingError
    from hybridteam.live.run import LiveRun

    check_clock(args)
    if bool(args.agent) == args.world:
        raise UsageError("give the agents this process runs (--agent NAME) or --world, not both")
    check_udp_flags(args)
    if args.world_timeout is not None and not 0 < args.world_timeout < math.inf:
        raise UsageError(f"--world-timeout must be a finite number > 0, got {args.world_timeout}")
    out = output_folder(args.output)
    team = load_team_or_report(args.team)
    if team is None:
        return EXIT_USAGE
    wire_team = None
    if args.wire_team is not None:
        wire_team = load_team_or_report(args.wire_team)
        if wire_team is None:
            return EXIT_USAGE
    agents = list(dict.fromkeys(args.agent))
    if args.world and args.plant != "sim":
        raise UsageError("--world hosts no agent: --plant is for the agents' processes")
    copies = drop_copies(args.drop_copy)
    if args.losses_from:  # (this process's share of the counterexample's losses)
        from hybridteam.engine.compile.compiler import compile_team

        for kind, ns in losses_from(args.losses_from, compile_team(team), [agents])[0].items():
            copies.setdefault(kind, set()).update(ns)
    stopped: list[str] = []

    def on_signal(signum: int, _frame) -> None:
        stopped.append(signal.Signals(signum).name)

    transport = open_transport(args, team, agents)
    try:
        plants = open_plants(args, team, agents, on_silent=stopped.append)
    except BaseException:
        transport.close()
        raise
    for s in (signal.SIGINT, signal.SIGTERM):
        signal.signal(s, on_signal)
    try:
        live = LiveRun(
            team,
            agents,
            transport,
            transport_name=args.transport,
            time_scale=args.time_scale,
            duration=args.duration,
            stop=lambda: stopped[0] if stopped else None,
            drop=args.drop,
            delay=args.delay,
            seed=args.seed,
            drop_copies=copies,
            plants=plants,
            plant_name=args.plant,
            world=args.world,
            wire_team=wire_team,
            **({"world_timeout": args.world_timeout} if args.world_timeout is not None else {}),
        )
        if args.transport == "ros2":
            wait_for_peers(transport, args.ros_peers)
        start = None  # (run time 0: now, or launch's wall time)
        if args.ready:
            print(
                "ready "
                + ("ros2" if args.transport == "ros2" else "{}:{}".format(*transport.address)),
                flush=True,
            )
            start = go_time(sys.stdin.readline())
        trace = live.run(start)
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
    outcome = trace.outcomes[0]
    summary = {
        "team": team.name,
        "agents": agents,
        "outcome": outcome["outcome"],
        "t_end": outcome["t"],
        "message": outcome["message"],
        "transitions": len(trace.transitions),
        "messages": len(trace.messages),
        "live": trace.meta["live"],
    }
    write_folder(out, trace, summary)  # (cmd_live's caller's handlers back only after)
    say(
        f"{team.name}: {', '.join(agents) or 'the world'} {outcome['outcome']} at "
        f"t={outcome['t']:.6g}: "
        f"{outcome['message']}; wrote {out}/ (trace.json, summary.json)"
    )
    return EXIT_OK


def open_transport(args: argparse.Namespace, team, agents: list[str]):
    """The transport ``--transport`` names, or a one-line error: a taken port, a ROS 2
    transport without rclpy (the [ros] extra), a bad domain. UDP's addresses are the
    flags' over the team file's (:mod:`.udp`)."""
    from hybridteam.live.transport import TransportError, UdpTransport

    if args.transport == "udp":
        udp = udp_settings(args, team, agents)
        try:
            return UdpTransport(udp.listen, udp.peers, mode=udp.mode, interface=udp.interface)
        except TransportError as exc:
            raise UsageError(str(exc)) from None
    try:
        from hybridteam.live.ros2 import Ros2Transport

        return Ros2Transport(
            team.name, "_".join(agents or ["world"]), ("data", "control"), domain_id=args.domain_id
        )
    except (ImportError, ValueError) as exc:
        raise UsageError(f"--transport ros2: {exc}") from None


#: Wall seconds ``--plant ros2`` waits at least for a robot's first odometry (ROS
#: discovery: the robot's driver is found asynchronously, within a second or two).
FIRST_ODOMETRY = 10.0


def open_plants(
    args: argparse.Namespace, team, agents: list[str], on_silent: Callable[[str], None]
) -> dict:
    """The hosted agents' external plants ``--plant`` names, by agent: none for ``sim``
    (the engine integrates them); for ``ros2`` each agent's robot through its ``deploy:``
    entry, once its first odometry (and scan, with a scan topic) has arrived
    (``on_silent``: told why when a robot's odometry or laser falls silent later, to stop
    the run). A one-line UsageError for an agent with no entry or whose plant a robot
    cannot drive (neither unicycle nor holonomic), a time scale (a robot keeps the wall
    clock's pace), rclpy missing, or a robot that says nothing at the start (within its
    timeout, and at least FIRST_ODOMETRY)."""
    if args.plant == "sim":
        return {}
    check_robot_clock(args)
    from hybridteam.live.ros2_plant import PlantSilent, RobotPlant, Ros2Plant

    for name in agents:
        if name not in team.deploy:
            raise UsageError(
                f"--plant ros2: agent '{name}' has no entry in the team file's "
                "deploy: section (its robot's cmd_vel and odom topics)"
            )
        try:
            RobotPlant.check(name, team.agent(name).plant.kind)
        except ValueError as exc:
            raise UsageError(f"--plant ros2: {exc}") from None
    plants: dict = {}
    try:
        for name in agents:
            robot = Ros2Plant(name, team.deploy[name], domain_id=args.domain_id, team=team.name)
            plants[name] = RobotPlant(robot, team.agent(name).plant.kind, on_silent)
            # the first odometry, before the clock starts (finding the robot's driver on
            # the domain can take longer than the silence its timeout allows later)
            robot.pose(max(robot.deploy.timeout, FIRST_ODOMETRY))
            plants[name].state(0.0)
            if robot.deploy.scan is not None:  # (and its laser's, which laws read)
                robot.scan(max(robot.deploy.timeout, FIRST_ODOMETRY))
    except BaseException as exc:
        for plant in plants.values():
            plant.robot.close()
        if isinstance(exc, ImportError | ValueError | PlantSilent):
            raise UsageError(f"--plant ros2: {exc}") from None
        raise
    return plants


def check_robot_clock(args: argparse.Namespace) -> None:
    """UsageError for ``--plant ros2`` with a time scale: a robot keeps the wall clock's
    pace (``live`` and ``launch`` alike)."""
    if args.plant == "ros2" and args.time_scale != 1:
        raise UsageError(
            f"--plant ros2: a robot moves on the wall clock; --time-scale "
            f"must be 1, got {args.time_scale:g}"
        )


def wait_for_peers(transport, count: int) -> None:
    """Block until the ROS 2 transport is matched with ``count`` others on both sockets:
    until a reader has matched a writer it drops that writer's datagrams, so agents that
    started talking before discovery ended would lose their first messages."""
    import time

    end = time.monotonic() + START_TIMEOUT
    while any(transport.peers(s) < count for s in ("data", "control")):
        if time.monotonic() > end:
            raise UsageError(
                f"--ros-peers {count}: only "
                f"{min(transport.peers(s) for s in ('data', 'control'))} "
                f"found within {START_TIMEOUT:g} s (same --domain-id?)"
            )
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
    from hybridteam.live.run import check_drop_copies
    from hybridteam.live.wire import wire_mismatch
    from hybridteam.trace import Trace

    check_clock(args)
    check_robot_clock(args)
    out = output_folder(args.output)
    team = load_team_or_report(args.team)
    if team is None:
        return EXIT_USAGE
    robots = launched_robots(args, team)
    full = compile_team(team)
    names = [ca.name for ca in full.agents]
    try:
        hosted_team(full, names)
        check_drop_copies(full, drop_copies(args.drop_copy))
    except HostingError as exc:
        raise UsageError(str(exc)) from None
    drifted = agent_teams(args.agent_team, names)
    for name, path in drifted.items():  # refused here, not as a process that fails to start
        other = load_team_or_report(path)
        if other is None:
            return EXIT_USAGE
        why = wire_mismatch(compile_team(other), full)
        if why is not None:
            raise UsageError(f"--agent-team {name}={path}: {why}")
    scripted = (
        dict(zip(names, losses_from(args.losses_from, full, [[n] for n in names]), strict=True))
        if args.losses_from
        else {}
    )
    ending = [names[a] for a in full.ending]
    # the processes: one per agent, and the world process when the team has components
    hosts = [*names, *([WORLD_PROCESS] if team.world else [])]
    # (summary.json is written last: an older one must not make a failed launch's folder
    # look complete)
    (out / "summary.json").unlink(missing_ok=True)
    ports = free_ports(len(hosts)) if args.transport == "udp" else [0] * len(hosts)
    domain = launch_domain(args, robots)
    stopped: list[str] = []

    def on_signal(signum: int, _frame) -> None:
        stopped.append(signal.Signals(signum).name)

    previous = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    procs: dict[str, subprocess.Popen] = {}
    try:
        for k, name in enumerate(hosts):
            folder = out / "agents" / name
            folder.mkdir(parents=True, exist_ok=True)
            # (an older run's: what says the process completed its folder, see left_no_trace)
            (folder / "summary.json").unlink(missing_ok=True)
            command = process_command(
                args,
                name,
                k,
                ports,
                domain,
                folder,
                robots,
                drifted.get(name),
                scripted.get(name, {}),
            )
            with open(folder / "live.log", "wb") as logfile:
                procs[name] = subprocess.Popen(
                    command, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=logfile
                )
        for name, proc in procs.items():
            if not _ready(proc, START_TIMEOUT):
                raise UsageError(
                    f"agent '{name}' did not start: "
                    f"{_last_line(out / 'agents' / name / 'live.log')}"
                )
        now = time.time()
        for proc in procs.values():  # every clock starts now (the same time 0 for all)
            assert proc.stdin is not None
            proc.stdin.write(f"go {now!r}\n".encode())
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
    missing = left_no_trace({n: p.returncode for n, p in procs.items()}, out / "agents")
    for name, why in missing.items():
        say(f"hybridteam: agent '{name}' left no trace: {why}")
    if all(n in missing for n in names):
        raise UsageError("no agent's process left a trace")
    traces = [Trace.load(out / "agents" / n / "trace.json") for n in hosts if n not in missing]
    losses = (
        {}
        if not args.losses_from
        else {
            "losses_from": {
                "counterexample": args.losses_from,
                "drops": {
                    a: {t: sorted(ns) for t, ns in sorted(d.items())}
                    for a, d in scripted.items()
                    if d
                },
            }
        }
    )
    outcome = write_merged(out, traces, ending, missing, losses).outcomes[0]
    say(
        f"{team.name}: {outcome['outcome']} at t={outcome['t']:.6g}; wrote {out}/ "
        "(trace.json, summary.json, agents/NAME/)"
    )
    return EXIT_OK


def write_merged(
    out,
    traces: list,
    ending: list[str],
    missing: dict[str, str],
    live: dict | None = None,
    align: str = "wall",
):
    """The team trace of a live run's process traces (:mod:`hybridteam.live.merge`),
    written to ``out`` with its summary (:func:`write_folder`); ``missing``: the agents
    whose process left no trace, and why; ``live``: more of ``meta.live`` (launch's
    ``losses_from``); ``align``: how the clocks are aligned (``launch``: one machine's
    wall clock). ``launch`` and ``merge`` both end so. The
    traces are taken in the team's order (a process by its first agent, the world
    process last), whichever order they come in. Returns the team's trace."""
    from hybridteam.live.merge import merge_traces

    order = {a: k for k, a in enumerate(traces[0].agents)}
    traces = sorted(
        traces,
        key=lambda tr: min(
            (order.get(a, len(order)) for a in tr.meta["live"]["agents"]), default=len(order)
        ),
    )
    merged = merge_traces(traces, ending, align)
    merged.meta["live"]["missing"] = missing
    merged.meta["live"].update(live or {})
    merged.outcomes[0]["message"] += "".join(
        f"; {n}: no trace ({why})" for n, why in missing.items()
    )
    outcome = merged.outcomes[0]
    summary = {
        "team": merged.meta["team"],
        "outcome": outcome["outcome"],
        "t_end": outcome["t"],
        "message": outcome["message"],
        "transitions": len(merged.transitions),
        "messages": len(merged.messages),
        "live": merged.meta["live"],
    }
    write_folder(out, merged, summary)
    return merged


def cmd_merge(args: argparse.Namespace) -> int:
    """The folders (or trace files) of one live run's processes, started by hand or on
    several machines, merged as ``launch`` merges its own: one line, exit 2, and nothing
    written for a trace that cannot be read, is not a live process's, or is not of the
    same run as the others."""
    from pathlib import Path

    from hybridteam.cli.common import load_trace
    from hybridteam.live.merge import MergeError, process_problem

    out = output_folder(args.output)
    traces, read = [], set()
    for given in args.traces:
        path = Path(given) / "trace.json" if Path(given).is_dir() else Path(given)
        if path.resolve() == (out / "trace.json").resolve():
            raise UsageError(
                f"{given}: is the output's own trace (-o {args.output}); merge into another folder"
            )
        if path.resolve() in read:
            raise UsageError(f"{given}: given twice")
        read.add(path.resolve())
        trace = load_trace(str(path))
        problem = process_problem(trace)
        if problem is not None:
            raise UsageError(f"{path}: {problem}")
        traces.append(trace)
    first = traces[0]
    hosted = {a for tr in traces for a in tr.meta["live"]["agents"]}
    missing = {a: "no trace given" for a in first.agents if a not in hosted}
    try:
        merged = write_merged(
            out, traces, first.meta["live"].get("ending", []), missing, align=args.align
        )
    except MergeError as exc:
        raise UsageError(f"cannot merge: {exc}") from None
    say(
        f"{first.meta['team']}: {merged.outcomes[0]['outcome']} at "
        f"t={merged.outcomes[0]['t']:.6g}; merged {len(traces)} process trace(s) "
        f"{alignment_text(merged.meta['live'])}; wrote {out}/ (trace.json, summary.json)"
    )
    return EXIT_OK


def alignment_text(live: dict) -> str:
    """How a merged trace's clocks were aligned and by how much its times could be off
    (its ``meta.live``), as ``merge`` says it."""
    from hybridteam.live.merge import clock_error

    if live["align"] == "wall":
        error = clock_error(live["clock_bounds"])
        return (
            "on one wall clock, "
            + (
                "no message bounds their clocks' offsets"
                if error is None
                else f"their clocks' offsets bounded by their messages within {error:.3g} s"
            )
            + " (meta.live.clock_bounds)"
        )
    processes, errors, ref = live["processes"], live["clock_errors_s"], live["clock_reference"]
    known = [e for k, e in enumerate(errors) if e is not None and k != ref]
    unknown = [
        ", ".join(p["agents"]) or "the world"
        for p, e in zip(processes, errors, strict=True)
        if e is None
    ]
    return (
        f"on {', '.join(processes[ref]['agents']) or 'the world'}'s clock, "
        + (
            f"the others' aligned by their messages within {max(known):.3g} s"
            if known
            else "no other's aligned by messages"
        )
        + (
            f", {'; '.join(unknown)} not (no messages both ways: wall clock taken, error unknown)"
            if unknown
            else ""
        )
        + " (meta.live.clock_errors_s)"
    )


def losses_from(path: str, cteam, processes: list[list[str]]) -> list[dict[str, set[int]]]:
    """``--losses-from``: the copies the counterexample at ``path`` loses, as the scripted
    drops (``{type: {n}}``) of each of ``processes`` (the agents of each;
    :mod:`hybridteam.live.counterexample`), each drop said on stderr; or one UsageError:
    not a counterexample verify wrote, a property that holds, another team's, losses a
    live run cannot script."""
    from hybridteam.cli.common import load_trace, read_json
    from hybridteam.live.counterexample import (
        CounterexampleError,
        check_verdict,
        drops,
        locate,
        losses,
    )

    trace_path, summary_path, name = locate(path)
    try:
        if not summary_path.is_file():
            raise CounterexampleError(
                "not a counterexample 'hybridteam verify' wrote (no "
                f"{summary_path}; give VERIFY_OUT/PROPERTY)"
            )
        check_verdict(
            read_json(summary_path, "verify summaries", "a verify summary")[1], name, summary_path
        )
        trace = load_trace(str(trace_path))
        found = [losses(trace, cteam, agents) for agents in processes]
    except (CounterexampleError, UsageError) as exc:
        raise UsageError(f"--losses-from {path}: {exc}") from None
    for loss in (loss for each in found for loss in each):
        say(f"hybridteam: {loss.text}")
    return [drops(each) for each in found]


def launched_robots(args: argparse.Namespace, team) -> list[str]:
    """The agents ``launch --plant ros2`` drives as robots: those with a ``deploy:`` entry
    (none for ``--plant sim``). A one-line UsageError if there is none, or one a robot
    cannot drive, before any process starts."""
    if args.plant == "sim":
        return []
    from hybridteam.live.ros2_plant import RobotPlant

    robots = [a.name for a in team.agents if a.name in team.deploy]
    if not robots:
        raise UsageError(
            "--plant ros2: the team file's deploy: section names no agent's "
            "robot (its cmd_vel and odom topics)"
        )
    for name in robots:
        try:
            RobotPlant.check(name, team.agent(name).plant.kind)
        except ValueError as exc:
            raise UsageError(f"--plant ros2: {exc}") from None
    return robots


def launch_domain(args: argparse.Namespace, robots: list[str]) -> int | None:
    """The ROS domain launch's processes share: ``--domain-id``; else, with robots, none
    given (each process's ``ROS_DOMAIN_ID``, else 0: where the robots' drivers are); else
    one chosen from this process's id, so that launches do not hear each other."""
    if args.domain_id is not None:
        return args.domain_id
    return None if robots else 1 + os.getpid() % 100


def process_command(
    args: argparse.Namespace,
    name: str,
    k: int,
    ports: list[int],
    domain: int | None,
    folder,
    robots: list[str],
    drifted: str | None = None,
    drops: dict[str, set[int]] | None = None,
) -> list[str]:
    """The ``hybridteam live`` command line of launch's ``k``-th process, hosting agent
    ``name`` (or the world process): its clock, faults and folder; its UDP port and peers,
    or how many others to wait for on ROS 2; the ROS domain (:func:`launch_domain`) where
    it talks or drives over ROS 2; ``--plant ros2`` for an agent in ``robots``;
    ``drifted``: the team file it runs instead (``--agent-team``, speaking the team's
    wire); ``drops``: its scripted drops (``--losses-from``)."""
    command = [
        sys.executable,
        "-m",
        "hybridteam.cli",
        "live",
        *([drifted, "--wire-team", args.team] if drifted else [args.team]),
        *(["--world"] if name == WORLD_PROCESS else ["--agent", name]),
        "--time-scale",
        repr(args.time_scale),
        "--log-level",
        args.log_level,
        "--ready",
        *fault_args(args, k),
        *(
            a
            for t, ns in sorted((drops or {}).items())
            for n in sorted(ns)
            for a in ("--drop-copy", f"{t}:{n}")
        ),
        "-o",
        str(folder),
        "--transport",
        args.transport,
    ]
    if name in robots:
        command += ["--plant", "ros2"]
    if args.transport == "udp":
        port = ports[k]
        command += ["--listen", f"127.0.0.1:{port}"]
        command += [a for p in ports if p != port for a in ("--peer", f"127.0.0.1:{p}")]
    else:  # every process in one domain, each waiting for all the others
        command += ["--ros-peers", str(len(ports) - 1)]
    if domain is not None and (args.transport == "ros2" or name in robots):
        command += ["--domain-id", str(domain)]
    if args.duration is not None:
        command += ["--duration", repr(args.duration)]
    return command


def left_no_trace(codes: dict[str, int | None], agents) -> dict[str, str]:
    """The launched processes (by folder name under ``agents``, with their exit codes)
    that left no complete folder, each with why. A folder is complete once its
    ``summary.json`` is there (written last): a process whose run had ended and whose
    folder was written may still be stopped by launch's SIGTERM as it exits (a ROS 2
    process takes a while to tear its nodes down), and its trace is the run's all the same."""
    return {
        n: _exit_text(code, agents / n / "live.log")
        for n, code in codes.items()
        if not (agents / n / "summary.json").exists()
    }


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
        raise UsageError(f"cannot write {exc.filename or out}: {exc.strerror or exc}") from None


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


def go_time(line: str) -> float | None:
    """The start ``--ready`` was given on stdin: ``go`` (now: None) or ``go WALL`` (run time
    0 at wall time WALL, ``time.time()`` on this machine, launch's one for every process);
    UsageError for anything else."""
    words = line.split()
    if not words or words[0] != "go" or len(words) > 2:
        raise UsageError("not started: stdin did not say 'go' (--ready)")
    if len(words) == 1:
        return None
    try:
        wall = float(words[1])
    except ValueError:
        wall = math.nan
    if not abs(time.time() - wall) <= START_TIMEOUT:
        raise UsageError(
            f"not started: 'go {words[1][:20]}' is no wall time within "
            f"{START_TIMEOUT:g} s of now (--ready)"
        )
    return wall


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
