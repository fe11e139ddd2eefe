"""Merging a live run's process traces (hybridteam/live/merge.py), on hand-made traces
whose answers are known: times moved to the first process's clock, samples read there,
and clocks skewed by known amounts aligned from messages of known latencies."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from hybridteam.cli.live import alignment_text
from hybridteam.live.merge import MergeError, clock_error, merge_traces
from hybridteam.trace import INTERVAL_COLUMNS, MESSAGE_COLUMNS, TRANSITION_COLUMNS, Table, Trace

AGENTS = [
    {"name": n, "plant": "flow", "state": ["x"], "inputs": [], "modes": []} for n in ("a", "b")
]


def process(
    agent: str,
    wall_start: float,
    transitions: list[tuple],
    x: list[float],
    outcome: str = "ok",
    t_end: float = 2.0,
) -> Trace:
    """One process's trace hosting ``agent`` (scale 2): its transitions ``(t, target)``,
    its agent's samples ``x`` at 0, 1, 2 (the other agent's NaN)."""
    rows = {c: [] for c in TRANSITION_COLUMNS}
    for t, target in transitions:
        for c, v in zip(TRANSITION_COLUMNS, (0, agent, t, 0, "", target, "init", ""), strict=True):
            rows[c].append(v)
    samples = {n: np.full((3, 1, 1), np.nan) for n in ("a", "b")}
    samples[agent] = np.array(x, float).reshape(3, 1, 1)
    meta = {
        "team": "t",
        "n": 1,
        "seed": 0,
        "duration": 2.0,
        "agents": AGENTS,
        "live": {"agents": [agent], "digest": "d", "wall_start": wall_start, "time_scale": 2.0},
    }
    messages = Table(
        MESSAGE_COLUMNS,
        {
            "instance": [0],
            "seq": [0],
            "sender": ["a" if agent == "b" else "b"],
            "receiver": [agent],
            "socket": ["control"],
            "type": ["m"],
            "t_send": [0.5],
            "t_recv": [0.75],
            "status": ["delivered"],
            "reason": [""],
            "msg_id": [-1],
        },
    )
    return Trace(
        meta,
        [{"instance": 0, "outcome": outcome, "t": t_end, "message": ""}],
        Table(TRANSITION_COLUMNS, rows),
        Table(INTERVAL_COLUMNS),
        messages,
        np.array([0.0, 1.0, 2.0]),
        samples,
    )


def test_times_move_to_the_first_process_clock():
    """b's process started 0.5 wall s after a's, at time scale 2: 1.0 run s later, so
    its times gain 1.0 and its samples, read at the common times 0, 1, 2, are its own at
    -1 (none), 0 and 1."""
    a = process("a", 100.0, [(0.0, "A0"), (1.5, "A1")], [0.0, 10.0, 20.0])
    b = process("b", 100.5, [(0.0, "B0"), (0.25, "B1")], [5.0, 7.0, 9.0], t_end=1.5)
    merged = merge_traces([b, a], ending=["a", "b"])
    assert merged.meta["live"]["offsets"] == [1.0, 0.0]
    assert list(
        zip(
            merged.transitions["agent"],
            merged.transitions["t"],
            merged.transitions["target"],
            strict=True,
        )
    ) == [("a", 0.0, "A0"), ("b", 1.0, "B0"), ("b", 1.25, "B1"), ("a", 1.5, "A1")]
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
        {"from": ["a"], "to": ["b"], "offset_s": [-0.125, 0.125]}
    ]
    b.messages.columns["t_recv"][:] = 1.5  # b's copy from a: 1.0 run s, 0.5 wall s
    a.messages.columns["status"][:] = "lost"  # and a received nothing from b
    assert merge_traces([a, b]).meta["live"]["clock_bounds"] == [
        {"from": ["a"], "to": ["b"], "offset_s": [None, 0.5]}
    ]


def test_the_merge_s_clock_error_is_the_widest_bound_both_ways():
    """Offsets within [-0.125, 0.125] and [0.2, 0.3] (0 is not even in it: the merge's
    one clock is off by 0.2 to 0.3 s there): at most 0.3 s; a pair bounded one way only
    bounds nothing."""
    bounds = [{"offset_s": [-0.125, 0.125]}, {"offset_s": [None, 0.5]}, {"offset_s": [0.2, 0.3]}]
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
    samples = {
        "a": np.full((3, 1, 1), np.nan),
        "b": np.full((3, 1, 1), np.nan),
        "box": np.array(box, float).reshape(3, 1, 1),
    }
    meta = {
        **tr.meta,
        "obstacles": {"circles": [[0.0, 0.0, 1.0]]},
        "live": {**tr.meta["live"], "agents": [], "world": True},
    }
    return Trace(
        meta,
        tr.outcomes,
        tr.transitions,
        tr.intervals,
        tr.messages.filter(np.zeros(1, bool)),
        tr.sample_times,
        samples,
    )


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


# ------------------------------------------------------- clocks aligned by messages
K = 2.0  # the time scale of every process below


def on_machine(
    agent: str,
    agents: list[str],
    start: float,
    clock: float,
    transitions: list[tuple[float, str]],
    received: list[tuple[str, float, float, float]],
) -> Trace:
    """The trace of a process hosting ``agent`` whose wall clock reads true time ``T`` as
    ``T + clock``, started at true time ``start`` (so it recorded ``start + clock``), at
    time scale K, as the live clock records: a transition ``(T, target)`` at run time
    ``K (T - start)``; a copy received ``(sender, T_send, sender's clock, latency)`` with
    its send time read on the sender's wall clock and converted with this process's
    start, ``K (T_send + sender's clock - (start + clock))``, and its arrival on this
    process's own run clock, ``K (T_send + latency - start)``."""
    rows = {c: [] for c in TRANSITION_COLUMNS}
    for t, target in transitions:
        for c, v in zip(
            TRANSITION_COLUMNS, (0, agent, K * (t - start), 0, "", target, "init", ""), strict=True
        ):
            rows[c].append(v)
    n = len(received)
    messages = Table(
        MESSAGE_COLUMNS,
        {
            "instance": [0] * n,
            "seq": list(range(n)),
            "sender": [r[0] for r in received],
            "receiver": [agent] * n,
            "socket": ["control"] * n,
            "type": ["m"] * n,
            "t_send": [K * (ts + c - (start + clock)) for _, ts, c, _ in received],
            "t_recv": [K * (ts + lat - start) for _, ts, _, lat in received],
            "status": ["delivered"] * n,
            "reason": [""] * n,
            "msg_id": [-1] * n,
        },
    )
    spec = [{"name": n, "plant": "flow", "state": ["x"], "inputs": [], "modes": []} for n in agents]
    meta = {
        "team": "t",
        "n": 1,
        "seed": 0,
        "duration": 2.0,
        "agents": spec,
        "live": {"agents": [agent], "digest": "d", "wall_start": start + clock, "time_scale": K},
    }
    samples = {n: np.full((3, 1, 1), np.nan) for n in agents}
    return Trace(
        meta,
        [{"instance": 0, "outcome": "ok", "t": 1.0, "message": ""}],
        Table(TRANSITION_COLUMNS, rows),
        Table(INTERVAL_COLUMNS),
        messages,
        np.array([0.0, 1.0, 2.0]),
        samples,
    )


# True clocks: a's reads +0.3 s, b's -0.2 s (b's clock is 0.5 s behind a's), c's +0.1 s.
# a started at true 100.0, b at 100.5, c at 100.2: the merged time of true T is 2 (T - 100).
CLOCK = {"a": 0.3, "b": -0.2, "c": 0.1}
START = {"a": 100.0, "b": 100.5, "c": 100.2}


def pair(
    agents: list[str],
    links: dict[tuple[str, str], float],
    transitions: dict[str, list[tuple[float, str]]],
) -> list[Trace]:
    """One process per agent; ``links[(p, q)]``: the latency of the one copy p sent to q,
    at true time 101.0 (a), 101.2 (b) or 101.3 (c)."""
    sent = {"a": 101.0, "b": 101.2, "c": 101.3}
    return [
        on_machine(
            q,
            agents,
            START[q],
            CLOCK[q],
            transitions.get(q, []),
            [(p, sent[p], CLOCK[p], lat) for (p, r), lat in links.items() if r == q],
        )
        for q in agents
    ]


def test_with_latencies_alike_both_ways_the_messages_give_the_clocks_exactly():
    """a->b and b->a both take 0.05 s: b's copy reads 0.05 - 0.5 = -0.45 s, a's 0.05 +
    0.5 = 0.55 s, so b's clock minus a's lies in [-0.55, -0.45]: estimate -0.5 (the
    truth), error bound 0.05. b's transition at true 101.5 merges at 2 (101.5 - 100) = 3.0,
    a copy's send and arrival at their true times (one wall clock would put b's
    transition at 2 (101.5 - 0.2 - 100.3) = 2.0, a whole K 0.5 early)."""
    traces = pair(
        ["a", "b"],
        {("a", "b"): 0.05, ("b", "a"): 0.05},
        {"a": [(100.5, "A1")], "b": [(101.5, "B1")]},
    )
    merged = merge_traces(traces, align="messages")
    live = merged.meta["live"]
    assert live["align"] == "messages" and live["clock_reference"] == 0
    assert live["clock_offsets_s"] == pytest.approx([0.0, -0.5], abs=1e-12)
    assert live["clock_errors_s"] == pytest.approx([0.0, 0.05], abs=1e-12)
    assert merged.transitions["t"].tolist() == pytest.approx([1.0, 3.0], abs=1e-12)
    # b received a's copy (sent 101.0, arrived 101.05), a received b's (101.2, 101.25)
    assert merged.messages["sender"].tolist() == ["a", "b"]
    assert merged.messages["t_send"].tolist() == pytest.approx([2.0, 2.4], abs=1e-12)
    assert merged.messages["t_recv"].tolist() == pytest.approx([2.1, 2.5], abs=1e-12)
    assert live["wall_start"] == pytest.approx(100.3, abs=1e-12)  # a's start, a's clock
    wall = merge_traces(traces)  # (one machine's clock assumed: b's times 1.0 early)
    assert wall.meta["live"]["align"] == "wall"
    assert wall.transitions["t"].tolist() == pytest.approx([1.0, 2.0], abs=1e-12)


def test_with_latencies_unlike_the_estimate_is_off_by_half_their_difference():
    """a->b takes 0.02 s, b->a 0.06 s: b's clock minus a's in [-0.56, -0.48], estimate
    -0.52 (0.02 off: half the latencies' difference), bound 0.04 (half their sum). b's
    times move 2 x 0.02 = 0.04 run s late, within the stated 2 x 0.04; a copy b sent is
    read on b's clock, so its send time is as late, whoever recorded it."""
    traces = pair(["a", "b"], {("a", "b"): 0.02, ("b", "a"): 0.06}, {"b": [(101.5, "B1")]})
    merged = merge_traces(traces, align="messages")
    live = merged.meta["live"]
    assert live["clock_bounds"][0]["offset_s"] == pytest.approx([-0.56, -0.48], abs=1e-12)
    assert live["clock_offsets_s"] == pytest.approx([0.0, -0.52], abs=1e-12)
    assert live["clock_errors_s"] == pytest.approx([0.0, 0.04], abs=1e-12)
    assert merged.transitions["t"].tolist() == pytest.approx([3.04], abs=1e-12)
    assert abs(3.04 - 3.0) <= K * live["clock_errors_s"][1]
    # b's copy to a (true 2.4 -> 2.5): its send 0.04 late; a's to b (2.0 -> 2.04): its
    # arrival, on b's clock, 0.04 late
    assert merged.messages["t_send"].tolist() == pytest.approx([2.0, 2.44], abs=1e-12)
    assert merged.messages["t_recv"].tolist() == pytest.approx([2.08, 2.52], abs=1e-12)


def test_a_chain_of_processes_sums_the_pairs_estimates_along_the_tightest_path():
    """a<->b as above (estimate -0.52, bound 0.04); b<->c: b->c 0.01 s, c->b 0.03 s, so
    c's clock minus b's in [0.27, 0.31]: 0.29, bound 0.02. c from a through b: -0.52 +
    0.29 = -0.23 (truth -0.2), bound 0.06. A direct a<->c pair 0.2 s each way (exact
    midpoint, bound 0.2) is the looser path and is not taken."""
    links = {("a", "b"): 0.02, ("b", "a"): 0.06, ("b", "c"): 0.01, ("c", "b"): 0.03}
    transitions = {"c": [(101.0, "C1")]}
    for extra in ({}, {("a", "c"): 0.2, ("c", "a"): 0.2}):
        merged = merge_traces(
            pair(["a", "b", "c"], {**links, **extra}, transitions), align="messages"
        )
        live = merged.meta["live"]
        assert live["clock_offsets_s"] == pytest.approx([0.0, -0.52, -0.23], abs=1e-12)
        assert live["clock_errors_s"] == pytest.approx([0.0, 0.04, 0.06], abs=1e-12)
        # c's transition at true 101.0 (truth 2.0): 2 x 0.03 late, within 2 x 0.06
        assert merged.transitions["t"].tolist() == pytest.approx([2.06], abs=1e-12)


def test_a_process_not_bounded_both_ways_keeps_its_wall_clock_and_an_unknown_error():
    """c only hears b (nothing from c reached anyone): its clock is not estimated (0, its
    wall clock taken for the reference's) and its error is None. Given first, it cannot
    be the reference: a reaches b, so a is. c's arrivals stand at its wall clock's
    reading of them: b's copy (sent at true 101.2, 0.01 s on its way) at 2 x (101.21 +
    0.1 - 100.3) = 2.02 (truth 2.42); its send time, read on b's clock, is moved by b's
    estimate: 2.44 (truth 2.4)."""
    traces = pair(["a", "b", "c"], {("a", "b"): 0.02, ("b", "a"): 0.06, ("b", "c"): 0.01}, {})
    merged = merge_traces([traces[2], traces[0], traces[1]], align="messages")
    live = merged.meta["live"]
    assert live["clock_reference"] == 1
    assert live["clock_offsets_s"] == pytest.approx([0.0, 0.0, -0.52], abs=1e-12)
    assert live["clock_errors_s"][0] is None
    assert live["clock_errors_s"][1:] == pytest.approx([0.0, 0.04], abs=1e-12)
    got = merged.messages.filter(merged.messages["receiver"] == "c")
    assert got["t_send"].tolist() == pytest.approx([2.44], abs=1e-12)
    assert got["t_recv"].tolist() == pytest.approx([2.02], abs=1e-12)
    # what hybridteam merge says of it
    assert alignment_text(live) == (
        "on a's clock, the others' aligned by their messages within 0.04 s, c not (no "
        "messages both ways: wall clock taken, error unknown) (meta.live.clock_errors_s)"
    )


def test_bounds_that_contradict_each_other_bound_nothing():
    """b's copy arrived 0.1 s 'before' it was sent by a's clock both ways (a clock
    stepped during the run): [lo, hi] = [0.1, -0.1] is empty; b's error is unknown."""
    traces = pair(["a", "b"], {("a", "b"): 0.0, ("b", "a"): 0.0}, {})
    traces[0].messages.columns["t_recv"] -= K * 0.1
    traces[1].messages.columns["t_recv"] -= K * 0.1
    live = merge_traces(traces, align="messages").meta["live"]
    assert live["clock_bounds"][0]["offset_s"] == pytest.approx([-0.4, -0.6], abs=1e-12)
    assert live["clock_errors_s"] == [0.0, None]
    assert live["clock_offsets_s"] == [0.0, 0.0]


# ---------------------------------------------------------------- hybridteam merge
HANDSHAKE = Path(__file__).parents[1] / "fixtures" / "live" / "handshake.yaml"


def cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "hybridteam.cli", *args], capture_output=True, timeout=120
    )


@pytest.fixture(scope="module")
def launched(tmp_path_factory) -> Path:
    """A launch of the handshake team: its merged trace and each process's folder."""
    out = tmp_path_factory.mktemp("launch") / "out"
    done = cli("launch", str(HANDSHAKE), "--time-scale", "4", "-o", str(out))
    assert done.returncode == 0, done.stderr.decode()
    return out


def test_merging_a_launch_s_folders_gives_the_launch_s_own_trace(launched, tmp_path):
    """The processes' folders, given in another order than the team's, on one wall clock
    as launch aligns them: the merged trace and summary are the launch's, key for key
    (launch merges through the same code)."""
    agents = launched / "agents"
    done = cli(
        "merge",
        str(agents / "granter"),
        str(agents / "requester" / "trace.json"),
        "--align",
        "wall",
        "-o",
        str(tmp_path / "m"),
    )
    assert done.returncode == 0, done.stderr.decode()
    line = done.stderr.decode().strip()
    assert line.startswith("live handshake: ok at t=") and "\n" not in line
    bounds = json.loads((tmp_path / "m" / "trace.json").read_text())["meta"]["live"]["clock_bounds"]
    lo, hi = bounds[0]["offset_s"]  # (request and grant crossed both ways)
    assert f"within {max(abs(lo), abs(hi)):.3g} s (meta.live.clock_bounds)" in line
    for name in ("trace.json", "summary.json"):
        assert json.loads((tmp_path / "m" / name).read_text()) == json.loads(
            (launched / name).read_text()
        ), name
    # the end rule came from the processes' records: each process knows the team's
    assert Trace.load(agents / "granter" / "trace.json").meta["live"]["ending"] == [
        "requester",
        "granter",
    ]


def test_a_launch_s_folders_aligned_by_their_messages_agree_with_its_one_clock(launched, tmp_path):
    """On one machine the wall clocks are one, so the launch's offsets are exact: aligned
    by their messages (merge's default), the granter's clock is estimated within the
    bound the line and meta.live state, and its rows move by no more than K times it.
    (On one machine, every copy's receive minus send time is its latency, which is not
    negative, so the truth, 0, is in every pair's bounds: the estimate, their midpoint,
    is within their half-width of it however loaded the machine.)"""
    done = cli(
        "merge",
        str(launched / "agents" / "requester"),
        str(launched / "agents" / "granter"),
        "-o",
        str(tmp_path / "m"),
    )
    assert done.returncode == 0, done.stderr.decode()
    live = Trace.load(tmp_path / "m" / "trace.json").meta["live"]
    wall = Trace.load(launched / "trace.json").meta["live"]
    assert live["align"] == "messages" and wall["align"] == "wall"
    assert live["clock_reference"] == 0  # the requester's process, the team's first
    d, error, scale = live["clock_offsets_s"][1], live["clock_errors_s"][1], 4.0
    assert error is not None and abs(d) <= error
    moved = (live["offsets"][1] - live["offsets"][0]) - (wall["offsets"][1] - wall["offsets"][0])
    assert moved == pytest.approx(-scale * d, abs=1e-9)
    line = done.stderr.decode().strip()
    assert (
        "\n" not in line
        and f"on requester's clock, the others' aligned by their "
        f"messages within {error:.3g} s (meta.live.clock_errors_s)"
        in line
    )


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


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda d, t: [str(t / "nowhere")], "nowhere: no such file"),
        (lambda d, t: [str(t)], "trace.json: no such file"),
        (
            lambda d, t: [str(d / "agents" / "granter"), str(d / "agents" / "granter")],
            "granter: given twice",
        ),
        (
            lambda d, t: [edited(d, t, lambda j: j["meta"].pop("live"))],
            "edited.json: not a live process's trace (no meta.live)",
        ),
        (
            lambda d, t: [edited(d, t, lambda j: j["meta"]["live"].update(wall_start="noon"))],
            "edited.json: meta.live.wall_start is not a finite number",
        ),
        (
            lambda d, t: [edited(d, t, lambda j: j["meta"]["live"].update(time_scale=0))],
            "edited.json: meta.live.time_scale is not a finite number > 0",
        ),
        (
            lambda d, t: [edited(d, t, lambda j: j["meta"]["live"].update(agents=["intruder"]))],
            "edited.json: meta.live.agents is not a list of the team's agents",
        ),
        (
            lambda d, t: [
                str(d / "agents" / "granter"),
                edited(d, t, lambda j: j["meta"]["live"].update(digest="0" * 16)),
            ],
            "cannot merge: the traces are not the processes of one live team",
        ),
        (
            lambda d, t: [
                str(d / "agents" / "granter"),
                edited(d, t, lambda j: j["meta"]["live"].update(agents=["granter"])),
            ],
            "cannot merge: an agent is hosted by two of the processes",
        ),
        (
            lambda d, t: [str(d / "agents" / "granter"), str(t / "out")],
            "is the output's own trace (-o",
        ),
    ],
)
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


def with_intervals(tr: Trace, rows: list[tuple[str, float, float]]) -> Trace:
    """``tr`` with its agent's mode intervals ``(mode, start, end)``, all at depth 1."""
    agent = tr.meta["live"]["agents"][0]
    table = Table(
        INTERVAL_COLUMNS,
        {
            "instance": [0] * len(rows),
            "agent": [agent] * len(rows),
            "mode": [m for m, _, _ in rows],
            "depth": [1] * len(rows),
            "start": [s for _, s, _ in rows],
            "end": [e for _, _, e in rows],
        },
    )
    return Trace(
        tr.meta, tr.outcomes, tr.transitions, table, tr.messages, tr.sample_times, tr.samples
    )


def test_a_final_mode_reached_early_is_held_to_the_teams_end():
    """Both processes on one clock (same wall start). a's run ended by the end rule at
    t = 1.5 in its final mode Parked (its process stopped recording there), b's at 2.0:
    in the team's trace Parked lasts to 2.0, as in a simulation (a final mode is never
    left), while Go, which ended at 1.5 by a transition, keeps its end. A process
    stopped (not by the end rule) keeps its intervals as recorded."""
    a = with_intervals(
        process("a", 100.0, [], [0.0, 1.0, 2.0], t_end=1.5),
        [("Go", 0.0, 1.5), ("Parked", 1.5, 1.5)],
    )
    b = with_intervals(process("b", 100.0, [], [0.0, 1.0, 2.0], t_end=2.0), [("Wait", 0.0, 2.0)])
    merged = merge_traces([a, b], ending=["a", "b"])
    ends = {
        m: e
        for m, e in zip(
            merged.intervals["mode"].tolist(), merged.intervals["end"].tolist(), strict=True
        )
    }
    assert ends == {"Go": 1.5, "Parked": 2.0, "Wait": 2.0}
    stopped = with_intervals(
        process("a", 100.0, [], [0.0, 1.0, 2.0], outcome="stopped", t_end=1.5), [("Go", 0.0, 1.5)]
    )
    merged = merge_traces([stopped, b], ending=["b"])
    assert merged.intervals.where(agent="a")["end"].tolist() == [1.5]
