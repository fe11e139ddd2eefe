"""A response's backward peeling compiled (:mod:`hybridteam.verify.peel`) against the
scipy path of :mod:`hybridteam.verify.properties` (where numba is not installed): a graph
worked out by hand, and every response property of the role protocol's mutants and the
docking handshakes — the same states reach a dead end or a psi-free cycle, and the same
verdicts and lassos come out of :func:`~hybridteam.verify.verify`."""

from __future__ import annotations

import numpy as np
import pytest

from hybridteam.verify import Options, verify
from hybridteam.verify.kernel import numba_available
from hybridteam.verify.properties import _reaching, _reverse, truths
from tests.verify.test_verify import docking, roles_team
from tests.verify.test_verify_tables import ROLE_CASES, ROLE_IDS

pytestmark = pytest.mark.skipif(not numba_available(), reason="numba is not installed")


def test_a_graph_worked_out_by_hand():
    """0 -> 1, 1 -> 2, 2 -> 1 (a cycle), 3 -> 4 (4 a dead end), 5 -> 6, 6 -> 7 and
    6 -> 7 again (7 not free), 0 -> 3. Free: 1..6. 1 and 2 lie on a cycle, 3 reaches the
    dead 4; 6's only successor is not free and 5's only one is 6: both peeled."""
    from hybridteam.verify.peel import reaching, reverse

    edges = {0: [1, 3], 1: [2], 2: [1], 3: [4], 5: [6], 6: [7, 7]}
    row = np.zeros(9, np.int32)
    for k in range(8):
        row[k + 1] = row[k] + len(edges.get(k, []))
    dst = np.array([d for k in range(8) for d in edges.get(k, [])], np.uint32)
    free = np.array([k in range(1, 7) for k in range(8)])
    dead = np.array([k == 4 for k in range(8)])
    rev_ptr, rev_idx, out = reverse(row, dst, free)
    assert out.tolist() == [0, 1, 1, 1, 0, 1, 0, 0]  # (edges to free states from free ones)
    assert [rev_idx[rev_ptr[v] : rev_ptr[v + 1]].tolist() for v in range(8)] == [
        [],
        [2],
        [1],
        [],
        [3],
        [],
        [5],
        [],
    ]
    reach, _ = reaching(row, dst, free, dead)
    assert np.flatnonzero(reach).tolist() == [1, 2, 3, 4]


def _graphs(tmp_path):
    for (events, protocol, extra, without_c, opts), name in zip(ROLE_CASES, ROLE_IDS, strict=True):
        if extra == "no_operator":
            extra = "  no_operator: always(not in_mode(operator, Command))\n"
        kw = {} if protocol is None else {"protocol": protocol}
        yield name, roles_team(tmp_path, events, extra=extra, without_c=without_c, **kw), opts
    for acknowledged in (False, True):
        yield f"docking-{acknowledged}", docking(tmp_path, acknowledged), {"losses": 1}


def test_the_compiled_peeling_is_the_scipy_peeling_on_every_model(tmp_path, monkeypatch):
    from hybridteam.verify.peel import reaching

    responses = 0
    for name, team, opts in _graphs(tmp_path):
        report = verify(team, Options(symmetry="off", **opts), replay=False)
        g = report.graph
        row, dst = g.edges.csr()
        for v in report.verdicts:
            if v.prop.kind != "response":
                continue
            responses += 1
            waiting = ~truths(v.prop.psi, report.skeleton, g)
            dead = waiting & g.terminal()
            ours, _ = reaching(row, dst, waiting, dead)
            theirs = _reaching(*_reverse(g, waiting), waiting, dead)
            assert np.array_equal(ours, theirs), (name, v.prop.name)
        monkeypatch.setenv("HYBRIDTEAM_NUMBA", "0")  # the scipy path (and the Python loop)
        slow = verify(team, Options(symmetry="off", **opts), replay=False)
        monkeypatch.delenv("HYBRIDTEAM_NUMBA")
        assert [(v.prop.name, v.holds, v.state, v.lasso) for v in report.verdicts] == [
            (v.prop.name, v.holds, v.state, v.lasso) for v in slow.verdicts
        ], name
    assert responses >= 20
