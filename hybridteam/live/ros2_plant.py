"""A robot on ROS 2 as an agent's plant: velocity commands out, pose and ranges in.

A live agent whose plant is a real robot (or a robot simulator) does not integrate its
kinematics: it publishes the law's input as a ``geometry_msgs/msg/Twist`` and reads its
state back from the robot's ``nav_msgs/msg/Odometry``, its range readings from a
``sensor_msgs/msg/LaserScan``. What to talk to is one agent's ``deploy`` settings
(:class:`~hybridteam.model.deploy.PlantDeploy`: the team file's ``deploy:`` section, one
entry per agent: its ``cmd_vel``, ``odom`` and ``scan`` topics, its odometry ``frame`` and
how long odometry may be ``timeout`` silent).

**Commands.** The input keeps the plant's names: a unicycle's ``v`` and ``omega`` become
``linear.x`` and ``angular.z``, a holonomic base's ``vx``, ``vy`` and ``omega`` become
``linear.x``, ``linear.y`` and ``angular.z`` (body frame, m/s and rad/s, as REP 103 and the
model both have them). A non-finite input is refused rather than sent to a motor driver.
:meth:`Ros2Plant.close` publishes a zero Twist first: a robot whose agent stops must not
keep driving on its last command. Commands go out reliable, keeping the last one only (a
reliable writer is heard by reliable and best-effort drivers alike; an older command is
worth nothing once a newer one is out).

**Pose.** ``(x, y, theta)`` from the odometry pose, ``theta`` the yaw of its quaternion,
``atan2(2 (w z + x y), w^2 + x^2 - y^2 - z^2)``: this form needs no normalised quaternion
(both arguments scale alike), and for a robot on the floor (roll and pitch zero) it is the
heading. An Odometry in another frame than ``frame``, or with no orientation (a zero or
non-finite quaternion, a non-finite position), is dropped and counted: a pose in the wrong
frame is a wrong pose. :meth:`Ros2Plant.pose` is the latest pose with its stamp; when none
has arrived within ``timeout`` it raises :class:`PlantSilent`, which says how many were
dropped for their frame.

**Ranges.** The latest scan's ranges clipped to ``[range_min, range_max]`` as the model's
range sensors are: ``+inf`` (no echo, REP 117) and NaN (no valid reading) read as
``range_max``, ``-inf`` (an object closer than the sensor can see) as ``range_min``.

Odometry and scans are read best-effort (heard from reliable and best-effort publishers
alike), keeping the last 5: only the latest matters.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable, Mapping
from typing import Any, NamedTuple

import numpy as np

from hybridteam.live.ros2 import DEFAULT_NAMESPACE, SpunNode, ros_name
from hybridteam.model.deploy import PlantDeploy

__all__ = ["PlantDeploy", "PlantSilent", "Pose", "RobotPlant", "Ros2Plant", "Scan",
           "clipped_ranges", "yaw"]

log = logging.getLogger(__name__)

#: law input name -> (Twist field, component)
TWIST_FIELDS = {"v": ("linear", "x"), "vx": ("linear", "x"), "vy": ("linear", "y"),
                "omega": ("angular", "z")}

#: seconds :meth:`Ros2Plant.close` waits for reliable drivers to acknowledge the stop
STOP_ACK_WAIT = 0.5

class Pose(NamedTuple):
    """A robot's pose from odometry: ``stamp`` is the message's (the robot's clock, in
    seconds), ``received`` its arrival on this machine's ``time.monotonic()``."""

    x: float
    y: float
    theta: float
    stamp: float
    received: float


class Scan(NamedTuple):
    """A laser scan's ranges (clipped, see :func:`clipped_ranges`), beam ``i`` at angle
    ``angle_min + i * angle_increment`` from the sensor's heading."""

    ranges: tuple[float, ...]
    angle_min: float
    angle_increment: float
    range_min: float
    range_max: float
    stamp: float
    received: float


class PlantSilent(TimeoutError):
    """The robot said nothing on a topic within the timeout."""


def yaw(x: float, y: float, z: float, w: float) -> float:
    """The heading of quaternion ``(x, y, z, w)``: rotation about z, in (-pi, pi]; it need
    not be normalised. NaN for the zero quaternion (no orientation at all)."""
    s, c = 2.0 * (w * z + x * y), w * w + x * x - y * y - z * z
    if s == 0.0 and c == 0.0 and x == y == z == w == 0.0:
        return math.nan
    return math.atan2(s, c)


def clipped_ranges(ranges: Any, range_min: float, range_max: float) -> tuple[float, ...]:
    """LaserScan ranges as the model's range sensors read: clipped to ``[range_min,
    range_max]``, ``+inf`` and NaN as ``range_max``, ``-inf`` as ``range_min`` (REP 117)."""
    values = np.asarray(ranges, dtype=float)
    values = np.where(np.isnan(values), range_max, values)
    return tuple(np.clip(values, range_min, range_max).tolist())


def _seconds(stamp: Any) -> float:
    return stamp.sec + stamp.nanosec * 1e-9


class _Latest:
    """The newest value of one topic, and a way to wait for one fresh enough."""

    def __init__(self) -> None:
        self.value: Any = None
        self._fresh = threading.Condition()

    def put(self, value: Any) -> None:
        with self._fresh:
            self.value = value
            self._fresh.notify_all()

    def get(self, max_age: float) -> Any:
        """The newest value received within ``max_age`` s, waiting at most ``max_age`` s
        for one; None if there is none."""
        deadline = time.monotonic() + max_age
        with self._fresh:
            while True:
                now = time.monotonic()
                if self.value is not None and now - self.value.received <= max_age:
                    return self.value
                if now >= deadline:
                    return None
                self._fresh.wait(deadline - now)


class Ros2Plant:
    """One agent's robot over ROS 2 topics: :meth:`command` out, :meth:`pose` and
    :meth:`scan` in (module docstring)."""

    def __init__(self, agent: str, deploy: Mapping[str, Any] | PlantDeploy, *,
                 domain_id: int | None = None, context: Any = None,
                 team: str | None = None) -> None:
        self.agent = agent
        self.deploy = d = (deploy if isinstance(deploy, PlantDeploy)
                           else PlantDeploy.from_mapping(deploy, ("deploy", agent)))
        self.dropped = {"frame": 0, "invalid": 0}  # odometry messages refused, by reason
        self._foreign_frames: set[str] = set()
        self._pose, self._scan = _Latest(), _Latest()
        where = DEFAULT_NAMESPACE + (f"/{ros_name(team)}" if team is not None else "")
        self._spun = SpunNode(f"{ros_name(agent)}_plant", where, domain_id=domain_id,
                              context=context)
        try:
            from geometry_msgs.msg import Twist
            from nav_msgs.msg import Odometry
            from sensor_msgs.msg import LaserScan
        except ImportError:
            self._spun.close()
            raise ImportError("the ros2 plant needs the ROS 2 message packages: "
                              "pip install 'hybridteam[ros]'") from None

        self._Twist = Twist
        q = self._spun.ros.qos
        readings = q.QoSProfile(depth=5, reliability=q.ReliabilityPolicy.BEST_EFFORT,
                                durability=q.DurabilityPolicy.VOLATILE)
        commands = q.QoSProfile(depth=1, reliability=q.ReliabilityPolicy.RELIABLE,
                                durability=q.DurabilityPolicy.VOLATILE)
        node = self._spun.node
        try:
            self._cmd = node.create_publisher(Twist, d.cmd_vel, commands)
            self._subscriptions = [node.create_subscription(Odometry, d.odom, self._on_odom,
                                                            readings)]
            if d.scan is not None:
                self._subscriptions.append(
                    node.create_subscription(LaserScan, d.scan, self._on_scan, readings))
        except Exception:
            self._spun.close()
            raise

    def _on_odom(self, msg: Any) -> None:
        received = time.monotonic()
        if msg.header.frame_id != self.deploy.frame:
            self.dropped["frame"] += 1
            if msg.header.frame_id not in self._foreign_frames:
                self._foreign_frames.add(msg.header.frame_id)
                log.warning("%s: odometry on %s is in frame %r, not %r: dropped", self.agent,
                            self.deploy.odom, msg.header.frame_id, self.deploy.frame)
            return
        p, o = msg.pose.pose.position, msg.pose.pose.orientation
        theta = yaw(o.x, o.y, o.z, o.w)
        if not all(math.isfinite(v) for v in (p.x, p.y, theta)):
            self.dropped["invalid"] += 1
            return
        self._pose.put(Pose(p.x, p.y, theta, _seconds(msg.header.stamp), received))

    def _on_scan(self, msg: Any) -> None:
        received = time.monotonic()
        self._scan.put(Scan(clipped_ranges(msg.ranges, msg.range_min, msg.range_max),
                            msg.angle_min, msg.angle_increment, msg.range_min, msg.range_max,
                            _seconds(msg.header.stamp), received))

    def command(self, inputs: Mapping[str, float]) -> None:
        """Publish the law's input (``v``/``omega`` or ``vx``/``vy``/``omega``) as a Twist;
        components not given are zero."""
        if "v" in inputs and ("vx" in inputs or "vy" in inputs):
            raise ValueError(f"{self.agent}: give either v (unicycle) or vx, vy (holonomic)")
        msg = self._Twist()
        for name, value in inputs.items():
            if name not in TWIST_FIELDS:
                raise ValueError(f"{self.agent}: no Twist field for input {name!r}; a robot "
                                 f"takes {', '.join(TWIST_FIELDS)}")
            if not math.isfinite(value):
                raise ValueError(f"{self.agent}: input {name} = {value} is not finite; "
                                 "not sent to the robot")
            group, axis = TWIST_FIELDS[name]
            setattr(getattr(msg, group), axis, float(value))
        self._cmd.publish(msg)

    def pose(self, timeout: float | None = None) -> Pose:
        """The latest odometry pose, waiting for one up to ``timeout`` s (the deploy
        setting by default); :class:`PlantSilent` if none arrived within that time."""
        wait = self.deploy.timeout if timeout is None else timeout
        pose = self._pose.get(wait)
        if pose is None:
            why = (f"{self.dropped['frame']} arrived in frame "
                   f"{', '.join(map(repr, sorted(self._foreign_frames)))}, not "
                   f"{self.deploy.frame!r}" if self.dropped["frame"] else
                   "is the robot's driver running, on this ROS_DOMAIN_ID?")
            raise PlantSilent(f"{self.agent}: no odometry on {self.deploy.odom} within "
                              f"{wait:g} s; {why}")
        return pose

    def scan(self, timeout: float | None = None) -> Scan:
        """The latest laser scan, waiting for one up to ``timeout`` s (the deploy setting by
        default); :class:`PlantSilent` if none arrived within that time."""
        if self.deploy.scan is None:
            raise ValueError(f"{self.agent}: no scan topic in its deploy settings")
        wait = self.deploy.timeout if timeout is None else timeout
        scan = self._scan.get(wait)
        if scan is None:
            raise PlantSilent(f"{self.agent}: no laser scan on {self.deploy.scan} within "
                              f"{wait:g} s")
        return scan

    def close(self) -> None:
        """Stop the robot (a zero Twist), then release the node. Idempotent."""
        if not self._spun.closed:
            self._cmd.publish(self._Twist())
            # reliable readers acknowledge it; best-effort ones got it or never will
            self._cmd.wait_for_all_acked(self._spun.ros.Duration(seconds=STOP_ACK_WAIT))
        self._spun.close()

    def __enter__(self) -> Ros2Plant:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class RobotPlant:
    """A :class:`Ros2Plant` as an agent's external plant in the engine
    (:mod:`hybridteam.engine.run.plant`): the held inputs out as a Twist at every instant, the
    latest odometry pose in wherever the engine needs the agent's state.

    Only a unicycle agent is driven so: its inputs ``(v, omega)`` are body-frame, as a
    Twist's are, and its state ``(x, y, theta)`` is an odometry pose. A holonomic agent's
    ``(vx, vy)`` are world-frame (:mod:`hybridteam.dynamics.plants`) and would need turning
    into the body frame first; it is refused rather than driven wrongly.

    A robot whose odometry falls silent for its ``timeout`` ends the run rather than
    breaking it: ``on_silent`` is told why (a live run's stop request: the run ends at its
    next wait, ``stopped``, its trace complete) and the last pose stands until then.
    """

    def __init__(self, robot: Ros2Plant, kind: str,
                 on_silent: Callable[[str], None] | None = None) -> None:
        self.check(robot.agent, kind)
        self.robot = robot
        self.on_silent = on_silent
        self.last: np.ndarray | None = None  # the last pose read
        self.silent = False

    @staticmethod
    def check(agent: str, kind: str) -> None:
        """ValueError unless agent ``agent``'s plant ``kind`` is one a robot drives."""
        if kind != "unicycle":
            raise ValueError(f"agent '{agent}' has a {kind} plant; a robot over ROS 2 "
                             "drives a unicycle agent (v, omega as a Twist; x, y, theta "
                             "from odometry)")

    def command(self, inputs: np.ndarray, t: float) -> None:
        v, omega = inputs.tolist()
        self.robot.command({"v": v, "omega": omega})

    def state(self, t: float) -> np.ndarray:
        """The latest pose (:meth:`Ros2Plant.pose`). Once odometry has been silent for
        the deploy setting's timeout, the last pose, ``on_silent`` told why (once); without
        ``on_silent``, or before any pose, :class:`PlantSilent`."""
        if self.silent:
            assert self.last is not None
            return self.last
        try:
            pose = self.robot.pose()
        except PlantSilent as exc:
            if self.on_silent is None or self.last is None:
                raise
            self.silent = True
            log.warning("%s", exc)
            self.on_silent(str(exc))
            return self.last
        self.last = np.array([pose.x, pose.y, pose.theta])
        return self.last
