"""The Zeno check's memory (``engine/run/zeno.py``): an agent's transition is Zeno when it
comes within the window of the one ``max_transitions`` before it, in its own instance."""

from __future__ import annotations

import numpy as np

from hybridteam.engine.run.zeno import ZenoWindow


def test_the_transition_max_transitions_back_decides_by_hand():
    """Two remembered, window 1e-6: at 0, 0.5, 0.5 + 1e-7 the third is 0.5000001 after
    the first (not Zeno); the fourth, at 0.5 + 2e-7, is 2e-7 after the second (Zeno). The
    other instance and the other agent remember their own."""
    z = ZenoWindow(n=2, agents=2, max_transitions=2, window=1e-6)
    one = np.array([0])
    assert z.fired(0, one, np.array([0.0])).size == 0
    assert z.fired(0, one, np.array([0.5])).size == 0
    assert z.fired(1, one, np.array([0.5])).size == 0  # (agent 1's own ring)
    assert z.fired(0, one, np.array([0.5 + 1e-7])).size == 0
    assert z.fired(0, one, np.array([0.5 + 2e-7])).tolist() == [0]
    both = np.array([0, 1])
    assert z.fired(0, both, np.array([0.5 + 3e-7, 0.5 + 3e-7])).tolist() == [0]  # (1: its first)


def test_clear_forgets_every_transition():
    z = ZenoWindow(n=1, agents=1, max_transitions=1, window=1.0)
    one = np.array([0])
    z.fired(0, one, np.array([0.0]))
    assert z.fired(0, one, np.array([0.5])).tolist() == [0]
    z.clear()
    assert z.fired(0, one, np.array([0.6])).size == 0  # nothing before it any more
    assert z.fired(0, one, np.array([0.7])).tolist() == [0]
