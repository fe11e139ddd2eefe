"""Detect rules' verdicts from bounds on what a ring reads of a box payload (world/sight.py):
the bounds hold the cast's readings, verdicts kept under small motions stay the cast's,
and a run takes them without changing its trace."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from hybridteam import load
from hybridteam.api import Run
from hybridteam.engine.compile.compiler import compile_team
from hybridteam.engine.run.simulator import Simulator
from hybridteam.floatpaths import FLOAT_PATHS
from hybridteam.world import sight
from hybridteam.world.obstacles import Obstacles
from hybridteam.world.raycast import cast
from hybridteam.world.sensors import RangeRing

ROOT = Path(__file__).resolve().parents[2]
IR = RangeRing(24, 0.8, mount_radius=0.3)
SONAR = RangeRing(16, 5.0, 0.05, mount_radius=0.2, half_angle=0.2, rays_per_beam=3)


def cast_in_box_frame(ring: RangeRing, beams, pose, hw: float, hd: float) -> np.ndarray:
    """What the ring on a robot at ``pose`` (box frame) reads of the box's outline, each
    beam its nearest ray: the cast the component makes (raycast), without clipping."""
    corners = np.array([[-hw, -hd], [hw, -hd], [hw, hd], [-hw, hd]])
    edges = np.c_[corners, np.roll(corners, -1, axis=0)]
    origins, directions = ring.rays(np.array([pose]), beams)
    dist = cast(origins, directions, edges, None, np.inf)[0]
    return np.minimum.reduce(dist.reshape(beams.size, ring.rays_per_beam), axis=1)


def test_the_bounds_hold_a_hand_computed_reading_and_a_miss():
    """A ring of 4 beams mounted 0.3 from the centre, the robot at (-1, 0) facing +x in
    the frame of a box 0.8 by 0.5: beam 0 meets the face x = -0.4 at 1 - 0.3 - 0.4 = 0.3;
    beams 1 and 3 look along y from x = -1, beside the box, and beam 2 away from it: they
    miss it. The bounds are within the margin of the reading and infinite for a miss."""
    ring = RangeRing(4, 2.0, mount_radius=0.3)
    beams = np.arange(4)
    lower, upper = sight.box_reading_bounds(ring, beams, (-1.0, 0.0, 0.0), 0.4, 0.25)
    margin = sight.MARGIN * (1 + 0.4 + 0.25)
    assert lower[0] == pytest.approx(0.3 - margin, abs=1e-12)
    assert upper[0] == pytest.approx(0.3 + margin, abs=1e-12)
    assert lower[1:].tolist() == [math.inf] * 3 and upper[1:].tolist() == [math.inf] * 3
    # every sensor inside a box 0.8 by 0.8 (under a carried box): every bound is open
    lower, upper = sight.box_reading_bounds(ring, beams, (0.05, 0.0, 0.0), 0.4, 0.4)
    assert lower.tolist() == [0.0] * 4 and upper.tolist() == [math.inf] * 4


@pytest.mark.parametrize("ring", [IR, SONAR], ids=["ir", "sonar cone"])
def test_the_bounds_hold_the_cast_on_random_and_aligned_poses(ring):
    """Every beam's cast reading lies within its bounds: random poses around boxes of
    random sizes, a third of them aligned with the box and a beam (rays along its axes,
    through its corners' lines), origins inside the box included."""
    rng = np.random.default_rng(7)
    beams = np.arange(ring.count)
    for trial in range(600):
        hw, hd = rng.uniform(0.05, 1.0, 2)
        pose = (*rng.uniform(-2.5, 2.5, 2), rng.uniform(-4.0, 4.0))
        if trial % 3 == 0:  # headings on the beams' grid: rays parallel to the faces
            pose = (pose[0], pose[1], round(pose[2] / (math.pi / 12)) * (math.pi / 12))
        lower, upper = sight.box_reading_bounds(ring, beams, pose, hw, hd)
        reading = cast_in_box_frame(ring, beams, pose, hw, hd)
        assert np.all(lower <= reading) and np.all(reading <= upper), (pose, hw, hd)


@pytest.mark.parametrize("ring", [IR, SONAR], ids=["ir", "sonar cone"])
def test_verdicts_proved_by_the_bounds_stay_the_casts_under_the_allowed_motion(ring):
    """The component's rule: a beam surely reads below a threshold where its upper bound
    is a margin below it, surely not where its lower bound is at least it; such a verdict
    is kept while the ring moves no more than ``kept_for`` relative to the box. Cast
    again after random motions that size: the reading is on the verdict's side."""
    rng = np.random.default_rng(11)
    checked = 0
    for _ in range(3000):
        hw, hd = rng.uniform(0.1, 0.8, 2)
        beam = np.array([rng.integers(ring.count)])
        pose = (*rng.uniform(-1.5, 1.5, 2), rng.uniform(-4.0, 4.0))
        below = rng.uniform(0.05, 1.2)
        allow = sight.kept_for(hw, hd)
        lower, upper = sight.box_reading_bounds(ring, beam, pose, hw, hd)
        if ring.min_range < below and upper[0] < below - allow:
            seen = True
        elif below <= ring.max_range and lower[0] >= below:
            seen = False
        else:
            continue
        step = rng.normal(size=3)
        reach = ring.mount_radius + below
        now = tuple(np.add(pose, step * allow / sight.motion((0, 0, 0), tuple(step), reach)))
        assert sight.motion(pose, now, reach) <= allow * (1 + 1e-9)
        reading = max(cast_in_box_frame(ring, beam, now, hw, hd)[0], ring.min_range)
        assert (min(reading, ring.max_range) < below) == seen, (pose, now, hw, hd, below)
        checked += 1
    assert checked > 1500  # most draws are settled by the bounds


def run_counting(name: str) -> tuple[str, Obstacles]:
    """A transport experiment's trace and its obstacles component (its counters)."""
    team = load(ROOT / "examples" / "transport" / f"{name}.yaml")
    sim = Simulator(compile_team(team), 1)
    run = Run.of(sim.run())
    (obstacles,) = [c for c in sim.ensemble.world.components if isinstance(c, Obstacles)]
    return run.to_json(), obstacles


def test_experiment_2_takes_the_proved_verdicts_with_the_casts_trace():
    """Experiment 2's XR4000 carries the box its IR ring sees, and passes a post: its rules'
    verdicts come from the bounds (proved, or kept), with the post cast alone where it is
    within reach, or are the last ones where nothing moved, at most of its ticks; the run's
    trace is the one the casts give (the float paths off: every rule reads its cast
    beams)."""
    fast, sighted = run_counting("experiment2")
    with FLOAT_PATHS.off():
        cast_only, casting = run_counting("experiment2")
    work = sighted.work
    assert casting.work.proved == casting.work.kept == casting.work.still == 0
    assert min(work.proved, work.kept, work.statics, work.still) > 50
    assert work.reads < casting.work.reads / 4  # (the approach law's own readings remain)
    assert fast == cast_only


@pytest.mark.slow
def test_experiment_3_takes_the_proved_verdicts_with_the_casts_trace():
    """Experiment 3 adds the Scout's sonar (a cone of three rays a beam) behind the team,
    with jitter on the links: the same trace with the casts only."""
    fast, sighted = run_counting("experiment3")
    with FLOAT_PATHS.off():
        cast_only, _ = run_counting("experiment3")
    assert sighted.work.proved + sighted.work.kept > 1000
    assert fast == cast_only
