"""A study's rows come from runs that record no output samples.

Samples are only recorded, never read by the run, so a run without them must reach the
same outcomes, transitions, messages and world statistics as the run that keeps them:
checked here against the full run's trace, for a flow model, a world component's
statistics (the ladder) and a team with streams, a payload and obstacles.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from hybridteam.api import load, simulate, summaries
from hybridteam.engine.compile.compiler import compile_team
from hybridteam.engine.run.simulator import Simulator

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
COUNTS = {"message", "transitions", "messages"}


@pytest.mark.parametrize(
    "name, duration",
    [
        ("automata/thermostat.yaml", None),
        ("ladder/sample.yaml", None),
        ("transport/experiment1.yaml", 20.0),
    ],
)
def test_a_run_without_samples_is_the_run_with_them(name, duration):
    team = load(EXAMPLES / name)
    cteam = compile_team(team)
    seeds = [3, 4]
    full = Simulator(cteam, 2, seed=seeds, duration=duration).run()
    bare = Simulator(cteam, 2, seed=seeds, duration=duration, samples=False).run()
    assert len(full.sample_times) > 1 and len(bare.sample_times) == 0
    assert bare.outcomes == full.outcomes  # outcome, end time, the world's statistics
    for table in ("transitions", "messages", "intervals"):
        a, b = getattr(full, table), getattr(bare, table)
        assert a.columns.keys() == b.columns.keys()
        for col in a.columns:
            np.testing.assert_array_equal(a[col], b[col])


def test_study_rows_are_a_full_runs_summary_rows():
    # without its requirements: their checks read samples, so those runs keep them
    team = dataclasses.replace(load(EXAMPLES / "ladder" / "sample.yaml"), requirements=())
    (row,) = summaries(team, 1, accelerate=False)
    (want,) = simulate(team).summary()["instances"]
    assert row == {k: v for k, v in want.items() if k not in COUNTS}
