"""The engine's plant seam: an agent whose plant is outside the engine.

A simulation integrates every agent's plant (:mod:`.step`). A live agent driving a robot
does not: its plant is the robot (:mod:`hybridteam.live.ros2_plant`, or a robot
simulator), which the engine commands and reads instead. The
:class:`~.simulator.Simulator` is given such plants by agent index (``plants=``): at every
instant of the agent (each control tick, a mode's entry, an arrival) it hands the plant the
held inputs (commands out), and wherever it needs the agent's state (every step's end, the
output samples, which then are instants of their own, and the start) it asks the plant
(pose in) rather than integrating.

What the engine cannot do with a plant it does not integrate is locate a guard's
zero-crossing inside a step: there is no arc to search, only readings. A guard or invariant
on an external plant's state is therefore *sampled*: evaluated on the state the plant gives
at each step's end, that is at every instant the live loop takes (control ticks, ``after:``
deadlines, output samples, arrivals), and a flip there is taken as a crossing at that
instant. A guard crossed between two instants fires at the next one, at most one control
period (plus the age of the plant's reading) late.

Implementing another plant: a class with :meth:`ExternalPlant.command` and
:meth:`ExternalPlant.state`, passed as ``Simulator(cteam, 1, plants={agent_index: plant})``.
``command`` receives the agent's held inputs in the plant's input order (a unicycle's
``v, omega``) at every instant of the agent; ``state`` returns the agent's state in the
plant's state order (a unicycle's ``x, y, theta``) whenever the engine needs it, and may
block or raise to end the run. :func:`check_external` refuses an agent whose model
integrates its plant (a ``flow:`` plant, a continuous law). The live implementation is
:class:`hybridteam.live.ros2_plant.RobotPlant` (``hybridteam/live/ros2_plant.py``: a
robot over ROS 2 Twist and Odometry topics).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Protocol

import numpy as np

if TYPE_CHECKING:
    from hybridteam.engine.compile.compiled import CTeam


class ExternalPlant(Protocol):
    """An agent's plant outside the engine (module docstring)."""

    def command(self, inputs: np.ndarray, t: float) -> None:
        """Take the agent's held inputs (in the plant's input order) at run time ``t``."""

    def state(self, t: float) -> np.ndarray:
        """The agent's plant state (in the plant's state order) at run time ``t``: the
        plant's latest reading of it."""


def check_external(cteam: CTeam, plants: Mapping[int, ExternalPlant]) -> None:
    """ValueError for an external plant the engine cannot drive: one the agent's model
    would integrate (a ``flow:`` plant, a continuous law), whose inputs change at every
    Runge–Kutta stage rather than being held between instants."""
    for a in plants:
        if not 0 <= a < len(cteam.agents):
            raise ValueError(f"plants: no agent {a} in the team")
        ca = cteam.agents[a]
        if ca.plant.kind == "flow" or any(d.needs_rk for d in ca.drivers):
            raise ValueError(
                f"agent '{ca.name}': an external plant takes held inputs; "
                "its flow or continuous law would need the plant integrated"
            )
