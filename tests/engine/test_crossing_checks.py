"""Crossing location with ``simulation.crossing_checks: 0`` (only the step's ends checked).

Regression: the per-agent search results were kept in a list that an agent with watched
atoms but no flip did not append to, so a later agent's states at the crossing were
written into an earlier agent (a constant w = 7 became the other agent's 0.5), or the run
crashed when the two agents' states differ in size.
"""

from __future__ import annotations

import numpy as np
import pytest

import hybridteam as ht

TEAM = """
team: pair
agents:
  still:
    plant: {{kind: flow, state: {{{still_state}}}}}
    initial: Hold
    modes:
      Hold:
        flow: {{w: 0}}
        transitions:
          - {{to: Done, guard: w > 100}}        # watched, never flips
      Done: {{final: true}}
  mover:
    plant: {{kind: flow, state: {{x: 0.0}}}}
    initial: Go
    modes:
      Go:
        flow: {{x: 1}}
        transitions:
          - {{to: Stop, guard: x >= 0.5}}       # crosses at t = 0.5
      Stop:
        flow: {{x: 0}}
simulation: {{duration: 1.0, sample_period: 0.25, crossing_checks: {checks}}}
"""


@pytest.mark.parametrize("checks", [0, 2])
@pytest.mark.parametrize("still_state", ["w: 7.0", "w: 7.0, z: 3.0"])
def test_an_agent_keeps_its_state_when_another_one_crosses(team_from_yaml, checks, still_state):
    run = ht.simulate(team_from_yaml(TEAM.format(checks=checks, still_state=still_state)))
    (stop,) = run.transitions.filter(run.transitions["target"] == "Stop")
    assert stop.t == pytest.approx(0.5, abs=1e-9)
    still = run.samples["still"][:, 0]
    np.testing.assert_array_equal(still[:, 0], 7.0)  # w never changes
    if still.shape[1] == 2:
        np.testing.assert_array_equal(still[:, 1], 3.0)
    np.testing.assert_allclose(run.samples["mover"][:, 0, 0], [0.0, 0.25, 0.5, 0.5, 0.5], atol=1e-9)
