"""The team's world components at run time, and what an agent's law may read of them.

:class:`World` instantiates the components a team lists under ``world:``, evaluates their
numeric settings per instance (expressions of team parameters, so an ensemble can sweep
a ladder's length) and the numbers inside the list settings a component names in
``per_instance`` (the obstacles' walls, so a study can sweep a door's width), and calls
them at every instant before laws are sampled.
:class:`AgentView` is what a law's context carries: the component readings its robot may
sense, and the law's own memory (per-instance values a discrete-time controller keeps
from one period to the next, such as how far along its guide path it is).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from hybridteam.engine.compile.settings import component_values
from hybridteam.errors import ModelError
from hybridteam.world.component import WorldComponent, lookup

if TYPE_CHECKING:
    from hybridteam.engine.run.access import EnsembleAccess
    from hybridteam.model import Team


class World:
    """Every component of one simulation, called in declaration order."""

    def __init__(self, team: Team, n: int, team_params: Mapping[str, np.ndarray]) -> None:
        self.components: list[WorldComponent] = []
        self.specs = team.world
        for spec in team.world:
            cls = lookup(spec.use)
            self.components.append(
                cls(team, n, component_values(cls, spec.values, team_params, n, spec.where))
            )
        #: which component answers each name a robot senses (the first that lists it),
        #: learnt at the first reading: a law reads several at every tick
        self._senses: dict[str, WorldComponent] = {}

    @property
    def any(self) -> bool:
        return bool(self.components)

    @property
    def raises(self) -> bool:
        """Whether some component may raise events (then nobody is deadlocked)."""
        return any(c.raises for c in self.components)

    def start(self, access: EnsembleAccess) -> None:
        """Start every component; a component's ValueError (a setting it cannot run with,
        found only now that agents and states are known) is located at its entry."""
        for c, spec in zip(self.components, self.specs, strict=True):
            try:
                c.start(access)
            except ModelError as exc:  # its path is inside the component's settings
                raise ModelError(
                    (*spec.where, "with", *exc.path), exc.message, hint=exc.hint, at_key=exc.at_key
                ) from None
            except ValueError as exc:
                raise ModelError(spec.where, str(exc)) from None

    def update(self, access: EnsembleAccess, idx: np.ndarray) -> np.ndarray:
        """Run every component on the live instances of ``idx``; returns the instances
        where events were raised (through the access, or returned by ``update``)."""
        raised: list[np.ndarray] = []
        for c in self.components:
            live = access.live(idx)
            if live.size:
                got = c.update(access, live)
                if got is not None and len(got):
                    raised.append(np.asarray(got, np.intp))
        pushed = access.take_raised()
        if not raised:
            return pushed
        return np.unique(np.concatenate([*raised, pushed]))

    def sense(self, agent: int, idx: np.ndarray, name: str) -> np.ndarray:
        c = self._senses.get(name)
        if c is not None:
            return c.sense(agent, idx, name)
        for c in self.components:
            if name in c.senses():
                self._senses[name] = c
                return c.sense(agent, idx, name)
        known = sorted({s for c in self.components for s in c.senses()})
        raise KeyError(
            f"no world component lets a robot sense '{name}'"
            + (
                f" (known: {', '.join(known)})"
                if known
                else " (the team declares no 'world:' components)"
            )
        )

    def sample_series(self) -> dict[str, tuple[str, ...]]:
        return {k: v for c in self.components for k, v in c.sample_series().items()}

    def sample(self, idx: np.ndarray) -> dict[str, np.ndarray]:
        return {k: v for c in self.components for k, v in c.sample(idx).items()}

    def summary(self, i: int) -> dict[str, Any]:
        return {k: v for c in self.components for k, v in c.summary(i).items()}

    def meta(self) -> dict[str, Any]:
        """The components' scene descriptions in the trace's form, merged key by key in
        declaration order as traces have always had them (a later component's ``world``
        entry replaces an earlier one's of the same key; lists of payloads join)."""
        out: dict[str, Any] = {}
        for c in self.components:
            for key, value in c.describe().to_meta().items():
                if isinstance(value, dict) and isinstance(out.get(key), dict):
                    out[key] = {**out[key], **value}
                elif isinstance(value, list) and isinstance(out.get(key), list):
                    out[key] = [*out[key], *value]
                else:
                    out[key] = value
        return out


class AgentView:
    """One agent's window on the world and its law memory, for instances ``idx``."""

    __slots__ = ("_instances", "agent", "everyone", "idx", "memory", "n", "world")

    def __init__(
        self,
        world: World | None,
        agent: int,
        idx: np.ndarray | slice,
        memory: dict[str, np.ndarray],
        everyone: np.ndarray,
    ) -> None:
        """``everyone``: every instance's index (read-only), the agent state's."""
        self.world, self.agent, self.idx, self.memory = world, agent, idx, memory
        self.everyone, self.n = everyone, everyone.size
        self._instances: np.ndarray | None = None

    def instances(self) -> np.ndarray:
        """The instances' indices (computed once: a law senses several things a tick)."""
        if self._instances is None:
            idx = self.idx
            if isinstance(idx, slice):  # (a view: everyone is read-only)
                self._instances = self.everyone[idx]
            else:
                self._instances = np.asarray(idx, np.intp)
        return self._instances

    def sense(self, name: str) -> np.ndarray:
        if self.world is None:
            raise KeyError(
                f"no world component lets a robot sense '{name}' (the team "
                "declares no 'world:' components)"
            )
        return self.world.sense(self.agent, self.instances(), name)

    def recall(self, name: str, initial: float) -> np.ndarray:
        store = self.memory.get(name)
        if store is None:
            store = self.memory[name] = np.full(self.n, float(initial))
        kept = store[self.idx]  # a copy where idx is an index array; a view for a slice
        return kept.copy() if isinstance(self.idx, slice) else kept

    def keep(self, name: str, values: np.ndarray) -> None:
        store = self.memory.get(name)
        if store is None:
            store = self.memory[name] = np.full(self.n, np.nan)
        store[self.idx] = values
