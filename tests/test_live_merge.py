"""Merging a live run's process traces (hybridteam/live/merge.py), on hand-made traces
whose answers are known: times moved to the first process's clock, samples read there."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from hybridteam.live.merge import MergeError, clock_error, merge_traces
from hybridteam.trace import INTERVAL_COLUMNS, MESSAGE_COLUMNS, TRANSITION_COLUMNS, Table, Trace

AGENTS = [{"name": n, "plant": "flow", "state": ["x"], "inputs": [], "modes": []}
          for n in ("a", "b")]


def process(agent: str, wall_start: float, transitions: list[tuple], x: list[float],
            outcome: str = "ok", t_end: float = 2.0) -> Trace:
    """One process's trace hosting ``agent`` (scale 2): its transitions ``(t, target)``,
    its agent's samples ``x`` at 0, 1, 2 (the other agent's NaN)."""
    rows = {c: [] for c in TRANSITION_COLUMNS}
    for t, target in transitions:
        for c, v in zip(TRANSITION_COLUMNS, (0, agent, t, 0, "", target, "init", ""),
                        strict=True):
            rows[c].append(v)
    samples = {n: np.full((3, 1, 1), np.nan) for n in ("a", "b")}
    samples[agent] = np.array(x, float).reshape(3, 1, 1)
    meta = {"team": "t", "n": 1, "seed": 0, "duration": 2.0, "agents": AGENTS,
            "live": {"agents": [agent], "digest": "d", "wall_start": wall_start,
                     "time_scale": 2.0}}
    messages = Table(MESSAGE_COLUMNS, {
        "instance": [0], "seq": [0], "sender": ["a" if agent == "b" else "b"],
        "receiver": [agent], "socket": ["control"], "type": ["m"], "t_send": [0.5],
        "t_recv": [0.75], "status": ["delivered"], "reason": [""], "msg_id": [-1]})
    return Trace(meta, [{"instance": 0, "outcome": outcome, "t": t_end, "message": ""}],
                 Table(TRANSITION_COLUMNS, rows), Table(INTERVAL_COLUMNS), messages,
                 np.array([0.0, 1.0, 2.0]), samples)


def test_times_move_to_the_first_process_clock():
    """b's process started 0.5 wall s after a's, at time scale 2: 1.0 run s later, so
    its times gain 1.0 and its samples, read at the common times 0, 1, 2, are its own at
    -1 (none), 0 and 1."""
    a = process("a", 100.0, [(0.0, "A0"), (1.5, "A1")], [0.0, 10.0, 20.0])
    b = process("b", 100.5, [(0.0, "B0"), (0.25, "B1")], [5.0, 7.0, 9.0], t_end=1.5)
    merged = merge_traces([b, a], ending=["a", "b"])
    assert merged.meta["live"]["offsets"] == [1.0, 0.0]
    assert list(zip(merged.transitions["agent"], merged.transitions["t"],
                    merged.transitions["target"], strict=True)) == [
        ("a", 0.0, "A0"), ("b", 1.0, "B0"), ("b", 1.25, "B1"), ("a", 1.5, "A1")]
    assert merged.messages["t_send"].tolist() == [0.5, 1.5]  # a's copy, then b's
    assert merged.messages["t_recv"].tolist() == [0.75, 1.75]
    np.testing.assert_array_equal(merged.samples["a"][:, 0, 0], [0.0, 10.0, 20.0])
    np.testing.assert_array_equal(merged.samples["b"][:, 0, 0], [np.nan, 5.0, 7.0])
    assert merged.outcomes[0]["outcome"] == "ok"
    assert merged.outcomes[0]["t"] == 2.5  # b's end, 1.5 on its clock


def test_messages_bound_how_far_apart_the_clocks_are():
    """Each process received one copy 0.25 run s (0.125 wall s at scale 2) after its send
    time: b's clock is at most 0.125 s ahead of a's, and (from b to a) at most 0.125 s
    behind."""
    a = process("a", 100.0, [], [0, 0, 0])
    b = process("b", 100.5, [], [0, 0, 0])
    assert merge_traces([a, b]).meta["live"]["clock_bounds"] == [
        {"from": ["a"], "to": ["b"], "offset_s": [-0.125, 0.125]}]
    b.messages.columns["t_recv"][:] = 1.5  # b's copy from a: 1.0 run s, 0.5 wall s
    a.messages.columns["status"][:] = "lost"  # and a received nothing from b
    assert merge_traces([a, b]).meta["live"]["clock_bounds"] == [
        {"from": ["a"], "to": ["b"], "offset_s": [None, 0.5]}]


def test_the_merge_s_clock_error_is_the_widest_bound_both_ways():
    """Offsets within [-0.125, 0.125] and [0.2, 0.3] (0 is not even in it: the merge's
    one clock is off by 0.2 to 0.3 s there): at most 0.3 s; a pair bounded one way only
    bounds nothing."""
    bounds = [{"offset_s": [-0.125, 0.125]}, {"offset_s": [None, 0.5]},
              {"offset_s": [0.2, 0.3]}]
    assert clock_error(bounds) == 0.3
    assert clock_error(bounds[1:2]) is None
    assert clock_error([]) is None


def test_the_first_outcome_of_the_end_rule_hosts_is_the_team_s():
    a = process("a", 0.0, [], [0, 0, 0], outcome="stopped")
    b = process("b", 0.0, [], [0, 0, 0], outcome="delivered")
    assert merge_traces([a, b], ending=["b"]).outcomes[0]["outcome"] == "delivered"
    assert merge_traces([b, a], ending=["a", "b"]).outcomes[0]["outcome"] == "stopped"


def test_traces_of_different_runs_are_refused():
    a = process("a", 0.0, [], [0, 0, 0])
    b = process("b", 0.0, [], [0, 0, 0])
    b.meta["live"]["digest"] = "other"
    with pytest.raises(MergeError, match="not the processes of one live team"):
        merge_traces([a, b])
    with pytest.raises(MergeError, match="hosted by two"):
        merge_traces([a, process("a", 0.0, [], [0, 0, 0])])


def world_process(wall_start: float, box: list[float], outcome: str = "ok") -> Trace:
    """The world process's trace (no agent here, scale 2): the world's series ``box`` at
    0, 1, 2, its meta the world's (what views draw), every agent's samples NaN."""
    tr = process("a", wall_start, [], [np.nan] * 3, outcome=outcome)
    samples = {"a": np.full((3, 1, 1), np.nan), "b": np.full((3, 1, 1), np.nan),
               "box": np.array(box, float).reshape(3, 1, 1)}
    meta = {**tr.meta, "obstacles": {"circles": [[0.0, 0.0, 1.0]]},
            "live": {**tr.meta["live"], "agents": [], "world": True}}
    return Trace(meta, tr.outcomes, tr.transitions, tr.intervals,
                 tr.messages.filter(np.zeros(1, bool)), tr.sample_times, samples)


def test_the_world_series_and_meta_come_from_the_world_process():
    """The world process started 0.5 wall s after a's (1.0 run s at scale 2): its box
    series, read at the common times 0, 1, 2, is its own at -1 (none), 0 and 1; the
    meta the views draw the world from is its."""
    a = process("a", 100.0, [(0.0, "A0")], [0.0, 10.0, 20.0])
    b = process("b", 100.0, [(0.0, "B0")], [1.0, 2.0, 3.0])
    world = world_process(100.5, [3.0, 4.0, 5.0])
    merged = merge_traces([a, b, world], ending=["a"])
    np.testing.assert_array_equal(merged.samples["box"][:, 0, 0], [np.nan, 3.0, 4.0])
    np.testing.assert_array_equal(merged.samples["a"][:, 0, 0], [0.0, 10.0, 20.0])
    assert merged.meta["obstacles"] == {"circles": [[0.0, 0.0, 1.0]]}
    # every process's own end is in the message, the world process's by that name
    assert merged.outcomes[0]["message"].split("; ")[2].startswith("the world: ok at t=")


def test_a_run_whose_end_rule_processes_left_no_trace_merges_with_the_world_process():
    """No process hosts the rule's agent (its process died): every process decides, the
    world process (which hosts none) among them, and its outcome is the team's."""
    b = process("b", 100.0, [(0.0, "B0")], [1.0, 2.0, 3.0])
    world = world_process(100.0, [3.0, 4.0, 5.0], outcome="link_broken")
    merged = merge_traces([b, world], ending=["a"])
    assert merged.outcomes[0]["outcome"] == "link_broken"


# ---------------------------------------------------------------- hybridteam merge
HANDSHAKE = Path(__file__).parent / "fixtures" / "live" / "handshake.yaml"


def cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "hybridteam.cli", *args],
                          capture_output=True, timeout=120)


@pytest.fixture(scope="module")
def launched(tmp_path_factory) -> Path:
    """A launch of the handshake team: its merged trace and each process's folder."""
    out = tmp_path_factory.mktemp("launch") / "out"
    done = cli("launch", str(HANDSHAKE), "--time-scale", "4", "-o", str(out))
    assert done.returncode == 0, done.stderr.decode()
    return out


def test_merging_a_launch_s_folders_gives_the_launch_s_own_trace(launched, tmp_path):
    """The processes' folders, given in another order than the team's: the merged trace
    and summary are the launch's, key for key (launch merges through the same code)."""
    agents = launched / "agents"
    done = cli("merge", str(agents / "granter"), str(agents / "requester" / "trace.json"),
               "-o", str(tmp_path / "m"))
    assert done.returncode == 0, done.stderr.decode()
    line = done.stderr.decode().strip()
    assert line.startswith("live handshake: ok at t=") and "\n" not in line
    bounds = json.loads((tmp_path / "m" / "trace.json").read_text())["meta"]["live"][
        "clock_bounds"]
    lo, hi = bounds[0]["offset_s"]  # (request and grant crossed both ways)
    assert f"within {max(abs(lo), abs(hi)):.3g} s (meta.live.clock_bounds)" in line
    for name in ("trace.json", "summary.json"):
        assert json.loads((tmp_path / "m" / name).read_text()) == \
            json.loads((launched / name).read_text()), name
    # the end rule came from the processes' records: each process knows the team's
    assert Trace.load(agents / "granter" / "trace.json").meta["live"]["ending"] == \
        ["requester", "granter"]


def test_a_merge_missing_a_process_says_which(launched, tmp_path):
    done = cli("merge", str(launched / "agents" / "requester"), "-o", str(tmp_path / "m"))
    assert done.returncode == 0, done.stderr.decode()
    merged = Trace.load(tmp_path / "m" / "trace.json")
    assert merged.meta["live"]["missing"] == {"granter": "no trace given"}
    assert merged.outcomes[0]["message"].endswith("; granter: no trace (no trace given)")
    assert set(merged.transitions["agent"].tolist()) == {"requester"}


def edited(launched: Path, tmp_path: Path, change) -> str:
    """The requester's trace with ``change`` applied to its JSON, as a file."""
    data = json.loads((launched / "agents" / "requester" / "trace.json").read_text())
    change(data)
    path = tmp_path / "edited.json"
    path.write_text(json.dumps(data))
    return str(path)


@pytest.mark.parametrize(("make", "message"), [
    (lambda d, t: [str(t / "nowhere")], "nowhere: no such file"),
    (lambda d, t: [str(t)], "trace.json: no such file"),
    (lambda d, t: [str(d / "agents" / "granter"), str(d / "agents" / "granter")],
     "granter: given twice"),
    (lambda d, t: [edited(d, t, lambda j: j["meta"].pop("live"))],
     "edited.json: not a live process's trace (no meta.live)"),
    (lambda d, t: [edited(d, t, lambda j: j["meta"]["live"].update(wall_start="noon"))],
     "edited.json: meta.live.wall_start is not a finite number"),
    (lambda d, t: [edited(d, t, lambda j: j["meta"]["live"].update(time_scale=0))],
     "edited.json: meta.live.time_scale is not a finite number > 0"),
    (lambda d, t: [edited(d, t, lambda j: j["meta"]["live"].update(agents=["intruder"]))],
     "edited.json: meta.live.agents is not a list of the team's agents"),
    (lambda d, t: [str(d / "agents" / "granter"),
                   edited(d, t, lambda j: j["meta"]["live"].update(digest="0" * 16))],
     "cannot merge: the traces are not the processes of one live team"),
    (lambda d, t: [str(d / "agents" / "granter"),
                   edited(d, t, lambda j: j["meta"]["live"].update(agents=["granter"]))],
     "cannot merge: an agent is hosted by two of the processes"),
    (lambda d, t: [str(d / "agents" / "granter"), str(t / "out")],
     "is the output's own trace (-o"),
])
def test_bad_merge_input_is_one_line_and_nothing_written(launched, tmp_path, make, message):
    (tmp_path / "out").mkdir()
    if message.startswith("is the output"):
        shutil.copy(launched / "agents" / "requester" / "trace.json", tmp_path / "out")
    before = sorted(p.name for p in (tmp_path / "out").iterdir())
    done = cli("merge", *make(launched, tmp_path), "-o", str(tmp_path / "out"))
    assert done.returncode == 2
    lines = done.stderr.decode().strip().splitlines()
    assert len(lines) == 1 and message in lines[0], lines
    assert lines[0].startswith("hybridteam: error: ")
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == before
