"""The public extension API: everything a mode library imports from hybridteam.

A mode library is a Python package that registers **laws** (vectorized control laws a mode
binds with ``law: {use: NAME}``) and **world components** (what belongs to no single
agent: a payload, a corridor and its referee, a charging dock), optionally with a **batch
fast path** that stands in for the engine on the teams it recognises. It is found through
the ``hybridteam.libraries`` entry-point group, so a third-party package ships one without
touching hybridteam (see ``docs/extending.md`` and ``examples/extending/``).

A library imports this module only (plus numpy/scipy and, for geometry,
:mod:`hybridteam.world.geometry`). Three objects are the whole contract between the
engine and a library:

- :class:`LawContext` — what a law sees for the ``m`` instances it is evaluated on: state,
  parameters, variables, time, stream estimates, what world components let its robot
  sense, and its own memory between periods;
- :class:`WorldAccess` — what a world component may read and do of the running ensemble:
  poses, states, variables, parameters, time, ending instances with an outcome, raising
  local events, finding sibling components;
- :class:`BatchRequest` — what a batch fast path is given: the team resolved as the
  engine resolves it (parameters after overrides, settings, initial states) and the
  team's shape as plain read-only values.

A component says what the views draw of it (walls, obstacles, regions, guide paths,
payload outlines, robots' footprints) with a :class:`SceneDescription` and its parts
(:mod:`hybridteam.world.scene`).

The engine may change anything else between versions; these three, the scene description
and the registration decorators are kept stable and documented.

A library that keeps a path on Python floats beside its array version (the ladder's law
and corridor instant) takes it only while ``FLOAT_PATHS.on``, re-exported here from
:mod:`hybridteam.floatpaths`: the public switch that runs everything on arrays, so the two
versions can be compared through one documented setting. It writes such a path once, over
an operations namespace ``ops`` (:data:`Ops`: numpy for arrays), and has
:func:`float_form` generate the float form from that source.
"""

from __future__ import annotations

from hybridteam.errors import ModelError
from hybridteam.floatpaths import FLOAT_PATHS as FLOAT_PATHS  # (a value: see the docstring)
from hybridteam.floatpaths import Ops, float_form
from hybridteam.laws import Estimate, LawContext, LawFunction, LawSpec, law
from hybridteam.model import Agent, Team
from hybridteam.world.access import WorldAccess, require_variable
from hybridteam.world.component import WorldComponent, settings_error, world_component
from hybridteam.world.request import (
    AgentShape,
    BatchRequest,
    ModeShape,
    OneLaw,
    TransitionShape,
)
from hybridteam.world.scene import (
    BarShape,
    BoxShape,
    CircleObstacle,
    CollisionMark,
    Footprint,
    GuidePath,
    PolygonObstacle,
    Region,
    SceneDescription,
    WallObstacle,
)

__all__ = [
    "Agent",
    "AgentShape",
    "BarShape",
    "BatchRequest",
    "BoxShape",
    "CircleObstacle",
    "CollisionMark",
    "Estimate",
    "Footprint",
    "GuidePath",
    "LawContext",
    "LawFunction",
    "LawSpec",
    "ModeShape",
    "ModelError",
    "OneLaw",
    "Ops",
    "PolygonObstacle",
    "Region",
    "SceneDescription",
    "Team",
    "TransitionShape",
    "WallObstacle",
    "WorldAccess",
    "WorldComponent",
    "float_form",
    "law",
    "require_variable",
    "settings_error",
    "world_component",
]
