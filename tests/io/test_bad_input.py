"""Malformed input: one clear located message, exit status 2, no traceback, nothing run."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hybridteam.cli import main
from hybridteam.io.filekind import InputErrors
from hybridteam.kinds import load_any
from tests.conftest import EXAMPLES, FIXTURES

BAD = FIXTURES / "bad"

# file -> (line, path or field named in the message, words the message must contain)
CORPUS = {
    "yaml_missing_colon.yaml": (8, "", "could not find expected ':'"),
    "yaml_bad_indent.yaml": (6, "", "mapping values are not allowed"),
    "yaml_tab.yaml": (9, "", "tabs are not allowed"),
    "yaml_unclosed_flow.yaml": (7, "", "expected ',' or '}'"),
    "empty.yaml": (1, "", "file is empty"),
    "comments_only.yaml": (1, "", "file is empty"),
    "binary_garbage.yaml": (2, "", "not a text file"),
    "latin1.yaml": (1, "", "invalid UTF-8"),
    "top_level_list.yaml": (1, "", "expected a mapping"),
    "unknown_file_kind.yaml": (1, "kind", "did you mean 'team'"),
    "unknown_top_key.yaml": (2, "agnets", "did you mean 'agents'"),
    "unknown_key_in_transition.yaml": (14, "transitions[0].gaurd", "did you mean 'guard'"),
    "unknown_key_in_mode.yaml": (16, "modes.Cool.flows", "did you mean 'flow'"),
    "duration_not_a_number.yaml": (20, "simulation.duration", "expected a number, got 'long'"),
    "negative_duration.yaml": (20, "simulation.duration", "must be >= 0, got -5"),
    "zero_sample_period.yaml": (21, "simulation.sample_period", "must be > 0"),
    "unknown_plant_kind.yaml": (5, "plant.kind", "did you mean 'flow'"),
    "unknown_target_mode.yaml": (
        14,
        "transitions[0].to",
        "unknown mode 'Col'; did you mean 'Cool'",
    ),
    "unknown_law.yaml": (10, "law", "unknown law 'constnt'; did you mean 'constant'"),
    "unknown_name_in_guard.yaml": (14, "transitions[0].guard", "unknown name 'xx'"),
    "guard_syntax_error.yaml": (14, "transitions[0].guard", "end of expression"),
    "guard_not_a_condition.yaml": (14, "transitions[0].guard", "must be a condition"),
    "guard_attribute.yaml": (14, "transitions[0].guard", "attribute"),
    "guard_import.yaml": (14, "transitions[0].guard", "__import__"),
    "flow_unknown_function.yaml": (12, "modes.Heat.flow.x", "did you mean 'sin'"),
    "duplicate_mode.yaml": (15, "modes.Heat", "duplicate key 'Heat'"),
    "missing_plant.yaml": (4, "agents.thermostat", "missing required key 'plant'"),
    "missing_modes.yaml": (4, "agents.thermostat", "missing required key 'modes'"),
    "unknown_initial.yaml": (9, "agents.thermostat.initial", "unknown initial mode 'Hot'"),
    "unicycle_unknown_state.yaml": (6, "plant.state.heading", "no state 'heading'"),
    "unicycle_unknown_input.yaml": (10, "inputs.speed", "no input 'speed'"),
    "flow_on_unicycle.yaml": (10, "modes.Go.flow", "needs a flow plant"),
    "limits_reversed.yaml": (7, "plant.limits.v", "lower limit 1.0 exceeds upper -1.0"),
    "assign_to_parameter.yaml": (14, "do[0]", "'K' is a parameter and cannot be assigned"),
    "negative_after.yaml": (13, "transitions[0].after", "after must be >= 0"),
    "scenario_unknown_agent.yaml": (22, "scenario[0].agent", "did you mean 'thermostat'"),
    "bad_agent_name.yaml": (3, "agents", "'my thermostat' is not valid"),
    "no_initial_among_children.yaml": (4, "agents.thermostat.initial", "no 'initial'"),
    "law_and_flow_together.yaml": (16, "modes.Cool", "declares both"),
    "law_parameter_shadows_state.yaml": (
        13,
        "law.with.x",
        "binding parameter 'x' of law 'constant' has the name of a state",
    ),
    "period_without_inputs.yaml": (16, "modes.Cool", "'period' samples 'inputs'"),
    "message_declared_twice.yaml": (
        4,
        "messages.request",
        "already declared by protocol 'role_assignment'",
    ),
    "deploy_unknown_agent.yaml": (22, "deploy.thermo", "did you mean 'thermostat'"),
    "deploy_relative_topic.yaml": (24, "deploy.thermostat.odom", "expected a topic's full name"),
    "deploy_unknown_setting.yaml": (25, "deploy.thermostat.frmae", "did you mean 'frame'"),
}


def test_corpus_is_complete():
    assert len(CORPUS) >= 25
    assert set(CORPUS) == {p.name for p in BAD.glob("*.yaml")}


@pytest.mark.parametrize("name", sorted(CORPUS))
def test_bad_file_gives_one_located_error_and_exit_2(name, capsys):
    line, field, words = CORPUS[name]
    path = BAD / name
    status = main(["validate", str(path)])
    out, err = capsys.readouterr()
    assert status == 2
    assert out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    msg = lines[0]
    where = f"{path}:{line}:" if line else f"{path}: "
    assert msg.startswith(where), msg
    assert field in msg and words in msg, msg
    assert "Traceback" not in err


def test_run_refuses_bad_input_and_writes_nothing(tmp_path, capsys):
    out = tmp_path / "out"
    status = main(["run", str(BAD / "unknown_target_mode.yaml"), "-o", str(out)])
    assert status == 2
    assert not out.exists()
    assert "unknown mode 'Col'" in capsys.readouterr().err


def test_run_refuses_a_binding_parameter_named_as_a_state(tmp_path, capsys):
    """``ctx['x']`` reads a binding parameter before a state: a ``with: {x: ...}`` would
    hide the robot's position from the law, so it is refused where it is written."""
    out = tmp_path / "out"
    path = BAD / "law_parameter_shadows_state.yaml"
    assert main(["run", str(path), "-o", str(out)]) == 2
    assert not out.exists()
    assert capsys.readouterr().err.startswith(f"{path}:13:29: ")


def test_dangerous_guard_never_runs(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["run", str(BAD / "guard_import.yaml"), "-o", "out"]) == 2
    assert not (tmp_path / "x").exists()
    assert not (tmp_path / "out").exists()


def test_cli_process_prints_no_traceback(tmp_path):
    """As a real process: exit 2 and the message, for a YAML error and an argument error."""
    for args in (
        ["validate", str(BAD / "binary_garbage.yaml")],
        [
            "run",
            str(EXAMPLES / "automata" / "thermostat.yaml"),
            "-o",
            str(tmp_path / "o"),
            "-n",
            "0",
        ],
        [
            "run",
            str(EXAMPLES / "automata" / "thermostat.yaml"),
            "-o",
            str(tmp_path / "o"),
            "--set",
            "thermostat.KK=1",
        ],
        ["frobnicate"],
    ):
        proc = subprocess.run(
            [sys.executable, "-m", "hybridteam.cli", *args], capture_output=True, text=True
        )
        assert proc.returncode == 2, (args, proc.stderr)
        assert "Traceback" not in proc.stderr and proc.stderr.strip()
    assert not (tmp_path / "o").exists()


VALID = [p.read_bytes() for p in sorted((EXAMPLES / "automata").glob("*.yaml"))]


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.sampled_from(VALID), st.data())
def test_mutated_files_never_raise_uncaught(tmp_path_factory, text, data):
    """Random edits of valid files: either they load, or they fail with located errors."""
    raw = bytearray(text)
    for _ in range(data.draw(st.integers(1, 4))):
        op = data.draw(st.sampled_from(["flip", "delete", "insert", "dup"]))
        pos = data.draw(st.integers(0, max(len(raw) - 1, 0)))
        if op == "flip" and raw:
            raw[pos] = data.draw(st.integers(0, 255))
        elif op == "delete" and raw:
            del raw[pos : pos + data.draw(st.integers(1, 8))]
        elif op == "insert":
            raw[pos:pos] = data.draw(
                st.sampled_from(
                    [
                        b":",
                        b"-",
                        b" ",
                        b"\n",
                        b"{",
                        b"]",
                        b"'",
                        b"__",
                        b"x",
                        b"1e9",
                        b"!!python",
                        b"&a",
                        b"*a",
                        b"\t",
                        b"\x00",
                        b"and",
                        b"(",
                        b"**",
                        b"nan",
                    ]
                )
            )
        elif op == "dup":
            end = min(len(raw), pos + data.draw(st.integers(1, 40)))
            raw[pos:pos] = raw[pos:end]
    path = Path(tmp_path_factory.mktemp("mut")) / "team.yaml"
    path.write_bytes(bytes(raw))
    try:
        loaded = load_any(path)
    except InputErrors as exc:
        assert exc.errors and all(str(e).startswith(str(path)) for e in exc.errors)
    else:
        assert loaded.kind == "team"
