"""Components that act only at some robots' sensing instants say so
(``WorldComponent.judged_agents``): a single run's instant at which none of them senses
calls no component at all; one component that may act at any instant is called at every
instant, and so are the others then."""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

import hybridteam as ht
from hybridteam.library import WorldAccess, WorldComponent, world_component


class _Counting(WorldComponent):
    """Counts its updates, and the instants it was called at."""

    params: ClassVar[dict[str, Any]] = {}

    def start(self, world: WorldAccess) -> None:
        self.called: list[float] = []

    def update(self, world: WorldAccess, idx: np.ndarray) -> None:
        self.called.append(float(world.t[idx[0]]))


@world_component("tests.at_ticks_of_a")
class AtTicksOfA(_Counting):
    """Acts at A's ticks alone."""

    def judged_agents(self) -> tuple[int, ...]:
        return (0,)


@world_component("tests.at_any_instant")
class AtAnyInstant(_Counting):
    """May act at any instant (the default)."""


TEAM = """\
team: ticks
agents:
  A:
    plant: {{kind: unicycle, state: {{x: 0, y: 0, theta: 0}}}}
    modes: {{Go: {{inputs: {{v: 0, omega: 0}}, period: 0.25}}}}
  B:
    plant: {{kind: unicycle, state: {{x: 1, y: 0, theta: 0}}}}
    modes: {{Go: {{inputs: {{v: 0, omega: 0}}, period: 0.1}}}}
world:
{world}
simulation: {{duration: 1}}
"""


def components(tmp_path, uses: list[str]) -> list[_Counting]:
    from hybridteam.engine.compile.compiler import compile_team
    from hybridteam.engine.run.simulator import Simulator

    path = tmp_path / "ticks.yaml"
    path.write_text(TEAM.format(world="\n".join(f"  - use: {u}" for u in uses)))
    sim = Simulator(compile_team(ht.load(path)), 1)
    sim.run()
    return [c for c in sim.ensemble.world.components if isinstance(c, _Counting)]


def test_a_component_judging_a_robot_is_called_at_its_ticks_alone(tmp_path):
    """A ticks every 0.25 s, B every 0.1 s: the run's instants are the union (0, 0.1,
    0.2, 0.25, 0.3, 0.4, 0.5, ...); the component judging A is called at A's ticks
    0, 0.25, 0.5, 0.75 and 1 (the end) only."""
    (judging,) = components(tmp_path, ["tests.at_ticks_of_a"])
    np.testing.assert_allclose(judging.called, [0.0, 0.25, 0.5, 0.75, 1.0], atol=1e-12)


def test_beside_one_acting_at_any_instant_every_component_is_called(tmp_path):
    """With a component that names no agents, each instant calls both (the judging one
    then tests its robots itself): B's ticks included."""
    judging, anytime = components(tmp_path, ["tests.at_ticks_of_a", "tests.at_any_instant"])
    assert judging.called == anytime.called
    assert len(anytime.called) >= 12  # 0, 0.1, ..., 1 and 0.25, 0.75
