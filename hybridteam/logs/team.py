"""What a log is read against: the team's trace header and its parameters.

A robot's log says nothing about the model, so the header of the trace made from it (agents,
their state names and modes, world series, payloads) and the parameter values its
requirements read are the ones a run of the team starts with: a simulator is built and run
for no time at all, so both come from the code that makes them for every run.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from hybridteam.api import parameters
from hybridteam.engine.compile.compiler import compile_team
from hybridteam.engine.run.simulator import Simulator
from hybridteam.model import Team


def team_frame(team: Team) -> tuple[dict[str, Any], dict[str, tuple[list[str], np.ndarray]]]:
    """``(meta, params)`` of one instance of ``team``: the trace header of a run of it, and
    per agent its parameter names and values (one row), as requirement checks read them."""
    sim = Simulator(compile_team(team), 1, seed=team.simulation.seed, duration=0.0)
    return sim.run().meta, parameters(sim)
