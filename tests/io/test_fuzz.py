"""Fuzzing: random structural mutations of every kind of input, through the command line.

Hypothesis mutates the shipped examples — a team, a protocol, a study — and a trace: it
deletes keys, renames them, replaces values by values of other kinds (numbers out of
range, strings, lists, maps, null, NaN text, expressions that divide by zero), duplicates
list items. Each mutant goes through ``validate``; a team that validates also runs briefly,
and a trace goes through the views. Whatever the mutant, the command must end with exit 0
or 2 within the time bound — never a traceback (an exception escaping ``main`` fails the
test), never a hang. Derandomized, so a failure here fails the same way again.
"""

from __future__ import annotations

import json
import signal
from pathlib import Path
from typing import Any

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hybridteam.cli import main

ROOT = Path(__file__).resolve().parents[2]
SOURCES = {
    "team": ROOT / "examples" / "protocols" / "handover.yaml",
    "flow": ROOT / "examples" / "automata" / "water_tanks.yaml",
    "protocol": ROOT / "protocols" / "role_assignment.yaml",
    "study": ROOT / "tests" / "fixtures" / "sweep" / "study.yaml",
}
VALUES = [
    None,
    "",
    0,
    -1,
    1e300,
    -1e-300,
    "x",
    "1/0",
    "sqrt(-1)",
    "nan",
    "inf",
    True,
    [],
    {},
    [1, 2],
    {"a": 1},
    "a" * 300,
    10**30,
    "t > ",
    "Cool",
    "agents",
    0.5,
]
SETTINGS = settings(
    max_examples=40,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)


def paths(data: Any, prefix: tuple = ()) -> list[tuple]:
    """Every path into nested dicts and lists (the root excluded)."""
    out = []
    if isinstance(data, dict):
        for k, v in data.items():
            out.append((*prefix, k))
            out += paths(v, (*prefix, k))
    elif isinstance(data, list):
        for i, v in enumerate(data):
            out.append((*prefix, i))
            out += paths(v, (*prefix, i))
    return out


def mutate(data: Any, draw) -> Any:
    """One to three structural mutations at random places."""
    data = json.loads(json.dumps(data))
    for _ in range(draw(st.integers(1, 3))):
        found = paths(data)
        if not found:
            break
        path = draw(st.sampled_from(found))
        parent = data
        for p in path[:-1]:
            parent = parent[p]
        key = path[-1]
        how = draw(st.sampled_from(["delete", "replace", "rename", "duplicate"]))
        if how == "delete":
            del parent[key]
        elif how == "replace":
            parent[key] = draw(st.sampled_from(VALUES))
        elif how == "rename" and isinstance(parent, dict):
            parent[str(key)[:-1] + "x"] = parent.pop(key)
        elif how == "duplicate" and isinstance(parent, list):
            parent.insert(key, parent[key])
    return data


class _Hang(Exception):
    pass


def _alarm(signum, frame):
    raise _Hang("a command took longer than 20 s")


def run_cli(argv: list[str]) -> int:
    old = signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(20)
    try:
        return main(argv)
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


@pytest.mark.parametrize("kind", sorted(SOURCES))
@SETTINGS
@given(data=st.data())
def test_mutated_files_validate_and_run_or_are_refused(kind, data, tmp_path_factory, capsys):
    folder = tmp_path_factory.mktemp(kind)
    original = yaml.safe_load(SOURCES[kind].read_text())
    if kind == "study":  # its team, beside it
        team = original.get("team", "handshake.yaml")
        (folder / team).write_text((SOURCES[kind].parent / team).read_text())
    mutant = mutate(original, data.draw)
    path = folder / f"{kind}.yaml"
    path.write_text(yaml.safe_dump(mutant, sort_keys=False))
    code = run_cli(["validate", str(path)])
    assert code in (0, 2)
    if code == 0 and kind in ("team", "flow"):
        code = run_cli(
            [
                "run",
                str(path),
                "-o",
                str(folder / "out"),
                "--duration",
                "0.5",
                "--no-views",
                "--quiet",
            ]
        )
        assert code in (0, 2)
    assert "Traceback" not in capsys.readouterr().err


@pytest.fixture(scope="module")
def trace(tmp_path_factory) -> dict:
    folder = tmp_path_factory.mktemp("trace")
    assert (
        main(
            [
                "run",
                str(SOURCES["team"]),
                "-o",
                str(folder),
                "--no-views",
                "--quiet",
                "--duration",
                "4",
            ]
        )
        == 0
    )
    return json.loads((folder / "trace.json").read_text())


@SETTINGS
@given(data=st.data())
def test_mutated_traces_draw_or_are_refused(trace, data, tmp_path_factory, capsys):
    folder = tmp_path_factory.mktemp("views")
    path = folder / "trace.json"
    path.write_text(json.dumps(mutate(trace, data.draw)))
    for argv in (
        ["timeline", str(path), "-o", str(folder / "t.png")],
        ["sequence", str(path)],
        ["plot", str(path), "-o", str(folder / "p.png")],
    ):
        assert run_cli(argv) in (0, 2)
    assert "Traceback" not in capsys.readouterr().err
