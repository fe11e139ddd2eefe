"""Merging a live run's process traces (hybridteam/live/merge.py), on hand-made traces
whose answers are known: times moved to the first process's clock, samples read there."""

from __future__ import annotations

import numpy as np
import pytest

from hybridteam.live.merge import MergeError, merge_traces
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


def test_a_run_whose_end_rule_processes_left_no_trace_merges_with_the_world_process():
    """No process hosts the rule's agent (its process died): every process decides, the
    world process (which hosts none) among them, and its outcome is the team's."""
    b = process("b", 100.0, [(0.0, "B0")], [1.0, 2.0, 3.0])
    world = world_process(100.0, [3.0, 4.0, 5.0], outcome="link_broken")
    merged = merge_traces([b, world], ending=["a"])
    assert merged.outcomes[0]["outcome"] == "link_broken"
