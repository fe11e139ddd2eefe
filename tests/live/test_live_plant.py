"""The engine's plant seam (engine/run/plant.py), without ROS or the wall clock: a scripted
robot that ignores its commands and moves at 0.3 m/s, where the model says 0.5 m/s, so
every time and pose is known by hand and differs from what integrating the model gives.
Also the team file's deploy: section as the model reads it, and what ``hybridteam live
--plant ros2`` refuses before any ROS (the run against a robot: test_live_robot.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import hybridteam as ht
from hybridteam.engine.compile.compiler import compile_team
from hybridteam.engine.run.simulator import Simulator

TEAM = Path(__file__).parents[1] / "fixtures" / "live" / "drive.yaml"
SPEED = 0.3  # the scripted robot's, m/s (the model commands 0.5)


class ScriptedRobot:
    """A plant that records its commands and is at ``(SPEED t, 0, 0)`` at run time t."""

    def __init__(self) -> None:
        self.commands: list[tuple[float, list[float]]] = []

    def command(self, inputs: np.ndarray, t: float) -> None:
        self.commands.append((t, inputs.tolist()))

    def state(self, t: float) -> np.ndarray:
        return np.array([SPEED * t, 0.0, 0.0])


def stops(trace) -> list[tuple[float, str]]:
    return [
        (float(t), s)
        for t, s in zip(trace.transitions["t"], trace.transitions["target"], strict=True)
    ]


def test_the_integrated_plant_is_the_default():
    """Without plants the engine integrates: x = 0.5 t reaches 1 at t = 2, located."""
    trace = Simulator(compile_team(ht.load(TEAM)), 1).run()
    assert stops(trace) == [(0.0, "Forward"), (2.0, "Stopped")]


def test_an_external_plant_is_commanded_and_read_and_its_guard_sampled():
    """The robot's x = 0.3 t passes 1 at t = 10/3, between the control ticks 3.3 and 3.4
    (the output samples, every 0.25 s, are instants too: 3.25, 3.5): the guard, sampled,
    fires at 3.4, not at 10/3 (no zero-crossing to locate) nor at 2.0 (the model's
    arc). Every instant commands the held inputs, 0.5 m/s until the stop's zero; the
    trace's samples are the robot's poses, 0.3 t, not the model's 0.5 t."""
    robot = ScriptedRobot()
    trace = Simulator(compile_team(ht.load(TEAM)), 1, plants={0: robot}).run()
    (t0, first), (t1, last) = stops(trace)
    assert (t0, first, last) == (0.0, "Forward", "Stopped")
    assert t1 == pytest.approx(3.4, abs=1e-12)
    assert trace.outcomes[0]["outcome"] == "ok"
    times = [t for t, _ in robot.commands]
    ticks = [0.1 * k for k in range(35)]
    for tick in ticks:  # a command at every control tick up to the stop
        assert min(abs(t - tick) for t in times) < 1e-12
    assert all(u == [0.5, 0.0] for t, u in robot.commands[:-1])
    assert robot.commands[-1][1] == [0.0, 0.0]
    assert robot.commands[-1][0] == pytest.approx(3.4, abs=1e-12)
    sampled = trace.sample_times <= t1
    x = trace.samples["robot"][sampled, 0, 0]
    assert trace.sample_times[sampled].tolist() == [0.25 * k for k in range(14)]
    np.testing.assert_allclose(x, SPEED * trace.sample_times[sampled], rtol=0, atol=1e-12)


def test_the_robot_starts_where_it_is():
    """The initial state is the plant's reading, not the file's (x = 0): a robot already
    at x = 1.2 stops at the first instant, t = 0."""

    class Ahead(ScriptedRobot):
        def state(self, t: float) -> np.ndarray:
            return np.array([1.2, 0.0, 0.0])

    trace = Simulator(compile_team(ht.load(TEAM)), 1, plants={0: Ahead()}).run()
    assert stops(trace)[-1] == (0.0, "Stopped")


def test_external_plants_drive_one_run_with_held_inputs(team_from_yaml):
    cteam = compile_team(ht.load(TEAM))
    with pytest.raises(ValueError, match="single run"):
        Simulator(cteam, 2, plants={0: ScriptedRobot()})
    flow = team_from_yaml("""\
        team: f
        agents:
          b:
            plant: {kind: flow, state: {h: 1.0}}
            modes:
              Fall: {flow: {h: -1}}
        """)
    with pytest.raises(ValueError, match="held inputs"):
        Simulator(compile_team(flow), 1, plants={0: ScriptedRobot()})


def test_the_deploy_section_is_read_and_simulation_ignores_it(team_from_yaml):
    """The fixture's deploy: entry is the robot's settings (defaults filled in); the same
    team without it simulates to the same trace."""
    from hybridteam.model.deploy import PlantDeploy

    team = ht.load(TEAM)
    assert team.deploy == {
        "robot": PlantDeploy("/drive/robot/cmd_vel", "/drive/robot/odom", None, "odom", 2.0)
    }
    text = TEAM.read_text()
    bare = team_from_yaml(text[: text.index("\ndeploy:")])
    assert bare.deploy == {}
    with_deploy = Simulator(compile_team(team), 1).run()
    without = Simulator(compile_team(bare), 1).run()
    assert with_deploy.samples["robot"].tobytes() == without.samples["robot"].tobytes()
    assert stops(with_deploy) == stops(without)


@pytest.mark.parametrize(
    ("deploy", "args", "message"),
    [
        (
            False,
            [],
            "--plant ros2: agent 'robot' has no entry in the team file's deploy: "
            "section (its robot's cmd_vel and odom topics)",
        ),
        (
            True,
            ["--time-scale", "2"],
            "--plant ros2: a robot moves on the wall clock; --time-scale must be 1, got 2",
        ),
        (
            True,
            [],
            "--plant ros2: the ros2 transport and plant need rclpy: pip install 'hybridteam[ros]'",
        ),
    ],
)
def test_plant_ros2_refusals_are_one_line(tmp_path, capsys, monkeypatch, deploy, args, message):
    """Each before any run or file: one line, exit 2 (rclpy made unimportable here, so
    the last holds wherever the test runs)."""
    import sys

    from hybridteam.cli import main

    monkeypatch.setitem(sys.modules, "rclpy", None)
    text = TEAM.read_text()
    team = tmp_path / "drive.yaml"
    team.write_text(text if deploy else text[: text.index("\ndeploy:")] + "\n")
    out = tmp_path / "out"
    status = main(
        [
            "live",
            str(team),
            "--agent",
            "robot",
            "--plant",
            "ros2",
            "--listen",
            "127.0.0.1:0",
            "-o",
            str(out),
            *args,
        ]
    )
    assert status == 2
    assert capsys.readouterr().err.strip().splitlines() == [f"hybridteam: error: {message}"]
    assert not out.exists()


def test_a_holonomic_command_is_turned_into_the_body_frame_by_hand():
    """v_body = R(-yaw) v_world: facing +x nothing turns; facing +y, world +x is the
    robot's right (body -y) and world +y its front; heading atan2(3, 4) (cos 0.8, sin
    0.6): world (2, 1) is body (0.8 * 2 + 0.6 * 1, -0.6 * 2 + 0.8 * 1) = (2.2, -0.4)."""
    import math

    from hybridteam.live.ros2_plant import body_velocity

    assert body_velocity(0.5, -0.2, 0.0) == (0.5, -0.2)
    assert body_velocity(1.0, 0.0, math.pi / 2) == pytest.approx((0.0, -1.0), abs=1e-15)
    assert body_velocity(0.0, 1.0, math.pi / 2) == pytest.approx((1.0, 0.0), abs=1e-15)
    assert body_velocity(2.0, 1.0, math.atan2(3, 4)) == pytest.approx((2.2, -0.4), abs=1e-15)
    assert body_velocity(1.0, 0.0, math.radians(30)) == pytest.approx(
        (math.sqrt(3) / 2, -0.5), abs=1e-15
    )


class Commanded:
    """A Ros2Plant stand-in: at a fixed pose, keeping the Twist fields it is given."""

    agent = "robot"

    def __init__(self, theta: float) -> None:
        from hybridteam.live.ros2_plant import PlantDeploy, Pose

        self.deploy = PlantDeploy("/robot/cmd_vel", "/robot/odom")

        self.at = Pose(1.0, 2.0, theta, 0.0, 0.0)
        self.sent: list[dict[str, float]] = []

    def pose(self, timeout=None):
        return self.at

    def command(self, inputs):
        self.sent.append(inputs)


def test_a_holonomic_agent_is_driven_in_its_body_frame():
    """The held inputs (vx, vy, omega) of a holonomic agent go out as a Twist turned by
    the yaw of the pose read (a robot facing +y told to go +x world moves to its right);
    a unicycle's (v, omega) go out as they are."""
    import math

    from hybridteam.live.ros2_plant import RobotPlant

    robot = Commanded(math.pi / 2)
    plant = RobotPlant(robot, "holonomic")
    plant.command(np.array([0.5, 0.0, 0.25]), 0.0)  # (reads the pose first)
    plant.state(0.1)
    plant.command(np.array([0.3, 0.4, 0.0]), 0.1)
    assert [sorted(c) for c in robot.sent] == [["omega", "vx", "vy"]] * 2
    assert [[c["vx"], c["vy"], c["omega"]] for c in robot.sent] == [
        pytest.approx([0.0, -0.5, 0.25], abs=1e-15),
        pytest.approx([0.4, -0.3, 0.0], abs=1e-15),
    ]
    unicycle = Commanded(math.pi / 2)
    RobotPlant(unicycle, "unicycle").command(np.array([0.5, 0.25]), 0.0)
    assert unicycle.sent == [{"v": 0.5, "omega": 0.25}]


def test_an_agent_a_robot_cannot_drive_is_refused(tmp_path, capsys):
    """A flow plant has no velocity to send as a Twist: one line, before any ROS."""
    from hybridteam.cli import main

    team = tmp_path / "flow.yaml"
    team.write_text("""
team: flow
agents:
  robot:
    plant: {kind: flow, state: {x: 0.0}}
    initial: Grow
    modes:
      Grow: {flow: {x: "1"}}
simulation: {duration: 1.0}
deploy:
  robot: {cmd_vel: /robot/cmd_vel, odom: /robot/odom}
""")
    status = main(
        [
            "live",
            str(team),
            "--agent",
            "robot",
            "--plant",
            "ros2",
            "--listen",
            "127.0.0.1:0",
            "-o",
            str(tmp_path / "out"),
        ]
    )
    assert status == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        "hybridteam: error: --plant ros2: agent 'robot' has a flow plant; a robot "
        "over ROS 2 drives a unicycle agent (v, omega) or a holonomic one (vx, vy, "
        "omega), as a Twist, its x, y, theta from odometry"
    ]
    assert not (tmp_path / "out").exists()


# ---------------------------------------------------------------------- launch --plant ros2
EXPERIMENT2 = Path(__file__).parents[2] / "examples" / "transport" / "experiment2.yaml"


def launch_args(*argv: str):
    """``hybridteam launch`` arguments as its parser reads them."""
    import argparse

    from hybridteam.cli import live

    parser = argparse.ArgumentParser()
    live.register(parser.add_subparsers(dest="command"))
    return parser.parse_args(["launch", *argv])


def test_launch_passes_the_plant_to_the_robots_processes(tmp_path):
    """Experiment 2 with the Labmate's robot in deploy: (not the XR4000's, nor the
    operator's): only the Labmate's process drives a robot; the world process and the
    others simulate. Over UDP the robot's domain is ROS_DOMAIN_ID's unless given; over
    ros2 every process shares the given one."""
    from hybridteam.cli.live import WORLD_PROCESS, launched_robots, process_command

    team_file = tmp_path / "e2.yaml"
    team_file.write_text(
        EXPERIMENT2.read_text()
        .replace(  # (its requirements: not here)
            "requirements_from: [requirements.yaml]\n", ""
        )
        .replace(
            "\nsimulation:",
            "\ndeploy:\n  labmate: {cmd_vel: /labmate/cmd_vel, odom: /labmate/odom}\n\nsimulation:",
        )
    )
    team = ht.load(team_file)
    hosts = ["xr4000", "labmate", "operator", WORLD_PROCESS]
    ports = [47001, 47002, 47003, 47004]

    def commands(*argv: str, domain=None) -> dict[str, list[str]]:
        args = launch_args(str(team_file), "-o", str(tmp_path / "out"), *argv)
        robots = launched_robots(args, team)
        return {
            name: process_command(args, name, k, ports, domain, tmp_path / name, robots)
            for k, name in enumerate(hosts)
        }

    def option(command: list[str], flag: str) -> list[str]:
        return [command[i + 1] for i, a in enumerate(command) if a == flag]

    udp = commands("--plant", "ros2")
    assert {n: option(c, "--plant") for n, c in udp.items()} == {
        "xr4000": [],
        "labmate": ["ros2"],
        "operator": [],
        WORLD_PROCESS: [],
    }
    assert all(option(c, "--domain-id") == [] for c in udp.values())
    assert option(udp["labmate"], "--listen") == ["127.0.0.1:47002"]
    assert option(udp["labmate"], "--peer") == [
        "127.0.0.1:47001",
        "127.0.0.1:47003",
        "127.0.0.1:47004",
    ]
    assert option(udp["labmate"], "--time-scale") == ["1.0"]
    # a domain given: the robot's process drives there; the others talk over UDP
    udp7 = commands("--plant", "ros2", domain=7)
    assert {n: option(c, "--domain-id") for n, c in udp7.items()} == {
        "xr4000": [],
        "labmate": ["7"],
        "operator": [],
        WORLD_PROCESS: [],
    }
    ros = commands("--plant", "ros2", "--transport", "ros2", domain=7)
    assert all(
        option(c, "--domain-id") == ["7"] and option(c, "--ros-peers") == ["3"]
        for c in ros.values()
    )
    assert {n: option(c, "--plant") for n, c in ros.items()} == {
        n: option(c, "--plant") for n, c in udp.items()
    }
    # without --plant ros2 nobody drives a robot, deploy: or not
    assert all(option(c, "--plant") == [] for c in commands().values())


def test_launch_domain_is_the_robots_unless_given():
    from hybridteam.cli.live import launch_domain

    assert launch_domain(launch_args("t.yaml", "-o", "o", "--domain-id", "9"), ["a"]) == 9
    assert launch_domain(launch_args("t.yaml", "-o", "o"), ["a"]) is None  # ROS_DOMAIN_ID
    assert 1 <= launch_domain(launch_args("t.yaml", "-o", "o"), []) <= 100


@pytest.mark.parametrize(
    ("deploy", "args", "message"),
    [
        (
            True,
            ["--time-scale", "4"],
            "--plant ros2: a robot moves on the wall clock; --time-scale must be 1, got 4",
        ),
        (
            False,
            [],
            "--plant ros2: the team file's deploy: section names no agent's robot "
            "(its cmd_vel and odom topics)",
        ),
    ],
)
def test_launch_plant_ros2_refusals_are_one_line(tmp_path, capsys, deploy, args, message):
    from hybridteam.cli import main

    text = TEAM.read_text()
    team = tmp_path / "drive.yaml"
    team.write_text(text if deploy else text[: text.index("\ndeploy:")] + "\n")
    out = tmp_path / "out"
    status = main(["launch", str(team), "--plant", "ros2", "-o", str(out), *args])
    assert status == 2
    assert capsys.readouterr().err.strip().splitlines() == [f"hybridteam: error: {message}"]
    assert not out.exists()


def test_a_sigterm_while_the_folder_is_written_is_the_live_process_s(tmp_path, monkeypatch):
    """launch stops the processes still running once the end rule's have ended; one whose
    run has just ended may get that SIGTERM as it writes its folder. Its handler is still
    the live process's then (the run is over: nothing to stop), not the caller's (a real
    process's default, which would kill it with its folder half-written); the caller's is
    back once ``live`` returns."""
    import os
    import signal

    from hybridteam.cli import live, main

    caller: list[int] = []
    previous = signal.signal(signal.SIGTERM, lambda signum, _frame: caller.append(signum))
    written = live.write_folder

    def sigterm_then_write(out, trace, summary) -> None:
        os.kill(os.getpid(), signal.SIGTERM)
        written(out, trace, summary)

    monkeypatch.setattr(live, "write_folder", sigterm_then_write)
    try:
        status = main(
            [
                "live",
                str(TEAM),
                "--agent",
                "robot",
                "--listen",
                "127.0.0.1:0",
                "--duration",
                "0.1",
                "--time-scale",
                "10",
                "-o",
                str(tmp_path / "o"),
            ]
        )
        assert status == 0
        assert caller == []  # (the live process's handler took it)
        assert (tmp_path / "o" / "summary.json").exists()
        os.kill(os.getpid(), signal.SIGTERM)  # the caller's own again
        assert caller == [signal.SIGTERM]
    finally:
        signal.signal(signal.SIGTERM, previous)


LASER_TEAM = """
team: laser
world:
  - use: obstacles
    with:
      detect:
        - {agent: robot, sensor: ir, ring: {count: 4, max_range: 2.5, mount_radius: 0.2},
           beams: [0], below: 0.3, raise: near}
agents:
  robot:
    plant: {kind: unicycle, state: {x: 0.0, y: 0.0, theta: 0.0}}
    initial: Look
    modes:
      Look: {inputs: {v: 0, omega: 0}, period: 0.1, transitions: [{to: Seen, on: near}]}
      Seen: {inputs: {v: 0, omega: 0}, period: 0.1}
simulation: {duration: 1.0, sample_period: 0.1}
"""


class ScannedRobot:
    """A robot standing still whose laser (4 beams every 90 degrees from ahead) reads 1 m
    ahead until run time 0.42, then 0.4 m: what its ring's front beam reads is 0.8, then
    0.2 (less its 0.2 mount radius)."""

    laser = True

    def __init__(self) -> None:
        self.t = 0.0

    def command(self, inputs: np.ndarray, t: float) -> None:
        pass

    def state(self, t: float) -> np.ndarray:
        self.t = t
        return np.zeros(3)

    def ranges(self, ring):
        import math

        from hybridteam.live.ros2_plant import Scan, ring_ranges

        ahead = 1.0 if self.t < 0.42 else 0.4
        return ring_ranges(Scan((ahead, 3.0, 3.0, 3.0), 0.0, math.pi / 2, 0.0, 8.0, 0.0, 0.0), ring)


def test_a_robots_detect_rules_read_its_laser(team_from_yaml):
    """The rule 'front beam below 0.3 raises near' runs in the robot's process on its
    laser: near is raised at the first instant its laser reads 0.2 ahead (run time 0.5,
    the first control tick past 0.42), and the world process's raising of near
    at the start (its model says otherwise) is not taken."""
    from hybridteam.live.run import LiveRun
    from hybridteam.live.transport import UdpTransport
    from hybridteam.live.wire import READING, WORLD_INDEX

    team = team_from_yaml(LASER_TEAM)
    transport = UdpTransport(("127.0.0.1", 0))
    world = UdpTransport(("127.0.0.1", 0), [transport.address])
    try:
        live = LiveRun(
            team,
            ["robot"],
            transport,
            duration=1.0,
            time_scale=5,
            plants={"robot": ScannedRobot()},
            plant_name="ros2",
        )
        world.send(
            live.codec.encode_world(
                READING,
                WORLD_INDEX,
                0,
                0,
                {**{f"ir.{k}": 0.1 for k in range(4)}, "event.near": 1.0},
                0.0,
            ),
            "data",
        )
        trace = live.run()
    finally:
        transport.close()
        world.close()
    assert stops(trace) == [(0.0, "Look"), (pytest.approx(0.5, abs=1e-9), "Seen")]


def test_a_laser_falling_silent_stops_the_run_with_the_last_scan_standing():
    """As silent odometry: the laser's silence is told once (the live run then stops),
    the last scan read stands meanwhile and is not waited for again; with nobody to tell,
    or before any scan, it is an error."""
    import math

    from hybridteam.live.ros2_plant import PlantDeploy, PlantSilent, RobotPlant, Scan
    from hybridteam.world.sensors import RangeRing

    class GoesSilent:
        agent = "robot"
        deploy = PlantDeploy("/robot/cmd_vel", "/robot/odom", "/robot/scan")

        def __init__(self, scans: int) -> None:
            self.scans, self.asked = scans, 0

        def scan(self, timeout=None):
            self.asked += 1
            if self.asked > self.scans:
                raise PlantSilent("robot: no laser scan on /robot/scan within 2 s")
            return Scan((1.0, 2.0, 3.0, 4.0), 0.0, math.pi / 2, 0.0, 8.0, 0.0, 0.0)

    ring = RangeRing(count=4, max_range=5.0)
    told: list[str] = []
    robot = GoesSilent(1)
    plant = RobotPlant(robot, "unicycle", on_silent=told.append)
    assert plant.laser
    assert [plant.ranges(ring).tolist() for _ in range(3)] == [[1.0, 2.0, 3.0, 4.0]] * 3
    assert told == ["robot: no laser scan on /robot/scan within 2 s"]
    assert robot.asked == 2  # (silent once: not waited for again)
    with pytest.raises(PlantSilent):
        RobotPlant(GoesSilent(0), "unicycle", on_silent=told.append).ranges(ring)
    with pytest.raises(PlantSilent):
        unheard = RobotPlant(GoesSilent(1), "unicycle")
        unheard.ranges(ring)
        unheard.ranges(ring)
