"""Which topic of a rosbag2 holds what: the names ``export`` writes, and the mapping file
that tells ``import`` where a robot's own log keeps them.

One place defines the names, so that export and import agree (a run exported and imported
back is the same run) and ``docs/logs.md`` has one list to describe. Per agent ``A``:

==================  ==================================  =================================
topic               type                                holds
==================  ==================================  =================================
``/A/state``        ``std_msgs/msg/Float64MultiArray``  the state vector, exact (labels)
``/A/pose``         ``geometry_msgs/msg/PoseStamped``   planar pose in ``map``
``/A/odom``         ``nav_msgs/msg/Odometry``           pose and body-frame velocity
``/A/cmd_vel``      ``geometry_msgs/msg/Twist``         commands (when the trace has them)
``/A/mode``         ``std_msgs/msg/String``             each transition, compact JSON
``/A/stays``        ``std_msgs/msg/String``             each stay in a mode, compact JSON
``/A/messages``     ``std_msgs/msg/String``             each team message A sent, JSON
==================  ==================================  =================================

and ``/payloads/P/pose`` (PoseStamped), ``/hybridteam/series/S`` (Float64MultiArray, a
world series), ``/hybridteam/run`` (String: the trace's meta and outcome, once), ``/tf``
and ``/clock`` (``rosgraph_msgs/msg/Clock``: the run's sample times, as a simulator
publishes its clock).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, field, replace

from pydantic import BaseModel, ConfigDict, ValidationError

from hybridteam.model.deploy import PlantDeploy

RUN = "/hybridteam/run"
TF = "/tf"
CLOCK = "/clock"
MAP_FRAME = "map"

STRING = "std_msgs/msg/String"
ARRAY = "std_msgs/msg/Float64MultiArray"
POSE = "geometry_msgs/msg/PoseStamped"
ODOM = "nav_msgs/msg/Odometry"
TWIST = "geometry_msgs/msg/Twist"
TF_TYPE = "tf2_msgs/msg/TFMessage"
CLOCK_TYPE = "rosgraph_msgs/msg/Clock"

#: The kinds of topic an agent has, in the mapping file's words ...
AGENT_KEYS = ("state", "pose", "odom", "cmd", "modes", "stays", "messages")
#: ... and the last part of their names as export writes them (``/A/cmd_vel``)
AGENT_KINDS = ("state", "pose", "odom", "cmd_vel", "mode", "stays", "messages")


def default_topic(agent: str, kind: str) -> str:
    """Export's name of an agent's topic of ``kind`` (one of :data:`AGENT_KINDS`)."""
    return f"/{agent}/{kind}"


def base_frame(agent: str) -> str:
    """An agent's body frame, child of ``map`` in ``/tf`` (``Odometry.child_frame_id``)."""
    return f"{agent}/base_link"


def series_topic(name: str) -> str:
    return f"/hybridteam/series/{name}"


def payload_topic(name: str) -> str:
    return f"/payloads/{name}/pose"


@dataclass(frozen=True)
class AgentTopics:
    """The topics of one agent; None: not in this log."""

    state: str | None
    pose: str | None
    odom: str | None
    cmd: str | None
    modes: str | None
    stays: str | None
    messages: str | None

    @classmethod
    def default(cls, agent: str) -> AgentTopics:
        return cls(*(default_topic(agent, kind) for kind in AGENT_KINDS))


@dataclass(frozen=True)
class Topics:
    """Every topic of a log: per agent, and per payload its pose."""

    agents: dict[str, AgentTopics]
    payloads: dict[str, str] = field(default_factory=dict)
    mapped: bool = False  # from a mapping file: a named topic must be in the bag

    @classmethod
    def default(
        cls, agents: list[str], payloads: list[str], deploy: Mapping[str, PlantDeploy] | None = None
    ) -> Topics:
        """Export's names; an agent with ``deploy:`` settings (the team file's, which a
        live run drives its robot through) has its robot's odometry and command topics
        from them, as its robot's log records them."""
        deploy = deploy or {}
        return cls(
            {
                a: replace(AgentTopics.default(a), odom=deploy[a].odom, cmd=deploy[a].cmd_vel)
                if a in deploy
                else AgentTopics.default(a)
                for a in agents
            },
            {p: payload_topic(p) for p in payloads},
        )

    def names(self) -> set[str]:
        """Every topic these name."""
        return {
            t for at in self.agents.values() for t in at.__dict__.values() if t is not None
        } | set(self.payloads.values())


class _AgentMapping(BaseModel):
    model_config = ConfigDict(extra="forbid")
    state: str | None = None
    pose: str | None = None
    odom: str | None = None
    cmd: str | None = None
    modes: str | None = None
    stays: str | None = None
    messages: str | None = None


class MappingFile(BaseModel):
    """A mapping file (``--map``): per agent, the topics of its log (see docs/logs.md)."""

    model_config = ConfigDict(extra="forbid")
    agents: dict[str, _AgentMapping]
    payloads: dict[str, str] = {}


def load_mapping(path: str | os.PathLike, agents: list[str], payloads: list[str]) -> Topics:
    """The topics a mapping file names; an agent it leaves out, or a key of an agent it
    leaves out, has no such topic. Raises :class:`~hybridteam.io.filekind.InputErrors`
    (file:line:column) for a bad file or a name that is not the team's."""
    from hybridteam.io.errors import located_errors
    from hybridteam.io.filekind import InputErrors, read_document

    doc = read_document(path)
    try:
        parsed = MappingFile.model_validate(doc.data)
    except ValidationError as exc:
        raise InputErrors(
            located_errors(exc, MappingFile, doc.data, doc.positions, doc.filename)
        ) from None
    errors = []
    for section, known, names in (
        ("agents", agents, parsed.agents),
        ("payloads", payloads, parsed.payloads),
    ):
        for name in names:
            if name not in known:
                errors.append(
                    doc.positions.error(
                        (section, name),
                        f"'{name}' is not one of the team's {section} "
                        f"({', '.join(known) or 'none'})",
                        at_key=True,
                    )
                )
    if errors:
        raise InputErrors(errors)
    empty = AgentTopics(*(None,) * len(AGENT_KEYS))
    out = {
        a: replace(empty, **parsed.agents[a].model_dump()) if a in parsed.agents else empty
        for a in agents
    }
    return Topics(out, dict(parsed.payloads), mapped=True)
