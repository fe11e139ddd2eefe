"""Declarations of hybrid models: modes, transitions, agents, teams (plain data)."""

from hybridteam.model.modes import (
    Action,
    Assign,
    History,
    LawBinding,
    Mode,
    Raise,
    Send,
    Transition,
)
from hybridteam.model.protocol import AckPolicy, MessageSpec, StreamSpec
from hybridteam.model.team import (
    Agent,
    EndRule,
    LinkSettings,
    NetworkSpec,
    PlantSpec,
    Requirement,
    ScenarioEvent,
    Simulation,
    Team,
    WorldSpec,
    Zeno,
)

__all__ = [
    "AckPolicy",
    "Action",
    "Agent",
    "Assign",
    "EndRule",
    "History",
    "LawBinding",
    "LinkSettings",
    "MessageSpec",
    "Mode",
    "NetworkSpec",
    "PlantSpec",
    "Raise",
    "Requirement",
    "ScenarioEvent",
    "Send",
    "Simulation",
    "StreamSpec",
    "Team",
    "Transition",
    "WorldSpec",
    "Zeno",
]
