"""Agents, teams and simulation settings, as plain declarations."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from hybridteam.errors import DocPath
from hybridteam.model.deploy import PlantDeploy, UdpDeploy
from hybridteam.model.modes import Mode
from hybridteam.model.protocol import MessageSpec, StreamSpec

if TYPE_CHECKING:  # the model only carries a preset; it never needs the robots package
    from hybridteam.robots.presets import RobotPreset


@dataclass(frozen=True)
class PlantSpec:
    """An agent's kinematics: ``unicycle``, ``holonomic``, ``flow``, or ``none`` (an agent
    with no plant, e.g. a human operator who only exchanges messages).

    ``state`` gives the initial value of every state component (numbers or expressions of
    parameters, so an ensemble can vary initial conditions through parameter overrides).
    ``limits`` saturate the inputs: ``{"v": (-1, 1)}``.
    """

    kind: str
    state: dict[str, str | float]
    limits: dict[str, tuple[float, float]] = field(default_factory=dict)
    where: DocPath = ()


@dataclass(frozen=True)
class Agent:
    """One robot (or any hybrid automaton): a plant, a mode tree, variables and parameters.

    ``preset`` is the robot model the agent was declared with (``model: xr4000``), with the
    team's overrides applied: its plant kind and limits are already in ``plant``; world
    components read the rest (footprint, sensors, manipulator) from here. None for an agent
    declared with explicit kinematics.
    """

    name: str
    plant: PlantSpec
    root: Mode
    parameters: dict[str, float | str] = field(default_factory=dict)  # str: an expression
    variables: dict[str, str | float] = field(default_factory=dict)
    where: DocPath = ()
    streams: tuple[StreamSpec, ...] = ()
    preset: RobotPreset | None = None
    operator: bool = False  # a protocol's operator: no body; not waited for by default


@dataclass(frozen=True)
class EndRule:
    """When a run ends before its duration: once ``all`` (or ``any``) of ``agents`` are in
    final modes; ``agents`` None means every agent but operators."""

    agents: tuple[str, ...] | None = None
    when: str = "all"  # "all" | "any"
    where: DocPath = ()


@dataclass(frozen=True)
class ScenarioEvent:
    """A scripted local event: at time ``at``, raise ``event`` in ``agent``."""

    at: float
    agent: str
    event: str
    where: DocPath = ()


@dataclass(frozen=True)
class Zeno:
    """Caps that stop a run that would never advance (or crawl toward a Zeno point).

    More than ``max_steps_per_instant`` discrete steps at one time instant, or more than
    ``max_transitions`` transitions of one agent within ``window`` seconds, end the instance
    with outcome ``zeno``.
    """

    max_steps_per_instant: int = 1000
    max_transitions: int = 100
    window: float = 1e-6


@dataclass(frozen=True)
class LinkSettings:
    """Delay and loss of messages on a link: numbers or expressions of team parameters, so
    an ensemble can vary them per instance (``latency: link_latency``)."""

    latency: str | float = 0.0
    jitter: str | float = 0.0
    loss: str | float = 0.0
    where: DocPath = ()


@dataclass(frozen=True)
class NetworkSpec:
    """The broadcast medium: default link settings, per-link overrides keyed by
    ``(sender, receiver)``, and receive-rate limits (messages per second a receiver can
    process, per socket; ``"*"`` for all sockets)."""

    default: LinkSettings = field(default_factory=LinkSettings)
    links: dict[tuple[str, str], LinkSettings] = field(default_factory=dict)
    rate_limits: dict[str, dict[str, float]] = field(default_factory=dict)
    where: DocPath = ()


@dataclass(frozen=True)
class Simulation:
    """How to simulate: duration, output sampling and integrator accuracy."""

    duration: float = 10.0
    seed: int = 0
    sample_period: float | None = None
    rtol: float = 1e-10
    atol: float = 1e-12
    max_step: float | None = None
    min_step: float | None = None  # None: 1e-6 of the duration (engine/run/numerics.py)
    event_tol: float = 1e-12
    crossing_checks: int = 2
    zeno: Zeno = field(default_factory=Zeno)
    where: DocPath = ()

    def output_period(self) -> float:
        """Trace sampling period: as declared, else 1/500 of the duration."""
        return self.sample_period if self.sample_period else self.duration / 500.0


@dataclass(frozen=True)
class WorldSpec:
    """A world component (``use``: its registered name) and its ``with:`` settings."""

    use: str
    values: dict[str, object] = field(default_factory=dict)
    where: DocPath = ()


@dataclass(frozen=True)
class Requirement:
    """A named requirement: a Signal Temporal Logic formula checked on every run (see
    :mod:`hybridteam.requirements`). ``formula`` is text, compiled when the team is."""

    name: str
    formula: str
    description: str | None = None
    where: DocPath = ()


@dataclass(frozen=True)
class Team:
    """Agents that run in parallel, with shared parameters and a simulation setup."""

    name: str
    agents: tuple[Agent, ...]
    parameters: dict[str, float] = field(default_factory=dict)
    simulation: Simulation = field(default_factory=Simulation)
    scenario: tuple[ScenarioEvent, ...] = ()
    source: str | None = None
    network: NetworkSpec = field(default_factory=NetworkSpec)
    messages: dict[str, MessageSpec] = field(default_factory=dict)
    world: tuple[WorldSpec, ...] = ()
    #: the folder of the team file: ``module:function`` laws are looked for there first
    folder: str | None = None
    end: EndRule = field(default_factory=EndRule)
    requirements: tuple[Requirement, ...] = ()
    #: which of two enabled nested transitions fires first: ``outer_first`` (Stateflow's)
    #: or ``inner_first`` (SCXML's: the innermost source; between regions, document order)
    priority_rule: str = "outer_first"
    #: per agent name, where its robot is over ROS 2 (the ``deploy:`` section; live runs
    #: with ``--plant ros2`` read it, simulation ignores it)
    deploy: dict[str, PlantDeploy] = field(default_factory=dict)
    #: the team's UDP addressing in ``deploy:`` (its ``udp`` key, the agents' ``listen``;
    #: ``hybridteam live`` reads it, simulation ignores it)
    udp: UdpDeploy = field(default_factory=UdpDeploy)

    def __repr__(self) -> str:
        names = ", ".join(a.name for a in self.agents)
        return (
            f"<Team {self.name!r}: {len(self.agents)} agent(s) ({names}), "
            f"{self.simulation.duration:g} s>"
        )

    def _repr_html_(self) -> str:
        """In Jupyter: the team's state diagram, drawn inline. Drawing lives above the
        model, so it is imported here, when a notebook asks, and never at import."""
        from hybridteam.notebook import team_html

        return team_html(self)

    def agent(self, name: str) -> Agent:
        for a in self.agents:
            if a.name == name:
                return a
        raise KeyError(name)
