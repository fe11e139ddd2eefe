"""The ROS 2 transport and robot plant of the live runtime (hybridteam/live/ros2*.py).

The tests that talk over ROS 2 skip where rclpy cannot be imported (it comes with the
``ros`` extra: CPython 3.11 wheels for Linux x86_64); the names, quaternions, ranges and
deploy settings are checked everywhere. Every process uses its own ROS domain (from its
pid) with discovery kept on this machine, and every test its own team and topics, so
parallel runs and earlier tests are not heard.
"""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import threading
import time

import pytest

from hybridteam.errors import ModelError
from hybridteam.live.ros2 import SOCKET_DEPTH, Ros2Transport, ros_modules, ros_name
from hybridteam.live.ros2_plant import (
    PlantDeploy,
    PlantSilent,
    Scan,
    clipped_ranges,
    ring_ranges,
    yaw,
)
from hybridteam.world.sensors import RangeRing

# rclpy's type descriptions import lark, which imports sre_parse (deprecated in Python 3.11)
pytestmark = pytest.mark.filterwarnings("ignore:module 'sre_:DeprecationWarning")

DOMAIN = 1 + os.getpid() % 100  # 1..100: valid ROS domain ids on Linux


@pytest.fixture
def team(request):
    return f"t{os.getpid()}_{request.node.name}"


def until(condition, timeout: float = 5.0) -> bool:
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.002)
    return True


def collect(transport, count: int, timeout: float = 5.0) -> list[tuple[bytes, float]]:
    got: list[tuple[bytes, float]] = []
    deadline = time.monotonic() + timeout
    while len(got) < count and time.monotonic() < deadline:
        transport.wait(deadline - time.monotonic())
        got += transport.receive()
    return got


def pair(team, sockets=("data", "control")):
    a = Ros2Transport(team, "a", sockets, domain_id=DOMAIN)
    b = Ros2Transport(team, "b", sockets, domain_id=DOMAIN)
    assert until(lambda: all(t.peers(s) == 1 for t in (a, b) for s in sockets)), "no discovery"
    return a, b


# -- names, quaternions, ranges, settings: no ROS needed ------------------------------------


def test_names_fold_to_ros_tokens():
    assert ros_name("Experiment 2: ladder") == "Experiment_2_ladder"
    assert ros_name("scout-1") == "scout_1"
    assert ros_name("a__b_") == "a_b"  # ROS names have no repeated or trailing underscores
    assert ros_name("2nd team") == "_2nd_team"  # nor a leading digit
    with pytest.raises(ValueError, match="no letter or digit"):
        ros_name("--")


def test_yaw_of_hand_computed_quaternions():
    s45, c45 = math.sin(math.pi / 4), math.cos(math.pi / 4)
    assert yaw(0.0, 0.0, 0.0, 1.0) == 0.0
    assert yaw(0.0, 0.0, s45, c45) == pytest.approx(math.pi / 2, abs=1e-15)
    assert yaw(0.0, 0.0, 1.0, 0.0) == pytest.approx(math.pi, abs=1e-15)
    assert yaw(0.0, 0.0, -0.5, math.sqrt(3) / 2) == pytest.approx(-math.pi / 3, abs=1e-15)
    # not normalised: (0, 0, 2, 2) is a quarter turn too (2 (w z + x y) = 8, w^2 - z^2 = 0)
    assert yaw(0.0, 0.0, 2.0, 2.0) == pytest.approx(math.pi / 2, abs=1e-15)
    # a roll of 45 degrees about x turns nothing about z
    assert yaw(math.sin(math.pi / 8), 0.0, 0.0, math.cos(math.pi / 8)) == 0.0
    assert math.isnan(yaw(0.0, 0.0, 0.0, 0.0))


def test_scan_ranges_read_as_the_models_range_sensors():
    raw = [1.5, math.inf, math.nan, -math.inf, 0.05, 12.0, 0.1, 10.0]
    assert clipped_ranges(raw, 0.1, 10.0) == (1.5, 10.0, 10.0, 0.1, 0.1, 10.0, 0.1, 10.0)


def scan_of(ranges, angle_min: float, increment: float) -> Scan:
    return Scan(tuple(ranges), angle_min, increment, 0.0, 100.0, 0.0, 0.0)


def test_a_laser_scan_read_as_a_range_ring_by_hand():
    """Each ray of the ring reads the scan beam along its direction, less the mount
    radius (the laser at the centre, the sensor on the hull on that line), clipped to the
    ring's range; a direction the scan does not cover reads max_range."""
    ring = RangeRing(count=4, max_range=2.5, min_range=0.04, mount_radius=0.2)
    # 8 beams every 45 degrees from 0: the ring's (0, 90, 180, 270) are beams 0, 2, 4, 6
    full = scan_of([1.0, 2.0, 4.0, 0.1, 3.0, 4.0, 0.1, 1.5], 0.0, math.pi / 4)
    assert ring_ranges(full, ring).tolist() == pytest.approx(
        [1.0 - 0.2, 2.5, 2.5, 0.04]
    )  # 4.0 - 0.2 and 3.0 - 0.2 past 2.5; 0.1 - 0.2 below 0.04
    # a front laser (-45, 0, 45 degrees): the ring's sides and back are not covered
    front = scan_of([0.5, 0.3, 0.9], -math.pi / 4, math.pi / 4)
    assert ring_ranges(front, RangeRing(count=4, max_range=2.0)).tolist() == pytest.approx(
        [0.3, 2.0, 2.0, 2.0]
    )
    # clockwise beams (a negative increment): 180, 90, 0, -90 degrees
    clockwise = scan_of([1.0, 2.0, 3.0, 4.0], math.pi, -math.pi / 2)
    assert ring_ranges(clockwise, RangeRing(count=4, max_range=10.0)).tolist() == pytest.approx(
        [3.0, 2.0, 1.0, 4.0]
    )
    # a sonar cone (rays at -0.3, 0, 0.3 rad) over beams every 0.1 rad from -0.5: beams
    # 2, 5 and 8; it reads the nearest echo, less its mount radius
    ranges = [5.0] * 11
    ranges[2], ranges[5], ranges[8] = 0.7, 1.2, 0.9
    cone = RangeRing(count=1, max_range=3.0, mount_radius=0.1, half_angle=0.3, rays_per_beam=3)
    assert ring_ranges(scan_of(ranges, -0.5, 0.1), cone).tolist() == pytest.approx([0.6])
    assert ring_ranges(scan_of([], 0.0, 0.1), ring).tolist() == [2.5] * 4  # nothing seen


RINGS_TEAM = """
team: rings
world:
  - use: obstacles
    with:
      detect:
        - {agent: robot, sensor: ir, ring: {count: 4, max_range: 2.5, mount_radius: 0.2},
           below: 0.1, raise: near}
        - {agent: other, sensor: ir, ring: {count: 4, max_range: 2.5}, below: 0.1,
           raise: near}
agents:
  robot:
    plant: {kind: unicycle, state: {x: 0.0, y: 0.0, theta: 0.0}}
    initial: Look
    modes:
      Look: {inputs: {v: 0, omega: 0}, period: 0.1, transitions: [{to: Look, on: near}]}
  other:
    plant: {kind: unicycle, state: {x: 5.0, y: 0.0, theta: 0.0}}
    initial: Look
    modes:
      Look: {inputs: {v: 0, omega: 0}, period: 0.1, transitions: [{to: Look, on: near}]}
simulation: {duration: 1}
"""


def test_a_robots_laser_answers_its_rings_and_the_world_process_the_rest(team_from_yaml):
    """In a process hosting both agents, the robot with a laser reads its ring ``ir`` (4
    beams on a 0.2 hull, 2.5 range) from it; without a laser (no scan topic: None), and
    for the other agent, the ring is the world process's reading."""
    import numpy as np

    from hybridteam.engine.compile.compiler import compile_team
    from hybridteam.engine.run.simulator import Simulator
    from hybridteam.live.wire import READING, WORLD_INDEX, Codec
    from hybridteam.live.world import WorldLink, WorldReadings, world_seam
    from tests.live.test_live_world import Sent

    class Laser:
        def __init__(self, scan):
            self.scan = scan

        def ranges(self, ring):
            return None if self.scan is None else ring_ranges(self.scan, ring)

    cteam = compile_team(team_from_yaml(RINGS_TEAM))
    link = WorldLink(Codec(cteam, frozenset({"ir"})), Sent(), [0, 1], host=False)
    world = Simulator(cteam, 1, world=world_seam(WorldReadings, link)).ensemble.world
    for a in (0, 1):
        link.take(
            link.codec.decode(
                link.codec.encode_world(
                    READING, WORLD_INDEX, a, a, {f"ir.{k}": 1.5 + a for k in range(4)}, 1.0
                )
            )
        )
    # a laser every 90 degrees from 0: 0.5, 3, 0.9, 0.25
    world.read_lasers({0: Laser(scan_of([0.5, 3.0, 0.9, 0.25], 0.0, math.pi / 2))})
    idx = np.array([0])
    assert world.sense(0, idx, "ir").tolist() == [pytest.approx([0.3, 2.5, 0.7, 0.05])]
    assert world.sense(1, idx, "ir").tolist() == [[2.5] * 4]  # (the world's: 1.5 + 1)
    world.read_lasers({0: Laser(None)})
    assert world.sense(0, idx, "ir").tolist() == [[1.5] * 4]


def test_deploy_settings_checked_where_they_are():
    d = PlantDeploy.from_mapping({"cmd_vel": "/s/cmd_vel", "odom": "/s/odom"})
    assert (d.scan, d.frame, d.timeout) == (None, "odom", 2.0)
    where = ("deploy", "scout1")
    with pytest.raises(ModelError, match="missing 'odom'") as e:
        PlantDeploy.from_mapping({"cmd_vel": "/s/cmd_vel"}, where)
    assert e.value.path == where
    with pytest.raises(ModelError, match="did you mean 'scan'") as e:
        PlantDeploy.from_mapping({"cmd_vel": "/c", "odom": "/o", "scna": "/s"}, where)
    assert e.value.path == (*where, "scna")
    for bad in (0, -1.0, math.inf, True, "2"):
        with pytest.raises(ModelError, match="seconds > 0") as e:
            PlantDeploy.from_mapping({"cmd_vel": "/c", "odom": "/o", "timeout": bad}, where)
        assert e.value.path == (*where, "timeout")
    for bad in (3, "", "scout1/odom", "/scout 1/odom", "/scout1//odom", "/a__b", "/2nd/odom"):
        with pytest.raises(ModelError, match="topic's full name") as e:
            PlantDeploy.from_mapping({"cmd_vel": "/c", "odom": bad}, where)
        assert e.value.path == (*where, "odom")
    with pytest.raises(ModelError, match="frame name") as e:
        PlantDeploy.from_mapping({"cmd_vel": "/c", "odom": "/o", "frame": ""}, where)
    assert e.value.path == (*where, "frame")


def test_bad_sockets_namespaces_and_domains_refused_before_any_ros():
    with pytest.raises(ValueError, match="unknown socket 'radio'"):
        Ros2Transport("t", "a", ["data", "radio"])
    with pytest.raises(ValueError, match="no socket"):
        Ros2Transport("t", "a", [])
    for ns in ("hybridteam", "/2x", "/a__b", "/a b", "/", "/a//b"):
        with pytest.raises(ValueError, match="not a ROS namespace"):
            Ros2Transport("t", "a", ["data"], namespace=ns)
    for domain in (-1, 233, True, 1.5):
        with pytest.raises(ValueError, match=r"domain id must be an integer in 0\.\.232"):
            Ros2Transport("t", "a", ["data"], domain_id=domain)


def test_without_rclpy_one_error_says_what_to_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "rclpy", None)  # import rclpy now fails
    with pytest.raises(ImportError, match=r"pip install 'hybridteam\[ros\]'"):
        ros_modules()
    with pytest.raises(ImportError, match=r"hybridteam\[ros\]"):
        Ros2Transport("t", "a", ["data"])


# -- the transport over ROS 2 ---------------------------------------------------------------


def test_two_transports_exchange_datagrams_but_not_their_own(ros, team):
    a, b = pair(team)
    try:
        assert a.topics == {
            "data": f"/hybridteam/{ros_name(team)}/data",
            "control": f"/hybridteam/{ros_name(team)}/control",
        }
        sent = time.monotonic()
        a.send(b"\x00stream\xff", "data")
        a.send(b"control\x00", "control")
        b.send(b"answer", "control")
        at_b, at_a = collect(b, 2), collect(a, 1)
        done = time.monotonic()
        assert sorted(p for p, _ in at_b) == [b"\x00stream\xff", b"control\x00"]
        assert [p for p, _ in at_a] == [b"answer"]
        assert all(sent <= t <= done for _, t in at_a + at_b)
        time.sleep(0.2)  # anything more (an echo of one's own datagram) has arrived by now
        assert a.receive() == [] and b.receive() == []
    finally:
        a.close()
        b.close()


ECHO = """
import sys
from hybridteam.live.ros2 import Ros2Transport
team, domain = sys.argv[1], int(sys.argv[2])
with Ros2Transport(team, "echo", ["control"], domain_id=domain) as echo:
    while echo.peers("control") < 1:
        echo.wait(0.01)
    print("ready", flush=True)
    if not echo.wait(10.0):
        sys.exit("echo: nothing arrived")
    for payload, _ in echo.receive():
        echo.send(b"echo:" + payload, "control")
    sys.stdin.read()  # open until the test has its answer
"""


def test_agents_in_two_processes_hear_each_other(ros, team):
    proc = subprocess.Popen(
        [sys.executable, "-c", ECHO, team, str(DOMAIN)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    a = Ros2Transport(team, "a", ["control"], domain_id=DOMAIN)
    try:
        assert proc.stdout.readline() == "ready\n"
        assert until(lambda: a.peers("control") == 1)
        a.send(b"\x01ping", "control")
        assert [p for p, _ in collect(a, 1)] == [b"echo:\x01ping"]
    finally:
        a.close()
        try:
            proc.communicate(timeout=15)
        finally:
            proc.kill()  # a no-op once it has exited
    assert proc.returncode == 0


def test_wait_times_out_or_wakes_on_arrival(ros, team):
    a, b = pair(team, ("data",))
    try:
        t0 = time.monotonic()
        assert b.wait(0.05) is False
        assert time.monotonic() - t0 >= 0.05
        sender = threading.Timer(0.1, a.send, (b"late", "data"))
        sender.start()
        t0 = time.monotonic()
        assert b.wait(10.0) is True
        assert time.monotonic() - t0 < 2.0  # woken by the arrival, not by the timeout
        sender.join()
        assert b.wait(0.0) is True  # still waiting to be taken
        assert [p for p, _ in b.receive()] == [b"late"]
        assert b.wait(0.0) is False
    finally:
        a.close()
        b.close()


def test_a_burst_on_either_socket_is_kept_while_the_reader_is_busy(ros, team):
    """40 datagrams published while the reader's executor is held up (its callback waits
    on the transport's lock, as a loaded machine holds it up) all reach ``receive``, in
    order, on either socket: the topic's history is shared by every sender and kind (an
    instant's streams and world poses from every teammate at once), as a UDP socket's
    buffer is, and a burst that outgrows it would lose the oldest."""
    for socket in ("data", "control"):
        a, b = pair(f"{team}_{socket}", [socket])
        try:
            burst = [f"{socket} {k}".encode() for k in range(40)]
            with b._lock:  # (the executor's first callback waits here)
                for payload in burst:
                    a.send(payload, socket)
                time.sleep(0.3)  # (every one delivered to the reader's history)
            assert [p for p, _ in collect(b, 40)] == burst, socket
        finally:
            a.close()
            b.close()


def test_each_socket_has_its_documented_qos(ros, team):
    from rclpy.qos import DurabilityPolicy, ReliabilityPolicy

    a = Ros2Transport(team, "a", ["data", "control"], domain_id=DOMAIN)
    ctx = ros.Context()
    ros.init(context=ctx, domain_id=DOMAIN)
    observer = ros.create_node("observer", context=ctx)
    try:
        for socket, depth in (("data", 64), ("control", 64)):
            assert SOCKET_DEPTH[socket] == depth
            topic = a.topics[socket]

            # what the graph announces to every other participant
            def ends(topic=topic):
                return [
                    *observer.get_publishers_info_by_topic(topic),
                    *observer.get_subscriptions_info_by_topic(topic),
                ]

            assert until(lambda ends=ends: len(ends()) == 2), "no discovery"
            for end in ends():
                assert end.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT
                assert end.qos_profile.durability == DurabilityPolicy.VOLATILE
            assert a._publishers[socket].qos_profile.depth == depth  # history is not announced
    finally:
        a.close()
        observer.destroy_node()
        ctx.try_shutdown()


def test_close_is_clean_and_idempotent(ros, team):
    before = set(threading.enumerate())
    a, b = pair(team)
    assert len(set(threading.enumerate()) - before) == 2  # one executor thread each
    a.close()
    b.close()
    a.close()
    assert set(threading.enumerate()) == before
    with pytest.raises(RuntimeError, match="after close"):
        a.send(b"x", "data")
    # a context handed in is its owner's to shut down
    ctx = ros.Context()
    ros.init(context=ctx, domain_id=DOMAIN)
    c = Ros2Transport(team, "c", ["data"], context=ctx)
    c.close()
    assert ctx.ok()
    ctx.try_shutdown()
    assert set(threading.enumerate()) == before


def test_oversized_datagrams_and_storms_are_dropped_and_counted(ros, team):
    """Anyone on the domain may publish on a team's topic: a datagram too large for UDP, and
    datagrams beyond what may wait, are dropped and counted, as a UDP socket drops them."""
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from std_msgs.msg import UInt8MultiArray

    b = Ros2Transport(team, "b", ["control"], domain_id=DOMAIN, max_waiting=3)
    ctx = ros.Context()
    ros.init(context=ctx, domain_id=DOMAIN)
    stranger = ros.create_node("stranger", context=ctx)
    try:
        topic = b.topics["control"]
        qos = QoSProfile(depth=64, reliability=ReliabilityPolicy.BEST_EFFORT)
        pub = stranger.create_publisher(UInt8MultiArray, topic, qos)
        stranger.create_subscription(UInt8MultiArray, topic, lambda _msg: None, qos)
        assert until(lambda: b.peers("control") == 1 and pub.get_subscription_count() == 2)

        def publish(payload: bytes) -> None:
            msg = UInt8MultiArray()
            msg.data = payload
            pub.publish(msg)

        publish(bytes(65508))  # one byte more than a UDP datagram carries
        assert until(lambda: b.dropped["oversized"] == 1)
        publish(bytes(65507))
        assert [len(p) for p, _ in collect(b, 1)] == [65507]
        for i in range(5):
            publish(b"storm %d" % i)
            time.sleep(0.005)
        assert until(lambda: b.dropped["overflow"] == 2)
        assert [p for p, _ in b.receive()] == [b"storm 0", b"storm 1", b"storm 2"]
        with pytest.raises(ValueError, match="65508 bytes; at most 65507"):
            b.send(bytes(65508), "control")
    finally:
        b.close()
        stranger.destroy_node()
        ctx.try_shutdown()


def test_ctrl_c_is_the_runtimes_and_leaves_the_transport_open(ros, team):
    """rclpy's own SIGINT handler would shut the context down under the live runtime while
    it still writes its trace: a transport's own context does not install it."""
    a, b = pair(team, ("control",))
    try:
        with pytest.raises(KeyboardInterrupt):
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(5.0)  # the interrupt comes first
        a.send(b"after ctrl-c", "control")
        assert [p for p, _ in collect(b, 1)] == [b"after ctrl-c"]
    finally:
        a.close()
        b.close()


# -- the robot plant against a fake robot ---------------------------------------------------


class FakeRobot:
    """A robot driver in the test: publishes Odometry and LaserScan every 10 ms, records
    the Twists it is sent."""

    def __init__(self, ros, ns: str, *, frame: str = "odom") -> None:
        from geometry_msgs.msg import Twist
        from nav_msgs.msg import Odometry
        from rclpy.executors import SingleThreadedExecutor
        from sensor_msgs.msg import LaserScan

        self.ctx = ros.Context()
        ros.init(context=self.ctx, domain_id=DOMAIN)
        self.node = ros.create_node("fake_robot", context=self.ctx)
        self.twists: list = []
        odom = Odometry()
        odom.header.frame_id = frame
        odom.header.stamp.sec, odom.header.stamp.nanosec = 12, 250_000_000
        odom.pose.pose.position.x, odom.pose.pose.position.y = 1.0, -2.0
        q = odom.pose.pose.orientation  # a heading of 150 degrees: (z, w) = (sin 75, cos 75)
        q.z, q.w = math.sin(math.radians(75)), math.cos(math.radians(75))
        scan = LaserScan()
        scan.header.stamp.sec = 13
        scan.angle_min, scan.angle_increment = -0.75, 0.75  # exact in float32
        scan.range_min, scan.range_max = 0.2, 8.0
        scan.ranges = [2.5, math.inf, math.nan]
        odom_pub = self.node.create_publisher(Odometry, f"{ns}/odom", 10)
        scan_pub = self.node.create_publisher(LaserScan, f"{ns}/scan", 10)
        self.node.create_subscription(Twist, f"{ns}/cmd_vel", self.twists.append, 10)
        self.node.create_timer(0.01, lambda: (odom_pub.publish(odom), scan_pub.publish(scan)))
        self.executor = SingleThreadedExecutor(context=self.ctx)
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self.executor.spin)
        self.thread.start()

    def close(self) -> None:
        self.executor.shutdown()
        self.thread.join()
        self.node.destroy_node()
        self.ctx.try_shutdown()


def deploy(ns: str, **more) -> dict:
    return {"cmd_vel": f"{ns}/cmd_vel", "odom": f"{ns}/odom", "scan": f"{ns}/scan", **more}


def twist(t) -> tuple[float, ...]:
    return (t.linear.x, t.linear.y, t.linear.z, t.angular.x, t.angular.y, t.angular.z)


def test_plant_reads_the_robots_pose_and_scan_and_drives_it(ros, team):
    from hybridteam.live.ros2_plant import Ros2Plant

    ns = f"/{ros_name(team)}/scout1"
    before = set(threading.enumerate())
    robot = FakeRobot(ros, ns)
    plant = Ros2Plant("scout1", deploy(ns), domain_id=DOMAIN)
    try:
        pose = plant.pose(timeout=5.0)
        assert (pose.x, pose.y) == (1.0, -2.0)
        assert pose.theta == pytest.approx(math.radians(150), abs=1e-12)
        assert pose.stamp == 12.25
        assert pose.received <= time.monotonic()
        scan = plant.scan(timeout=5.0)
        assert scan.ranges == (2.5, 8.0, 8.0)
        assert (scan.angle_min, scan.angle_increment) == (-0.75, 0.75)
        assert scan.stamp == 13.0

        assert until(lambda: plant._cmd.get_subscription_count() == 1)
        # one at a time: the command writer keeps only the newest, as a driver wants it
        plant.command({"v": 0.5, "omega": -0.25})
        assert until(lambda: len(robot.twists) == 1)
        plant.command({"vx": 0.3, "vy": -0.2, "omega": 0.1})
        assert until(lambda: len(robot.twists) == 2)
        assert [twist(t) for t in robot.twists] == [
            (0.5, 0.0, 0.0, 0.0, 0.0, -0.25),
            (0.3, -0.2, 0.0, 0.0, 0.0, 0.1),
        ]
        for bad in ({"v": math.nan}, {"speed": 1.0}, {"v": 1.0, "vy": 1.0}):
            with pytest.raises(ValueError):
                plant.command(bad)
        plant.close()  # stops the robot
        assert until(lambda: len(robot.twists) == 3)
        assert twist(robot.twists[-1]) == (0.0,) * 6
    finally:
        plant.close()
        robot.close()
    assert set(threading.enumerate()) == before


def test_plant_says_when_no_odometry_arrives(ros, team):
    from hybridteam.live.ros2_plant import Ros2Plant

    ns = f"/{ros_name(team)}/scout1"
    with Ros2Plant("scout1", deploy(ns, timeout=0.2), domain_id=DOMAIN) as plant:
        t0 = time.monotonic()
        with pytest.raises(
            PlantSilent,
            match=f"no odometry on {ns}/odom within 0.2 s; is the robot's driver running",
        ):
            plant.pose()
        assert time.monotonic() - t0 >= 0.2
    # odometry in another frame than the deploy setting's is no pose: dropped, and said
    robot = FakeRobot(ros, ns, frame="map")
    try:
        with Ros2Plant("scout1", deploy(ns), domain_id=DOMAIN) as plant:
            assert until(lambda: plant.dropped["frame"] > 0)
            with pytest.raises(PlantSilent, match=r"arrived in frame 'map', not 'odom'"):
                plant.pose(timeout=0.1)
    finally:
        robot.close()


HANDSHAKE = os.path.join(
    os.path.dirname(os.path.dirname(__file__)), "fixtures", "live", "handshake.yaml"
)


def test_launch_over_ros2_shakes_hands_as_the_simulation_does(ros, tmp_path):
    """``hybridteam launch --transport ros2``: one process per agent, their datagrams on
    ROS 2 topics; every agent's transitions, and the team's order of them across the two
    processes, are those of ``hybridteam run`` of the same file, as over UDP."""
    import hybridteam as ht
    from hybridteam.trace import Trace

    out = tmp_path / "launch"
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "hybridteam.cli",
            "launch",
            HANDSHAKE,
            "--transport",
            "ros2",
            "--time-scale",
            "4",
            "-o",
            str(out),
        ],
        capture_output=True,
        timeout=180,
    )
    assert proc.returncode == 0, proc.stderr.decode()
    merged = Trace.load(out / "trace.json")
    sim = ht.simulate(ht.load(HANDSHAKE))
    for agent in ("requester", "granter"):
        assert [(r.source, r.target, r.cause) for r in merged.transitions if r.agent == agent] == [
            (r.source, r.target, r.cause) for r in sim.transitions if r.agent == agent
        ]
    assert [(r.agent, r.target) for r in merged.transitions if r.cause != "init"] == [
        (r.agent, r.target) for r in sim.transitions if r.cause != "init"
    ]
    assert merged.outcomes[0]["outcome"] == "ok"
    assert {p["transport"] for p in merged.meta["live"]["processes"]} == {"ros2"}


def test_experiment2_launched_over_ros2_hands_over_as_the_simulation_does(ros, tmp_path):
    """The issue's acceptance over ``ros2``: the world process, the robots and the
    operator, each a process whose team datagrams and world poses and readings travel on
    ROS 2 topics, end ``success``, each agent's modes those of ``hybridteam run`` with the
    latency measured in this run, every transition within two control periods
    (:func:`tests.live.test_live_world.launched_as_simulated`, the UDP test's check). Its own
    domain (101..200: apart from the other ROS tests' 1..100). At time scale 2, not the
    UDP test's 4: the two periods are 0.1 run seconds, 25 ms of wall time at 4, and five
    processes with their ROS 2 executor threads on two cores ran the hand-overs 0.134 s
    late at 4 in a clean checkout's CI run; at 2 they have 50 ms of wall time, the
    tolerance in run time unchanged. A copy the topic lost is allowed for as in the UDP
    test (the next run here lost the first ``docked`` copy: its resend 0.1 s later)"""
    import importlib.util

    import hybridteam as ht
    from tests.live.test_live_world import EXPERIMENT2, launched_as_simulated

    if importlib.util.find_spec("hybridteam.protocols") is None:
        pytest.skip(
            "hybridteam's shipped protocols (experiment 2 uses one) are not "
            "importable: hybridteam is not installed in this interpreter "
            "(pip install -e .)"
        )
    launched_as_simulated(
        tmp_path / "launch",
        ht.load(EXPERIMENT2),
        ["--transport", "ros2", "--domain-id", str(101 + os.getpid() % 100)],
        time_scale=2,
    )
    merged = json.loads((tmp_path / "launch" / "summary.json").read_text())
    processes = merged["live"]["processes"]
    assert {p["transport"] for p in processes} == {"ros2"}
    assert [p["world"] for p in processes].count(True) == 1  # (the world process's too)


def test_a_process_stopped_after_writing_its_folder_left_its_trace(tmp_path):
    """launch stops the processes still running once the end rule's have ended; one that
    had ended too and written its folder may get that SIGTERM while it tears its ROS 2
    nodes down. Its folder is complete (summary.json, written last, is there): its trace
    counts. One killed before it wrote, or that exited with an error, left none."""
    from hybridteam.cli.live import left_no_trace

    for name, files in {
        "done": ("trace.json", "summary.json", "live.log"),
        "cut": ("trace.json", "live.log"),
        "broke": ("live.log",),
    }.items():
        (tmp_path / name).mkdir()
        for f in files:
            (tmp_path / name / f).write_text("{}" if f.endswith(".json") else "boom\n")
    assert left_no_trace(
        {"done": -signal.SIGTERM, "cut": -signal.SIGTERM, "broke": 2}, tmp_path
    ) == {"cut": "killed by SIGTERM", "broke": "exit status 2: boom"}


def test_waiting_for_teammates_that_never_come_is_one_line(monkeypatch):
    """A process told to wait for more ROS 2 teammates than discovery finds says so in one
    line once the start timeout passes (a transport here that never matches anyone)."""
    from hybridteam.cli import live
    from hybridteam.cli.common import UsageError

    class Alone:
        def peers(self, socket):
            return 0

    monkeypatch.setattr(live, "START_TIMEOUT", 0.05)
    with pytest.raises(
        UsageError,
        match=r"^--ros-peers 2: only 0 found within 0.05 s "
        r"\(same --domain-id\?\)$",
    ):
        live.wait_for_peers(Alone(), 2)
    live.wait_for_peers(Alone(), 0)  # nobody to wait for: at once
