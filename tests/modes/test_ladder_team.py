"""The ladder library through the engine: the YAML team, its world component, the CLI.

The engine path (two holonomic agents under ``ladder.carry``, the ``ladder.corridor``
world judging outcomes and keeping statistics) must reproduce the vectorized stepper, which
the kernel tests pin to the paper; the stepper's batch path for studies must give the
engine's rows instance by instance.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hybridteam.modes.ladder import Pairs, random_pairs, sample_run
from hybridteam.modes.ladder import simulate as kernel
from hybridteam.modes.ladder.params import ROBOT_FIELDS

from hybridteam.api import load, simulate, summaries
from hybridteam.cli import main
from hybridteam.world import corridor_with_turn, point_segment_distances, segments_intersect

SAMPLE = Path(__file__).resolve().parents[2] / "examples" / "ladder" / "sample.yaml"
PAPER = {
    "steps": 855,
    "steps_in_corner": 378,
    "path_length": (1592.86, 1595.63),
    "corner_path_length": (640.975, 641.939),
}
LISTS = ("path_length", "corner_path_length", "max_offset")


def overrides_for(pairs: Pairs) -> dict[str, np.ndarray]:
    ov: dict[str, np.ndarray] = {"length": pairs.length}
    for row, name in enumerate(("R1", "R2")):
        for k in ROBOT_FIELDS:
            ov[f"{name}.{k}"] = pairs.robot[k][row]
    return ov


def assert_same_rows(a: list[dict], b: list[dict]) -> None:
    assert len(a) == len(b)
    for x, y in zip(a, b, strict=True):
        assert set(x) == set(y)
        for key in x:
            if key in LISTS:
                np.testing.assert_allclose(x[key], y[key], rtol=1e-9, atol=1e-9, err_msg=key)
            else:
                assert x[key] == y[key], (x["instance"], key, x[key], y[key])


def test_sample_team_reproduces_the_stepper_and_the_paper():
    run = simulate(load(SAMPLE))
    row = run.summary()["instances"][0]
    assert row["outcome"] == "success"
    k = kernel(Pairs.of(sample_run()))
    assert row["steps"] == k.steps[0] == row["t_end"]
    assert row["steps_in_corner"] == k.corner_steps[0]
    np.testing.assert_allclose(row["path_length"], k.path[0], rtol=1e-12)
    np.testing.assert_allclose(row["corner_path_length"], k.corner_path[0], rtol=1e-12)
    np.testing.assert_allclose(row["max_offset"], k.max_offset[0], rtol=1e-9)
    print("\nSection 4 sample run through the engine (paper -> ours, deviation):")
    for key, target in PAPER.items():
        for paper, ours in zip(np.atleast_1d(target), np.atleast_1d(row[key]), strict=True):
            dev = (ours - paper) / paper
            print(f"  {key:20s} {paper:9.3f} -> {ours:9.3f}  {dev:+.2%}")
            assert abs(dev) <= 0.10
    # the modes tell the same story: Carry until both robots arrive
    tr = run.transitions
    assert sorted(tr["target"][tr["cause"] == "event:arrived"].tolist()) == ["Arrived"] * 2


def test_sample_run_is_safe_at_every_step():
    run = simulate(load(SAMPLE))
    corridor = corridor_with_turn()
    for name in ("R1", "R2"):
        xy = run.samples[name][:, 0, :2]
        xy = xy[~np.isnan(xy[:, 0])]
        d, _ = point_segment_distances(xy, corridor.walls)
        assert d.min() >= 26.0
    lad = run.samples["ladder"][:, 0]
    lad = lad[~np.isnan(lad[:, 0])]
    half = 225.0 * np.c_[np.cos(lad[:, 2]), np.sin(lad[:, 2])]
    segs = np.hstack([lad[:, :2] - half, lad[:, :2] + half])
    assert not segments_intersect(segs, corridor.walls).any()
    assert run.meta["payloads"] == ["ladder"]
    assert run.meta["world"]["regions"][0]["label"] == "corner"


def test_ladder_485_succeeds_through_the_engine():
    (row,) = summaries(load(SAMPLE), 1, {"length": 485.0}, accelerate=False)
    assert row["outcome"] == "success"


def test_engine_ensemble_equals_the_batch_stepper_instance_by_instance():
    pairs = random_pairs(np.random.default_rng(11), 12, length=480.0)
    team = load(SAMPLE)
    engine = summaries(team, 12, overrides_for(pairs), accelerate=False)
    batch = summaries(team, 12, overrides_for(pairs))
    # the batch path keeps no trace, so only the engine checks the sample's requirement;
    # its robustness is the smallest margin to the offset limit the batch path measured
    verdicts = [row.pop("requirements") for row in engine]
    assert all("requirements" not in row for row in batch)
    assert_same_rows(engine, batch)
    for i, (both, row) in enumerate(zip(verdicts, batch, strict=True)):
        verdict = both["no_link_break"]
        margin = min(pairs.robot["olim"][k][i] - row["max_offset"][k] for k in (0, 1))
        assert verdict["robustness"] == pytest.approx(margin, abs=1e-9)
        assert verdict["satisfied"] == (row["outcome"] != "link_break")
    assert len({r["outcome"] for r in engine}) >= 2  # the comparison covers several endings
    single = summaries(team, 1, overrides_for(pairs.take(slice(5, 6))), accelerate=False)
    assert_same_rows(single, [{**engine[5], "instance": 0, "requirements": verdicts[5]}])


def test_batch_path_declines_teams_it_does_not_compute(tmp_path):
    text = SAMPLE.read_text().replace(
        "          - {to: Stuck, on: stuck}",
        "          - {to: Stuck, on: stuck}\n          - {to: Stuck, guard: t > 5000}",
    )
    path = tmp_path / "guarded.yaml"
    path.write_text(text)
    from hybridteam.engine.compile.compiler import compile_team
    from hybridteam.engine.run.batch import batch_rows

    assert batch_rows(compile_team(load(path)), 1, {}, 0) is None
    assert batch_rows(compile_team(load(SAMPLE)), 1, {}, 0) is not None


def test_cli_run_prints_statistics_and_writes_summary(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["run", str(SAMPLE), "-o", str(out)]) == 0
    text = capsys.readouterr().out
    k = kernel(Pairs.of(sample_run()))
    assert f"steps {k.steps[0]}, steps_in_corner {k.corner_steps[0]}" in text
    summary = json.loads((out / "summary.json").read_text())
    row = summary["instances"][0]
    assert row["outcome"] == "success"
    assert {"steps", "steps_in_corner", "path_length", "corner_path_length", "max_offset"} <= set(
        row
    )
    assert len(row["path_length"]) == 2
    assert (out / "trajectories.png").stat().st_size > 10_000
    header = (out / "samples.csv").read_text().splitlines()[0]
    assert "ladder.x" in header


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        (
            "use: ladder.corridor",
            "use: ladder.corrdor",
            "unknown world component 'ladder.corrdor'; did you mean 'ladder.corridor'",
        ),
        ("goal_gap: 70 ", "goal_gapp: 70 ", "'ladder.corridor' has no setting 'goal_gapp'"),
        ("length: length", "length: lenght", "unknown name 'lenght'"),
        (
            "      Stuck: {final: true, outcome: stuck}",
            "      Stuck: {outcome: stuck}",
            "needs 'final: true'",
        ),
    ],
)
def test_bad_world_input_is_located(tmp_path, capsys, old, new, message):
    text = SAMPLE.read_text()
    assert old in text
    bad = tmp_path / "bad.yaml"
    bad.write_text(text.replace(old, new, 1))
    assert main(["run", str(bad), "-o", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert message in err
    assert err.startswith(f"{bad}:")
    assert not (tmp_path / "o" / "summary.json").exists()


def test_clearance_requirement_is_the_ladders_distance_to_the_walls():
    """The sample's ``clear_of_walls`` robustness is the smallest distance between the
    ladder (its length through the sampled centre and heading) and any wall, computed
    here from the trace with end-to-segment distances."""
    run = simulate(load(SAMPLE))
    verdict = run.summary()["instances"][0]["requirements"]["clear_of_walls"]
    lad = run.samples["ladder"][:, 0]
    lad = lad[~np.isnan(lad[:, 0])]
    half = 225.0 * np.c_[np.cos(lad[:, 2]), np.sin(lad[:, 2])]
    ends = (lad[:, :2] - half, lad[:, :2] + half)
    walls = corridor_with_turn().walls
    gaps = [point_segment_distances(e, walls)[0].min(axis=1) for e in ends]
    for corner in (walls[:, :2], walls[:, 2:]):  # a wall's end nearest the ladder's middle
        bars = np.hstack(ends)
        gaps.append(point_segment_distances(corner, bars)[0].min(axis=0))
    want = np.minimum.reduce(gaps).min()
    assert verdict["satisfied"] and 0 < want < 30
    assert verdict["robustness"] == pytest.approx(want, abs=1e-9)


def test_clearance_is_published_only_when_asked(tmp_path, capsys):
    """Without ``clearance: true`` the corridor computes no clearance series (it costs a
    fifth of an engine run), so a requirement reading it is an unknown signal; a setting
    that is not a switch is a located error."""
    text = SAMPLE.read_text()
    off = tmp_path / "off.yaml"
    off.write_text(text.replace("      clearance: true", "      clearance: false"))
    assert main(["validate", str(off)]) == 2
    err = capsys.readouterr().err
    assert "unknown signal 'ladder_clearance.walls'" in err and "off.yaml:" in err
    bad = tmp_path / "bad.yaml"
    bad.write_text(text.replace("      clearance: true", "      clearance: 1"))
    assert main(["validate", str(bad)]) == 2
    assert "with.clearance: expected true or false, got 1.0" in capsys.readouterr().err
