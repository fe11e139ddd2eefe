"""The ladder library: the paper's sample run, physical limits, safety, batch independence,
and the vectorized stepper against the scalar reference loop."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hybridteam.modes.ladder import (
    Pairs,
    Settings,
    law,
    random_pairs,
    reference,
    sample_run,
    simulate,
)
from hybridteam.modes.ladder.guide import guide_paths
from hybridteam.modes.ladder.kernel import LINK_BROKEN, STUCK, SUCCESS
from hybridteam.modes.ladder.scene import law_params

from hybridteam.world import (
    corridor_with_turn,
    longest_ladder,
    point_segment_distances,
    segments_intersect,
    segments_intersect_polygon,
    two_grasp_slack,
)

CORRIDOR = corridor_with_turn()

#: Section 4, Fig. 8: steps, steps in the corner, path lengths, in-corner path lengths.
PAPER = {
    "steps": 855,
    "corner steps": 378,
    "path R1": 1592.86,
    "path R2": 1595.63,
    "corner path R1": 640.975,
    "corner path R2": 641.939,
}


def assert_safe(result, pairs):
    """No robot centre closer than its radius to a wall, no ladder meeting a wall: every step."""
    steps, n = result.trajectory.shape[:2]
    d, _ = point_segment_distances(result.trajectory.reshape(-1, 2), CORRIDOR.walls)
    gap = d.min(axis=1).reshape(steps, n, 2) - pairs.robot["radius"].T[None]
    assert np.nanmin(gap) >= 0.0
    hits = segments_intersect(result.tips.reshape(-1, 4), CORRIDOR.walls)
    assert not hits.any()


def corner_flags(result, i):
    """Whether the ladder meets the corner square before each step, by world geometry."""
    tips = result.tips[: result.steps[i], i].reshape(-1, 4)
    return segments_intersect_polygon(tips, CORRIDOR.corner)


def test_sample_run_reproduces_the_paper():
    pairs = Pairs.of(sample_run())
    r = simulate(pairs, record=True)
    assert r.outcome_names == ["success"]
    ours = {
        "steps": r.steps[0],
        "corner steps": r.corner_steps[0],
        "path R1": r.path[0, 0],
        "path R2": r.path[0, 1],
        "corner path R1": r.corner_path[0, 0],
        "corner path R2": r.corner_path[0, 1],
    }
    print("\nSection 4 sample run       paper       ours   deviation")
    for key, paper in PAPER.items():
        dev = 100.0 * (ours[key] - paper) / paper
        print(f"  {key:16s} {paper:12.3f} {ours[key]:10.3f}   {dev:+6.2f} %")
    for key, paper in PAPER.items():
        assert abs(ours[key] - paper) <= 0.10 * paper, key
    assert_safe(r, pairs)
    # The corner statistic agrees with the polygon test of the world geometry.
    flags = corner_flags(r, 0)
    assert flags.sum() == r.corner_steps[0]
    moved = np.hypot(*np.diff(r.trajectory[:, 0], axis=0).transpose(2, 0, 1))
    np.testing.assert_allclose(moved.sum(axis=0), r.path[0], rtol=1e-12)
    np.testing.assert_allclose(moved[flags].sum(axis=0), r.corner_path[0], rtol=1e-12)
    assert np.all(r.max_offset[0] <= 10.0)
    # It ends on the goals.
    np.testing.assert_allclose(r.position[0], r.scene.goal[:, 0], atol=Settings().arrive_tol)


def test_ladder_485_succeeds():
    pairs = Pairs.of(replace(sample_run(), length=485.0))
    r = simulate(pairs, record=True)
    assert r.outcome_names == ["success"]
    assert_safe(r, pairs)


def test_ladder_beyond_the_physical_limit_never_succeeds():
    """Past the robots' rigid limit plus the springs' slack no pair gets round the corner."""
    sample = sample_run()
    f, b = sample.front, sample.rear
    limit = longest_ladder(200, 200, max(f.radius, b.radius)) + two_grasp_slack(
        f.olim, b.olim, f.sc, b.sc
    )
    lengths = [limit + 1.0, limit + 30.0]
    pairs = Pairs.of([replace(sample, length=L) for L in lengths])
    r = simulate(pairs, record=True)
    assert SUCCESS not in r.outcome
    assert_safe(r, pairs)
    pop = random_pairs(np.random.default_rng(7), 24, length=1.0)
    slack = two_grasp_slack(10.0, 10.0, 1.0, 1.0)
    pop = Pairs(np.full(24, longest_ladder(200, 200, 26.0) + slack + 1.0), pop.robot)
    r = simulate(pop, record=True)
    assert SUCCESS not in r.outcome and set(r.outcome) <= {STUCK, LINK_BROKEN}
    assert_safe(r, pop)


def test_random_population_is_safe_and_counts_the_corner_right():
    pairs = random_pairs(np.random.default_rng(3), 30, length=420.0)
    r = simulate(pairs, record=True)
    assert_safe(r, pairs)
    for i in range(0, 30, 3):
        assert corner_flags(r, i).sum() == r.corner_steps[i]


def test_ensemble_equals_single_runs_exactly():
    """100 random pairs (the paper's population S) in one batch = 100 runs of one pair."""
    pairs = random_pairs(np.random.default_rng(2024), 100, length=450.0)
    batch = simulate(pairs)
    assert len(set(batch.outcome.tolist())) == 3  # successes, stuck and broken links
    for i in range(100):
        one = simulate(pairs.take(i))
        for name in (
            "outcome",
            "steps",
            "corner_steps",
            "path",
            "corner_path",
            "max_offset",
            "position",
        ):
            assert np.array_equal(getattr(batch, name)[i], getattr(one, name)[0]), (i, name)


def _reference_cases():
    sample = sample_run()
    pop = random_pairs(np.random.default_rng(11), 3, length=400.0)
    spin = replace(
        sample,
        front=replace(sample.front, kr=1.0),
        rear=replace(sample.rear, kr=0.5, orsp=3.0, lookahead=0),
    )
    return [sample, spin, *[pop.scenario(i) for i in range(3)]]


def test_kernel_agrees_with_the_scalar_reference():
    cases = _reference_cases()
    batch = simulate(Pairs.of(cases), record=True)
    for i, case in enumerate(cases):
        ref = reference.run(case, record=True)
        assert ref.outcome[0] == batch.outcome[i]
        assert ref.steps[0] == batch.steps[i]
        assert ref.corner_steps[0] == batch.corner_steps[i]
        steps = ref.steps[0] + 1
        np.testing.assert_allclose(
            ref.trajectory[:, 0], batch.trajectory[:steps, i], rtol=0, atol=1e-9
        )
        np.testing.assert_allclose(ref.tips[:, 0], batch.tips[:steps, i], rtol=0, atol=1e-9)
        np.testing.assert_allclose(ref.path[0], batch.path[i], rtol=1e-12)
        np.testing.assert_allclose(ref.corner_path[0], batch.corner_path[i], rtol=1e-12)
        np.testing.assert_allclose(ref.max_offset[0], batch.max_offset[i], rtol=1e-12)


def _tracked_index(path, positions, window):
    """The windowed nearest-point index along a recorded trajectory, and the global one."""
    idx, out, glob = 0, [], []
    last = len(path) - 1
    for p in positions:
        d = np.hypot(*(path - p).T)
        cand = np.clip(np.arange(idx - window, idx + window + 1), 0, last)
        idx = int(np.clip(idx + np.argmin(d[cand]) - window, 0, last))
        out.append(idx)
        glob.append(int(np.argmin(d)))
    return np.array(out), np.array(glob)


def test_law_step_is_the_kernels_law_per_robot():
    """The per-robot law in world coordinates reproduces the stepper's synchronous moves."""
    cases = _reference_cases()[:2]
    pairs = Pairs.of(cases)
    r = simulate(pairs, record=True)
    settings = Settings()
    for row in range(2):
        prm = law_params(pairs, r.scene, row)
        for i in range(2):
            traj = r.trajectory[: r.steps[i] + 1, i]
            path = r.scene.paths[row, i]
            tracked, nearest = _tracked_index(path, traj[:-1, row], settings.window)
            # The windowed search finds the global nearest point all along the run.
            np.testing.assert_array_equal(tracked, nearest)
            prev = np.concatenate([[0], tracked[:-1]])
            for t in range(0, r.steps[i], 37):
                one = {k: v[i : i + 1] for k, v in prm.items()}
                move, idx = law.step(
                    traj[t : t + 1, row],
                    traj[t : t + 1, 1 - row],
                    path[None],
                    prev[t : t + 1],
                    one,
                    CORRIDOR,
                    window=settings.window,
                )
                assert idx[0] == tracked[t]
                np.testing.assert_allclose(
                    move[0], traj[t + 1, row] - traj[t, row], rtol=0, atol=1e-9
                )


def test_guide_paths():
    start = np.array([[100.0, 70.0], [100.0, 70.0], [100.0, 520.0]])
    goal = np.array([[1130.0, 1100.0], [1130.0, 1100.0], [680.0, 1100.0]])
    alpha = np.array([0.35, 0.9, 0.65])
    paths = guide_paths(CORRIDOR, start, goal, alpha, approach=200.0)
    assert paths.shape == (3, 160, 2)
    np.testing.assert_array_equal(paths[:, 0], start)
    np.testing.assert_array_equal(paths[:, -1], goal)
    # Equally spaced along the arc: chords differ from each other only where the path
    # bends (a chord is shorter than its arc), by well under 1 %.
    gaps = np.hypot(*np.diff(paths, axis=1).transpose(2, 0, 1))
    assert np.all(gaps >= 0.99 * gaps.max(axis=1, keepdims=True))

    # A larger alpha takes a more outer route: it crosses the corner's entry edge nearer
    # the outer wall (x = 0) and its exit edge nearer the outer wall (y = 1200).
    def crossing(path, axis, level):
        k = np.flatnonzero(np.diff(np.sign(path[:, axis] - level)))[0]
        s = (level - path[k, axis]) / (path[k + 1, axis] - path[k, axis])
        return path[k, 1 - axis] + s * (path[k + 1, 1 - axis] - path[k, 1 - axis])

    assert crossing(paths[1], 1, 1000.0) < crossing(paths[0], 1, 1000.0)
    assert crossing(paths[1], 0, 200.0) > crossing(paths[0], 0, 200.0)
    # Each path is computed on its own.
    one = guide_paths(CORRIDOR, start[1:2], goal[1:2], alpha[1:2], approach=200.0)
    assert np.array_equal(one[0], paths[1])


def test_population_ranges():
    pairs = random_pairs(np.random.default_rng(0), 200)
    r = pairs.robot
    olim = r["olim"]
    assert np.all((r["orsp"] >= 0) & (r["orsp"] <= 0.2 * olim))
    assert np.all((r["v_max"] >= 0.5) & (r["v_max"] <= 1.5))
    assert set(np.unique(r["lookahead"]).astype(int)) <= set(range(21))
    assert np.all((r["alpha"] >= 0.35) & (r["alpha"] <= 0.9))
    assert np.all(r["kc"] == 1) and np.all(r["sc"] == 1) and np.all(r["kr"] == 0)
    # Pair i does not depend on how many pairs are drawn.
    few = random_pairs(np.random.default_rng(0), 5)
    for k in r:
        np.testing.assert_array_equal(few.robot[k], r[k][:, :5])


@pytest.mark.parametrize("turn", ["left", "right"])
def test_turn_direction_does_not_change_the_run(turn):
    """The law runs in the corner frame, so a left turn is the mirror image of a right one."""
    base = simulate(Pairs.of(sample_run()))
    other = simulate(Pairs.of(sample_run()), corridor_with_turn(turn=turn))
    assert other.steps[0] == base.steps[0] and other.corner_steps[0] == base.corner_steps[0]
    np.testing.assert_allclose(other.path, base.path, rtol=1e-9)
    mirror = np.array([1.0 if turn == "right" else -1.0, 1.0])
    np.testing.assert_allclose(other.position, base.position * mirror, atol=1e-6)
