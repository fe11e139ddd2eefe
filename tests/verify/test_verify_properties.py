"""The response check (:func:`hybridteam.verify.properties._response`) on hand-made state
graphs whose answer is worked out by hand: which phi states start a psi-free path into a
dead end or a cycle, and the lasso it reports. A property that holds is decided on the
psi-free subgraph's reverse alone (peeling off states that cannot reach a dead end or a
cycle), without strongly connected components, whose float64 copy of every edge was the
checks' peak of memory."""

from __future__ import annotations

import sys
from array import array

import numpy as np
import pytest

from hybridteam.verify.explore import NONE, Graph
from hybridteam.verify.properties import Property
from hybridteam.verify.store import Edges

#: the module (``hybridteam.verify.properties`` as an attribute is the function the package
#: exports under that name)
P = sys.modules[Property.__module__]
RESPONSE = Property("r", "response", "always(implies(phi, eventually(psi)))")


def graph(states: int, edges: list[tuple[int, int]], cut: set[int] | None = None) -> Graph:
    """A graph of ``states`` states (only their number is read) and these edges."""
    e = Edges()
    for a, b in edges:
        e.add(a, b, ("deliver", a, b))
    e.freeze(states)
    return Graph(list(range(states)), array("I", [NONE] * states), e, cut=cut or set())


def flags(states: int, *on: int) -> np.ndarray:
    out = np.zeros(states, bool)
    out[list(on)] = True
    return out


@pytest.fixture
def no_components(monkeypatch):
    """A check that calls scipy's strongly connected components fails."""

    def refuse(*args, **kw):
        raise AssertionError("strongly connected components computed")

    monkeypatch.setattr(P, "connected_components", refuse)


def test_a_response_that_holds_takes_no_strongly_connected_components(no_components):
    # 0 -> 1 -> 2 -> 3 (psi), 1 -> 4 -> 3, 0 -> 5 (psi): every path from 0 meets psi, and
    # 1, 2, 4 (psi-free, each with psi-free successors) are peeled off in turn
    g = graph(6, [(0, 1), (1, 2), (2, 3), (1, 4), (4, 3), (0, 5), (4, 3)])
    v = P._response(RESPONSE, g, flags(6, 0), flags(6, 3, 5))
    assert v.holds is True


def test_a_psi_free_dead_end_behind_a_chain_is_reached():
    # 0 -> 1 -> 2 -> 3 -> 4, 4 a dead end; 1 -> 5 (psi): from 0 the path 0 1 2 3 4 avoids
    # psi and ends
    g = graph(6, [(0, 1), (1, 5), (1, 2), (2, 3), (3, 4)])
    v = P._response(RESPONSE, g, flags(6, 0), flags(6, 5))
    assert v.holds is False
    assert (v.state, v.lasso, v.loops) == (0, [0, 1, 2, 3, 4], False)


def test_a_psi_free_cycle_is_reached_and_a_cut_state_is_not_a_dead_end():
    # 0 -> 1 -> 2 -> 3 -> 2 (a cycle free of psi), 0 -> 4 (cut: its successors unknown);
    # 5 -> 6 (psi) is elsewhere; phi at 0 and 5: 0 violates through the cycle
    g = graph(7, [(0, 4), (0, 1), (1, 2), (2, 3), (3, 2), (5, 6)], cut={4})
    v = P._response(RESPONSE, g, flags(7, 0, 5), flags(7, 6))
    assert v.holds is False
    # (the lasso: the shortest way to the nearest cycle state, then the cycle's next one)
    assert (v.state, v.lasso, v.loops) == (0, [0, 1, 2, 3], True)
    # with psi on the cycle, and 4 cut (not a dead end), nothing free of psi ends or loops
    assert P._response(RESPONSE, g, flags(7, 0, 5), flags(7, 3, 6)).holds is True


def test_states_that_lead_only_to_peeled_states_are_peeled_and_others_remain():
    # 0 -> 1 -> 2 (psi) and 0 -> 3 -> 4 -> 3 (a cycle); 5 -> 1 twice (a duplicate edge):
    # phi at 5 holds (1 leads to psi only), phi at 0 does not (the cycle)
    g = graph(6, [(0, 1), (1, 2), (0, 3), (3, 4), (4, 3), (5, 1), (5, 1)])
    assert P._response(RESPONSE, g, flags(6, 5), flags(6, 2)).holds is True
    v = P._response(RESPONSE, g, flags(6, 0, 5), flags(6, 2))
    assert (v.holds, v.state, v.lasso, v.loops) == (False, 0, [0, 3, 4], True)


@pytest.mark.parametrize("block", [1, 2, 3, 1 << 20])
def test_the_psi_free_subgraph_is_the_same_whatever_the_block(block):
    # free: 0, 1, 3, 4; edges among them, in each state's order: 0->1, 0->1, 1->3, 3->4,
    # 4->0 (2 and 5 are not free: their edges, and the edges into them, go)
    g = graph(6, [(0, 1), (0, 2), (0, 1), (1, 3), (2, 3), (3, 5), (3, 4), (4, 0), (5, 0)])
    indptr, indices = P._psi_free(g, ~flags(6, 2, 5), block)
    assert indptr.dtype == indices.dtype == np.int32
    assert indptr.tolist() == [0, 2, 3, 3, 4, 5, 5]
    assert indices.tolist() == [1, 1, 3, 4, 0]
