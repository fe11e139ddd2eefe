"""World components: the parts of a simulation that belong to no single agent.

A payload held by several robots, a corridor that judges when a ladder has made it round
the corner, range sensors that need every robot's pose: these read the whole team's state
at once, so they cannot be an agent's law. A team file lists them under ``world:``; each is
a class registered by name (``@world_component("ladder.corridor")``) in a mode library and
found through the ``hybridteam.libraries`` entry points, like laws.

The engine calls a component at every instant of every instance, *before* the agents'
laws are sampled, so a law sees what the component worked out from the current state.
What it judges from a robot's sensors it should judge at that robot's sensing instants
(``world.sensing(agent, idx)``: its law ticks), so that a message arriving between two
other robots changes nothing it reports, and an instant where nobody senses costs it
next to nothing (the built-in ``obstacles`` and ``payload`` components do so).
It hands the component a :class:`~hybridteam.world.access.WorldAccess`, never itself:
through it ``update`` reads poses, variables and parameters, ends instances
(``world.finish(idx, "link_broken", ...)``) and raises local events in agents
(``world.raise_event(idx, agent, "arrived")``; their discrete phase runs at that instant).
Laws read what a component lets their robot sense through ``LawContext.sense(name)``.
Everything is vectorized over the ensemble and per instance, so an ensemble still equals
that many single runs.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from hybridteam.discovery import load_libraries, registry
from hybridteam.errors import ModelError
from hybridteam.world.scene import SceneDescription

if TYPE_CHECKING:
    from hybridteam.model import Team
    from hybridteam.world.access import WorldAccess
    from hybridteam.world.request import BatchRequest


class WorldComponent:
    """Base class of world components; subclasses override what they need.

    ``params`` are the defaults of the component's ``with:`` settings: a float default
    makes the setting a number or an expression of team parameters (evaluated per
    instance, so ensembles can sweep it), a str or list default makes it a literal.
    """

    name: ClassVar[str] = ""
    params: ClassVar[Mapping[str, Any]] = {}
    #: Local events the component may raise in agents. While it may, an agent waiting for
    #: one is not deadlocked (the component is a pending source of events).
    raises: ClassVar[tuple[str, ...]] = ()
    #: List settings whose numbers may be written as expressions of team parameters
    #: (``walls: [[2, "-door / 2", 2, -1]]``): each such expression reaches the component
    #: as an ``(n,)`` array, its value in every instance, so a study can sweep it; the
    #: numbers written as numbers stay plain floats. ``hybridteam validate`` checks the
    #: expressions where they are written.
    per_instance: ClassVar[tuple[str, ...]] = ()

    @classmethod
    def batch(cls, request: BatchRequest) -> list[dict[str, Any]] | None:
        """An accelerated equivalent of simulating ``request.team`` for its per-instance
        summaries, or None when the component does not recognise the team.

        Parameter studies need thousands of runs of one kind of team; a library may own a
        specialised batch simulator for the teams it defines (tests must pin it to the
        engine instance by instance). The request carries everything resolved as the
        engine would (parameters after overrides, this component's settings, initial
        states) and the team's shape (:mod:`hybridteam.world.request`). Rows carry
        ``instance``, ``outcome``, ``t_end`` and the component's :meth:`summary` keys.
        """
        return None

    @classmethod
    def check(cls, team: Team, values: Mapping[str, Any]) -> list[ModelError]:
        """Problems in the literal settings ``values`` (as written, defaults not filled in),
        each located by its path inside ``with:`` (``("detect", 0, "agent")``).

        ``hybridteam validate`` reports them at their line in the team file, before
        anything runs; a component's constructor should raise the same problems as one
        ValueError (:func:`settings_error`), for teams built in Python.
        """
        return []

    def __init__(self, team: Team, n: int, values: Mapping[str, Any]) -> None:
        self.team, self.n, self.values = team, n, dict(values)

    def start(self, world: WorldAccess) -> None:
        """Called once, after every agent's initial state is set and before the first
        instant; agents' states may be read (and, for placements, written) here. The
        ``world`` stays valid for the whole run: a component may keep it for
        :meth:`sense`.

        A setting it cannot run with, found only now, is an error at the setting's line:
        raise :class:`~hybridteam.errors.ModelError` with the path inside ``with:``
        (``ModelError(("update",), ...)``); any other ValueError is reported at the
        component's entry in the team file."""

    def update(self, world: WorldAccess, idx: np.ndarray) -> np.ndarray | None:
        """React to the state of the live instances ``idx`` at their current time: end
        instances, raise events, update what robots sense (through ``world``). Returns None,
        or the instances where it raised events (the engine reads either)."""

    def sense(self, agent: int, idx: np.ndarray, name: str) -> np.ndarray:
        """What agent ``agent`` senses as ``name`` in instances ``idx`` (for its law)."""
        raise KeyError(name)

    def senses(self) -> tuple[str, ...]:
        """Names :meth:`sense` answers (for error messages)."""
        return ()

    def sample_series(self) -> dict[str, tuple[str, ...]]:
        """Extra trace sample series (e.g. a payload's pose): name -> component names."""
        return {}

    def sample(self, idx: np.ndarray) -> dict[str, np.ndarray]:
        """Current values of :meth:`sample_series` for instances ``idx``: name -> (m, d)."""
        return {}

    def summary(self, i: int) -> dict[str, Any]:
        """Statistics of instance ``i`` at the end of the run (for ``summary.json``)."""
        return {}

    def describe(self) -> SceneDescription:
        """What the views draw of this component (walls, regions, obstacles, guide paths,
        collision marks, payload outlines, robots' footprints), asked once at the end of
        a run; see :mod:`hybridteam.world.scene`. Nothing, by default."""
        return SceneDescription()


def settings_error(component: str, problems: Sequence[ModelError]) -> ValueError:
    """One ValueError naming every problem and the setting it is in:
    ``obstacles: detect[0].agent: unknown agent 'C'; did you mean 'A'?``."""
    return ValueError(f"{component}: " + "; ".join(str(p) for p in problems))


_REGISTRY: dict[str, type[WorldComponent]] = registry()


def world_component(name: str):
    """Register a :class:`WorldComponent` subclass under ``name``."""

    def deco(cls: type[WorldComponent]) -> type[WorldComponent]:
        if "meta" in vars(cls):  # the untyped form, which nothing reads any more
            raise TypeError(
                f"world component '{name}' ({cls.__qualname__}) defines meta(); "
                "say what the views draw with describe() returning a "
                "SceneDescription instead (docs/extending.md)"
            )
        cls.name = name
        _REGISTRY[name] = cls
        return cls

    return deco


def lookup(name: str) -> type[WorldComponent]:
    """The component class registered as ``name`` (after loading mode libraries)."""
    _builtins()
    if name not in _REGISTRY:
        load_libraries()
    return _REGISTRY[name]


def registered() -> list[str]:
    _builtins()
    load_libraries()
    return sorted(_REGISTRY)


def _builtins() -> None:
    """The framework's own components (a carried payload, static obstacles and the range
    sensors that see them) register on first use, and again should a registry have been
    restored to before it (:func:`hybridteam.discovery.isolated`)."""
    from hybridteam.world.carried import CarriedPayload
    from hybridteam.world.obstacles import Obstacles

    for cls in (CarriedPayload, Obstacles):
        _REGISTRY.setdefault(cls.name, cls)
