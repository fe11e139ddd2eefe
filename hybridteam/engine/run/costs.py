"""What a run's crossing search cost: counters the engine keeps as it goes.

They play the part scipy's ``OdeResult.nfev`` plays for ``solve_ivp``: a test of the search
asserts how much work a case takes by reading them, not by wrapping the engine's functions,
so a refactor that keeps the work keeps the counts (and one that changes the work says so).
They are read after a run (:attr:`Simulator.costs
<hybridteam.engine.run.simulator.Simulator.costs>`, ``Run.costs``) and never during it: no
result depends on them, and counting is one integer addition per search call.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class Costs:
    """The crossing search's work over a whole run, all instances together."""

    #: True steps: Runge–Kutta steps integrated from a step's start to a time the search
    #: chose (its trial points, and the state at a located crossing), one per call over
    #: however many instances it integrates at once (a single run's: one per instance).
    true_steps: int = 0
    #: Flips located, one per instance and flip: searched for the crossing's time (on the
    #: dense output, then on true steps where it may matter), as opposed to flips passed
    #: without locating them (foregone, see :data:`.crossing.search.SKIP_FOREGONE`).
    located: int = 0
