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
from hybridteam.model.team import (
    Agent,
    LinkSettings,
    NetworkSpec,
    PlantSpec,
    ScenarioEvent,
    Simulation,
    Team,
    Zeno,
)

__all__ = [
    "Action", "Agent", "Assign", "History", "LawBinding", "LinkSettings", "Mode",
    "NetworkSpec", "PlantSpec", "Raise",
    "ScenarioEvent", "Send", "Simulation", "Team", "Transition", "Zeno",
]
