"""A world component writes an agent's variable (``WorldAccess.set_variable``) as an
assignment would: per instance, and the guards that read it are taken at that instant.

The battery below drains ``battery`` from 1 at ``rate`` per second; the robot's law ticks
every 0.25 s, the run's only instants. The guard ``battery <= 0.3`` becomes true at
t* = 0.7 / rate and is taken at the first instant at or after it: 5.75 s for rate 0.125
(t* = 5.6), 11.25 s for rate 0.0625 (t* = 11.2).
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
import pytest

import hybridteam as ht
from hybridteam.library import WorldAccess, WorldComponent, world_component


@world_component("tests.battery")
class Battery(WorldComponent):
    """``battery`` = its value at the start - rate * t, written at every instant; with
    ``only`` >= 0, in that instance alone."""

    params: ClassVar[dict[str, Any]] = {
        "robot": "rover",
        "rate": 0.1,
        "only": -1.0,
        "variable": "battery",
    }

    def start(self, world: WorldAccess) -> None:
        self.full = world.variable(self.values["robot"], self.values["variable"], np.arange(self.n))

    def update(self, world: WorldAccess, idx: np.ndarray) -> None:
        only = int(self.values["only"][0])
        if only >= 0:
            idx = idx[idx == only]
        charge = self.full[idx] - self.values["rate"][idx] * world.t[idx]
        world.set_variable(self.values["robot"], self.values["variable"], idx, charge)


TEAM = """\
team: battery
parameters: {{drain: 0.125}}
agents:
  rover:
    plant: {{kind: unicycle, state: {{x: 0, y: 0, theta: 0}}}}
    variables: {{battery: 1.0}}
    initial: Drive
    modes:
      Drive:
        inputs: {{v: 0.2, omega: 0}}
        period: 0.25
        transitions: [{{to: Low, guard: battery <= 0.3}}]
      Low: {{inputs: {{v: 0, omega: 0}}, period: 0.25, final: true, outcome: low_battery}}
world:
  - use: tests.battery
    with: {{robot: rover, rate: drain{extra}}}
simulation: {{duration: 20}}
"""


def team(team_from_yaml, extra: str = ""):
    return team_from_yaml(TEAM.format(extra=extra))


def test_the_guard_on_a_written_variable_fires_at_the_first_instant_past_the_crossing(
    team_from_yaml,
):
    run = ht.simulate(team(team_from_yaml))
    (d,) = run.diagnostics
    assert d["outcome"] == "low_battery"
    assert d["t"] == pytest.approx(5.75, abs=1e-12)
    tr = run.transitions
    (k,) = np.flatnonzero(np.char.endswith(np.asarray(tr["target"], str), "Low"))
    assert tr["t"][k] == pytest.approx(5.75, abs=1e-12) and tr["cause"][k] == "guard"


def test_each_instance_drains_at_its_own_rate_and_equals_its_single_run(team_from_yaml):
    t = team(team_from_yaml)
    run = ht.simulate(t, n=2, overrides={"drain": [0.125, 0.0625]})
    assert [d["t"] for d in run.diagnostics] == pytest.approx([5.75, 11.25], abs=1e-12)
    one = ht.simulate(t, overrides={"drain": [0.0625]})
    assert one.diagnostics[0]["t"] == run.diagnostics[1]["t"]


def test_a_write_touches_only_its_instances(team_from_yaml):
    run = ht.simulate(team(team_from_yaml, ", only: 1"), n=2)
    assert run.outcomes == ["ok", "low_battery"]  # instance 0 keeps its full battery


@world_component("tests.nan_battery")
class NanBattery(Battery):
    """Writes NaN: a component's bug, refused where it happens."""

    def update(self, world: WorldAccess, idx: np.ndarray) -> None:
        world.set_variable(self.values["robot"], "battery", idx, np.nan)


def test_a_variable_that_is_not_a_finite_number_or_unknown_is_refused(team_from_yaml):
    nan = team_from_yaml(TEAM.format(extra="").replace("tests.battery", "tests.nan_battery"))
    with pytest.raises(
        ValueError,
        match=r"set_variable: 'rover.battery' would be nan in "
        r"instance 0",
    ):
        ht.simulate(nan)
    with pytest.raises(
        ValueError,
        match=r"agent 'rover' has no variable 'batery'.*did you "
        r"mean 'battery'",
    ):
        ht.simulate(team(team_from_yaml, ", variable: batery"))
