"""``--jobs N`` in the Python loop (``--kernel off``; the compiled loop's threads are
``tests/verify/test_verify_kernel.py``'s): successors computed by a pool of processes
give the same graph as one process — the same states in the same order, the same edges,
parents, verdicts and replayed counterexamples — and the pool's processes end with the
check, on an error in a worker and on Ctrl-C alike."""

from __future__ import annotations

import multiprocessing
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from hybridteam.cli.common import EXIT_INTERRUPTED
from hybridteam.verify import Options, verify
from hybridteam.verify.machine import Copy, Machine, State
from hybridteam.verify.pool import WorkerDied
from hybridteam.verify.store import Parts, Renumber, decode, state_key
from tests.verify.test_verify import REQUEST, docking, mutate, roles_team, verdicts
from tests.verify.test_verify_kernel import edge_choices

ROOT = Path(__file__).resolve().parents[2]


def _same_graph(one, two) -> None:
    """The two reports' graphs and verdicts are the same, item by item."""
    a, b = one.graph, two.graph
    assert len(a.states) == len(b.states) and a.transitions == b.transitions
    assert list(a.states) == list(b.states)  # the same states, numbered alike
    assert list(a.parent) == list(b.parent)
    assert len(a.edges) == len(b.edges)
    # the edges as the checks read them (one job may take the compiled loop, which
    # keeps only this view: each state's edges in the order added), and their choices
    (row_a, dst_a, _), (row_b, dst_b, _) = a.edges.view(), b.edges.view()
    assert np.array_equal(row_a, row_b) and np.array_equal(dst_a, dst_b)
    assert edge_choices(a) == edge_choices(b)
    assert a.zeno == b.zeno and a.cut == b.cut and a.exhaustive == b.exhaustive
    assert [(v.prop.name, v.holds, v.state, v.others, v.lasso) for v in one.verdicts] == [
        (v.prop.name, v.holds, v.state, v.others, v.lasso) for v in two.verdicts
    ]


def test_two_jobs_explore_the_same_graph_as_one(tmp_path):
    """The role protocol with a request and a loss (its min_hold guard reads time: both
    outcomes are tried, so the retries of free comparisons are exercised too)."""
    team = roles_team(tmp_path, "b")
    one = verify(team, Options(losses=1), replay=False)
    two = verify(team, Options(losses=1, jobs=2, batch=64, kernel="off"), replay=False)
    assert len(one.graph.states) == 2275  # (several chunks a level with batch 64)
    _same_graph(one, two)
    assert all(v.holds for v in two.verdicts)


def test_two_jobs_find_and_replay_the_same_counterexample(tmp_path):
    team = roles_team(tmp_path, "b", mutate(REQUEST, REQUEST.replace("to: Requesting", "to: Lead")))
    one = verify(team, Options(losses=0))
    two = verify(team, Options(losses=0, jobs=2, kernel="off"))
    _same_graph(one, two)
    v1, v2 = verdicts(one)["one_leader"], verdicts(two)["one_leader"]
    assert v2.holds is False and two.counterexample(v2) == one.counterexample(v1)
    assert two.replays["one_leader"][1].reproduced


@pytest.mark.slow
def test_two_jobs_on_the_docking_handshake(tmp_path):
    team = docking(tmp_path, acknowledged=False)
    _same_graph(
        verify(team, Options(losses=1), replay=False),
        verify(team, Options(losses=1, jobs=2, kernel="off"), replay=False),
    )


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


def test_an_error_in_a_worker_ends_the_pool(tmp_path, monkeypatch):
    pids = tmp_path / "pids"

    def broken(self, jobs):  # (the workers are forked: they inherit this)
        with pids.open("a") as f:
            f.write(f"{os.getpid()}\n")
        raise RuntimeError("a broken successor function")

    monkeypatch.setattr(Machine, "run", broken)
    with pytest.raises(RuntimeError, match="a broken successor function"):
        verify(roles_team(tmp_path, "b"), Options(losses=1, jobs=2, kernel="off"), replay=False)
    workers = {int(p) for p in pids.read_text().split()}
    assert workers and os.getpid() not in workers  # it failed in the workers
    assert not multiprocessing.active_children()
    assert not [p for p in workers if _alive(p)]


def test_a_worker_killed_ends_the_check(tmp_path, monkeypatch):
    """A worker killed (as the system's out-of-memory killer would) ends the check with
    one error within seconds, instead of waiting forever for its chunk."""
    pids = tmp_path / "pids"

    def killed(self, jobs):
        with pids.open("a") as f:
            f.write(f"{os.getpid()}\n")
        os.kill(os.getpid(), signal.SIGKILL)

    monkeypatch.setattr(Machine, "run", killed)
    start = time.monotonic()
    with pytest.raises(WorkerDied, match=r"worker process \d+ of verify --jobs 2 ended"):
        verify(roles_team(tmp_path, "b"), Options(losses=1, jobs=2, kernel="off"), replay=False)
    assert time.monotonic() - start < 60  # (a check every second; a loaded machine)
    workers = {int(p) for p in pids.read_text().split()}
    assert workers and not multiprocessing.active_children()
    assert not [p for p in workers if _alive(p)]


def _children(pid: int) -> set[int]:
    """The processes whose parent is ``pid`` (from /proc)."""
    out = set()
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue
            if int(stat[stat.rindex(")") + 2 :].split()[1]) == pid:
                out.add(int(entry.name))
    return out


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads /proc")
def test_ctrl_c_ends_the_pool_and_writes_nothing(tmp_path):
    out = tmp_path / "out"
    code = "import sys; from hybridteam.cli import main; sys.exit(main(sys.argv[1:]))"
    proc = subprocess.Popen(
        [
            sys.executable,
            "-c",
            code,
            "verify",
            str(ROOT / "examples" / "protocols" / "roles_verify.yaml"),
            "--losses",
            "0",
            "--jobs",
            "2",
            "--kernel",
            "off",
            "-o",
            str(out),
            "--progress",
            "none",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        deadline = time.monotonic() + 120
        workers: set[int] = set()
        while len(workers) < 2 and time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.1)
            workers = _children(proc.pid)
        assert len(workers) == 2, "the pool's two workers started"
        time.sleep(1.0)  # exploring, with chunks at the workers
        assert proc.poll() is None, "still exploring (the check takes longer than this)"
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == EXIT_INTERRUPTED
    assert err.strip().splitlines() == ["hybridteam: interrupted; nothing written"]
    assert not [p for p in workers if _alive(p)]
    assert not (out / "verify.json").exists()


def test_keys_from_other_processes_are_renumbered_as_made_here():
    """Two workers number parts each in their own order; their keys, read in the order
    one process would have made them, get the numbers that process gives."""
    copy = Copy(0, 1, "control", "request", 0, (("priority", 2.0),))
    ack = Copy(1, 0, "control", "__ack__", -1, (("id", 0.0),))
    states = [
        State(((b"\x01\x00", (1.0,)), (b"\x00\x01", ())), (copy,), (), (), 1, 0, 0, ()),
        State(((b"\x01\x00", (2.0,)), (b"\x00\x01", ())), (ack, copy), (), ((1, 0, 0),), 2, 1, 0),
        State(((b"\x01\x00", (2.0,)), (b"\x01\x01", ())), (), (), ((1, 0, 0),), 3, 1, 0, ()),
    ]
    here = Parts()
    expected = [state_key(here, s) for s in states]
    a, b = Parts(), Parts()
    state_key(b, states[2])  # worker b has numbered other parts first
    mine = Parts()
    renumber = Renumber(mine, agents=2)
    made = [(1, state_key(a, states[0]), a), (2, state_key(b, states[1]), b)]
    made.append((1, state_key(a, states[2]), a))
    sent = {1: 0, 2: 0}
    got = []
    for source, key, parts in made:
        renumber.learn(source, parts.values[sent[source] :])
        sent[source] = len(parts.values)
        got.append(renumber.key(source, key))
    assert got == expected and mine.values == here.values
    assert [decode(mine, 2, k) for k in got] == states
