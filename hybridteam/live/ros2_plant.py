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
``linear.x``, ``linear.y`` and ``angular.z`` (body frame, m/s and rad/s, as REP 103 has
them: :class:`RobotPlant` turns a holonomic model's world-frame velocity into the body
frame before it comes here). A non-finite input is refused rather than sent to a motor driver.
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

**The laser as the model's range rings.** A law reads its robot's range ring ``ir`` with
``ctx.sense("ir")`` (:mod:`hybridteam.world.obstacles`); with a ``scan`` topic, the agent
reads the ring from the robot's laser instead of the world process's ray casting
(:meth:`RobotPlant.ranges`, :func:`ring_ranges`): each of the ring's rays reads the scan
beam nearest its direction, less the ring's mount radius, the nearest of a cone's rays,
clipped to the ring's ``[min_range, max_range]``. The scan is taken in the robot's base
frame: the laser at its centre, facing its heading, so a ray of a sensor on the hull
(``mount_radius`` out, looking radially) lies on the laser's beam of the same direction
and reads that beam less the mount radius; a cone's off-centre rays are read the same
way (exact on its centre line). A direction the scan does not cover (farther than half
an increment from every beam) reads ``max_range``, nothing seen, as the ring reads where
nothing is in range. The robot's detect rules run on these readings in its agent's
process (:meth:`hybridteam.live.world.WorldReadings.detect_on_lasers`).

Odometry and scans are read best-effort (heard from reliable and best-effort publishers
alike), keeping the last 5: only the latest matters.
"""

from __future__ import annotations

import functools
import logging
import math
import threading
import time
from collections.abc import Callable, Mapping
from typing import Any, NamedTuple

import numpy as np

from hybridteam.live.ros2 import DEFAULT_NAMESPACE, SpunNode, ros_name
from hybridteam.model.deploy import PlantDeploy
from hybridteam.world.sensors import RangeRing

__all__ = [
    "ROBOT_KINDS",
    "PlantDeploy",
    "PlantSilent",
    "Pose",
    "RobotPlant",
    "Ros2Plant",
    "Scan",
    "body_velocity",
    "clipped_ranges",
    "ring_ranges",
    "yaw",
]

log = logging.getLogger(__name__)

#: law input name -> (Twist field, component)
TWIST_FIELDS = {
    "v": ("linear", "x"),
    "vx": ("linear", "x"),
    "vy": ("linear", "y"),
    "omega": ("angular", "z"),
}

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


@functools.lru_cache(maxsize=64)
def _beams_of(
    ring: RangeRing, angle_min: float, increment: float, count: int
) -> tuple[np.ndarray, np.ndarray]:
    """For each ray of ``ring`` ``(count, rays_per_beam)``: the scan beam nearest its
    direction, and whether that beam is within half an increment of it (the scan covers
    it). A scan's geometry does not change between its messages: computed once per ring."""
    beams = angle_min + increment * np.arange(count)
    diff = np.abs((ring.ray_angles[..., None] - beams + math.pi) % (2.0 * math.pi) - math.pi)
    nearest = diff.argmin(axis=-1)
    gap = np.take_along_axis(diff, nearest[..., None], axis=-1)[..., 0]
    return nearest, gap <= abs(increment) / 2.0 + 1e-9


def ring_ranges(scan: Scan, ring: RangeRing) -> np.ndarray:
    """The readings ``(count,)`` of range ring ``ring`` taken from the laser ``scan``
    (module docstring, *The laser as the model's range rings*)."""
    if not scan.ranges:
        return np.full(ring.count, float(ring.max_range))
    nearest, covered = _beams_of(ring, scan.angle_min, scan.angle_increment, len(scan.ranges))
    rays = np.where(covered, np.asarray(scan.ranges)[nearest] - ring.mount_radius, ring.max_range)
    return np.clip(rays.min(axis=1), ring.min_range, ring.max_range)


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

    def __init__(
        self,
        agent: str,
        deploy: Mapping[str, Any] | PlantDeploy,
        *,
        domain_id: int | None = None,
        context: Any = None,
        team: str | None = None,
    ) -> None:
        self.agent = agent
        self.deploy = d = (
            deploy
            if isinstance(deploy, PlantDeploy)
            else PlantDeploy.from_mapping(deploy, ("deploy", agent))
        )
        self.dropped = {"frame": 0, "invalid": 0}  # odometry messages refused, by reason
        self._foreign_frames: set[str] = set()
        self._pose, self._scan = _Latest(), _Latest()
        where = DEFAULT_NAMESPACE + (f"/{ros_name(team)}" if team is not None else "")
        self._spun = SpunNode(
            f"{ros_name(agent)}_plant", where, domain_id=domain_id, context=context
        )
        try:
            from geometry_msgs.msg import Twist
            from nav_msgs.msg import Odometry
            from sensor_msgs.msg import LaserScan
        except ImportError:
            self._spun.close()
            raise ImportError(
                "the ros2 plant needs the ROS 2 message packages: pip install 'hybridteam[ros]'"
            ) from None

        self._Twist = Twist
        q = self._spun.ros.qos
        readings = q.QoSProfile(
            depth=5,
            reliability=q.ReliabilityPolicy.BEST_EFFORT,
            durability=q.DurabilityPolicy.VOLATILE,
        )
        commands = q.QoSProfile(
            depth=1,
            reliability=q.ReliabilityPolicy.RELIABLE,
            durability=q.DurabilityPolicy.VOLATILE,
        )
        node = self._spun.node
        try:
            self._cmd = node.create_publisher(Twist, d.cmd_vel, commands)
            self._subscriptions = [
                node.create_subscription(Odometry, d.odom, self._on_odom, readings)
            ]
            if d.scan is not None:
                self._subscriptions.append(
                    node.create_subscription(LaserScan, d.scan, self._on_scan, readings)
                )
        except Exception:
            self._spun.close()
            raise

    def _on_odom(self, msg: Any) -> None:
        received = time.monotonic()
        if msg.header.frame_id != self.deploy.frame:
            self.dropped["frame"] += 1
            if msg.header.frame_id not in self._foreign_frames:
                self._foreign_frames.add(msg.header.frame_id)
                log.warning(
                    "%s: odometry on %s is in frame %r, not %r: dropped",
                    self.agent,
                    self.deploy.odom,
                    msg.header.frame_id,
                    self.deploy.frame,
                )
            return
        p, o = msg.pose.pose.position, msg.pose.pose.orientation
        theta = yaw(o.x, o.y, o.z, o.w)
        if not all(math.isfinite(v) for v in (p.x, p.y, theta)):
            self.dropped["invalid"] += 1
            return
        self._pose.put(Pose(p.x, p.y, theta, _seconds(msg.header.stamp), received))

    def _on_scan(self, msg: Any) -> None:
        received = time.monotonic()
        self._scan.put(
            Scan(
                clipped_ranges(msg.ranges, msg.range_min, msg.range_max),
                msg.angle_min,
                msg.angle_increment,
                msg.range_min,
                msg.range_max,
                _seconds(msg.header.stamp),
                received,
            )
        )

    def command(self, inputs: Mapping[str, float]) -> None:
        """Publish the law's input (``v``/``omega`` or ``vx``/``vy``/``omega``) as a Twist;
        components not given are zero."""
        if "v" in inputs and ("vx" in inputs or "vy" in inputs):
            raise ValueError(f"{self.agent}: give either v (unicycle) or vx, vy (holonomic)")
        msg = self._Twist()
        for name, value in inputs.items():
            if name not in TWIST_FIELDS:
                raise ValueError(
                    f"{self.agent}: no Twist field for input {name!r}; a robot "
                    f"takes {', '.join(TWIST_FIELDS)}"
                )
            if not math.isfinite(value):
                raise ValueError(
                    f"{self.agent}: input {name} = {value} is not finite; not sent to the robot"
                )
            group, axis = TWIST_FIELDS[name]
            setattr(getattr(msg, group), axis, float(value))
        self._cmd.publish(msg)

    def pose(self, timeout: float | None = None) -> Pose:
        """The latest odometry pose, waiting for one up to ``timeout`` s (the deploy
        setting by default); :class:`PlantSilent` if none arrived within that time."""
        wait = self.deploy.timeout if timeout is None else timeout
        pose = self._pose.get(wait)
        if pose is None:
            why = (
                f"{self.dropped['frame']} arrived in frame "
                f"{', '.join(map(repr, sorted(self._foreign_frames)))}, not "
                f"{self.deploy.frame!r}"
                if self.dropped["frame"]
                else "is the robot's driver running, on this ROS_DOMAIN_ID?"
            )
            raise PlantSilent(
                f"{self.agent}: no odometry on {self.deploy.odom} within {wait:g} s; {why}"
            )
        return pose

    def scan(self, timeout: float | None = None) -> Scan:
        """The latest laser scan, waiting for one up to ``timeout`` s (the deploy setting by
        default); :class:`PlantSilent` if none arrived within that time."""
        if self.deploy.scan is None:
            raise ValueError(f"{self.agent}: no scan topic in its deploy settings")
        wait = self.deploy.timeout if timeout is None else timeout
        scan = self._scan.get(wait)
        if scan is None:
            raise PlantSilent(
                f"{self.agent}: no laser scan on {self.deploy.scan} within {wait:g} s"
            )
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


#: the plants a robot over ROS 2 drives: their inputs make a Twist, their state a pose
ROBOT_KINDS = ("unicycle", "holonomic")


def body_velocity(vx: float, vy: float, yaw: float) -> tuple[float, float]:
    """World-frame velocity ``(vx, vy)`` in the frame of a robot heading ``yaw``:
    ``R(-yaw) (vx, vy)``, what a Twist's ``linear.x``, ``linear.y`` are."""
    c, s = math.cos(yaw), math.sin(yaw)
    return c * vx + s * vy, -s * vx + c * vy


class RobotPlant:
    """A :class:`Ros2Plant` as an agent's external plant in the engine
    (:mod:`hybridteam.engine.run.plant`): the held inputs out as a Twist at every instant, the
    latest odometry pose in wherever the engine needs the agent's state.

    A unicycle agent's inputs ``(v, omega)`` are body-frame, as a Twist's are, and go out
    as they are. A holonomic agent's ``(vx, vy)`` are world-frame
    (:mod:`hybridteam.dynamics.plants`): they are turned into the body frame by the yaw of
    the pose the engine last read (:func:`body_velocity`), the one its law computed them
    from; ``omega`` is the same in both frames. Between two instants the robot holds that
    body-frame Twist, so while it turns (``omega`` not zero) its world-frame velocity
    turns with it, by at most ``omega`` times the time to the next instant, where the
    model's keeps its direction. Both kinds' state ``(x, y, theta)`` is an odometry pose;
    other plants are refused.

    A robot whose odometry falls silent for its ``timeout`` ends the run rather than
    breaking it: ``on_silent`` is told why (a live run's stop request: the run ends at its
    next wait, ``stopped``, its trace complete) and the last pose stands until then.
    """

    def __init__(
        self, robot: Ros2Plant, kind: str, on_silent: Callable[[str], None] | None = None
    ) -> None:
        self.check(robot.agent, kind)
        self.robot, self.kind = robot, kind
        self.on_silent = on_silent
        self.last: np.ndarray | None = None  # the last pose read
        self.silent = False
        self.last_scan: Scan | None = None  # the last scan read
        self.scan_silent = False
        #: whether the robot has a laser (a scan topic) its agent's range rings are read from
        self.laser = robot.deploy.scan is not None
        #: every command given, ``(run time, the model's inputs)``: the trace's record of
        #: what the robot was told (:func:`hybridteam.trace.command_series`), which a
        #: conformance check drives the plant with
        self.commands: list[tuple[float, np.ndarray]] = []

    @staticmethod
    def check(agent: str, kind: str) -> None:
        """ValueError unless agent ``agent``'s plant ``kind`` is one a robot drives."""
        if kind not in ROBOT_KINDS:
            raise ValueError(
                f"agent '{agent}' has a {kind} plant; a robot over ROS 2 "
                "drives a unicycle agent (v, omega) or a holonomic one (vx, vy, "
                "omega), as a Twist, its x, y, theta from odometry"
            )

    def command(self, inputs: np.ndarray, t: float) -> None:
        self.commands.append((t, np.array(inputs, float)))
        if self.kind == "unicycle":
            v, omega = inputs.tolist()
            self.robot.command({"v": v, "omega": omega})
            return
        vx, vy, omega = inputs.tolist()
        pose = self.last if self.last is not None else self.state(t)
        bx, by = body_velocity(vx, vy, float(pose[2]))
        self.robot.command({"vx": bx, "vy": by, "omega": omega})

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

    def ranges(self, ring: RangeRing) -> np.ndarray | None:
        """What range ring ``ring`` reads, from the robot's laser (:func:`ring_ranges`);
        None without a ``scan`` topic (the ring is then the world process's). A laser
        silent for the deploy setting's timeout is as silent odometry: ``on_silent`` told
        why (once), the last scan read from then on; without ``on_silent``, or before any
        scan, :class:`PlantSilent`."""
        if self.robot.deploy.scan is None:
            return None
        if not self.scan_silent:
            try:
                self.last_scan = self.robot.scan()
            except PlantSilent as exc:
                if self.on_silent is None or self.last_scan is None:
                    raise
                self.scan_silent = True
                log.warning("%s", exc)
                self.on_silent(str(exc))
        assert self.last_scan is not None
        return ring_ranges(self.last_scan, ring)
