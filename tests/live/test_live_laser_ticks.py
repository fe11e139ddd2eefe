"""A robot's detect rules on its laser (:class:`hybridteam.live.world.WorldReadings`) read
the laser at the robot's sensing instants — its law ticks — as the simulator's
``obstacles`` component reads its rings: a message arriving between two ticks reads no
laser, and what the rule saw at the last tick stands. Driven without ROS: the laser is a
stand-in, the sensing instants are set by the test."""

from __future__ import annotations

import numpy as np

from hybridteam.engine.compile.compiler import compile_team
from hybridteam.engine.run.simulator import Simulator
from hybridteam.live.wire import Codec
from hybridteam.live.world import WorldLink, WorldReadings, world_seam
from tests.live.test_live_world import Sent

TEAM = """
team: laser
world:
  - use: obstacles
    with:
      detect:
        - {agent: robot, sensor: ir, ring: {count: 4, max_range: 2.5}, below: 0.1, raise: near}
agents:
  robot:
    plant: {kind: unicycle, state: {x: 0.0, y: 0.0, theta: 0.0}}
    initial: Look
    modes:
      Look: {inputs: {v: 0, omega: 0}, period: 0.1, transitions: [{to: Look, on: near}]}
simulation: {duration: 1}
"""

FAR, NEAR = [2.5] * 4, [2.5, 0.05, 2.5, 2.5]  # beam 1 below the rule's 0.1, or none


class Laser:
    """What the robot's laser reads as its ring, set by the test."""

    def __init__(self) -> None:
        self.values = FAR

    def ranges(self, ring):
        return np.asarray(self.values, float)


class Ticking:
    """The agents' process's engine access, but for whether the robot senses now (set
    by the test) and a record of the events raised."""

    def __init__(self, access) -> None:
        self._access = access
        self.ticks = True
        self.raised: list[str] = []

    def sensing(self, agent, idx):
        return np.full(len(idx), self.ticks)

    def raise_event(self, idx, agent, event) -> None:
        self.raised.append(event)
        self._access.raise_event(idx, agent, event)

    def __getattr__(self, name):
        return getattr(self._access, name)


def test_a_lasers_detect_rule_reads_at_its_robots_ticks_only(team_from_yaml):
    cteam = compile_team(team_from_yaml(TEAM))
    link = WorldLink(Codec(cteam, frozenset({"ir"})), Sent(), [0], host=False)
    sim = Simulator(cteam, 1, world=world_seam(WorldReadings, link))
    world, idx = sim.ensemble.world, np.array([0])
    laser = Laser()
    world.read_lasers({0: laser})
    access = Ticking(sim.access)

    def instant(ticks: bool, values: list[float]) -> None:
        access.ticks, laser.values = ticks, values
        world.update(access, idx)

    instant(True, FAR)  # a tick: nothing near
    instant(False, NEAR)  # arrivals between ticks: the laser is not read,
    instant(False, FAR)  # whatever it shows
    assert access.raised == []
    instant(True, NEAR)  # the next tick sees it: raised once
    assert access.raised == ["near"]
    instant(False, FAR)  # gone between ticks, back by the next: still the same approach
    instant(True, NEAR)
    assert access.raised == ["near"]
    instant(True, FAR)  # gone at a tick, back at the next: a new approach
    instant(True, NEAR)
    assert access.raised == ["near", "near"]
