"""The example notebook runs: its code cells, in order, from its folder (what a Jupyter
kernel would do, without needing one), and the displays it relies on work."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import hybridteam as ht

NOTEBOOK = Path(__file__).resolve().parents[1] / "examples" / "notebook.ipynb"


def test_the_example_notebook_runs(monkeypatch):
    pytest.importorskip("pandas")
    import matplotlib

    matplotlib.use("Agg")
    monkeypatch.chdir(NOTEBOOK.parent)
    cells = json.loads(NOTEBOOK.read_text())["cells"]
    space: dict = {}
    for cell in cells:
        if cell["cell_type"] == "code":
            source = "".join(cell["source"])
            exec(compile(source, f"{NOTEBOOK.name}[{cells.index(cell)}]", "exec"), space)
    switches = space["switches"]
    assert len(switches) == 20 and switches.iloc[-1] > switches.iloc[0]
    assert all(not cell.get("outputs") for cell in cells)  # kept clean in the repository


def test_runs_and_teams_show_themselves(team_from_yaml):
    team = ht.load(NOTEBOOK.parent / "automata" / "thermostat.yaml")
    assert repr(team) == "<Team 'thermostat': 1 agent(s) (thermostat), 160 s>"
    run = ht.simulate(team, duration=10.0)
    assert repr(run) == (
        f"<Run of 'thermostat': ok at t=10, {len(run.transitions)} transitions, 0 messages>"
    )
    page = run._repr_html_()
    assert "<td>ok</td>" in page and 'src="data:image/png;base64,' in page
    assert "<svg" in team._repr_html_()
    assert run.modes is run.intervals


def test_tables_become_data_frames(team_from_yaml):
    pd = pytest.importorskip("pandas")
    run = ht.simulate(
        ht.load(NOTEBOOK.parent / "automata" / "thermostat.yaml"),
        n=2,
        duration=10.0,
        overrides={"thermostat.K": [0.1, 0.2]},
    )
    frames = run.to_pandas()
    assert set(frames) == {"modes", "transitions", "messages", "samples", "outcomes"}
    assert list(frames["transitions"].columns) == list(run.transitions.names)
    tidy = frames["samples"]
    assert list(tidy.columns) == ["instance", "t", "series", "variable", "value"]
    # tidy: one row per instance, sample time and variable
    assert len(tidy) == 2 * len(run.sample_times)
    wide = run.samples_frame(wide=True)
    first = wide[wide["instance"] == 1].reset_index(drop=True)
    pd.testing.assert_series_equal(
        first["thermostat.x"], pd.Series(run.samples["thermostat"][:, 1, 0], name="thermostat.x")
    )
