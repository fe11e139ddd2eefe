"""What a world component may see and do of a running ensemble: :class:`WorldAccess`.

A world component (a payload, a corridor and its referee, range sensors) reads the whole
team's state and acts on the run: it ends instances with an outcome, raises local events
in agents, and finds its sibling components. It does so only through this interface,
which the engine implements over its ensemble state; a component never sees the engine's
arrays, queue or compiled team, so the engine can change how it stores them without
breaking a library.

Every call is vectorized over instances: ``idx`` is an index array of instances and the
answer has ``len(idx)`` rows, in that order. Agents are named by their team name or their
index in the team (what :meth:`WorldComponent.sense` receives).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from hybridteam.world.component import WorldComponent

Agent = int | str
"""An agent by name (``"labmate"``) or by its index in the team."""

Message = str | Callable[[int], str]
"""An outcome's message: one text, or a function of the instance number."""


class WorldAccess(ABC):
    """The engine as a world component sees it (see the module docstring).

    Abstract: every method is an :func:`~abc.abstractmethod`, so an implementation that
    leaves one out fails when it is instantiated (``TypeError`` naming the method), not
    when a component first calls it mid-run. The engine's implementation is
    :class:`~hybridteam.engine.run.access.EnsembleAccess`; a test double declares this
    class as its base and implements every method.
    """

    #: Number of instances in the ensemble.
    n: int
    #: Agent names in team order (an agent's index is its position here).
    agents: tuple[str, ...]

    # ------------------------------------------------------------------ time and runs
    @property
    @abstractmethod
    def t(self) -> np.ndarray:
        """Current time of every instance, shape ``(n,)`` (read-only)."""

    @abstractmethod
    def live(self, idx: np.ndarray) -> np.ndarray:
        """The instances of ``idx`` that have not ended."""

    @abstractmethod
    def finish(self, idx: np.ndarray, outcome: str, message: Message) -> None:
        """End instances ``idx`` now with ``outcome`` (``link_broken``, ...) and a message
        saying why (a text, or a function of the instance). Ended instances are skipped."""

    @abstractmethod
    def raise_event(self, idx: np.ndarray, agent: Agent, event: str) -> None:
        """Raise local event ``event`` in ``agent`` for instances ``idx`` at their current
        time; the engine runs their discrete phase at this instant. List the event in the
        component's ``raises`` so an agent waiting for it is not declared deadlocked."""

    @abstractmethod
    def sensing(self, agent: Agent, idx: np.ndarray) -> np.ndarray:
        """Whether the current time of each instance of ``idx`` is one of the agent's
        sensing instants: ``(m,)`` bool. A robot samples its sensors as its controller
        does, at its law's ticks (the control period's grid), not whenever a message
        happens to arrive somewhere in the team; the first instant of the run, and every
        instant of a robot with no control period (no law, or a continuous one), are
        sensing instants too. What a component judges from a robot's readings (a detect
        rule's edge, a grasp's break, a clearance) it judges at that robot's sensing
        instants, so unrelated traffic cannot move it (docs/design.md, *Semantics*)."""

    # ------------------------------------------------------------------ agents
    @abstractmethod
    def agent(self, name: Agent) -> int:
        """Index of an agent (ValueError with a "did you mean" for an unknown name)."""

    @abstractmethod
    def state_names(self, agent: Agent) -> tuple[str, ...]:
        """Names of the agent's plant state, in column order of :meth:`state`."""

    @abstractmethod
    def state(self, agent: Agent, idx: np.ndarray) -> np.ndarray:
        """The agent's plant state in instances ``idx``: ``(m, d)`` (a copy)."""

    @abstractmethod
    def set_state(
        self, agent: Agent, idx: np.ndarray, values: np.ndarray, names: Sequence[str] | None = None
    ) -> None:
        """Place the agent: write state components ``names`` (all when None) in instances
        ``idx``. Meant for :meth:`WorldComponent.start` (initial placements); writing the
        state later bypasses the engine's crossing detection."""

    @abstractmethod
    def has_pose(self, agent: Agent) -> bool:
        """Whether the agent's plant has a planar position (state components x and y)."""

    @abstractmethod
    def pose(self, agent: Agent, idx: np.ndarray) -> np.ndarray:
        """``(m, 3)``: x, y and heading theta of the agent in instances ``idx``, found by
        name in its plant state (the one rule for every plant: unicycle, holonomic or a
        flow naming them); theta is 0 for a plant without a heading. ValueError when the
        plant has no x and y."""

    @abstractmethod
    def variable_names(self, agent: Agent) -> tuple[str, ...]:
        """The agent's discrete variables (its own and those its protocols add)."""

    @abstractmethod
    def variable(self, agent: Agent, name: str, idx: np.ndarray) -> np.ndarray:
        """The agent's variable ``name`` in instances ``idx``: ``(m,)``."""

    @abstractmethod
    def set_variable(
        self, agent: Agent, name: str, idx: np.ndarray, values: np.ndarray | float
    ) -> None:
        """Write the agent's variable ``name`` in instances ``idx`` (``values``: ``(m,)`` or
        one number), as a transition's assignment ``name = ...`` writes it: per instance,
        as a float, those instances only (ended ones are skipped). The agents' discrete
        phase runs at this instant in those instances, so a guard reading the variable
        (``battery <= 0.2``) is taken now; a transition that assigns the variable at this
        instant writes after the component. ValueError for a value that is not a finite
        number. A battery draining ``battery`` is the recipe (``docs/extending.md``)."""

    @abstractmethod
    def parameter_names(self, agent: Agent) -> tuple[str, ...]:
        """The agent's parameters, team parameters included."""

    @abstractmethod
    def parameter(self, agent: Agent, name: str, idx: np.ndarray | None = None) -> np.ndarray:
        """The agent's parameter ``name`` (its own or the team's, after a run's overrides)
        in instances ``idx`` (all when None): ``(m,)``."""

    # ------------------------------------------------------------------ the world
    @abstractmethod
    def components(self, kind: type | str | None = None) -> list[WorldComponent]:
        """The team's world components in declaration order (this one included), or those
        of one class (and its subclasses) or registered name."""


def require_variable(world: WorldAccess, agent: Agent, name: str, setting: str) -> None:
    """ValueError naming ``setting`` unless the agent has variable ``name`` (what a
    component checks at the start when a setting names a variable, e.g. a grasp's
    ``engaged``; protocols add variables the team file does not list, so this cannot be
    a check of the file alone)."""
    if name not in world.variable_names(agent):
        known = ", ".join(world.variable_names(agent)) or "none"
        who = world.agents[world.agent(agent)]
        raise ValueError(
            f"{setting}: agent '{who}' has no variable '{name}' (its variables: {known})"
        )
