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
    AgentTopics,
    base_frame,
    command_series,
    payload_topic,
    series_topic,
)
from hybridteam.trace import Trace

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
            raise LogError(f"-o {path} says {SUFFIXES[suffix]} but --format says {fmt}; "
                           "name the file .mcap or .db3, or a folder, or drop --format")
        return SUFFIXES[suffix], True
    return fmt or "mcap", False


def stamp(t: float) -> int:
    """A trace time (s) as a bag stamp (ns since the epoch, t = 0 at stamp 0)."""
    return round(t * 1e9)


def write_bag(trace: Trace, path: str | os.PathLike, fmt: str | None = None,
              instance: int = 0) -> Path:
    """Write instance ``instance`` of ``trace`` as a rosbag2 at ``path`` (see
    :func:`bag_format`); returns ``path``. A folder bag is never written over."""
    require_rosbags()
    from rosbags.rosbag2 import StoragePlugin, Writer
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
    records = sorted(_records(run, typestore), key=lambda r: r[1])
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
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return path


def _records(run: Any, ts: Any) -> Iterator[tuple[str, int, str, Any]]:
    """Every message of the bag: ``(topic, stamp, type, message)``, per topic in time order."""
    T = ts.types
    meta = run.meta
    times = run.sample_times
    ns = [stamp(t) for t in times.tolist()]

    def header(k: int, frame: str) -> Any:
        sec, nsec = divmod(ns[k], 1_000_000_000)
        return T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec, nsec),
                                        frame_id=frame)

    def string(data: dict) -> Any:
        return T[STRING](data=json.dumps(data, separators=(",", ":"), allow_nan=False))

    def array(names: list[str], values: np.ndarray) -> Any:
        dim = T["std_msgs/msg/MultiArrayDimension"](label=",".join(names), size=len(names),
                                                    stride=len(names))
        return T[ARRAY](layout=T["std_msgs/msg/MultiArrayLayout"](dim=[dim], data_offset=0),
                        data=np.asarray(values, dtype=np.float64))

    def pose(x: float, y: float, th: float) -> Any:
        return T["geometry_msgs/msg/Pose"](
            position=T["geometry_msgs/msg/Point"](x=x, y=y, z=0.0),
            orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(th / 2),
                                                          w=math.cos(th / 2)))

    def vector(x: float, y: float, z: float) -> Any:
        return T["geometry_msgs/msg/Vector3"](x=x, y=y, z=z)

    yield RUN, 0, STRING, string({"meta": meta, "outcome": run.diagnostics[0]})
    for k, n in enumerate(ns):  # the sample grid, also where no value was recorded
        yield CLOCK, n, CLOCK_TYPE, T[CLOCK_TYPE](clock=header(k, "").stamp)
    transforms: dict[int, list[Any]] = {}
    for agent in meta["agents"]:
        name, names = agent["name"], list(agent["state"])
        topics = AgentTopics.default(name)
        values = run.samples[name][:, 0, :]
        have = ~np.isnan(values).any(axis=1)
        if names:
            for k in np.flatnonzero(have):
                yield topics.state, ns[k], ARRAY, array(names, values[k])
        if agent["plant"] in PLANAR and names[:3] == ["x", "y", "theta"]:
            yield from _planar(name, topics, values, have, times, ns, header, pose, vector,
                               T, transforms)
        if command_series(name) in meta.get("series", {}):
            yield from _commands(name, agent, run, ns, vector, T)
        yield from _json_rows(run.transitions, name, "agent", topics.modes, "t", string,
                              ("t", "step", "source", "target", "cause", "guard"))
        yield from _json_rows(run.intervals, name, "agent", topics.stays, "start", string,
                              ("mode", "depth", "start", "end"))
        yield from _json_rows(run.messages, name, "sender", topics.messages, "t_send", string,
                              ("seq", "sender", "receiver", "socket", "type", "t_send",
                               "t_recv", "status", "reason", "msg_id"))
    for sname, cols in meta.get("series", {}).items():
        values = run.samples[sname][:, 0, :]
        have = ~np.isnan(values).any(axis=1)
        for k in np.flatnonzero(have):
            yield series_topic(sname), ns[k], ARRAY, array(list(cols), values[k])
        if sname in (meta.get("payloads") or []) and list(cols)[:3] == ["x", "y", "theta"]:
            for k in np.flatnonzero(have):
                x, y, th = values[k, :3].tolist()
                yield payload_topic(sname), ns[k], POSE, T[POSE](
                    header=header(k, MAP_FRAME), pose=pose(x, y, th))
                transforms.setdefault(k, []).append(_transform(
                    T, header(k, MAP_FRAME), sname, x, y, th, vector))
    for k in sorted(transforms):
        yield TF, ns[k], TF_TYPE, T[TF_TYPE](transforms=transforms[k])


def _planar(name, topics, values, have, times, ns, header, pose, vector, T, transforms):
    """Pose, odometry and the ``/tf`` entry of a planar robot at each of its samples."""
    ks = np.flatnonzero(have)
    for j, k in enumerate(ks):
        x, y, th = values[k, :3].tolist()
        nxt = ks[j + 1] if j + 1 < len(ks) else (ks[j - 1] if j > 0 else k)
        dt = float(times[nxt] - times[k])
        if dt == 0:
            vx = vy = wz = 0.0
        else:  # the velocity held over the next period, in the body frame
            dx, dy, dth = ((values[nxt, :3] - values[k, :3]) / dt).tolist()
            vx, vy, wz = math.cos(th) * dx + math.sin(th) * dy, \
                -math.sin(th) * dx + math.cos(th) * dy, dth
        p = pose(x, y, th)
        yield topics.pose, ns[k], POSE, T[POSE](header=header(k, MAP_FRAME), pose=p)
        zero = np.zeros(36)
        yield topics.odom, ns[k], ODOM, T[ODOM](
            header=header(k, MAP_FRAME), child_frame_id=base_frame(name),
            pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=p, covariance=zero),
            twist=T["geometry_msgs/msg/TwistWithCovariance"](
                twist=T[TWIST](linear=vector(vx, vy, 0.0), angular=vector(0.0, 0.0, wz)),
                covariance=zero))
        transforms.setdefault(k, []).append(_transform(T, header(k, MAP_FRAME),
                                                       base_frame(name), x, y, th, vector))


def _transform(T, head, child: str, x: float, y: float, th: float, vector) -> Any:
    return T["geometry_msgs/msg/TransformStamped"](
        header=head, child_frame_id=child,
        transform=T["geometry_msgs/msg/Transform"](
            translation=vector(x, y, 0.0),
            rotation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(th / 2),
                                                       w=math.cos(th / 2))))


def _commands(name: str, agent: dict, run: Any, ns: list[int], vector, T):
    """``/A/cmd_vel``: a unicycle's ``(v, omega)``, a holonomic base's ``(vx, vy, omega)``
    (as the model has them, in the map frame), each sample where the trace has one."""
    values = run.samples[command_series(name)][:, 0, :]
    inputs = list(agent["inputs"])
    topic = AgentTopics.default(name).cmd
    for k in np.flatnonzero(~np.isnan(values).any(axis=1)):
        u = dict(zip(inputs, values[k].tolist(), strict=False))
        yield topic, ns[k], TWIST, T[TWIST](
            linear=vector(u.get("v", u.get("vx", 0.0)), u.get("vy", 0.0), 0.0),
            angular=vector(0.0, 0.0, u.get("omega", 0.0)))


def _json_rows(table: Any, name: str, column: str, topic: str, time: str, string,
               fields: tuple[str, ...]) -> Iterator[tuple[str, int, str, Any]]:
    """The rows of ``table`` that belong to ``name``, as compact JSON in time order, each
    with its ``row`` (its place in the trace's table, so import restores the order)."""
    rows = np.flatnonzero(table[column] == name)
    order = sorted(rows.tolist(), key=lambda r: (float(table[time][r]), r))
    for r in order:
        data: dict[str, Any] = {"row": r}
        for f in fields:
            v = table[f][r].item() if hasattr(table[f][r], "item") else table[f][r]
            data[f] = None if isinstance(v, float) and math.isnan(v) else v
        yield topic, stamp(float(table[time][r])), STRING, string(data)
