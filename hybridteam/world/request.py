"""What a world component's batch fast path is given: :class:`BatchRequest`.

A parameter study needs thousands of runs of one kind of team. A library that defines such
a team may own a specialised simulator for it (the ladder library's vectorized stepper),
offered through :meth:`WorldComponent.batch`. The engine hands it a request already
resolved the way the engine itself would resolve it — per-instance parameters after the
study's overrides, the component's settings evaluated per instance, every agent's initial
state — together with a read-only *shape* of the compiled team: plants, modes, laws and
transitions as plain values. The fast path recognises the teams it can stand in for from
that shape (:meth:`AgentShape.one_law` covers the common case: an agent that runs one law
until events end it) and returns None for any other team, which then runs on the engine.

Nothing here refers to the engine's internals, so the engine can change them freely; a
library's tests must still pin its fast path to the engine, instance by instance.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hybridteam.model import Agent, Send, Team


@dataclass(frozen=True)
class ModeShape:
    """One mode of a compiled agent (``path`` is dotted from the agent's root, which is
    ``""``). ``law`` is the registered name of the law the mode binds (None: none, or
    expression ``inputs:``/a ``flow:``), ``period`` its control period (0: continuous),
    ``bound`` the law parameters the binding sets (names)."""

    path: str
    kind: str  # "leaf" | "or" | "and"
    parent: str | None  # None for the root
    initial: str | None  # an OR mode's initial child
    final: bool
    outcome: str | None
    law: str | None = None
    period: float = 0.0
    bound: tuple[str, ...] = ()
    inputs: bool = False  # plant inputs from ``inputs:`` expressions
    flow: bool = False  # a ``flow:`` (classical hybrid automaton)
    invariant: str = ""


@dataclass(frozen=True)
class TransitionShape:
    """One compiled transition, in precedence order; guards and delays as written."""

    source: str
    target: str
    on: str | None
    guard: str
    after: bool
    actions: int  # number of assignments, sends and raises
    internal: bool


@dataclass(frozen=True)
class OneLaw:
    """An agent that runs one law in one mode from the start until an event ends it
    (:meth:`AgentShape.one_law`): the law, its period, the binding's parameter values per
    instance (law defaults filled in), and for each ending event the outcome its final
    mode names (``ok`` when it names none)."""

    mode: str
    law: str
    period: float
    params: dict[str, np.ndarray]
    bound: tuple[str, ...]
    ends: dict[str, str]


@dataclass(frozen=True)
class AgentShape:
    """A compiled agent as a fast path may see it, with its per-instance values.

    ``params`` maps every parameter (team ones included) to its ``(n,)`` values after the
    run's overrides; ``initial`` every plant state component to its ``(n,)`` initial
    values; ``limits`` the actuator limits of its inputs. ``law_params`` gives, per mode
    with a law, the binding's parameter values at the start of the run ``(n,)``.
    """

    name: str
    index: int
    plant: str
    state_names: tuple[str, ...]
    input_names: tuple[str, ...]
    limits: dict[str, tuple[float, float]]
    params: dict[str, np.ndarray]
    initial: dict[str, np.ndarray]
    variables: tuple[str, ...]
    modes: tuple[ModeShape, ...]
    transitions: tuple[TransitionShape, ...]
    law_params: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)

    def mode(self, path: str) -> ModeShape:
        for m in self.modes:
            if m.path == path:
                return m
        raise KeyError(f"agent '{self.name}' has no mode '{path}'")

    def one_law(self) -> OneLaw | None:
        """This agent's plan if it is the common shape a fast path stands in for, else None:
        the root's initial child is a leaf running a law (its only mode with a law, inputs
        or flow); every transition leaves that mode on an event (``on:``, no guard, delay
        or actions) into a final leaf; nothing else happens."""
        root = self.modes[0]
        if root.initial is None:
            return None
        first = self.mode(root.initial)
        driven = [m for m in self.modes if m.law or m.inputs or m.flow]
        if first.kind != "leaf" or first.law is None or driven != [first]:
            return None
        ends: dict[str, str] = {}
        for tr in self.transitions:
            if (
                tr.source != first.path
                or tr.on is None
                or tr.guard
                or tr.after
                or tr.actions
                or tr.internal
            ):
                return None
            target = self.mode(tr.target)
            if not target.final or target.kind != "leaf":
                return None
            ends[tr.on] = target.outcome or "ok"
        return OneLaw(
            first.path, first.law, first.period, self.law_params[first.path], first.bound, ends
        )


@dataclass(frozen=True)
class BatchRequest:
    """A request to stand in for the engine on ``n`` runs of ``team``.

    ``component`` is the index (in ``team.world``) of the component being asked and
    ``settings`` its ``with:`` settings with defaults filled in, numeric ones evaluated per
    instance as ``(n,)`` arrays. ``seed`` is one seed or one per instance (as the engine
    takes it), ``duration`` the simulated time of every run. The answer is one row per
    instance with ``instance``, ``outcome``, ``t_end`` and the component's summary keys.
    """

    team: Team
    n: int
    seed: int | list[int]
    duration: float
    component: int
    settings: Mapping[str, Any]
    agents: tuple[AgentShape, ...]
    team_params: Mapping[str, np.ndarray]

    def agent(self, name: str) -> AgentShape:
        for a in self.agents:
            if a.name == name:
                return a
        raise KeyError(f"no agent '{name}' in team '{self.team.name}'")

    @property
    def components(self) -> tuple[str, ...]:
        """Registered names of the team's world components, in declaration order."""
        return tuple(w.use for w in self.team.world)

    @property
    def quiet(self) -> bool:
        """No scenario events, no messages and no data streams: agents act only on their
        laws and on what the world tells them."""
        team = self.team
        return not (
            team.scenario
            or team.messages
            or any(a.streams for a in team.agents)
            or any(_sends(a) for a in team.agents)
        )

    def uniform(self, key: str) -> float | None:
        """A numeric setting's value if it is the same in every instance, else None."""
        values = np.asarray(self.settings[key], float)
        return float(values.flat[0]) if values.size and np.ptp(values) == 0 else None


def _sends(agent: Agent) -> bool:
    """Whether any transition of the agent sends a message."""
    return any(
        isinstance(act, Send)
        for _, mode in agent.root.walk()
        for tr in mode.transitions
        for act in tr.actions
    )
