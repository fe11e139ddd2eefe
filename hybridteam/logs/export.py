"""A run as a rosbag2, for Foxglove, PlotJuggler, RViz and ``ros2 bag``.

One instance of a trace becomes one bag (topics in :mod:`.topics`, documented in
``docs/logs.md``):

- every agent's state vector, exactly, on ``/A/state`` — what ``import`` reads back;
- a planar robot's pose (unicycle and holonomic plants: state ``x, y, theta``) as
  ``PoseStamped`` and ``Odometry`` in the ``map`` frame, and ``map -> A/base_link`` on
  ``/tf``. The trace records no inputs, so the odometry's velocity is the difference of
  consecutive samples turned into the body frame (held over the next period);
- commands on ``/A/cmd_vel`` where the trace has them (a log imported with commands);
- payload poses, world series, mode changes, stays and team messages;
- the sample times on ``/clock``, as a simulator publishes its clock (a run that stopped
  early has sample times with no value after its end, which no other topic shows).

Stamps are the trace's times in nanoseconds from the Unix epoch: ``t = 0`` is stamp 0 (a
simulated run has no wall time; tools show 1970-01-01). Mode changes and team messages
carry their exact times in their JSON as well, as a stamp has nanoseconds only.

The bag is written under a temporary name beside the target and renamed at the end:
an error leaves nothing behind.
"""

from __future__ import annotations

import json
import math
import os
import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from hybridteam.logs import LogError, require_rosbags
from hybridteam.logs.topics import (
    ARRAY,
    CLOCK,
    CLOCK_TYPE,
    MAP_FRAME,
    ODOM,
    POSE,
    RUN,
    STRING,
    TF,
    TF_TYPE,
    TWIST,
    base_frame,
    default_topic,
    payload_topic,
    series_topic,
)
from hybridteam.trace import MESSAGE_COLUMNS, Trace, command_series

#: ``-o`` names and the storage they mean: one MCAP or SQLite file, or a bag folder.
SUFFIXES = {".mcap": "mcap", ".db3": "sqlite3"}
FORMATS = ("mcap", "sqlite3")
PLANAR = ("unicycle", "holonomic")


def bag_format(path: str | os.PathLike, fmt: str | None) -> tuple[str, bool]:
    """``(storage, single_file)`` for ``-o path`` and ``--format``: ``run.mcap`` is one MCAP
    file, ``run.db3`` one SQLite file, any other name a rosbag2 folder (MCAP unless
    ``--format sqlite3``). A format that contradicts the name is a :class:`LogError`."""
    suffix = Path(path).suffix.lower()
    if fmt is not None and fmt not in FORMATS:
        raise LogError(f"--format {fmt}: expected {' or '.join(FORMATS)}")
    if suffix in SUFFIXES:
        if fmt is not None and fmt != SUFFIXES[suffix]:
            raise LogError(
                f"-o {path} says {SUFFIXES[suffix]} but --format says {fmt}; "
                "name the file .mcap or .db3, or a folder, or drop --format"
            )
        return SUFFIXES[suffix], True
    return fmt or "mcap", False


def stamp(t: float) -> int:
    """A trace time (s) as a bag stamp (ns since the epoch, t = 0 at stamp 0)."""
    return round(t * 1e9)


def write_bag(
    trace: Trace, path: str | os.PathLike, fmt: str | None = None, instance: int = 0
) -> Path:
    """Write instance ``instance`` of ``trace`` as a rosbag2 at ``path`` (see
    :func:`bag_format`); returns ``path``. A folder bag is never written over."""
    require_rosbags()
    from rosbags.rosbag2 import StoragePlugin, Writer, WriterError
    from rosbags.typesys import Stores, get_typestore

    from hybridteam.api import Run

    storage, single = bag_format(path, fmt)
    path = Path(path)
    if not 0 <= instance < trace.n:
        raise LogError(f"--instance {instance}: the trace has instances 0..{trace.n - 1}")
    if not single and path.exists():
        raise LogError(f"{path} exists: a rosbag2 folder is never written over")
    if single and path.is_dir():
        raise LogError(f"{path} is a folder, not a file")
    run = (trace if isinstance(trace, Run) else Run.of(trace)).instance(instance)
    typestore = get_typestore(Stores.ROS2_HUMBLE)
    records = sorted(_Messages(run, typestore).records(), key=lambda r: r[1])
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    bag = tmp / path.stem
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    try:
        tmp.mkdir()
        with Writer(bag, version=Writer.VERSION_LATEST, storage_plugin=plugin) as writer:
            conns: dict[str, Any] = {}
            for topic, ns, msgtype, msg in records:
                if topic not in conns:
                    conns[topic] = writer.add_connection(topic, msgtype, typestore=typestore)
                writer.write(conns[topic], ns, typestore.serialize_cdr(msg, msgtype))
        if single:
            os.replace(next(p for p in bag.iterdir() if p.name != "metadata.yaml"), path)
        else:
            os.replace(bag, path)
    except WriterError as exc:
        raise LogError(f"cannot write {path}: {exc}") from None
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return path


Record = tuple[str, int, str, Any]  # (topic, stamp in ns, message type, message)


class _Messages:
    """The messages of one instance of a run, built with the typestore's classes."""

    def __init__(self, run: Any, typestore: Any) -> None:
        self.run, self.T = run, typestore.types
        self.times = run.sample_times
        self.ns = [stamp(t) for t in self.times.tolist()]
        self.transforms: dict[int, list[Any]] = {}  # sample -> /tf entries

    # -- message builders ------------------------------------------------------------------
    def header(self, k: int, frame: str = MAP_FRAME) -> Any:
        sec, nsec = divmod(self.ns[k], 1_000_000_000)
        return self.T["std_msgs/msg/Header"](
            stamp=self.T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec), frame_id=frame
        )

    def string(self, data: dict) -> Any:
        return self.T[STRING](data=json.dumps(data, separators=(",", ":"), allow_nan=False))

    def array(self, names: list[str], values: np.ndarray) -> Any:
        T = self.T
        dim = T["std_msgs/msg/MultiArrayDimension"](
            label=",".join(names), size=len(names), stride=len(names)
        )
        return T[ARRAY](
            layout=T["std_msgs/msg/MultiArrayLayout"](dim=[dim], data_offset=0),
            data=np.asarray(values, dtype=np.float64),
        )

    def vector(self, x: float, y: float, z: float = 0.0) -> Any:
        return self.T["geometry_msgs/msg/Vector3"](x=x, y=y, z=z)

    def quaternion(self, th: float) -> Any:
        """A rotation by ``th`` about z."""
        return self.T["geometry_msgs/msg/Quaternion"](
            x=0.0, y=0.0, z=math.sin(th / 2), w=math.cos(th / 2)
        )

    def pose(self, x: float, y: float, th: float) -> Any:
        return self.T["geometry_msgs/msg/Pose"](
            position=self.T["geometry_msgs/msg/Point"](x=x, y=y, z=0.0),
            orientation=self.quaternion(th),
        )

    def add_transform(self, k: int, child: str, x: float, y: float, th: float) -> None:
        """``map -> child`` at sample ``k``, sent on ``/tf`` with the others of that time."""
        self.transforms.setdefault(k, []).append(
            self.T["geometry_msgs/msg/TransformStamped"](
                header=self.header(k),
                child_frame_id=child,
                transform=self.T["geometry_msgs/msg/Transform"](
                    translation=self.vector(x, y), rotation=self.quaternion(th)
                ),
            )
        )

    # -- the bag's contents ----------------------------------------------------------------
    def records(self) -> Iterator[Record]:
        """Every message of the bag, per topic in time order."""
        run, meta = self.run, self.run.meta
        yield RUN, 0, STRING, self.string({"meta": meta, "outcome": run.diagnostics[0]})
        for k, ns in enumerate(self.ns):  # the sample grid, also where no value was recorded
            yield CLOCK, ns, CLOCK_TYPE, self.T[CLOCK_TYPE](clock=self.header(k).stamp)
        for agent in meta["agents"]:
            yield from self.agent(agent)
        payloads = meta.get("payloads") or []
        for name, cols in meta.get("series", {}).items():
            values, have = self.sampled(name)
            for k in have:
                yield series_topic(name), self.ns[k], ARRAY, self.array(list(cols), values[k])
            if name in payloads and list(cols)[:3] == ["x", "y", "theta"]:
                for k in have:
                    x, y, th = values[k, :3].tolist()
                    yield (
                        payload_topic(name),
                        self.ns[k],
                        POSE,
                        self.T[POSE](header=self.header(k), pose=self.pose(x, y, th)),
                    )
                    self.add_transform(k, name, x, y, th)
        for k in sorted(self.transforms):
            yield TF, self.ns[k], TF_TYPE, self.T[TF_TYPE](transforms=self.transforms[k])

    def sampled(self, key: str) -> tuple[np.ndarray, np.ndarray]:
        """A series' values (samples x columns) and the samples where it has them."""
        values = self.run.samples[key][:, 0, :]
        return values, np.flatnonzero(~np.isnan(values).any(axis=1))

    def agent(self, agent: dict[str, Any]) -> Iterator[Record]:
        name, names = agent["name"], list(agent["state"])
        values, have = self.sampled(name)
        if names:
            for k in have:
                yield default_topic(name, "state"), self.ns[k], ARRAY, self.array(names, values[k])
        if agent["plant"] in PLANAR and names[:3] == ["x", "y", "theta"]:
            yield from self.planar(name, values, have)
        if command_series(name) in self.run.meta.get("series", {}):
            yield from self.commands(name, agent["inputs"], default_topic(name, "cmd_vel"))
        run = self.run
        yield from self.rows(
            run.transitions,
            name,
            "agent",
            default_topic(name, "mode"),
            "t",
            ("t", "step", "source", "target", "cause", "guard"),
        )
        yield from self.rows(
            run.intervals,
            name,
            "agent",
            default_topic(name, "stays"),
            "start",
            ("mode", "depth", "start", "end"),
        )
        yield from self.rows(
            run.messages,
            name,
            "sender",
            default_topic(name, "messages"),
            "t_send",
            MESSAGE_COLUMNS[1:],  # (all but the instance: one instance a bag)
        )

    def planar(self, name: str, values: np.ndarray, have: np.ndarray) -> Iterator[Record]:
        """Pose, odometry and the ``/tf`` entry of a planar robot at each of its samples;
        the odometry's velocity is the one held to the next sample, in the body frame."""
        T = self.T
        zero = np.zeros(36)
        pose_topic, odom_topic = default_topic(name, "pose"), default_topic(name, "odom")
        for j, k in enumerate(have):
            x, y, th = values[k, :3].tolist()
            nxt = have[j + 1] if j + 1 < len(have) else (have[j - 1] if j > 0 else k)
            dt = float(self.times[nxt] - self.times[k])
            vx = vy = wz = 0.0
            if dt != 0:
                dx, dy, wz = ((values[nxt, :3] - values[k, :3]) / dt).tolist()
                vx = math.cos(th) * dx + math.sin(th) * dy
                vy = -math.sin(th) * dx + math.cos(th) * dy
            pose = self.pose(x, y, th)
            yield pose_topic, self.ns[k], POSE, T[POSE](header=self.header(k), pose=pose)
            yield (
                odom_topic,
                self.ns[k],
                ODOM,
                T[ODOM](
                    header=self.header(k),
                    child_frame_id=base_frame(name),
                    pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=zero),
                    twist=T["geometry_msgs/msg/TwistWithCovariance"](
                        twist=T[TWIST](
                            linear=self.vector(vx, vy), angular=self.vector(0.0, 0.0, wz)
                        ),
                        covariance=zero,
                    ),
                ),
            )
            self.add_transform(k, base_frame(name), x, y, th)

    def commands(self, name: str, inputs: list[str], topic: str) -> Iterator[Record]:
        """A unicycle's ``(v, omega)``, a holonomic base's ``(vx, vy, omega)`` (in the map
        frame, as the model has them) as ``Twist``, each sample where the trace has one."""
        values, have = self.sampled(command_series(name))
        for k in have:
            u = dict(zip(inputs, values[k].tolist(), strict=False))
            yield (
                topic,
                self.ns[k],
                TWIST,
                self.T[TWIST](
                    linear=self.vector(u.get("v", u.get("vx", 0.0)), u.get("vy", 0.0)),
                    angular=self.vector(0.0, 0.0, u.get("omega", 0.0)),
                ),
            )

    def rows(
        self, table: Any, name: str, column: str, topic: str, time: str, fields: tuple[str, ...]
    ) -> Iterator[Record]:
        """The rows of ``table`` that belong to ``name``, as compact JSON in time order,
        each with its ``row`` (its place in the trace's table: import restores the order)."""
        rows = np.flatnonzero(table[column] == name).tolist()
        for r in sorted(rows, key=lambda r: (float(table[time][r]), r)):
            data: dict[str, Any] = {"row": r}
            for f in fields:
                v = table[f][r]
                v = v.item() if isinstance(v, np.generic) else v
                data[f] = None if isinstance(v, float) and math.isnan(v) else v
            yield topic, stamp(float(table[time][r])), STRING, self.string(data)
