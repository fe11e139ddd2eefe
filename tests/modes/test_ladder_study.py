"""Issue 7's acceptance: the ladder paper's Section 5 trends, from its own study files.

The study files of ``examples/ladder`` are loaded and run through the sweep API exactly as
``hybridteam sweep`` runs them (population S drawn by the study, the ladder's batch
stepper), restricted to the longest ladder (480) and the two factor values the claims
compare, so the test stays short. The thresholds are the issue's; the paper's own figures
are in the comments. The full tables are in ``examples/ladder/README.md``.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from hybridteam.sweep import load_study, restrict, run_study
from hybridteam.sweep.plan import Plan

LADDER = Path(__file__).resolve().parents[2] / "examples" / "ladder"
FACTORS = ("lookahead", "alpha", "kc", "orsp", "kr", "speed", "springs")


def rows_at_480(tmp_path: Path, name: str, factor: str, values: list[float]) -> dict[str, dict]:
    """The study's result rows at ladder length 480, by factor value label."""
    study = restrict(load_study(LADDER / f"{name}.yaml"), **{factor: values}, ladder_length=[480])
    result = run_study(study, tmp_path / name)
    assert result.complete
    return {row["value"]: row for row in result.table.rows}


def test_alpha_raises_success_for_long_ladders(tmp_path):
    # Paper, Sec. 5.2: "for a ladder of length 480, the success rate increases from 27% to
    # 89% when alpha increases from 0.40 to 0.80" (+62 points). Issue: at least +30.
    rows = rows_at_480(tmp_path, "alpha", "alpha", [0.4, 0.8])
    low, high = rows["0.4"], rows["0.8"]
    assert low["runs"] == high["runs"] == 100
    assert high["success"] - low["success"] >= 30, (low, high)
    # ... and "the number of steps in the corner decreases substantially for long ladders"
    assert high["mean_steps_in_corner"] < low["mean_steps_in_corner"]


def test_weak_correction_breaks_links(tmp_path):
    # Paper, Sec. 5.3: success "decreases dramatically when k_c decreases from 1.0 to 0.75
    # or 0.50 regardless of the ladder length, where as expected, almost all failures are
    # due to linkage breaks". Issue: at least 40 points fewer successes at k_c 0.5, and
    # link breaks at least 80 % of its failures.
    rows = rows_at_480(tmp_path, "kc", "kc", [0.5, 1.0])
    strong, weak = rows["1"], rows["0.5"]
    assert strong["success"] - weak["success"] >= 40, (strong, weak)
    failures = weak["runs"] - weak["success"]
    assert failures > 0 and weak["link_broken"] >= 0.8 * failures, weak
    assert weak["stuck"] + weak["link_broken"] == failures  # no third way to fail


def _speed_rows_at_240(tmp_path: Path, correction: str) -> dict[str, dict]:
    study = restrict(
        load_study(LADDER / "speed.yaml"),
        v_max=[(1.5, 1.5), (1.5, 0.75), (0.75, 1.5)],
        ladder_length=[240],
    )
    world = tuple(
        replace(w, values={**w.values, "correction": correction}) for w in study.team.world
    )
    study = replace(study, team=replace(study.team, world=world))
    result = run_study(study, tmp_path / correction)
    assert result.complete
    return {row["value"]: row for row in result.table.rows}


def test_speed_difference_costs_successes_only_under_the_distance_reading(tmp_path):
    # Paper, Sec. 5.6: at a speed ratio of 0.5 success drops, drastically for short ladders
    # (240 "about as good as 420"), all failures link breaks. Issue: a drop of at least 20
    # points at 240 against equal speeds. Under the printed formula (scaled) the faster
    # robot settles at offset orsp + (olim - orsp)(1 - ratio), half the range at 0.5 (see
    # test_ladder_readings), and the drop is at most 3 points; with the correction taken as
    # a distance per step (examples/ladder/README.md, "Readings of Section 3") it appears.
    printed = _speed_rows_at_240(tmp_path, "scaled")
    equal = printed["(1.5, 1.5)"]["success"]
    assert equal == 100
    assert all(equal - printed[v]["success"] <= 3 for v in ("(1.5, 0.75)", "(0.75, 1.5)"))
    distance = _speed_rows_at_240(tmp_path, "distance")
    equal = distance["(1.5, 1.5)"]["success"]
    slow_front = distance["(0.75, 1.5)"]
    assert equal - slow_front["success"] >= 20, distance
    assert slow_front["link_broken"] == slow_front["runs"] - slow_front["success"]


def test_the_study_files_share_population_s_and_lengths():
    """Seven files (and all.yaml) repeat one population block: they must not drift apart.
    Population S (Sec. 4): orsp in [0, 0.2] olim, v_max in [0.5, 1.5], lookahead 0..20,
    alpha in [0.35, 0.9], per robot; k_c = sc = 1 and k_r = 0 for both."""
    studies = [load_study(LADDER / f"{name}.yaml") for name in (*FACTORS, "all")]
    first = studies[0]
    for s in studies:
        assert (
            s.size,
            s.population_seed,
            s.fixed,
            s.draws,
            s.axes,
            s.success,
            s.outcomes,
            s.metrics,
        ) == (
            first.size,
            first.population_seed,
            first.fixed,
            first.draws,
            first.axes,
            first.success,
            first.outcomes,
            first.metrics,
        )
    assert [f for s in studies[:-1] for f in s.factors] == list(studies[-1].factors)
    assert first.size == 100 and dict(first.fixed) == {"kc": 1.0, "sc": 1.0, "kr": 0.0}
    assert first.axes[0].values == (240, 300, 360, 420, 480)
    draws = Plan(first).draws()
    bounds = {"orsp": (0, 2), "v_max": (0.5, 1.5), "lookahead": (0, 20), "alpha": (0.35, 0.9)}
    for name, (lo, hi) in bounds.items():
        both = np.stack([draws[f"R1.{name}"], draws[f"R2.{name}"]])
        assert lo <= both.min() and both.max() <= hi
        assert not np.array_equal(both[0], both[1])  # drawn per robot, not shared
    assert np.array_equal(draws["R1.lookahead"], np.round(draws["R1.lookahead"]))


@pytest.mark.parametrize("name", FACTORS)
def test_each_study_file_validates(name, capsys):
    from hybridteam.cli import main

    assert main(["validate", str(LADDER / f"{name}.yaml")]) == 0
    assert "ok (study)" in capsys.readouterr().out
