"""Falsification on the thermostat, where the answer is known in closed form.

The heater switches off exactly at x = high (a located crossing), so the highest
temperature of a run is ``high`` and ``always(x <= 22.1)`` has robustness
``22.1 - high``: violated exactly when high > 22.1.
"""

from __future__ import annotations

import json
import shlex

import numpy as np
import pytest

from hybridteam import load
from hybridteam.cli import main
from hybridteam.falsify.evaluate import Evaluator
from hybridteam.falsify.search import Vary, run_search
from tests.conftest import THERMOSTAT

TEAM = THERMOSTAT.replace("duration: 30,", "duration: 15,") + (
    "  upper: always(x <= 22.1)\n  heats: eventually(in_mode(Heat))\n"
)


@pytest.fixture
def team_file(tmp_path):
    path = tmp_path / "thermostat.yaml"
    path.write_text(TEAM)
    return path


@pytest.mark.parametrize("method", ["de", "random"])
def test_every_evaluation_has_the_closed_form_robustness(team_file, method):
    team = load(team_file)
    varies = [Vary("thermostat.high", 21.0, 22.2), Vary("thermostat.K", 0.1, 0.3)]
    search = run_search(
        varies,
        1,
        0,
        Evaluator(team, "upper", [v.key for v in varies]),
        budget=200,
        method=method,
        population=12,
        search_seed=3,
    )
    x, seeds, rho, _ = search.flat()
    assert np.allclose(rho, 22.1 - x[:, 0], atol=1e-9)
    first = search.first_falsified()
    assert first is not None and rho[first - 1] < 0 and (rho[: first - 1] >= 0).all()
    assert search.evaluations <= 200 and (seeds == 0).all()


def test_a_search_is_deterministic_and_resumes_from_its_record(team_file):
    team = load(team_file)
    varies = [Vary("thermostat.high", 21.0, 22.05)]  # never violated: uses the budget
    calls = []

    def evaluate(x, seeds):
        calls.append(len(seeds))
        return Evaluator(team, "upper", ["thermostat.high"])(x, seeds)

    first = run_search(varies, 3, 0, evaluate, budget=30, method="de", population=10)
    assert first.first_falsified() is None and first.evaluations == 30
    n_calls = len(calls)
    again = run_search(
        varies, 3, 0, evaluate, budget=50, method="de", population=10, record=first.generations
    )
    assert len(calls) - n_calls == 2  # only the two generations beyond the record
    x0, s0, r0, _ = first.flat()
    x1, s1, r1, _ = again.flat()
    assert np.array_equal(x1[:30], x0) and np.array_equal(s1[:30], s0)
    assert np.array_equal(r1[:30], r0)  # the record's robustness is kept, not recomputed
    assert set(s1.tolist()) <= {0, 1, 2}


def test_cli_finds_a_violation_and_its_command_replays_it(team_file, tmp_path, capsys):
    out = tmp_path / "search"
    code = main(
        [
            "falsify",
            str(team_file),
            "-r",
            "upper",
            "--vary",
            "thermostat.high=21:23",
            "--budget",
            "60",
            "--population",
            "8",
            "--progress",
            "none",
            "-o",
            str(out),
        ]
    )
    assert code == 0
    text = capsys.readouterr().out
    record = json.loads((out / "falsify.json").read_text())
    best = record["best"]
    assert best["robustness"] < 0
    assert best["robustness"] == pytest.approx(22.1 - best["values"]["thermostat.high"], abs=1e-9)
    assert record["replayed_robustness"] == best["robustness"]  # bit for bit
    assert (out / "convergence.png").stat().st_size > 0
    assert (out / "replay" / "summary.json").exists()
    # the printed command, run again, gives the same verdict and robustness
    line = next(s for s in text.splitlines() if s.startswith("replay: "))
    argv = shlex.split(line.removeprefix("replay: "))[1:]
    argv[argv.index("-o") + 1] = str(tmp_path / "again")
    assert main(argv) == 0
    summary = json.loads((tmp_path / "again" / "summary.json").read_text())
    verdict = summary["instances"][0]["requirements"]["upper"]
    assert verdict["satisfied"] is False and verdict["robustness"] == best["robustness"]


def test_cli_says_when_nothing_was_found(team_file, tmp_path, capsys):
    out = tmp_path / "search"
    code = main(
        [
            "falsify",
            str(team_file),
            "-r",
            "upper",
            "--vary",
            "thermostat.high=21:22",
            "--budget",
            "16",
            "--population",
            "8",
            "--method",
            "random",
            "--progress",
            "none",
            "--no-replay",
            "-o",
            str(out),
        ]
    )
    assert code == 1
    assert "not violated in 16 simulations" in capsys.readouterr().out
    # the same command again resumes: nothing left to simulate, the same record
    before = (out / "falsify.json").read_text()
    assert (
        main(
            [
                "falsify",
                str(team_file),
                "-r",
                "upper",
                "--vary",
                "thermostat.high=21:22",
                "--budget",
                "16",
                "--population",
                "8",
                "--method",
                "random",
                "--progress",
                "none",
                "--no-replay",
                "-o",
                str(out),
            ]
        )
        == 1
    )
    assert (out / "falsify.json").read_text() == before


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["-r", "uper", "--vary", "thermostat.high=21:23"], "no requirement 'uper'; did you mean"),
        (["-r", "upper", "--vary", "thermostat.high=23:21"], "LO must be below HI"),
        (["-r", "upper", "--vary", "thermostat.high"], "expected KEY=LO:HI"),
        (["-r", "upper", "--vary", "thermostat.hihg=21:23"], "thermostat.hihg"),
        (["-r", "upper", "--vary", "thermostat.high=21:23", "--budget", "0"], "--budget"),
        (["-r", "upper"], "give at least one --vary"),
        (
            ["-r", "upper", "--vary", "thermostat.K=-1e308:1e308"],
            "--vary 'thermostat.K=-1e308:1e308': the range is too wide (HI - LO is beyond the "
            "largest number)",
        ),
        # 1e9 instances of 151 samples of one state (1.2 kB), the Zeno check's ring of 100
        # transition times (0.8 kB) and ~0.4 kB of other arrays each
        (
            ["-r", "upper", "--vary", "thermostat.high=21:23", "--population", "1000000000"],
            "--population 1,000,000,000: a generation runs as one ensemble, which would need "
            "about 2,",
        ),
        (
            ["-r", "upper", "--vary", "thermostat.high=21:23", "--scheduler", "tcp://[::nope"],
            "the Dask scheduler at 'tcp://[::nope': not an address",
        ),
        (
            ["-r", "upper", "--vary", "thermostat.high=21:23", "--connect-timeout", "0"],
            "--connect-timeout must be a finite number > 0, got 0.0",
        ),
    ],
)
def test_bad_arguments_are_one_line_and_exit_2(team_file, tmp_path, capsys, args, words):
    code = main(["falsify", str(team_file), *args, "-o", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2 and words in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()


def test_a_folder_holding_another_search_is_refused(team_file, tmp_path, capsys):
    out = tmp_path / "search"
    base = [
        "falsify",
        str(team_file),
        "-r",
        "upper",
        "--budget",
        "8",
        "--population",
        "8",
        "--progress",
        "none",
        "--no-replay",
        "-o",
        str(out),
    ]
    main([*base, "--vary", "thermostat.high=21:22"])
    capsys.readouterr()
    assert main([*base, "--vary", "thermostat.high=21:22.5"]) == 2
    assert "holds a different search" in capsys.readouterr().err


RESUME = [
    "-r",
    "upper",
    "--vary",
    "thermostat.high=21:22",
    "--budget",
    "16",
    "--population",
    "8",
    "--method",
    "random",
    "--progress",
    "none",
    "--no-replay",
]


def _edit_generations(d, change):
    change(d["generations"])
    return d


@pytest.mark.parametrize(
    ("edit", "words"),
    [
        (lambda d: [1, 2], "expected a JSON object of a search's record"),
        (
            lambda d: _edit_generations(d, lambda g: g[0].__setitem__("x", "abc")),
            "generations[0].x: Input should be a valid list",
        ),
        (
            lambda d: _edit_generations(d, lambda g: g[0]["robustness"].__setitem__(0, "nope")),
            "generations[0].robustness[0]: expected a finite number, 'inf' or '-inf', got 'nope'",
        ),
        (lambda d: {**d, "generations": {"a": 1}}, "generations: Input should be a valid list"),
        (
            lambda d: _edit_generations(d, lambda g: g[0]["seeds"].__setitem__(0, 10**30)),
            "generations[0].seeds[0]: Input should be less than 9223372036854775808",
        ),
        (
            lambda d: _edit_generations(d, lambda g: g[1]["x"].__setitem__(0, [1.0, 2.0])),
            "generations[1].x: a candidate has 2 value(s), the search varies 1 key(s)",
        ),
        (
            lambda d: _edit_generations(d, lambda g: g[0]["outcomes"].pop()),
            "generations[0]: x, seeds, robustness and outcomes have 8, 8, 8 and 7 entries",
        ),
        (lambda d: {**d, "format": 3}, "format: Input should be a valid string"),
    ],
)
def test_a_replaced_or_edited_record_is_one_line_on_resume(
    team_file, tmp_path, capsys, edit, words
):
    out = tmp_path / "search"
    assert main(["falsify", str(team_file), *RESUME, "-o", str(out)]) == 1
    capsys.readouterr()
    record = out / "falsify.json"
    record.write_text(json.dumps(edit(json.loads(record.read_text()))))
    before = record.read_text()
    assert main(["falsify", str(team_file), *RESUME, "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert (
        err
        == f"hybridteam: error: {record}: cannot resume from it: {words}"
        + err[err.index(words) + len(words) :]
    )
    assert len(err.strip().splitlines()) == 1
    assert record.read_text() == before  # nothing rewritten


def _search(team_file, out, *extra):
    return main(
        [
            "falsify",
            str(team_file),
            "-r",
            "upper",
            "--vary",
            "thermostat.high=21:23",
            "--seeds",
            "3",
            "--budget",
            "24",
            "--population",
            "8",
            "--keep-going",
            "--no-replay",
            "-o",
            str(out),
            *extra,
        ]
    )


def _record(out) -> dict:
    record = json.loads((out / "falsify.json").read_text())
    return {k: v for k, v in record.items() if k not in ("executor", "wall_seconds", "replay")}


def test_workers_and_a_dask_cluster_give_the_same_search(team_file, tmp_path, capsys):
    """Each generation split over two processes, or over a Dask cluster, is the same
    ensemble evaluated elsewhere: the same candidates, seeds and robustness, bit for bit."""
    assert _search(team_file, tmp_path / "one", "--progress", "none") == 0
    assert _search(team_file, tmp_path / "pool", "--progress", "none", "--workers", "2") == 0
    reference = _record(tmp_path / "one")
    assert _record(tmp_path / "pool") == reference
    distributed = pytest.importorskip("dask.distributed")
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster:
        assert (
            _search(
                team_file,
                tmp_path / "dask",
                "--progress",
                "none",
                "--scheduler",
                cluster.scheduler_address,
            )
            == 0
        )
    assert _record(tmp_path / "dask") == reference


def test_progress_is_reported_in_lines_when_not_on_a_terminal(
    team_file, tmp_path, capsys, monkeypatch
):
    import functools

    from hybridteam import progress

    # lines start after a grace period (short work stays quiet); this search is short
    monkeypatch.setattr(progress, "LogProgress", functools.partial(progress.LogProgress, grace=0.0))
    assert _search(team_file, tmp_path / "log", "--progress", "auto") == 0
    err = capsys.readouterr().err  # pytest's capture is not a terminal: lines, not a bar
    lines = [s for s in err.splitlines() if "falsify upper:" in s]
    assert lines and all("sims" in s for s in lines) and "\r" not in err
