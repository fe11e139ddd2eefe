"""The compiled loop (:mod:`hybridteam.verify.kernel`, ``--kernel on``) against the Python
loop (``--kernel off``), which stays the reference semantics: on every verify test model,
mutant and example of ``tests/verify/`` the two explorations are the same graph — the same
states in the same order, the same BFS tree, the same edges with the same choices, the
same Zeno and cut states and bound — so the verdicts and the counterexamples are the same
too; and without numba ``--kernel auto`` takes the Python loop and says so."""

from __future__ import annotations

import sys
import threading
from pathlib import Path

import numpy as np
import pytest

from hybridteam import load
from hybridteam.cli import main
from hybridteam.verify import Options, kernel, verify
from hybridteam.verify.explore import Graph
from hybridteam.verify.kernel import numba_available
from hybridteam.verify.store import Grouped
from tests.verify.test_verify import REQUEST, docking, mutate, roles_team
from tests.verify.test_verify_bounds import COUNTERS, team_of
from tests.verify.test_verify_promela import acked_go
from tests.verify.test_verify_symmetry import ask_team
from tests.verify.test_verify_tables import (
    EXAMPLES,
    ROLE_CASES,
    ROLE_IDS,
    SMALL_CASES,
    SMALL_IDS,
    ZENO,
)

ROOT = Path(__file__).resolve().parents[2]

pytestmark = pytest.mark.skipif(not numba_available(), reason="numba is not installed")


def same_graph(a: Graph, b: Graph) -> None:
    assert len(a.states) == len(b.states)
    assert list(a.states) == list(b.states)
    assert [a.states.agents_of(k) for k in range(len(a.states))] == [
        b.states.agents_of(k) for k in range(len(b.states))
    ]
    assert list(a.parent) == list(b.parent)
    assert a.transitions == b.transitions
    # the edges as the checks read them (the compiled loop keeps only this view: each
    # state's edges in the order added), and every edge's choice (the compiled loop's
    # worked out again from its states)
    (row_a, dst_a, _), (row_b, dst_b, _) = a.edges.view(), b.edges.view()
    assert len(a.edges) == len(b.edges)
    assert (row_a.tolist(), dst_a.tolist()) == (row_b.tolist(), dst_b.tolist())
    assert edge_choices(a) == edge_choices(b)
    assert (a.zeno, a.cut, a.exhaustive, a.bound) == (b.zeno, b.cut, b.exhaustive, b.bound)


def edge_choices(g: Graph) -> list[tuple | None]:
    """Each edge's choice, state by state in the order added."""
    row, dst, _ = g.edges.view()
    return [
        g.edge_choice(k, int(b)) for k in range(len(g.states)) for b in dst[row[k] : row[k + 1]]
    ]


def both(team, **kw) -> None:
    """Explore ``team`` with the compiled loop and with the Python loop: the same graph,
    verdicts and counterexamples."""
    ours = verify(team, Options(kernel="on", symmetry="off", **kw), replay=False)
    ref = verify(team, Options(kernel="off", symmetry="off", **kw), replay=False)
    assert ours.graph.explorer == "compiled kernel"
    assert ref.graph.explorer.startswith("python")
    assert len(ours.graph.states) > 1
    same_graph(ours.graph, ref.graph)
    assert [(v.prop.name, v.holds, v.state, v.lasso) for v in ours.verdicts] == [
        (v.prop.name, v.holds, v.state, v.lasso) for v in ref.verdicts
    ]
    for v, w in zip(ours.violated, ref.violated, strict=True):
        assert ours.path(v) == ref.path(w)
        assert ours.counterexample(v) == ref.counterexample(w)
    # two threads, each level cut in chunks of 64 states shared from two states on (the
    # chunks' seams, the shares' and the queued retries' are all met on these models)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(kernel, "CHUNK", 64)
        mp.setattr(kernel, "SHARED", 2)
        two = verify(team, Options(kernel="on", symmetry="off", jobs=2, **kw), replay=False)
    assert two.graph.explorer == "compiled kernel, 2 threads"
    same_graph(two.graph, ours.graph)


@pytest.mark.parametrize(
    "events,protocol,extra,without_c,opts",
    [*ROLE_CASES, ("b", None, "", False, {"losses": 2, "max_states": 5000})],
    ids=[*ROLE_IDS, "roles-cut"],
)
def test_the_role_protocol_and_its_mutants(tmp_path, events, protocol, extra, without_c, opts):
    if extra == "no_operator":
        extra = "  no_operator: always(not in_mode(operator, Command))\n"
    kw = {} if protocol is None else {"protocol": protocol}
    both(roles_team(tmp_path, events, extra=extra, without_c=without_c, **kw), **opts)


def test_the_checks_read_the_explored_states_and_edges_without_copies(tmp_path):
    """What the compiled loop leaves for the checks is held once: the edges as added are
    their sparse-row view (no sources, no choices, no sorted copy; 32-bit offsets), and
    the agents' part numbers are each state's agents group number into the distinct
    agent tuples, spread for the rows a check reads only."""
    g = verify(roles_team(tmp_path, "b"), Options(kernel="on", losses=1), replay=False).graph
    assert g.explorer == "compiled kernel"
    edges, store = g.edges, g.states
    row, dst, how = edges.view()
    assert len(edges.src) == 0 and row.dtype == np.int32
    assert len(edges) == dst.size == row[-1] > 0
    assert np.shares_memory(dst, np.frombuffer(edges.column.memory, np.uint32))
    assert how is None and len(edges.how) == 0  # (worked out again for a path's edges)
    parts = store.agent_parts
    assert isinstance(parts, Grouped) and len(parts) == len(store)
    distinct = {s.agents for s in store}
    assert parts.table.shape == (len(distinct), 4)  # (three robots and the operator)
    block = [5, 17, len(store) - 1]
    assert [tuple(store.parts.values[p] for p in r) for r in parts[np.array(block)].tolist()] == [
        store[k].agents for k in block
    ]


@pytest.mark.parametrize("acknowledged", [False, True])
def test_the_docking_handshake(tmp_path, acknowledged):
    both(docking(tmp_path, acknowledged), losses=1)


@pytest.mark.parametrize(
    "text,opts",
    [
        *SMALL_CASES,
        (acked_go(1), {"losses": 1, "order": "fifo", "timeouts": "own"}),
        (ZENO, {"losses": 0}),  # a Zeno state: expanded by the engine in both
    ],
    ids=[*SMALL_IDS, "acked-go-fifo-own", "zeno"],
)
def test_the_small_models(tmp_path, text, opts):
    path = tmp_path / "team.yaml"
    path.write_text(text)
    both(load(path), **opts)


@pytest.mark.parametrize("path,opts", EXAMPLES)
def test_the_examples(path, opts):
    both(load(ROOT / "examples" / path), **opts)


def test_a_zeno_state_is_in_the_graph(tmp_path):
    path = tmp_path / "zeno.yaml"
    path.write_text(ZENO)
    report = verify(load(path), Options(losses=0, kernel="on"), replay=False)
    assert report.graph.zeno


def test_without_numba_auto_takes_the_python_loop_and_says_so(tmp_path, monkeypatch, capsys):
    """``HYBRIDTEAM_NUMBA=0`` is what a machine without numba looks like to verify: auto
    explores in Python (the same graph) and the first line says why; ``--kernel on`` is
    refused with the reason (exit 2)."""
    roles_team(tmp_path, "b")
    team = str(tmp_path / "team.yaml")
    args = ["verify", team, "--losses", "0", "--no-replay", "-o", str(tmp_path / "out")]
    assert main(args) == 0
    fast = capsys.readouterr().out.splitlines()[0]
    assert "compiled kernel" in fast
    monkeypatch.setenv("HYBRIDTEAM_NUMBA", "0")
    assert main(args) == 0
    slow = capsys.readouterr().out.splitlines()[0]
    assert "python loop: numba is not installed" in slow
    assert fast.split(" states")[0] == slow.split(" states")[0]  # the same count
    assert main([*args, "--kernel", "on"]) == 2
    assert "--kernel on: numba is not installed" in capsys.readouterr().err


def test_options_the_loop_does_not_serve_take_the_python_loop(tmp_path):
    team = roles_team(tmp_path, "b")
    # --jobs: the compiled loop's threads; the Python loop's process pool with --kernel off
    g = verify(team, Options(losses=0, jobs=2), replay=False).graph
    assert g.explorer == "compiled kernel, 2 threads"
    g = verify(team, Options(losses=0, jobs=2, kernel="off"), replay=False).graph
    assert g.explorer == "python loop: --kernel off"
    with pytest.raises(ValueError, match="--kernel on: --storage bitstate"):
        verify(team, Options(losses=0, storage="bitstate", kernel="on"), replay=False)
    # three interchangeable followers: symmetry in effect, explored by the Python loop
    # (with --kernel on too), the same counts as before (test_verify_symmetry.py)
    followers = ask_team(tmp_path)
    for which in ("auto", "on"):
        report = verify(followers, Options(losses=0, kernel=which), replay=False)
        assert report.symmetry is not None and report.symmetry.active
        assert report.graph.explorer == "python loop: symmetry or ample-set reduction is on"
        assert len(report.graph.states) == 21


def test_past_the_memory_limit_the_compiled_loop_stops_after_the_level(tmp_path, monkeypatch):
    """The compiled loop reads the resident size after each level (a level is applied
    whole): the first level's successors are cut, its state is expanded."""
    monkeypatch.setattr(sys.modules["hybridteam.verify.kernel"], "resident_bytes", lambda: 5e9)
    opts = Options(max_memory=4e9, kernel="on")
    g = verify(team_of(tmp_path, COUNTERS), opts, replay=False).graph
    assert g.bound == (
        "this process reached the memory limit of 4 GB after 3 states "
        "(5.000 GB resident; --max-memory GB raises it)"
    )
    assert len(g.states) == 3 and not g.exhaustive
    assert g.cut == {1, 2} and g.succ(0) == [1, 2]
    assert not g.terminal().any()


def test_rows_widened_and_made_32_bit_keep_every_state_and_its_number(tmp_path):
    """A group that outgrows its slots, or a number beyond 16 bits, re-lays the groups'
    sub-rows out: every state decodes as before, keeps its key and is found again at its
    own number."""
    from hybridteam.verify.kernel import Layout

    g = verify(roles_team(tmp_path, "b"), Options(losses=1, kernel="on"), replay=False).graph
    store = g.states
    before = list(store)
    keys = store.keys.copy()
    lay = store.lay
    assert store.dtype == np.uint16
    store.relayout(Layout(lay.agents, lay.copies + 3, lay.entries + 1, lay.seen + 2), np.uint32)
    assert store.dtype == np.uint32 and store.lay.width == lay.width + 6
    assert [t.dtype for t in store.groups] == [np.uint32] * 4
    assert [t.shape[1] for t in store.groups] == [4, lay.copies + 3, lay.entries + 1, lay.seen + 5]
    assert list(store) == before and np.array_equal(store.keys, keys)
    assert [store.add(store.row(k)) for k in range(len(store))] == list(range(len(store)))
    assert len(store) == len(before)


def test_a_group_past_its_key_bytes_takes_one_more_and_keeps_every_state(tmp_path):
    """A group's numbers take one byte in a key while it has at most 256 sub-rows (the
    copies here have more: the loop widened them); one more byte keeps every state at its
    number, its sub-rows found from the wider keys."""
    g = verify(roles_team(tmp_path, "b"), Options(losses=1, kernel="on"), replay=False).graph
    store = g.states
    assert store.counts.tolist()[1] > 256 and store.widths.tolist()[1] == 2
    assert store.counts.tolist()[0] <= 256 and store.widths.tolist()[0] == 1
    before = list(store)
    copies = store.numbers(1, slice(None))
    store.widen_key(1)
    assert store.widths.tolist()[1] == 3 and store.keys.shape[1] == int(store.widths.sum())
    assert np.array_equal(store.numbers(1, slice(None)), copies)
    assert list(store) == before
    assert [store.add(store.row(k)) for k in range(len(store))] == list(range(len(store)))


def test_an_interrupted_check_leaves_no_thread_behind(tmp_path, monkeypatch):
    """Ctrl-C while a thread computes the next chunk's successors: the check ends, and
    the threads with it (the pool waits for the chunk at work, then goes)."""
    taken: list[int] = []
    real = kernel._Explorer._commit_all

    def interrupted(self, parts):
        taken.append(len(parts))
        if self.pending is not None and len(taken) > 10:  # (a thread at the next chunk)
            raise KeyboardInterrupt
        return real(self, parts)

    monkeypatch.setattr(kernel._Explorer, "_commit_all", interrupted)
    monkeypatch.setattr(kernel, "CHUNK", 64)
    monkeypatch.setattr(kernel, "SHARED", 2)
    with pytest.raises(KeyboardInterrupt):
        verify(roles_team(tmp_path, "b"), Options(losses=1, jobs=2, kernel="on"), replay=False)
    assert len(taken) > 10
    assert not [t for t in threading.enumerate() if t.name.startswith("verify")]


def test_edges_and_parents_past_the_spill_size_are_read_from_a_file(tmp_path, monkeypatch):
    """Past :data:`~hybridteam.verify.kernel.SPILL` bytes the edges' destinations and
    the parents go to a temporary file and are read back mapped: the same graph,
    verdicts and counterexample (a request answered by taking the lead at once)."""
    team = roles_team(tmp_path, "b", mutate(REQUEST, REQUEST.replace("to: Requesting", "to: Lead")))
    here = verify(team, Options(kernel="on", losses=1), replay=False)
    monkeypatch.setattr(kernel, "SPILL", 64)
    spilled = verify(team, Options(kernel="on", losses=1), replay=False)
    g = spilled.graph
    assert isinstance(g.parent, np.memmap) and isinstance(g.edges.view()[1], np.memmap)
    assert len(g.states) > 64 // 4 and len(g.edges) > 64 // 4
    same_graph(g, here.graph)
    bad = [v for v in spilled.verdicts if not v.holds]
    assert [v.prop.name for v in bad] == ["one_leader"]
    assert spilled.counterexample(bad[0]) == here.counterexample(here.violated[0])
