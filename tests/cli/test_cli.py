"""The command line: what it writes, what it prints, and how it refuses bad arguments."""

from __future__ import annotations

import json
import math
import os
import site
import subprocess
import venv

import pytest

from hybridteam import Run
from hybridteam.cli import main
from tests.conftest import EXAMPLES, ROOT

THERMO = str(EXAMPLES / "automata" / "thermostat.yaml")


def test_run_writes_trace_tables_and_summary(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["run", THERMO, "-o", str(out), "--duration", "20"]) == 0
    names = {p.name for p in out.iterdir()}
    assert names == {
        "trace.json",
        "modes.csv",
        "transitions.csv",
        "messages.csv",
        "samples.csv",
        "summary.json",
        "modes.dot",
        "modes.mmd",
        "modes.svg",
        "timeline.png",
        "timeline.svg",
        "trajectories.png",
        "trajectories.svg",
        "sequence.mmd",
    }
    assert (out / "timeline.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    summary = json.loads((out / "summary.json").read_text())
    assert summary["outcomes"] == {"ok": 1}
    # the initial entry, then switches at 3.18, 5.19, 9.25, 11.25, 15.31, 17.31 (21.37 > 20)
    assert summary["instances"][0]["transitions"] == 7
    assert summary["wall_time_s"] > 0
    run = Run.load(out / "trace.json")
    switch = run.transitions["t"][1]
    assert abs(switch - math.log(11 / 8) / 0.1) < 1e-8
    header = (out / "transitions.csv").read_text().splitlines()[0]
    assert header == "instance,agent,t,step,source,target,cause,guard"
    samples = (out / "samples.csv").read_text().splitlines()
    assert samples[0] == "t,instance,thermostat.x" and samples[1] == "0.0,0,19.0"
    printed = capsys.readouterr().out
    assert "thermostat: 1 instance(s)" in printed and "ok: 1" in printed


def test_run_ensemble_with_per_instance_overrides(tmp_path):
    out = tmp_path / "ens"
    assert (
        main(
            [
                "run",
                THERMO,
                "-o",
                str(out),
                "--duration",
                "10",
                "--quiet",
                "--set",
                "thermostat.K=0.1,0.2,0.3",
            ]
        )
        == 0
    )
    run = Run.load(out / "trace.json")
    assert run.n == 3
    first = [run.instance(i).transitions["t"][1] for i in range(3)]
    for got, K in zip(first, (0.1, 0.2, 0.3), strict=True):
        assert abs(got - math.log(11 / 8) / K) < 1e-8


@pytest.mark.parametrize(
    "args, words",
    [
        (["-n", "0"], "-n must be at least 1"),
        (["--duration", "-1"], "--duration must be a finite number >= 0"),
        (["--set", "thermostat.K"], "expected KEY=VALUE"),
        (["--set", "thermostat.K=abc"], "values must be numbers"),
        (["--set", "thermostat.Q=1"], "names no parameter"),
        (["-n", "2", "--set", "thermostat.K=1,2,3"], "3 values for an ensemble of 2"),
        (["--seed", "-3"], "--seed must be >= 0"),
    ],
)
def test_run_refuses_bad_arguments(tmp_path, capsys, args, words):
    out = tmp_path / "o"
    assert main(["run", THERMO, "-o", str(out), *args]) == 2
    assert words in capsys.readouterr().err
    assert not (out / "summary.json").exists()


def test_validate_ok_and_warnings(tmp_path, capsys):
    assert main(["validate", THERMO]) == 0
    assert "ok (team)" in capsys.readouterr().out
    model = tmp_path / "warn.yaml"
    model.write_text("""team: w
agents:
  a:
    plant: {kind: flow, state: {x: 0}}
    initial: A
    modes:
      A: {transitions: [{to: B, after: 1}]}
      B: {}
      Orphan: {final: true}
""")
    assert main(["validate", str(model)]) == 0
    err = capsys.readouterr().err
    assert f"{model}:9:7: agents.a.modes.Orphan: mode 'Orphan' is unreachable" in err
    assert f"{model}:8:7: agents.a.modes.B: mode 'B' has no way out" in err
    assert main(["validate", "--strict", str(model)]) == 2


def test_validate_gives_every_file_its_verdict_after_a_failing_one(tmp_path, capsys):
    """A file after a failing one is still checked and says so; the exit is the worst."""
    bad = tmp_path / "bad.yaml"
    bad.write_text("team: b\nagents: 3\n")
    assert main(["validate", THERMO, str(bad), THERMO]) == 2
    captured = capsys.readouterr()
    assert captured.out.splitlines() == [f"{THERMO}: ok (team)"] * 2
    assert str(bad) in captured.err


def test_schema_prints_json_schema(capsys):
    assert main(["schema", "team"]) == 0
    schema = json.loads(capsys.readouterr().out)
    assert schema["additionalProperties"] is False
    assert {"team", "agents", "simulation"} <= set(schema["properties"])
    assert main(["schema", "teem"]) == 2
    assert "did you mean 'team'" in capsys.readouterr().err


def test_pip_install_into_a_fresh_venv_works_from_any_directory(tmp_path):
    """A non-editable install (dependencies from this environment) and the CLI elsewhere.

    The new venv sees this environment's packages through a path file, not through
    ``system_site_packages``: when the tests themselves run in a virtual environment, a
    nested venv's "system" packages are the base interpreter's, which lack ours.
    """
    env_dir = tmp_path / "venv"
    venv.create(env_dir, with_pip=True)
    py = env_dir / "bin" / "python"
    (inner,) = (env_dir / "lib").glob("python*/site-packages")
    (inner / "outer.pth").write_text("\n".join(site.getsitepackages()) + "\n")
    pip = subprocess.run(
        [str(py), "-m", "pip", "install", "--no-deps", "-q", str(ROOT)],
        capture_output=True,
        text=True,
    )
    assert pip.returncode == 0, pip.stderr
    work = tmp_path / "elsewhere"
    work.mkdir()
    (work / "model.yaml").write_text((EXAMPLES / "automata" / "thermostat.yaml").read_text())
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    cli = env_dir / "bin" / "hybridteam"
    done = subprocess.run(
        [str(cli), "run", "model.yaml", "-o", "out", "--duration", "5"],
        cwd=work,
        capture_output=True,
        text=True,
        env=env,
    )
    assert done.returncode == 0, done.stderr
    assert (work / "out" / "summary.json").exists()
    where = subprocess.run(
        [
            str(py),
            "-c",
            "import hybridteam, hybridteam.modes, hybridteam.protocols; print(hybridteam.__file__)",
        ],
        cwd=work,
        capture_output=True,
        text=True,
        env=env,
    )
    assert where.returncode == 0, where.stderr
    assert str(env_dir) in where.stdout  # the installed copy, not the checkout


def test_run_without_views_writes_only_the_trace(tmp_path):
    out = tmp_path / "plain"
    assert main(["run", THERMO, "-o", str(out), "--duration", "5", "--quiet", "--no-views"]) == 0
    assert {p.name for p in out.iterdir()} == {
        "trace.json",
        "modes.csv",
        "transitions.csv",
        "messages.csv",
        "samples.csv",
        "summary.json",
    }


RELAY = str(EXAMPLES / "automata" / "relay.yaml")


@pytest.fixture(scope="module")
def relay_trace(tmp_path_factory):
    out = tmp_path_factory.mktemp("relay")
    assert main(["run", RELAY, "-o", str(out), "--quiet", "--no-views"]) == 0
    return out / "trace.json"


def test_view_commands_write_their_files(tmp_path, relay_trace, capsys):
    assert main(["diagram", RELAY, "-o", str(tmp_path / "d.svg")]) == 0
    assert "<svg" in (tmp_path / "d.svg").read_text()
    assert capsys.readouterr().out == f"wrote {tmp_path / 'd.svg'}\n"
    assert main(["diagram", RELAY, "-f", "mermaid"]) == 0
    assert capsys.readouterr().out.startswith("stateDiagram-v2")
    assert (
        main(
            [
                "timeline",
                str(relay_trace),
                "--window",
                "4.9",
                "5.1",
                "-o",
                str(tmp_path / "t.svg"),
                "--data",
                str(tmp_path / "t.json"),
            ]
        )
        == 0
    )
    data = json.loads((tmp_path / "t.json").read_text())
    assert [(a["t_send"], a["type"]) for a in data["arrows"]] == [(5.0, "baton")]
    assert main(["plot", str(relay_trace), "-o", str(tmp_path / "p.png")]) == 0
    assert main(["animate", str(relay_trace), "-o", str(tmp_path / "a.gif"), "--fps", "5"]) == 0
    assert (tmp_path / "a.gif").read_bytes()[:6] == b"GIF89a"
    assert main(["sequence", str(relay_trace), "-f", "plantuml"]) == 0
    out = capsys.readouterr().out
    assert "@startuml" in out and "runner -> anchor" in out
    # every command that writes a file says so, one line each
    assert main(["diagram", RELAY, "-o", str(tmp_path / "d.pdf")]) == 0
    assert main(["sequence", str(relay_trace), "-o", str(tmp_path / "s.mmd")]) == 0
    assert capsys.readouterr().out.splitlines() == [
        f"wrote {tmp_path / 'd.pdf'}",
        f"wrote {tmp_path / 's.mmd'}",
    ]


@pytest.mark.parametrize(
    "args, words",
    [
        (["diagram", RELAY, "-f", "dott"], "did you mean 'dot'"),
        (["diagram", RELAY, "-f", "png"], "needs -o FILE"),
        (["timeline", "{trace}", "-o", "x.jpg"], "written as .png or .svg"),
        (["plot", "{trace}", "-f", "svg", "-o", "x.png"], "says png but --format says svg"),
        (["timeline", "{trace}", "--window", "5", "1"], "T0 must be < T1"),
        (["timeline", "{trace}", "--instance", "3"], "instances 0..0"),
        (["plot", "{missing}"], "no such file"),
        (["plot", "{notjson}"], "not a JSON file"),
        (["plot", "{notrace}"], "not a valid hybridteam trace: format: Field required"),
        (["animate", "{trace}", "-o", "a.avi"], ".gif or .mp4"),
    ],
)
def test_view_commands_refuse_bad_arguments(tmp_path, relay_trace, capsys, args, words):
    (tmp_path / "bad.json").write_text("{nope")
    (tmp_path / "other.json").write_text('{"hello": 1}')
    subst = {
        "{trace}": str(relay_trace),
        "{missing}": str(tmp_path / "none.json"),
        "{notjson}": str(tmp_path / "bad.json"),
        "{notrace}": str(tmp_path / "other.json"),
    }
    argv = [subst.get(a, a) for a in args]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert words in err and "Traceback" not in err


def test_views_write_vector_pdf_and_never_dot_text_under_another_name(
    tmp_path, relay_trace, capsys
):
    """A paper wants PDF; a file named .pdf must be one. The same figure gives the same
    bytes (no dates stamped in)."""
    first, second = tmp_path / "a.pdf", tmp_path / "b.pdf"
    for path in (first, second):
        assert main(["diagram", RELAY, "-o", str(path)]) == 0
    assert first.read_bytes()[:5] == b"%PDF-" and first.read_bytes() == second.read_bytes()
    for view in ("timeline", "plot"):
        out = tmp_path / f"{view}.pdf"
        assert main([view, str(relay_trace), "-o", str(out)]) == 0
        assert out.read_bytes()[:5] == b"%PDF-"
    assert main(["diagram", RELAY, "-o", str(tmp_path / "modes.pdff")]) == 2
    assert "cannot tell the format from '.pdff'" in capsys.readouterr().err
    assert not (tmp_path / "modes.pdff").exists()


def test_progress_is_reported_in_lines_when_not_on_a_terminal(tmp_path, capsys, monkeypatch):
    """Without a terminal (as here) --progress auto prints lines with an estimate, once the
    work has taken two seconds (a quick run stays quiet); the summary says how far the run
    got when it ended before its duration."""
    from hybridteam import progress

    clock = iter(range(0, 1000))  # each reading one second later
    monkeypatch.setattr(progress.time, "perf_counter", lambda: float(next(clock)))
    out = tmp_path / "ball"
    assert (
        main(
            ["run", str(EXAMPLES / "automata" / "bouncing_ball.yaml"), "-o", str(out), "--no-views"]
        )
        == 0
    )
    captured = capsys.readouterr()
    lines = [x for x in captured.err.splitlines() if x.startswith("hybridteam: bouncing")]
    assert lines and all("% simulated, " in x for x in lines)
    assert any("ETA" in x for x in lines)
    # the ball reaches its Zeno point at t = 2.5586 of the file's 5 s
    assert "2.55863 of 5 s simulated" in captured.out
    monkeypatch.undo()
    assert main(["run", THERMO, "-o", str(tmp_path / "q"), "--no-views"]) == 0
    assert "simulated," not in capsys.readouterr().err  # quick: no progress lines


def test_every_view_writes_a_valid_pdf(tmp_path, relay_trace, capsys):
    """Papers need vector PDF: the diagram, the timeline (whole and close-up) and the
    trajectories each write one with a PDF header and at least one page."""
    assert main(["plot", str(relay_trace), "-f", "pdf", "-o", str(tmp_path / "f.pdf")]) == 0
    outs = {
        "diagram": ["diagram", RELAY],
        "timeline": ["timeline", str(relay_trace)],
        "close-up": ["timeline", str(relay_trace), "--window", "4.9", "5.1"],
        "plot": ["plot", str(relay_trace)],
    }
    for name, args in outs.items():
        path = tmp_path / f"{name}.pdf"
        assert main([*args, "-o", str(path)]) == 0, name
        data = path.read_bytes()
        assert (
            data[:5] == b"%PDF-" and b"/Type /Page" in data and data.rstrip().endswith(b"%%EOF")
        ), name
