"""``hybridteam live --plant ros2``: one agent drives a robot over ROS 2 (a fake one here,
a thread integrating a unicycle from the Twists it receives and publishing Odometry at
50 Hz), with no teammates over UDP. Skips where rclpy cannot be imported (the ``ros``
extra: CPython 3.11 wheels for Linux x86_64); run it with an interpreter that has them."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from hybridteam.library import LawContext, law
from hybridteam.live.ros2 import ros_name
from hybridteam.trace import Trace, command_series

pytestmark = pytest.mark.filterwarnings("ignore:module 'sre_:DeprecationWarning")

ROOT = Path(__file__).resolve().parents[2]
TEAM = ROOT / "tests" / "fixtures" / "live" / "drive.yaml"
DOMAIN = 1 + (os.getpid() + 50) % 100  # (not test_live_ros2's: its own domain)
ODOM_PERIOD = 0.02  # the fake robot's: 50 Hz
CONTROL_PERIOD = 0.1  # the team's law period (drive.yaml)


class UnicycleRobot:
    """A robot's driver: every ``ODOM_PERIOD`` s it moves its unicycle under the last
    Twist received (exactly: an arc at constant v, omega) and publishes its pose as
    Odometry in frame ``odom``. Keeps every Twist with its ``time.time()`` of arrival and
    every published pose ``(x, y, theta, time.time())``."""

    def __init__(
        self, ros, ns: str, scan: dict | None = None, *, theta: float = 0.0, holonomic: bool = False
    ) -> None:
        """``scan``: LaserScan fields it publishes on ``ns/scan`` with every pose;
        ``theta``: its heading at the start; ``holonomic``: a base that also moves
        sideways (the Twist's linear.y, kept in ``lateral``), for a heading fixed while
        it moves (angular.z zero)."""
        from geometry_msgs.msg import Twist
        from nav_msgs.msg import Odometry
        from rclpy.executors import SingleThreadedExecutor
        from sensor_msgs.msg import LaserScan

        self.ctx = ros.Context()
        ros.init(context=self.ctx, domain_id=DOMAIN)
        self.node = ros.create_node("unicycle_robot", context=self.ctx)
        self.twists: list[tuple[float, float, float]] = []  # (v, omega, wall time)
        self.poses: list[tuple[float, float, float, float]] = []
        self.x = self.y = 0.0
        self.theta = theta
        self.v = self.vy = self.omega = 0.0
        self.holonomic = holonomic
        self.lateral: list[float] = []  # (holonomic) each Twist's linear.y
        self.silent = False  # set: it stops publishing odometry (its driver hangs)
        self.lock = threading.Lock()
        self._Odometry = Odometry
        self.pub = self.node.create_publisher(Odometry, f"{ns}/odom", 10)
        self.scan = None
        if scan is not None:
            self.scan = LaserScan(**scan)
            self.scan.header.frame_id = "base_link"
            self.scan_pub = self.node.create_publisher(LaserScan, f"{ns}/scan", 10)
        self.node.create_subscription(Twist, f"{ns}/cmd_vel", self._on_twist, 10)
        self.last = time.monotonic()
        self.node.create_timer(ODOM_PERIOD, self._tick)
        self.executor = SingleThreadedExecutor(context=self.ctx)
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self.executor.spin)
        self.thread.start()

    def _on_twist(self, msg) -> None:
        with self.lock:
            self.v, self.vy, self.omega = msg.linear.x, msg.linear.y, msg.angular.z
            self.twists.append((self.v, self.omega, time.time()))
            self.lateral.append(self.vy)

    def _tick(self) -> None:
        now = time.monotonic()
        dt, self.last = now - self.last, now
        with self.lock:
            v, vy, w = self.v, self.vy, self.omega
        if self.holonomic:  # (its heading fixed: the body frame's axes in the world)
            assert w == 0.0
            c, s = math.cos(self.theta), math.sin(self.theta)
            self.x += (c * v - s * vy) * dt
            self.y += (s * v + c * vy) * dt
        elif w == 0.0:
            self.x += v * math.cos(self.theta) * dt
            self.y += v * math.sin(self.theta) * dt
        else:
            th = self.theta + w * dt
            self.x += v / w * (math.sin(th) - math.sin(self.theta))
            self.y -= v / w * (math.cos(th) - math.cos(self.theta))
            self.theta = th
        if self.silent:
            return
        msg = self._Odometry()
        msg.header.frame_id = "odom"
        wall = time.time()
        msg.header.stamp.sec, msg.header.stamp.nanosec = int(wall), int(wall % 1 * 1e9)
        msg.pose.pose.position.x, msg.pose.pose.position.y = self.x, self.y
        q = msg.pose.pose.orientation
        q.z, q.w = math.sin(self.theta / 2), math.cos(self.theta / 2)
        self.pub.publish(msg)
        self.poses.append((self.x, self.y, self.theta, wall))
        if self.scan is not None:
            self.scan_pub.publish(self.scan)

    def close(self) -> None:
        self.executor.shutdown()
        self.thread.join()
        self.node.destroy_node()
        self.ctx.try_shutdown()


def team_file(tmp_path, ns: str, timeout: float) -> Path:
    """drive.yaml, its deploy: entry for the robot at ``ns``."""
    text = TEAM.read_text()
    team = tmp_path / "drive.yaml"
    team.write_text(
        text[: text.index("\ndeploy:")] + "\ndeploy:\n  robot: {cmd_vel: "
        f"{ns}/cmd_vel, odom: {ns}/odom, timeout: {timeout}}}\n"
    )
    return team


def run_live(team: Path, out: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [
            sys.executable,
            "-m",
            "hybridteam.cli",
            "live",
            str(team),
            "--agent",
            "robot",
            "--plant",
            "ros2",
            "--transport",
            "udp",
            "--listen",
            "127.0.0.1:0",
            "--domain-id",
            str(DOMAIN),
            "-o",
            str(out),
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
    )


def test_an_agent_drives_a_robot_over_ros2_to_its_final_mode(ros, tmp_path):
    """Forward at 0.5 m/s until the robot's odometry says x >= 1, then stop (drive.yaml):
    the agent reaches its final mode; the guard fires no earlier than the first odometry
    with x >= 1 was published, and no later than one control period (the next tick
    that samples it) after the robot's x passed 1.0 plus one odometry period (the
    reading's age), plus how late the loop woke (measured, in the trace) and 10 ms for
    delivery; the robot is driven at 0.5 m/s, and the last Twist is zero; every sample
    of the trace is a pose the robot published."""
    ns = f"/{ros_name(f't{os.getpid()}_plant')}/robot"
    team = team_file(tmp_path, ns, 5.0)
    robot = UnicycleRobot(ros, ns)
    out = tmp_path / "out"
    try:
        done = run_live(team, out)
        time.sleep(0.1)  # (the stop's Twist has been acknowledged; let the robot log it)
    finally:
        robot.close()
    assert done.returncode == 0, done.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["outcome"] == "ok" and summary["live"]["plant"] == "ros2"
    trace = Trace.load(out / "trace.json")
    fired = [
        float(t)
        for t, target in zip(trace.transitions["t"], trace.transitions["target"], strict=True)
        if target == "Stopped"
    ]
    assert len(fired) == 1
    live = trace.meta["live"]
    fired_wall = live["wall_start"] + fired[0]
    # where the robot's x passed 1.0: between the last published pose before and the
    # first at or past it (the robot moves at 0.5 m/s then), on the wall clock
    k = next(i for i, p in enumerate(robot.poses) if p[0] >= 1.0)
    (x0, _, _, w0), (x1, _, _, w1) = robot.poses[k - 1], robot.poses[k]
    crossed = w0 + (1.0 - x0) / (x1 - x0) * (w1 - w0)
    assert fired_wall >= w1 - 1e-3  # (the wall clocks of two threads: a millisecond)
    late = live["late_ms"].get("max", 0.0) / 1e3
    assert fired_wall - crossed <= CONTROL_PERIOD + ODOM_PERIOD + late + 0.01
    speeds = [v for v, _, _ in robot.twists]
    assert speeds[0] == 0.5 and speeds[-1] == 0.0
    assert all(w == 0.0 for _, w, _ in robot.twists)
    assert set(speeds) == {0.5, 0.0}
    x = trace.samples["robot"][:, 0, 0]
    published = {p[0] for p in robot.poses}
    recorded = x[~np.isnan(x)]
    assert recorded.size >= 2 and all(value in published for value in recorded)
    assert recorded[0] == 0.0 and every_step_forward(recorded)
    # what the robot was told, in the trace as a log's commands are (conformance drives
    # the plant with them): (0.5, 0) at every sample time before the stop, (0, 0) after
    cmd = trace.samples[command_series("robot")][:, 0, :]
    assert trace.meta["series"][command_series("robot")] == ["v", "omega"]
    before = trace.sample_times <= fired[0] - 1e-9
    assert (cmd[before] == [0.5, 0.0]).all() and (cmd[~before] == [0.0, 0.0]).all()


def every_step_forward(x: np.ndarray) -> bool:
    return bool(np.all(np.diff(x) >= 0))


def test_a_robot_falling_silent_stops_the_run_with_its_trace(ros, tmp_path):
    """The robot's odometry stops 0.5 s after its first Twist (its driver hangs), long
    before x reaches 1; with a 0.5 s timeout the run ends 'stopped', saying why, its
    trace and summary written, and the robot is sent a zero Twist."""
    ns = f"/{ros_name(f't{os.getpid()}_silent')}/robot"
    robot = UnicycleRobot(ros, ns)
    out = tmp_path / "out"

    def hang() -> None:
        while not robot.twists:
            time.sleep(0.005)
        time.sleep(0.5)
        robot.silent = True

    hanging = threading.Thread(target=hang, daemon=True)
    hanging.start()
    try:
        done = run_live(team_file(tmp_path, ns, 0.5), out)
        time.sleep(0.1)
    finally:
        robot.close()
    assert done.returncode == 0, done.stderr
    trace = Trace.load(out / "trace.json")
    outcome = trace.outcomes[0]
    assert outcome["outcome"] == "stopped"
    assert f"robot: no odometry on {ns}/odom within 0.5 s" in outcome["message"]
    assert outcome["t"] < 2.0  # (x = 0.5 t would have reached 1 at t = 2)
    assert "Stopped" not in trace.transitions["target"].tolist()
    assert json.loads((out / "summary.json").read_text())["outcome"] == "stopped"
    assert robot.twists[-1][:2] == (0.0, 0.0)


def test_launch_drives_the_deployed_robot(ros, tmp_path):
    """``hybridteam launch --plant ros2``: the agent's process launch starts drives the
    robot of its deploy: entry, in the given domain, to its final mode (the first Twist
    0.5 m/s, the last zero), and the merged trace says its plant was the robot."""
    ns = f"/{ros_name(f't{os.getpid()}_launch')}/robot"
    team = team_file(tmp_path, ns, 5.0)
    robot = UnicycleRobot(ros, ns)
    out = tmp_path / "out"
    try:
        done = subprocess.run(
            [
                sys.executable,
                "-m",
                "hybridteam.cli",
                "launch",
                str(team),
                "--plant",
                "ros2",
                "--domain-id",
                str(DOMAIN),
                "-o",
                str(out),
            ],
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=60,
        )
        time.sleep(0.1)  # (as above: the stop's Twist logged)
    finally:
        robot.close()
    assert done.returncode == 0, done.stderr
    trace = Trace.load(out / "trace.json")
    assert trace.transitions["target"].tolist() == ["Forward", "Stopped"]
    assert [p["plant"] for p in trace.meta["live"]["processes"]] == ["ros2"]
    assert robot.twists[0][:2] == (0.5, 0.0) and robot.twists[-1][:2] == (0.0, 0.0)
    assert max(p[0] for p in robot.poses) >= 1.0  # (the robot, not a model, got there)


def test_a_holonomic_agent_drives_its_robot_in_the_world_frame(ros, tmp_path):
    """drive.yaml as a holonomic base: vx = 0.5 (world frame) until x >= 1. The robot
    faces +y (odometry heading pi/2), so the Twist is (0, -0.5) in its frame, and it
    moves along world +x, y staying 0, to the final mode; sent as it was (linear.x 0.5),
    it would move along +y and never reach x = 1."""
    ns = f"/{ros_name(f't{os.getpid()}_omni')}/robot"
    team = team_file(tmp_path, ns, 5.0)
    team.write_text(
        team.read_text()
        .replace("kind: unicycle", "kind: holonomic")
        .replace("{v: 0.5, omega: 0}", "{vx: 0.5, vy: 0, omega: 0}")
        .replace("{v: 0, omega: 0}", "{vx: 0, vy: 0, omega: 0}")
    )
    robot = UnicycleRobot(ros, ns, theta=math.pi / 2, holonomic=True)
    out = tmp_path / "out"
    try:
        done = run_live(team, out)
        time.sleep(0.1)
    finally:
        robot.close()
    assert done.returncode == 0, done.stderr
    trace = Trace.load(out / "trace.json")
    assert trace.transitions["target"].tolist() == ["Forward", "Stopped"]
    assert robot.twists[0][0] == pytest.approx(0.0, abs=1e-15)
    assert robot.lateral[0] == -0.5
    assert robot.twists[-1][:2] == (0.0, 0.0) and robot.lateral[-1] == 0.0
    x, y, _, _ = robot.poses[-1]
    assert x >= 1.0 and abs(y) < 1e-9


@law("tests.laser_ring_keep", plants=("unicycle",))
def laser_ring_keep(ctx: LawContext) -> np.ndarray:
    """Stand still and keep what the ring ``ir`` reads at each tick, beam by beam."""
    r = ctx.sense("ir")
    for k in range(r.shape[1]):
        ctx.keep(f"ir{k}", r[:, k])
    return np.zeros((r.shape[0], 2))


LASER_TEAM = """
team: laser
world:
  - use: obstacles
    with:
      detect:
        - {agent: robot, sensor: ir, ring: {count: 4, max_range: 2.5, min_range: 0.04,
           mount_radius: 0.2}, beams: [0], below: 0.9, raise: near}
agents:
  robot:
    plant: {kind: unicycle, state: {x: 0.0, y: 0.0, theta: 0.0}}
    initial: Look
    modes:
      Look:
        law: {use: tests.laser_ring_keep, period: 0.1}
        transitions: [{to: Seen, on: near}]
      Seen: {law: {use: tests.laser_ring_keep, period: 0.1}}
simulation: {duration: 0.5, sample_period: 0.1}
deploy:
  robot: {cmd_vel: NS/cmd_vel, odom: NS/odom, scan: NS/scan, timeout: 5.0}
"""


def test_a_robots_laser_is_what_its_law_reads_of_its_ring(ros, tmp_path):
    """A robot's LaserScan (8 beams every 45 degrees from 0) reaches its agent's law as
    the ring ``ir`` reads (4 beams on a 0.2 hull, 0.04..2.5 m): beams 0, 2, 4, 6 of the
    scan less 0.2, clipped: 1.0 -> 0.8, inf (no echo, read 8.0) -> 2.5, 3.0 -> 2.5,
    0.1 -> 0.04; not the 1.0 on every beam the (stand-in) world process says. Its
    detect rule (the front beam below 0.9) reads it too: near at the first instant."""
    import hybridteam as ht
    from hybridteam.live.ros2_plant import RobotPlant, Ros2Plant
    from hybridteam.live.run import LiveRun
    from hybridteam.live.transport import UdpTransport
    from hybridteam.live.wire import READING, WORLD_INDEX

    ns = f"/{ros_name(f't{os.getpid()}_laser')}/robot"
    path = tmp_path / "laser.yaml"
    path.write_text(LASER_TEAM.replace("NS", ns))
    team = ht.load(path)
    robot = UnicycleRobot(
        ros,
        ns,
        scan={
            "angle_min": 0.0,
            "angle_increment": math.pi / 4,
            "range_min": 0.05,
            "range_max": 8.0,
            "ranges": [1.0, 2.0, math.inf, 0.1, 3.0, 4.0, 0.1, 1.5],
        },
    )
    transport = UdpTransport(("127.0.0.1", 0))
    world = UdpTransport(("127.0.0.1", 0), [transport.address])
    laser = Ros2Plant("robot", team.deploy["robot"], domain_id=DOMAIN, team=team.name)
    try:
        laser.pose(5.0)
        laser.scan(5.0)
        live = LiveRun(
            team,
            ["robot"],
            transport,
            plants={"robot": RobotPlant(laser, "unicycle")},
            plant_name="ros2",
        )
        world.send(
            live.codec.encode_world(
                READING, WORLD_INDEX, 0, 0, {f"ir.{k}": 1.0 for k in range(4)}, 0.0
            ),
            "data",
        )
        trace = live.run()
    finally:
        laser.close()
        transport.close()
        world.close()
        robot.close()
    memory = live.sim.ensemble.states[0].memory
    got = [float(memory[f"ir{k}"][0]) for k in range(4)]
    assert got == pytest.approx([1.0 - 0.2, 2.5, 2.5, 0.04])  # (float32 ranges: 1e-6)
    assert trace.outcomes[0]["outcome"] == "ok"
    rows = trace.transitions
    assert rows["target"].tolist() == ["Look", "Seen"] and rows["t"].tolist() == [0.0, 0.0]
