"""Parameter studies: per-instance seeds, plans, executors, chunking, resuming, errors, tables.

The study under test (``fixtures/sweep/study.yaml``) runs a two-message handshake over a
lossy link: a lost message leaves both agents waiting (``deadlock``), so both outcomes
occur and every table cell depends on the network's random draws — any seed mix-up between
runs, chunks or executors shows up as a different table.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import logging
import math
import shutil
import sys
import textwrap

import numpy as np
import pytest

import hybridteam as ht
from hybridteam.cli import main
from hybridteam.sweep.plan import Plan
from hybridteam.sweep.run import run_study
from hybridteam.sweep.store import StudyError, finished_chunks
from hybridteam.sweep.study import load_study
from hybridteam.sweep.table import aggregate
from hybridteam.sweep.worker import metric_value
from tests.conftest import FIXTURES

SWEEP = FIXTURES / "sweep"
STUDY = SWEEP / "study.yaml"
TEAM = SWEEP / "handshake.yaml"

BEACON = """
team: beacon
parameters: {p: 0.4}
network: {latency: 0.05, jitter: 0.02, loss: p}
agents:
  beacon:
    plant: {kind: flow, state: {c: 0}}
    initial: Send
    modes:
      Send:
        transitions:
          - {to: Send, after: 0.01, do: [{send: ping}]}
  listener:
    plant: {kind: flow, state: {c: 0}}
    variables: {heard: 0}
    initial: Listen
    modes:
      Listen:
        transitions:
          - {to: Listen, on: ping, do: ["heard += 1"]}
simulation: {duration: 1.0}
"""


@pytest.fixture(scope="module")
def study():
    return load_study(STUDY)


@pytest.fixture(scope="module")
def reference(study, tmp_path_factory):
    """The study run in this process, one setting per chunk: the table all others must match."""
    out = tmp_path_factory.mktemp("reference")
    result = run_study(study, out, chunk=study.size * study.repetitions)
    return result, (out / "results.csv").read_bytes(), (out / "runs.csv").read_bytes()


# ------------------------------------------------------------------ per-instance seeds
def test_ensemble_with_per_instance_seeds_equals_single_runs(team_from_yaml):
    team = team_from_yaml(BEACON)
    seeds = [3, 11, 2**62 + 12345]
    ens = ht.simulate(team, n=3, seed=seeds)
    assert ens.meta["seed"] == seeds
    for i, s in enumerate(seeds):
        one, mine = ht.simulate(team, seed=s), ens.instance(i)
        assert mine.meta["seed"] == s
        assert list(mine.messages["status"]) == list(one.messages["status"])
        np.testing.assert_array_equal(mine.messages["t_recv"], one.messages["t_recv"])
        np.testing.assert_array_equal(mine.transitions["t"], one.transitions["t"])
    statuses = [list(ens.instance(i).messages["status"]) for i in range(3)]
    assert statuses[0] != statuses[1] != statuses[2]  # the seeds really differ
    assert [p["seed"] for p in ens.summary()["instances"]] == seeds


def test_per_instance_seeds_are_checked(team_from_yaml):
    team = team_from_yaml(BEACON)
    with pytest.raises(ValueError, match="expected one integer or 3 integers"):
        ht.simulate(team, n=3, seed=[1, 2])
    with pytest.raises(ValueError, match="integer >= 0"):
        ht.simulate(team, n=2, seed=[1, -2])


# ------------------------------------------------------------------ the plan
def test_plan_orders_runs_seeds_and_members(study):
    plan = Plan(study, chunk=3)
    assert plan.per_setting == 8 and len(plan.settings) == 10 and plan.runs == 80
    s = plan.settings[3]  # p_loss = 0.3 at the second wait_time
    assert (s.factor, s.label, s.axes) == ("p_loss", "0.3", (("wait_time", 1.0),))
    assert dict(s.assign) == {"p_loss": 0.3, "wait": 1.0}
    # each factor's runs (p_loss: 6 settings of 8, latency: 4) cut into threes, across its
    # settings but never across factors
    assert [c.size for c in plan.chunks] == [3] * 16 + [3] * 10 + [2]
    assert [c.group for c in plan.chunks] == [0] * 16 + [1] * 11
    assert all(
        {plan.settings[s].factor for s in plan.setting_of(np.arange(c.start, c.stop))}
        == {("p_loss", "latency")[c.group]}
        for c in plan.chunks
    )
    children = np.random.SeedSequence(study.seed).spawn(plan.runs)
    assert plan.seeds(0, plan.runs) == [
        int(c.generate_state(1, np.uint64)[0] >> np.uint64(1)) for c in children
    ]
    task = plan.task(plan.chunks[1])  # runs 3, 4, 5: members 1, 2, 2; repetitions 1, 0, 1
    assert task.members == [1, 2, 2] and task.repetitions == [1, 0, 1]
    np.testing.assert_array_equal(task.overrides["d"], plan.draws()["d"][[1, 2, 2]])
    assert set(task.overrides["p_loss"]) == {0.0}
    task = plan.task(plan.chunks[2])  # runs 6, 7 of setting 0 and run 8 of setting 1
    assert task.settings == [0, 0, 1] and task.members == [3, 3, 0]
    assert task.overrides["wait"].tolist() == [0.5, 0.5, 1.0]  # each run its setting's
    task = plan.task(plan.chunks[16])  # latency 0.01: the factor's value beats the draw
    assert list(task.overrides)[-2:] == ["d", "wait"]  # set after the draws
    assert task.overrides["d"].tolist() == [0.01] * 3


def test_members_do_not_depend_on_the_population_size(study):
    from dataclasses import replace

    small, big = Plan(study).draws(), Plan(replace(study, size=9)).draws()
    for key in ("d", "wait"):
        np.testing.assert_array_equal(big[key][: study.size], small[key])
    assert np.all((big["d"] >= 0.01) & (big["d"] <= 0.05))


def test_population_set_fixes_parameters_a_factor_may_vary(tmp_path):
    path = _study(
        tmp_path,
        """\
        population: {size: 3, set: {d: 0.02, asker.wait: 2}}
        factors: {wait: [1]}
        """,
    )
    plan = Plan(load_study(path))
    assert {k: v.tolist() for k, v in plan.draws().items()} == {
        "d": [0.02] * 3,
        "asker.wait": [2.0] * 3,
    }
    overrides = plan.task(plan.chunks[0]).overrides
    assert list(overrides) == ["d", "asker.wait", "wait"]  # in order: the factor's 1 wins
    assert overrides["wait"].tolist() == [1.0] * 3


def test_restrict_keeps_some_values_and_the_population(study):
    from hybridteam.sweep import restrict

    part = restrict(study, p_loss=[0.3], wait_time=[1])
    plan, full = Plan(part), Plan(study)
    assert [(s.factor, s.label, s.axes) for s in plan.settings] == [
        ("p_loss", "0.3", (("wait_time", 1.0),)),
        ("latency", "0.01", (("wait_time", 1.0),)),
        ("latency", "0.2", (("wait_time", 1.0),)),
    ]
    assert all(np.array_equal(plan.draws()[k], v) for k, v in full.draws().items())
    assert part.digest != study.digest
    assert {s.factor for s in Plan(restrict(study, latency=[])).settings} == {"p_loss"}
    with pytest.raises(ValueError, match=r"p_loss: 0.5 is not one of the study's values"):
        restrict(study, p_loss=[0.5])
    with pytest.raises(ValueError, match="'wait' is no factor or axis of the study"):
        restrict(study, wait=[1])


# ------------------------------------------------------------------ executors and chunks
@pytest.mark.parametrize("chunk", [1, 3, 80])
def test_chunk_size_does_not_change_the_table(study, reference, tmp_path, chunk):
    run_study(study, tmp_path, chunk=chunk)
    assert (tmp_path / "results.csv").read_bytes() == reference[1]
    assert (tmp_path / "runs.csv").read_bytes() == reference[2]


def test_local_pool_gives_the_same_table(study, reference, tmp_path):
    result = run_study(study, tmp_path, workers=2, chunk=3)
    assert result.executor == "2 local processes" and len(result.computed) == 27
    assert (tmp_path / "results.csv").read_bytes() == reference[1]


def test_dask_cluster_gives_the_same_table(study, reference, tmp_path):
    distributed = pytest.importorskip("dask.distributed")
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster:
        with distributed.Client(cluster) as client:
            result = run_study(study, tmp_path / "client", client=client, chunk=5)
            assert result.executor.startswith("Dask at ")
        # the command line connects to a scheduler by address
        assert (
            main(
                [
                    "sweep",
                    str(STUDY),
                    "-o",
                    str(tmp_path / "cli"),
                    "--scheduler",
                    cluster.scheduler_address,
                    "--quiet",
                ]
            )
            == 0
        )
    for out in ("client", "cli"):
        assert (tmp_path / out / "results.csv").read_bytes() == reference[1]


def test_missing_dask_is_one_clear_error(study, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "dask.distributed", None)  # import fails
    with pytest.raises(StudyError, match=r"pip install 'hybridteam\[dask\]'"):
        run_study(study, tmp_path, scheduler="tcp://127.0.0.1:1")


def test_parquet_and_csv_chunks_give_the_same_table(study, reference, tmp_path):
    pytest.importorskip("pyarrow")
    run_study(study, tmp_path, chunk=8, fmt="parquet")
    assert {p.suffix for p in (tmp_path / "chunks").iterdir()} == {".parquet"}
    assert (tmp_path / "results.csv").read_bytes() == reference[1]


@pytest.mark.parametrize(
    ("workers", "chunk"),
    [
        (1, 500),  # one process: the study's size
        (2, 4),  # 8 runs: two chunks of 4
        (3, 3),  # ceil(8 / 3): chunks of 3, 3 and 2
        (5, 1),  # ceil(8 / 5) = 2 makes only four chunks; one run each makes eight
        (16, 1),  # more workers than runs: a run per chunk
    ],
)
def test_workers_asked_for_get_chunks_of_a_small_study(tmp_path, workers, chunk):
    from hybridteam.sweep.plan import spread_chunk

    study = load_study(_study(tmp_path, "population: {size: 4}\nfactors:\n  p_loss: [0.0, 0.3]\n"))
    assert (study.chunk, Plan(study).runs) == (500, 8)
    assert spread_chunk(study, workers) == chunk
    assert len(Plan(study, chunk).chunks) >= min(workers, 8)


def test_a_study_cut_finely_enough_keeps_its_chunk_size(study):
    """80 runs of two factors (48 and 32 runs): 27 chunks of 3 already feed 16 workers; at
    500, two chunks feed two workers, and four workers get ceil(80 / 4) = 20 (3 + 2
    chunks)."""
    from hybridteam.sweep.plan import spread_chunk

    assert spread_chunk(study, 16) == 3
    wide = dataclasses.replace(study, chunk=500)
    assert spread_chunk(wide, 2) == 500 and spread_chunk(wide, 4) == 20


def test_sweep_with_workers_uses_them_on_a_small_study(tmp_path, capsys):
    """--workers 2 on 8 runs of one factor: two chunks on two processes, the same table as
    in this process; resuming without --workers keeps the folder's chunk size."""
    path = _study(
        tmp_path, "duration: 3.0\npopulation: {size: 4}\nfactors:\n  p_loss: [0.0, 0.3]\n"
    )
    assert main(["sweep", str(path), "-o", str(tmp_path / "pool"), "--workers", "2"]) == 0
    assert "8 runs in 2 chunks (2 computed, 2 local processes)" in capsys.readouterr().out
    assert json.loads((tmp_path / "pool" / "study.json").read_text())["chunk"] == 4
    run_study(load_study(path), tmp_path / "alone")
    assert (tmp_path / "pool" / "results.csv").read_bytes() == (
        tmp_path / "alone" / "results.csv"
    ).read_bytes()
    half = run_study(load_study(path), tmp_path / "half", workers=2, max_chunks=1)
    assert half.plan.chunk == 4 and not half.complete
    rest = run_study(load_study(path), tmp_path / "half")
    assert rest.plan.chunk == 4 and rest.reused == half.computed and rest.executor == "in-process"
    assert (tmp_path / "half" / "results.csv").read_bytes() == (
        tmp_path / "alone" / "results.csv"
    ).read_bytes()
    # a --chunk that makes one chunk: the output says why the workers were not used
    assert (
        main(["sweep", str(path), "-o", str(tmp_path / "one"), "--workers", "2", "--chunk", "8"])
        == 0
    )
    assert "(1 computed, in-process: one chunk to compute)" in capsys.readouterr().out


def test_a_factor_may_set_a_network_setting(tmp_path, capsys):
    """``network.loss`` as a factor's key: the handshake always completes at loss 0 and
    never at loss 1 (both messages must arrive); a misspelt setting is located."""
    path = _study(
        tmp_path,
        "population: {size: 2}\nfactors:\n  loss: {key: network.loss, values: [0.0, 1.0]}\n",
    )
    table = run_study(load_study(path), tmp_path / "out").table
    assert [(r["value"], r["runs"], r["success_rate"]) for r in table.rows] == [
        ("0", 2, 1.0),
        ("1", 2, 0.0),
    ]
    path.write_text(path.read_text().replace("network.loss", "network.los"))
    assert main(["validate", str(path)]) == 2
    assert (
        f"{path}:5:15: factors.loss.key: override 'network.los' names no network "
        "setting of team 'handshake'; did you mean 'network.loss'?" in capsys.readouterr().err
    )


# ------------------------------------------------------------------ resuming
def test_interrupted_study_resumes_without_recomputing(study, reference, tmp_path):
    first = run_study(study, tmp_path, chunk=3, max_chunks=7)
    assert not first.complete and len(first.computed) == 7
    assert not (tmp_path / "results.csv").exists()
    done = finished_chunks(tmp_path)
    stamps = {k: p.stat().st_mtime_ns for k, p in done.items()}
    second = run_study(study, tmp_path, chunk=3)
    assert sorted(second.reused) == sorted(first.computed) == sorted(done)
    assert len(second.computed) == 20 and not set(second.computed) & set(done)
    assert {k: p.stat().st_mtime_ns for k, p in done.items()} == stamps
    assert (tmp_path / "results.csv").read_bytes() == reference[1]
    again = run_study(study, tmp_path, chunk=3)  # a finished study: nothing to compute
    assert again.computed == [] and len(again.reused) == 27


@pytest.mark.parametrize("damage", ["garbage", "truncated", "no checksum", "other rows"])
def test_a_damaged_chunk_is_computed_again_on_resume(study, reference, tmp_path, damage):
    """A chunk file that does not verify (its checksum, its row count) is never taken for
    a finished chunk: resuming computes it again, says so, and the table is a clean run's."""
    run_study(study, tmp_path, chunk=3, max_chunks=4, fmt="csv")
    done = finished_chunks(tmp_path)
    victim = done[sorted(done)[1]]
    text = victim.read_text()
    if damage == "garbage":
        victim.write_text("run,outcome\n1,ok\nnot,a,chunk\n")
    elif damage == "truncated":
        victim.write_text(text[: len(text) // 2])
    elif damage == "no checksum":
        victim.with_name(victim.name + ".sha256").unlink()
    else:  # one row of three, with a checksum made to match
        victim.write_text("\n".join(text.splitlines()[:2]) + "\n")
        victim.with_name(victim.name + ".sha256").write_text(
            hashlib.sha256(victim.read_bytes()).hexdigest() + "\n"
        )
    result = run_study(study, tmp_path, chunk=3, fmt="csv")
    assert victim.stem in result.computed and victim.stem not in result.reused
    (warning,) = [w for w in result.warnings if victim.name in w]
    assert warning.endswith(f"computing chunk {victim.stem} again")
    assert (tmp_path / "results.csv").read_bytes() == reference[1]


def test_a_resume_warning_goes_through_logging_and_the_cli_prints_it_once(
    study, tmp_path, caplog, capsys
):
    """The library says it computes a damaged chunk again through its module logger (a
    program sees it in its logging, not only in ``Outcome.warnings``); the command line
    prints the same warning once, as its own ``hybridteam: warning:`` line."""

    def damaged(out):
        run_study(study, out, chunk=3, max_chunks=2)
        done = finished_chunks(out)
        victim = done[sorted(done)[1]]
        victim.write_text("run,outcome\nnot,a,chunk\n")
        return victim

    victim = damaged(tmp_path / "api")
    with caplog.at_level(logging.WARNING, logger="hybridteam"):
        result = run_study(study, tmp_path / "api", chunk=3)
    (record,) = [r for r in caplog.records if victim.name in r.getMessage()]
    assert record.name == "hybridteam.sweep.run" and record.levelno == logging.WARNING
    assert result.warnings == [record.getMessage()]
    assert record.getMessage().endswith(f"computing chunk {victim.stem} again")

    victim = damaged(tmp_path / "cli")
    capsys.readouterr()
    assert main(["sweep", str(STUDY), "-o", str(tmp_path / "cli"), "--chunk", "3", "--quiet"]) == 0
    err = capsys.readouterr().err
    assert err.count("hybridteam: warning:") == 1, err
    assert f"hybridteam: warning: {victim}: " in err
    assert f"computing chunk {victim.stem} again\n" in err


def test_resuming_another_study_or_chunk_size_is_refused(study, tmp_path, capsys):
    run_study(study, tmp_path / "out", chunk=3, max_chunks=2)
    with pytest.raises(StudyError, match="resume with --chunk 3"):
        run_study(study, tmp_path / "out", chunk=4)
    changed = tmp_path / "study.yaml"
    changed.write_text(STUDY.read_text().replace("seed: 7", "seed: 8"))
    shutil.copy(TEAM, tmp_path / "handshake.yaml")
    assert main(["sweep", str(changed), "-o", str(tmp_path / "out"), "--chunk", "3"]) == 2
    assert "holds results of another study" in capsys.readouterr().err


# ------------------------------------------------------------------ bad input
def _study(tmp_path, body: str):
    shutil.copy(TEAM, tmp_path / "handshake.yaml")
    path = tmp_path / "study.yaml"
    path.write_text("kind: study\nteam: handshake.yaml\n" + textwrap.dedent(body))
    return path


@pytest.mark.parametrize(
    ("body", "where", "message"),
    [
        (
            "repetitons: 2\n",
            "3:1: repetitons",
            "unknown key 'repetitons'; did you mean 'repetitions'?",
        ),
        (
            "factors:\n  p_los: [0.1]\n",
            "4:3: factors.p_los",
            "override 'p_los' names no parameter of team 'handshake'; did you mean 'p_loss'?",
        ),
        (
            "axes:\n  loss: {key: asker.dd, values: [0.1]}\n",
            "4:15: axes.loss.key",
            "did you mean 'asker.d'?",
        ),
        (
            "population:\n  draws:\n    d: {uniform: [2, 1]}\n",
            "5:8: population.draws.d",
            "lo must be <= hi",
        ),
        (
            "factors:\n  v: {keys: [asker.d, granter.d], values: [[0.1, 0.2, 0.3]]}\n",
            "4:44: factors.v.values[0]",
            "expected 2 (asker.d, granter.d), got 3",
        ),
        ("metrics: [t_ned]\n", "3:11: metrics[0]", "did you mean 't_end'?"),
        ("axes:\n  runs: [1, 2]\n", "4:3: axes", "axis name 'runs' is taken"),
        (
            "axes:\n  d: [0.1]\nfactors:\n  d: [0.2]\n",
            "6:3: factors.d",
            "'d' sets asker.d, which axis 'd' sets too",
        ),
        (
            "axes:\n  start: {key: wait, values: [1]}\nfactors:\n  w: {key: granter.wait, "
            "values: [2]}\n",
            "6:3: factors.w",
            "'granter.wait' sets granter.wait, which axis 'start' sets too",
        ),
        ("chunk: 0\n", "3:8: chunk", "must be >= 1"),
        (
            "population:\n  set: {wiat: 1}\n",
            "4:9: population.set.wiat",
            "override 'wiat' names no parameter of team 'handshake'; did you mean 'wait'?",
        ),
        (
            "population:\n  set: {d: 0.02}\n  draws:\n    d: {uniform: [0.01, 0.05]}\n",
            "6:5: population.draws.d",
            "'d' sets asker.d, which population.set 'd' sets too",
        ),
    ],
)
def test_bad_study_files_name_file_line_and_field(tmp_path, capsys, body, where, message):
    path = _study(tmp_path, body)
    assert main(["sweep", str(path), "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"{path}:{where}: ") and message in err, err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists()


def test_missing_team_and_bad_team_are_located(tmp_path, capsys):
    path = tmp_path / "study.yaml"
    path.write_text("kind: study\nteam: nothere.yaml\n")
    assert main(["sweep", str(path), "-o", str(tmp_path / "out")]) == 2
    assert f"{path}:2:7: team: no team file 'nothere.yaml'" in capsys.readouterr().err
    (tmp_path / "nothere.yaml").write_text(TEAM.read_text().replace("after: wait", "aftr: 1"))
    assert main(["sweep", str(path), "-o", str(tmp_path / "out")]) == 2
    assert "nothere.yaml:15:" in capsys.readouterr().err and not (tmp_path / "out").exists()


def test_bad_arguments_exit_2(tmp_path, capsys):
    assert main(["sweep", str(STUDY), "-o", str(tmp_path / "o"), "--workers", "0"]) == 2
    assert main(["sweep", str(STUDY), "-o", str(tmp_path / "o"), "--chunk", "-1"]) == 2
    assert main(["report", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "--workers must be at least 1" in err and "no study.json" in err


# ------------------------------------------------------------------ table and report
def test_aggregation_by_hand(tmp_path):
    path = _study(
        tmp_path,
        """\
        population: {size: 2}
        factors: {p_loss: [0.1, 0.2]}
        success: [ok]
        outcomes: [ok, stuck]
        metrics: [t_end]
        """,
    )
    plan = Plan(load_study(path))
    runs = {
        "run": [3, 0, 1, 2],  # any order: the table is by setting
        "outcome": ["deadlock", "ok", "ok", "zeno"],
        "metric_t_end": [9.0, metric_value([1, 2, 3]), math.nan, 5.0],
    }
    table = aggregate(plan, runs)
    assert table.columns == [
        "factor",
        "value",
        "runs",
        "ok",
        "stuck",
        "zeno",
        "deadlock",
        "success_rate",
        "mean_t_end",
    ]
    first, second = table.rows
    assert first == {
        "factor": "p_loss",
        "value": "0.1",
        "runs": 2,
        "ok": 2,
        "stuck": 0,
        "zeno": 0,
        "deadlock": 0,
        "success_rate": 1.0,
        "mean_t_end": 2.0,
    }  # a list averaged over its elements; NaN left out
    assert second["runs"] == 2 and second["zeno"] == 1 and second["deadlock"] == 1
    assert second["success_rate"] == 0.0 and math.isnan(second["mean_t_end"])
    assert table.to_csv().splitlines()[2] == "p_loss,0.2,2,0,0,1,1,0.0,nan"
    assert metric_value([]) != metric_value([])  # NaN: nothing to average
    assert metric_value(True) == 1.0 and math.isnan(metric_value("text"))


def test_study_without_factors_runs_the_base_setting(tmp_path):
    path = _study(tmp_path, "population: {size: 3}\nrepetitions: 2\n")
    result = run_study(load_study(path), tmp_path / "out")
    assert [(r["factor"], r["value"], r["runs"]) for r in result.table.rows] == [("base", "", 6)]


def test_report_writes_plots_and_markdown(reference, tmp_path, capsys):
    out = tmp_path / "out"
    shutil.copytree(reference[0].plan.study.path.parent, tmp_path / "study")
    assert main(["sweep", str(tmp_path / "study" / "study.yaml"), "-o", str(out)]) == 0
    assert "80 runs in 27 chunks (27 computed, in-process)" in capsys.readouterr().out
    assert main(["report", str(out)]) == 0
    report = (out / "report.md").read_text()
    assert "![success rate against p_loss](plots/success_p_loss.png)" in report
    assert "| factor | value | wait_time | runs | ok | deadlock | success_rate |" in report
    for name in ("success_p_loss", "success_latency"):
        assert (out / "plots" / f"{name}.png").read_bytes()[:4] == b"\x89PNG"
        assert (out / "plots" / f"{name}.svg").exists()


def test_validate_and_schema_know_study_files(tmp_path, capsys):
    from hybridteam.cli import main

    assert main(["validate", str(STUDY)]) == 0
    assert "ok (study)" in capsys.readouterr().out
    bad = tmp_path / "study.yaml"
    bad.write_text(STUDY.read_text().replace("handshake.yaml", "handshak.yaml"))
    assert main(["validate", str(bad)]) == 2
    assert "no team file 'handshak.yaml'" in capsys.readouterr().err
    assert main(["schema", "study"]) == 0
    schema = capsys.readouterr().out
    assert '"population"' in schema and '"factors"' in schema


def test_sweep_progress_lines_without_a_terminal(study, reference, tmp_path, capsys, monkeypatch):
    """A study run from a script or CI says how far it is, in lines, with an estimate
    (the clock here ticks a second per reading, so the two-second grace is soon over)."""
    from hybridteam import progress

    clock = iter(range(0, 10_000))
    monkeypatch.setattr(progress.time, "perf_counter", lambda: float(next(clock)))
    assert (
        main(
            ["sweep", str(STUDY), "-o", str(tmp_path / "out"), "--chunk", "9", "--progress", "log"]
        )
        == 0
    )
    lines = [x for x in capsys.readouterr().err.splitlines() if "runs (" in x]
    total = reference[0].plan.runs
    assert lines[-1].startswith(f"hybridteam: {study.name}: {total:,}/{total:,} runs (100%)")
    assert len(lines) >= 2 and any("ETA" in x for x in lines[:-1])
    assert (tmp_path / "out" / "results.csv").read_bytes() == reference[1]
