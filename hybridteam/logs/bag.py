"""A rosbag2 as a run: the ordinary trace of a team, read from a log.

Topics are those ``export`` writes (:mod:`.topics`) — with a deployed robot's odometry and
commands where the team's ``deploy:`` section names them — or those a mapping file names.
What becomes what:

- samples: an agent's ``/A/state`` (exact), else its pose (``PoseStamped``, or the pose of
  an ``Odometry``; theta is the yaw, unwrapped so it turns continuously), else its
  odometry; payloads' poses and world series the same way; commands (``Twist``) as the
  series ``A.cmd`` of the plant's inputs. Each topic keeps its own stamps: the trace's
  sample times are all of them, and an agent has no value (NaN) at another's times
  (requirement checks interpolate over those, as between any two samples);
- transitions from ``/A/mode`` (JSON with at least ``target``, or a bare mode path), stays
  in modes from ``/A/stays`` or, when a log has none, from the transitions (a stay
  continues while the modes entered keep it as their prefix);
- team messages from ``/A/messages`` with their times.

Times are seconds after the log's first stamp (the exported run's ``t = 0`` is stamp 0, so
a round trip keeps its times). Anything wrong — another team's agents, a missing topic,
stamps going back, a message that does not decode, a cut-short file — is one
:class:`~hybridteam.logs.LogError` naming the file, topic and time.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterable, Iterator
from contextlib import contextmanager, suppress
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hybridteam.logs import LogError, require_rosbags
from hybridteam.logs.export import PLANAR
from hybridteam.logs.topics import (
    AGENT_KINDS,
    ARRAY,
    CLOCK,
    CLOCK_TYPE,
    ODOM,
    POSE,
    RUN,
    STRING,
    TWIST,
    Topics,
    payload_topic,
    series_topic,
)
from hybridteam.model import Team
from hybridteam.trace import (
    INTERVAL_COLUMNS,
    MESSAGE_COLUMNS,
    TRANSITION_COLUMNS,
    Table,
    command_series,
)

#: what each kind of topic may be
SAMPLED = {"state": (ARRAY,), "pose": (POSE, ODOM), "odom": (ODOM, POSE), "cmd": (TWIST,)}
EVENTS = {"modes": (STRING,), "stays": (STRING,), "messages": (STRING,)}


@dataclass
class _Topic:
    """One topic's messages as read: ``(ns, decoded)`` in bag order, and its type."""

    name: str
    msgtype: str
    records: list[tuple[int, Any]] = field(default_factory=list)


def read_bag(path: str | os.PathLike, team: Team, mapping: str | os.PathLike | None = None) -> Any:
    """The :class:`~hybridteam.api.Run` a rosbag2 (a folder, or one ``.mcap``/``.db3``
    file) records of ``team``; topics as a ``mapping`` file names them (default: export's
    names, and the ``deploy:`` section's odometry and command topics of an agent it has).
    Raises :class:`LogError`, or :class:`~hybridteam.io.filekind.InputErrors` for a bad
    mapping file."""
    require_rosbags()
    from hybridteam.api import Run
    from hybridteam.logs.team import team_frame
    from hybridteam.logs.topics import load_mapping
    from hybridteam.trace_schema import check_trace

    path = Path(path)
    meta, _params = team_frame(team)
    topics = None
    if mapping is not None:
        topics = load_mapping(
            mapping, [a["name"] for a in meta["agents"]], list(meta.get("payloads") or [])
        )
    with _BagFile(path) as bag:
        reading = _Reading(path, team, meta, bag.types, bag.read([RUN]).get(RUN), topics)
        reading.add_topics(bag.read(reading.wanted()))
    return reading.run(Run, check_trace)


class _BagFile:
    """An open rosbag2 whose topics are read on demand (a robot's log holds images and
    scans that a trace has no place for: they are never decoded). Whatever a file that is
    not a bag, is cut short or holds a message that does not decode raises in ``rosbags``
    becomes one :class:`LogError`."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def __enter__(self) -> _BagFile:
        from rosbags.rosbag2 import Reader
        from rosbags.typesys import Stores, get_typestore

        if not self.path.exists():
            raise LogError(f"{self.path}: no such file or folder")
        self.typestore = get_typestore(Stores.ROS2_HUMBLE)
        with self._damaged():
            self.reader = Reader(self.path)
            self.reader.open()
        self.connections = list(self.reader.connections)
        self.types: dict[str, str] = {}
        for conn in self.connections:
            if self.types.setdefault(conn.topic, conn.msgtype) != conn.msgtype:
                self.__exit__()
                raise LogError(
                    f"{self.path}: topic {conn.topic} has two types, "
                    f"{self.types[conn.topic]} and {conn.msgtype}"
                )
        return self

    def __exit__(self, *exc: object) -> None:
        with suppress(Exception):  # closing a damaged file: the error that matters is raised
            self.reader.close()

    def read(self, names: Iterable[str]) -> dict[str, _Topic]:
        """The messages of the named topics present, decoded, in bag order (a topic of a
        type this reader does not know has none)."""
        wanted = set(names) & set(self.types)
        out = {name: _Topic(name, self.types[name]) for name in wanted}
        conns = [
            c for c in self.connections if c.topic in wanted and c.msgtype in self.typestore.types
        ]
        if not conns:
            return out
        where: list[Any] = [None, None]
        with self._damaged(where):
            for conn, ns, raw in self.reader.messages(connections=conns):
                where[:] = [conn.topic, ns]
                out[conn.topic].records.append(
                    (ns, self.typestore.deserialize_cdr(raw, conn.msgtype))
                )
        return out

    @contextmanager
    def _damaged(self, where: list[Any] | None = None) -> Iterator[None]:
        """Any error of ``rosbags`` reading a damaged file as one :class:`LogError`;
        ``where``: the topic and stamp last read."""
        try:
            yield
        except LogError:
            raise
        except Exception as exc:  # rosbags' errors, whatever a damaged file raises in it
            at = (
                ""
                if not where or where[0] is None
                else f" (after topic {where[0]} at stamp {where[1]} ns)"
            )
            reason = str(exc) or type(exc).__name__
            raise LogError(
                f"{self.path}: not a readable rosbag2 or cut short{at}: {reason}"
            ) from None


class _Reading:
    """One bag read against one team (kept together: every error names the file)."""

    def __init__(
        self,
        path: Path,
        team: Team,
        meta: dict[str, Any],
        types: dict[str, str],
        header: _Topic | None,
        topics: Topics | None,
    ) -> None:
        self.path, self.team, self.types = path, team, types
        self.bag: dict[str, _Topic] = {}
        self.outcome: dict[str, Any] | None = None
        self.t0 = 0
        if header is not None and header.records:
            self.bag[RUN] = header
            self.t0 = header.records[0][0]  # export writes it first, at the log's start
            meta = self._recorded_meta(meta)
        self.meta = meta
        self.agents = [a["name"] for a in meta["agents"]]
        if topics is None:  # export's names, a deployed robot's own where it has them
            topics = Topics.default(self.agents, list(meta.get("payloads") or []), team.deploy)
        else:
            self._mapped_present(topics)
        self.topics = topics
        self.own = topics.names()
        self.mapped = topics.mapped

    def wanted(self) -> list[str]:
        """The topics this team's trace is made of (and, with export's names, those of
        agents the team does not have, to name them)."""
        names = [CLOCK, *self.topics.payloads.values()]
        for at in self.topics.agents.values():
            names += [t for t in at.__dict__.values() if t is not None]
        names += [series_topic(s) for s in self.meta.get("series", {})]
        if not self.mapped:
            names += [t for t in self.types if self._foreign(t)]
        return names

    def add_topics(self, bag: dict[str, _Topic]) -> None:
        """Take in the topics read from the bag (the wanted ones); ``t0`` becomes the
        earliest stamp among them."""
        self.bag.update(bag)
        self.t0 = min((ns for t in self.bag.values() for ns in self._stamps(t)), default=self.t0)

    def _foreign(self, topic: str) -> str | None:
        """The agent ``X`` a topic ``/X/pose`` (any of export's kinds) names, when the team
        has no such agent."""
        parts = topic.strip("/").split("/")
        if topic in self.own:  # a deployed robot's (/scout1/odom of agent robot)
            return None
        if len(parts) == 2 and parts[1] in AGENT_KINDS and parts[0] not in self.agents:
            return parts[0]
        return None

    # -- where times come from -------------------------------------------------------------
    def _stamps(self, topic: _Topic) -> list[int]:
        """The topic's times in ns: a message's header stamp where it has one, else the
        bag's."""
        return [_header_ns(msg, ns) for ns, msg in topic.records]

    def _t(self, ns: int) -> float:
        return (ns - self.t0) / 1e9

    def fail(self, topic: str, ns: int | None, message: str) -> LogError:
        when = "" if ns is None else f" at t={self._t(ns):.9g} s"
        return LogError(f"{self.path}: topic {topic}{when}: {message}")

    # -- which team ------------------------------------------------------------------------
    def _recorded_meta(self, meta: dict[str, Any]) -> dict[str, Any]:
        """The header an exported bag carries, when it is this team's (exact round trip)."""
        ns, msg = self.bag[RUN].records[0]
        try:
            data = json.loads(msg.data)
            recorded, outcome = data["meta"], data["outcome"]
            team_name = recorded["team"]
            names = [a["name"] for a in recorded["agents"]]
        except (ValueError, KeyError, TypeError) as exc:
            raise self.fail(RUN, ns, f"not the header of a hybridteam run ({exc})") from None
        if team_name != self.team.name or sorted(names) != sorted(
            a["name"] for a in meta["agents"]
        ):
            raise self.fail(
                RUN,
                ns,
                f"the log records team '{team_name}' (agents "
                f"{', '.join(names)}), not '{self.team.name}' (agents "
                f"{', '.join(a['name'] for a in meta['agents'])})",
            )
        self.outcome = dict(outcome, instance=0)
        return dict(recorded, n=1)

    def _same_team(self) -> None:
        """Export's names, and an agent of the team without samples: a topic ``/X/pose``
        (and the like) of an agent ``X`` the team does not have says the log is another
        team's (other topics of a log that has the team's are left alone)."""
        for name, topic in self.bag.items():
            agent = self._foreign(name)
            if agent is not None:
                ns = self._stamps(topic)[0] if topic.records else None
                raise self.fail(
                    name,
                    ns,
                    f"agent '{agent}' is not in team "
                    f"'{self.team.name}' (agents: {', '.join(self.agents)}): "
                    "a log of another team? (--map names the topics of a log "
                    "whose names differ)",
                )

    def _mapped_present(self, topics: Topics) -> None:
        for agent, at in topics.agents.items():
            for key, name in at.__dict__.items():
                if name is not None and name not in self.types:
                    raise LogError(
                        f"{self.path}: topic {name} ({agent}'s {key} in the "
                        "mapping) is not in the log"
                    )
        for payload, name in topics.payloads.items():
            if name not in self.types:
                raise LogError(
                    f"{self.path}: topic {name} ({payload}'s pose in the mapping) is not in the log"
                )

    def _topic(self, name: str | None, kinds: tuple[str, ...]) -> _Topic | None:
        if name is None or name not in self.bag:
            return None
        topic = self.bag[name]
        if topic.msgtype not in kinds:
            ns = topic.records[0][0] if topic.records else None
            raise self.fail(name, ns, f"has type {topic.msgtype}, expected {' or '.join(kinds)}")
        return topic

    # -- samples ---------------------------------------------------------------------------
    def _series_of(
        self, topic: _Topic, names: list[str], planar: bool
    ) -> tuple[np.ndarray, np.ndarray]:
        """``(times, values)`` of a sampled topic; times strictly increasing."""
        stamps = self._stamps(topic)
        for k in range(1, len(stamps)):
            if stamps[k] <= stamps[k - 1]:
                raise self.fail(
                    topic.name,
                    stamps[k],
                    "stamps go back or repeat (the "
                    f"previous one is t={self._t(stamps[k - 1]):.9g} s): "
                    "samples must be in time order",
                )
        rows = []
        for (_, msg), stamp_ns in zip(topic.records, stamps, strict=True):
            if topic.msgtype == ARRAY:  # labelled as export does, or unlabelled
                labels = msg.layout.dim[0].label.split(",") if msg.layout.dim else names
                if labels != names or len(msg.data) != len(names):
                    raise self.fail(
                        topic.name,
                        stamp_ns,
                        f"holds {','.join(labels) or '?'} "
                        f"({len(msg.data)} values), expected {','.join(names)}",
                    )
                rows.append(np.asarray(msg.data, float))
            elif topic.msgtype == TWIST:
                rows.append(_command(msg, names))
            else:
                pose = msg.pose.pose if topic.msgtype == ODOM else msg.pose
                q = pose.orientation
                yaw = math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))
                rows.append(np.array([pose.position.x, pose.position.y, yaw]))
        values = np.array(rows, float).reshape(len(rows), -1)
        if planar and len(rows) and topic.msgtype in (POSE, ODOM):
            values[:, 2] = np.unwrap(values[:, 2])
        return np.array([self._t(s) for s in stamps]), values

    def samples(self) -> tuple[np.ndarray, dict[str, tuple[np.ndarray, np.ndarray]]]:
        found: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        for agent in self.meta["agents"]:
            name, names = agent["name"], list(agent["state"])
            at = self.topics.agents.get(name)
            if not names or at is None:
                continue
            planar = agent["plant"] in PLANAR and names[:3] == ["x", "y", "theta"]
            state = self._topic(at.state, SAMPLED["state"])
            pose = (
                (self._topic(at.pose, SAMPLED["pose"]) or self._topic(at.odom, SAMPLED["odom"]))
                if planar
                else None
            )
            if state is None and pose is None:
                if not self.mapped:
                    self._same_team()
                wanted = [
                    t for t in (at.state, *((at.pose, at.odom) if planar else ())) if t is not None
                ]
                if not wanted:
                    raise LogError(
                        f"{self.path}: the mapping names no "
                        f"{'state, pose or odom' if planar else 'state'} topic "
                        f"of agent '{name}': it has no samples"
                    )
                raise LogError(
                    f"{self.path}: no topic {' or '.join(wanted)} in the log: "
                    f"agent '{name}' has no samples"
                )
            if state is not None:
                found[name] = self._series_of(state, names, planar)
            else:
                assert pose is not None
                t, v = self._series_of(pose, names[:3], planar)
                full = np.full((len(t), len(names)), np.nan)
                full[:, :3] = v
                found[name] = (t, full)
            cmd = self._topic(at.cmd, SAMPLED["cmd"])
            key = command_series(name)
            exact = series_topic(key) in self.bag  # an exported log's commands, exactly
            if cmd is not None and agent["inputs"] and not exact:
                found[key] = self._series_of(cmd, list(agent["inputs"]), False)
                self.meta.setdefault("series", {})[key] = list(agent["inputs"])
        for sname, cols in self.meta.get("series", {}).items():
            if sname in found:
                continue
            topic = self._topic(series_topic(sname), (ARRAY,))
            if topic is not None:
                found[sname] = self._series_of(topic, list(cols), False)
                continue
            pname = self.topics.payloads.get(sname, payload_topic(sname))
            pose = self._topic(pname, (POSE, ODOM))
            if pose is not None and list(cols)[:3] == ["x", "y", "theta"]:
                t, v = self._series_of(pose, ["x", "y", "theta"], True)
                full = np.full((len(t), len(cols)), np.nan)
                full[:, :3] = v
                found[sname] = (t, full)
        every = [t for t, _ in found.values()]
        clock = self._topic(CLOCK, (CLOCK_TYPE,)) if self.outcome is not None else None
        if clock is not None:  # an exported run's sample grid (see export)
            every.append(np.array([self._t(_clock_ns(msg)) for _, msg in clock.records]))
        times = np.unique(np.concatenate(every or [np.zeros(0)]))
        return times, found

    # -- events ----------------------------------------------------------------------------
    def _json(self, topic: _Topic) -> Iterable[tuple[int, Any]]:
        last = None
        for ns, msg in topic.records:
            if last is not None and ns < last:
                raise self.fail(
                    topic.name,
                    ns,
                    "stamps go back (the previous one is "
                    f"t={self._t(last):.9g} s): messages must be in time order",
                )
            last = ns
            text = msg.data
            try:
                data = json.loads(text)
            except ValueError:
                data = text.strip()  # a bare mode path
            yield ns, data

    def transitions(self) -> list[dict[str, Any]]:
        rows = []
        for agent in self.meta["agents"]:
            name = agent["name"]
            at = self.topics.agents.get(name)
            topic = self._topic(at.modes if at else None, EVENTS["modes"])
            if topic is None:
                continue
            paths = {m["path"] for m in agent["modes"]}
            previous = ""
            for ns, data in self._json(topic):
                if isinstance(data, str):
                    data = {"target": data}
                try:
                    target = data["target"]
                    row = {
                        "instance": 0,
                        "agent": name,
                        "t": _number(data.get("t"), self._t(ns)),
                        "step": int(data.get("step", 0)),
                        "source": str(data.get("source", previous)),
                        "target": target,
                        "cause": str(data.get("cause", "log")),
                        "guard": str(data.get("guard", "")),
                        "_row": data.get("row"),
                    }
                except (KeyError, TypeError, ValueError, AttributeError) as exc:
                    raise self.fail(
                        topic.name,
                        ns,
                        f"not a mode change ({exc}): expected "
                        "JSON with a 'target' mode, or a mode path",
                    ) from None
                if target not in paths:
                    raise self.fail(topic.name, ns, f"'{target}' is not a mode of agent '{name}'")
                previous = target
                rows.append(row)
        return _ordered(rows, ("t",))

    def intervals(self, transitions: list[dict[str, Any]], t_end: float) -> list[dict[str, Any]]:
        rows = []
        for agent in self.meta["agents"]:
            name = agent["name"]
            at = self.topics.agents.get(name)
            topic = self._topic(at.stays if at else None, EVENTS["stays"])
            if topic is None:
                rows += _stays_from(
                    name, agent, [r for r in transitions if r["agent"] == name], t_end
                )
                continue
            for ns, data in self._json(topic):
                try:
                    rows.append(
                        {
                            "instance": 0,
                            "agent": name,
                            "mode": str(data["mode"]),
                            "depth": int(data["depth"]),
                            "start": _number(data["start"], None),
                            "end": _number(data["end"], None),
                            "_row": data.get("row"),
                        }
                    )
                except (KeyError, TypeError, ValueError) as exc:
                    raise self.fail(topic.name, ns, f"not a stay in a mode ({exc})") from None
        return _ordered(rows, ("start", "depth"))

    def messages(self) -> list[dict[str, Any]]:
        rows = []
        for agent in self.meta["agents"]:
            name = agent["name"]
            at = self.topics.agents.get(name)
            topic = self._topic(at.messages if at else None, EVENTS["messages"])
            if topic is None:
                continue
            for ns, data in self._json(topic):
                try:
                    t_recv = _number(data.get("t_recv"), math.nan, nullable=True)
                    row = {
                        "instance": 0,
                        "seq": int(data.get("seq", 0)),
                        "sender": str(data.get("sender", name)),
                        "receiver": str(data["receiver"]),
                        "socket": str(data.get("socket", "control")),
                        "type": str(data["type"]),
                        "t_send": _number(data.get("t_send"), self._t(ns)),
                        "t_recv": t_recv,
                        "status": str(
                            data.get("status", "sent" if math.isnan(t_recv) else "delivered")
                        ),
                        "reason": str(data.get("reason", "")),
                        "msg_id": int(data.get("msg_id", -1)),
                        "_row": data.get("row"),
                    }
                except (KeyError, TypeError, ValueError, AttributeError) as exc:
                    raise self.fail(
                        topic.name,
                        ns,
                        f"not a team message ({exc}): expected JSON with 'receiver' and 'type'",
                    ) from None
                for role in ("sender", "receiver"):
                    if row[role] not in self.agents:
                        raise self.fail(
                            topic.name,
                            ns,
                            f"{role} '{row[role]}' is not in "
                            f"team '{self.team.name}' (agents: "
                            f"{', '.join(self.agents)})",
                        )
                rows.append(row)
        return _ordered(rows, ("t_send",))

    # -- the run ---------------------------------------------------------------------------
    def run(self, run_type: type, check_trace) -> Any:
        times, found = self.samples()
        transitions = self.transitions()
        messages = self.messages()
        ends = [*times.tolist(), *(r["t"] for r in transitions), *(r["t_send"] for r in messages)]
        t_end = max(ends, default=0.0)
        intervals = self.intervals(transitions, t_end)
        samples = {}
        columns = {a["name"]: len(a["state"]) for a in self.meta["agents"]}
        columns.update({k: len(v) for k, v in self.meta.get("series", {}).items()})
        for key, d in columns.items():
            arr = np.full((len(times), 1, d), np.nan)
            if key in found:
                t, v = found[key]
                arr[np.searchsorted(times, t), 0, :] = v
            samples[key] = arr
        meta = self.meta
        if self.outcome is None:
            meta = dict(meta, duration=t_end)
        outcome = self.outcome or {
            "instance": 0,
            "outcome": "log",
            "t": t_end,
            "message": "imported from a rosbag2 log",
        }
        run = run_type(
            meta,
            [outcome],
            _table(TRANSITION_COLUMNS, transitions),
            _table(INTERVAL_COLUMNS, intervals),
            _table(MESSAGE_COLUMNS, messages),
            times,
            samples,
        )
        problem = check_trace(run.to_dict())
        if problem is not None:
            raise LogError(f"{self.path}: the log does not make a valid trace: {problem}")
        return run


def _header_ns(msg: Any, ns: int) -> int:
    header = getattr(msg, "header", None)
    if header is None:
        return ns
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


def _clock_ns(msg: Any) -> int:
    return int(msg.clock.sec) * 1_000_000_000 + int(msg.clock.nanosec)


def _command(msg: Any, inputs: list[str]) -> np.ndarray:
    """A ``Twist`` as the plant's inputs, as export writes them."""
    by_name = {"v": msg.linear.x, "vx": msg.linear.x, "vy": msg.linear.y, "omega": msg.angular.z}
    return np.array([by_name.get(n, math.nan) for n in inputs], float)


def _number(value: Any, default: float | None, nullable: bool = False) -> float:
    if value is None:
        if default is None and not nullable:
            raise ValueError("a time is missing")
        return math.nan if default is None else default
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise TypeError(f"{value!r} is not a number")
    value = float(value)
    if not math.isfinite(value):
        raise ValueError(f"{value!r} is not a finite time")
    return value


def _ordered(rows: list[dict[str, Any]], keys: tuple[str, ...]) -> list[dict[str, Any]]:
    """Rows in their trace order when every one says where it was (an exported run), else
    in time order (stable: agents in the team's order)."""
    if rows and all(isinstance(r["_row"], int) for r in rows):
        return sorted(rows, key=lambda r: r["_row"])
    return sorted(rows, key=lambda r: tuple(r[k] for k in keys))


def _table(columns: tuple[str, ...], rows: list[dict[str, Any]]) -> Table:
    return Table(columns, {c: [r[c] for r in rows] for c in columns})


def _stays_from(
    name: str, agent: dict[str, Any], transitions: list[dict[str, Any]], t_end: float
) -> list[dict[str, Any]]:
    """Stays in modes from mode changes alone: after a change to ``A.B.C`` the agent is in
    ``A``, ``A.B`` and ``A.B.C``; a stay continues while the modes entered keep it."""
    depth = {m["path"]: m["depth"] for m in agent["modes"]}
    open_: list[tuple[str, float]] = []
    out = []
    for tr in sorted(transitions, key=lambda r: r["t"]):
        parts = tr["target"].split(".")
        chain = [".".join(parts[: i + 1]) for i in range(len(parts))]
        chain = [p for p in chain if p in depth]
        keep = 0
        while keep < min(len(open_), len(chain)) and open_[keep][0] == chain[keep]:
            keep += 1
        for mode, start in open_[keep:]:
            out.append(
                {
                    "instance": 0,
                    "agent": name,
                    "mode": mode,
                    "depth": depth[mode],
                    "start": start,
                    "end": tr["t"],
                    "_row": None,
                }
            )
        open_ = open_[:keep] + [(p, tr["t"]) for p in chain[keep:]]
    for mode, start in open_:
        out.append(
            {
                "instance": 0,
                "agent": name,
                "mode": mode,
                "depth": depth[mode],
                "start": start,
                "end": t_end,
                "_row": None,
            }
        )
    return out
