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

from hybridteam.engine.compile.values import require
from hybridteam.errors import DocPath, ModelError, did_you_mean
from hybridteam.expr import ExpressionError, compile_expression
from hybridteam.libraries import broken_note
from hybridteam.world.component import WorldComponent, lookup, registered

if TYPE_CHECKING:
    from hybridteam.engine.run.access import EnsembleAccess
    from hybridteam.model import Team


def check_world(team: Team) -> list[ModelError]:
    """Problems in a team's ``world:`` list: unknown components, settings, expressions."""
    errors: list[ModelError] = []
    symbols = {name: (lambda c: 0.0) for name in team.parameters}
    for spec in team.world:
        try:
            cls = lookup(spec.use)
        except KeyError:
            note = broken_note()
            errors.append(ModelError((*spec.where, "use"), f"unknown world component "
                                     f"'{spec.use}'" + (f" ({note})" if note else ""),
                                     hint=did_you_mean(spec.use, registered())))
            continue
        before = len(errors)
        for key, value in spec.values.items():
            where = (*spec.where, "with", key)
            if key not in cls.params:
                errors.append(ModelError(where, f"'{spec.use}' has no setting '{key}'",
                                         hint=did_you_mean(key, list(cls.params)), at_key=True))
                continue
            default = cls.params[key]
            if key in cls.per_instance and isinstance(value, list):
                errors += [ModelError((*where, *at), exc.message, offset=exc.offset,
                                      hint=exc.hint)
                           for at, exc in _nested_errors(value, symbols)]
            if _numeric(default):
                if isinstance(value, str):
                    try:
                        compile_expression(value, symbols)
                    except ExpressionError as exc:
                        errors.append(ModelError(where, exc.message, offset=exc.offset,
                                                 hint=exc.hint))
                elif not _numeric(value):
                    errors.append(ModelError(where, f"expected a number or an expression, "
                                             f"got {value!r}"))
            elif type(value) is not type(default):
                kind = {bool: "true or false", str: "a string", list: "a list"}.get(
                    type(default), f"a {type(default).__name__}")
                errors.append(ModelError(where, f"expected {kind}, got {value!r}"))
        if len(errors) == before:  # the component's own checks, on well-typed settings
            errors += [ModelError((*spec.where, "with", *e.path), e.message, hint=e.hint,
                                  at_key=e.at_key) for e in cls.check(team, spec.values)]
    return errors


def _nested_errors(value: Any, symbols: Mapping[str, Any], at: tuple[int, ...] = ()
                   ) -> list[tuple[tuple[int, ...], ExpressionError]]:
    """Expressions inside a list setting that do not compile, with their places in it."""
    if isinstance(value, str):
        try:
            compile_expression(value, symbols)
        except ExpressionError as exc:
            return [(at, exc)]
        return []
    if isinstance(value, list):
        return [e for k, v in enumerate(value) for e in _nested_errors(v, symbols, (*at, k))]
    return []


def _nested_values(value: Any, symbols: Mapping[str, Any], n: int, where: DocPath) -> Any:
    """A list setting with every expression inside it evaluated per instance: ``(n,)``
    arrays where the file has text, the literal numbers and everything else as they are."""
    if isinstance(value, str):
        got = np.broadcast_to(np.asarray(compile_expression(value, symbols)(None), float),
                              (n,)).copy()
        return require(got, where, "the expression", value)
    if isinstance(value, list):
        return [_nested_values(v, symbols, n, (*where, k)) for k, v in enumerate(value)]
    return value


def _numeric(value: Any) -> bool:
    """A number setting (evaluated per instance), as opposed to a literal; bools are not."""
    return isinstance(value, float | int) and not isinstance(value, bool)


def component_values(cls: type[WorldComponent], given: Mapping[str, Any],
                     team_params: Mapping[str, np.ndarray], n: int,
                     where: DocPath = ()) -> dict[str, Any]:
    """Settings with defaults filled in; numeric ones as (n,) arrays, one per instance,
    each a finite number (a ModelError at ``where`` + ``with.<key>`` otherwise)."""
    symbols = {k: (lambda c, v=v: v) for k, v in team_params.items()}
    out: dict[str, Any] = {}
    for key, default in cls.params.items():
        value = given.get(key, default)
        if _numeric(default):
            text = str(value)
            if isinstance(value, str):
                value = compile_expression(value, symbols)(None)
            value = np.broadcast_to(np.asarray(value, dtype=float), (n,)).copy()
            out[key] = require(value, (*where, "with", key), f"setting '{key}'", text)
        elif key in cls.per_instance:
            out[key] = _nested_values(value, symbols, n, (*where, "with", key))
        else:
            out[key] = value
    return out


class World:
    """Every component of one simulation, called in declaration order."""

    def __init__(self, team: Team, n: int, team_params: Mapping[str, np.ndarray]) -> None:
        self.components: list[WorldComponent] = []
        self.specs = team.world
        for spec in team.world:
            cls = lookup(spec.use)
            self.components.append(cls(team, n, component_values(cls, spec.values,
                                                                 team_params, n, spec.where)))
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
                raise ModelError((*spec.where, "with", *exc.path), exc.message,
                                 hint=exc.hint, at_key=exc.at_key) from None
            except ValueError as exc:
                raise ModelError(spec.where, str(exc)) from None

    def update(self, access: EnsembleAccess, idx: np.ndarray) -> np.ndarray:
        """Run every component on the live instances of ``idx``; returns the instances
        where events were raised (through the access, or returned by ``update``)."""
        raised = []
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
        raise KeyError(f"no world component lets a robot sense '{name}'"
                       + (f" (known: {', '.join(known)})" if known else
                          " (the team declares no 'world:' components)"))

    def sample_series(self) -> dict[str, tuple[str, ...]]:
        return {k: v for c in self.components for k, v in c.sample_series().items()}

    def sample(self, idx: np.ndarray) -> dict[str, np.ndarray]:
        return {k: v for c in self.components for k, v in c.sample(idx).items()}

    def summary(self, i: int) -> dict[str, Any]:
        return {k: v for c in self.components for k, v in c.summary(i).items()}

    def meta(self) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for c in self.components:
            for key, value in c.meta().items():
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

    def __init__(self, world: World | None, agent: int, idx: np.ndarray | slice,
                 memory: dict[str, np.ndarray], everyone: np.ndarray) -> None:
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
            raise KeyError(f"no world component lets a robot sense '{name}' (the team "
                           "declares no 'world:' components)")
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
