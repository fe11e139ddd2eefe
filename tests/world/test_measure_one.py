"""A single run's clearances on floats in a scene of posts (world/measure_one.py): the
array version's numbers, bit for bit, and its collisions left to it."""

from __future__ import annotations

import numpy as np

from hybridteam.api import load
from hybridteam.engine.compile.compiler import compile_team
from hybridteam.engine.run.simulator import Simulator
from hybridteam.floatpaths import FLOAT_PATHS
from hybridteam.world.carried import CarriedPayload
from hybridteam.world.obstacles import Obstacles

#: three planar robots (footprints 0.3, 0.2 and none), a box held by two of them, a bar
#: by the third, and three posts; collisions only warned of, so the run goes on
POSTS = """
kind: team
team: posts
world:
  - use: payload
    with:
      name: box
      width: 0.8
      depth: 0.5
      pose: [0, 0, 0]
      grasps: [{agent: A, point: [-0.4, 0]}, {agent: B, point: [0.4, 0]}]
  - use: payload
    with: {name: rod, shape: bar, length: 1.0, pose: [2, 2, 0.5], grasps: [{agent: C}]}
  - use: obstacles
    with:
      circles: [[1.5, 0.5, 0.2], [-1.0, 1.2, 0.4], [0.3, -1.4, 0.1]]
      radius: [[A, 0.3], [B, 0.2]]
      on_collision: warn
agents:
  A:
    plant: {kind: holonomic, state: {x: -1, y: 0, theta: 0}}
    modes: {S: {inputs: {vx: 0, vy: 0, omega: 0}, period: 0.1}}
  B:
    plant: {kind: holonomic, state: {x: 1, y: 0, theta: 0}}
    modes: {S: {inputs: {vx: 0, vy: 0, omega: 0}, period: 0.1}}
  C:
    plant: {kind: holonomic, state: {x: 2, y: 2, theta: 0}}
    modes: {S: {inputs: {vx: 0, vy: 0, omega: 0}, period: 0.1}}
simulation: {duration: 1}
"""


def test_a_single_instants_clearances_on_floats_are_the_array_versions(tmp_path):
    """Random poses of the robots and the payloads, random sensing robots and running
    minima: the float path leaves the same minima, reach and collisions as the array
    version (``FLOAT_PATHS.off()``), also where robots overlap posts or each other and
    where a payload touches a post (there it defers to the array version)."""
    path = tmp_path / "posts.yaml"
    path.write_text(POSTS)
    sim = Simulator(compile_team(load(path)), 1, duration=0.0)
    sim.run()
    components = sim.ensemble.world.components
    (obs,) = [c for c in components if isinstance(c, Obstacles)]
    payloads = [c for c in components if isinstance(c, CarriedPayload)]
    world, idx, scene = obs.world, np.arange(1), obs.scenes[0]
    rng = np.random.default_rng(3)
    collided = 0
    for trial in range(400):
        for a in range(3):
            world.set_state(a, idx, rng.uniform(-2.5, 2.5, (1, 3)), ["x", "y", "theta"])
        if trial % 4 == 0:  # B grazing A: footprints (0.3 + 0.2) apart within 0.02
            a_pose, turn = world.pose(0, idx)[0], rng.uniform(0, 2 * np.pi)
            gap = 0.5 + rng.uniform(-0.02, 0.02)
            b_pose = a_pose + np.array([gap * np.cos(turn), gap * np.sin(turn), 0.0])
            world.set_state(1, idx, b_pose[None], ["x", "y", "theta"])
        for p in payloads:
            p.pose[0] = rng.uniform(-2.5, 2.5, 3)
        sensing = {a: np.array([rng.random() < 0.7]) for a in range(3)}
        start = (rng.uniform(-0.5, 2.0, obs.min_clear.shape), rng.uniform(0.0, 2.0, 1))
        results = []
        for floats in (True, False):
            obs.min_clear[:], obs.payload_clear[:] = start
            obs.collisions = [{}]
            if floats:
                reach = obs._measure(world, idx, scene, sensing)
            else:
                with FLOAT_PATHS.off():
                    reach = obs._measure(world, idx, scene, sensing)
            results.append(
                (
                    obs.min_clear.tobytes(),
                    obs.payload_clear.tobytes(),
                    {a: r.tobytes() for a, r in reach.items()},
                    obs.collisions[0],
                )
            )
        assert results[0] == results[1]
        collided += bool(results[1][3])
    assert 20 < collided < 380  # both kinds of instant were drawn
