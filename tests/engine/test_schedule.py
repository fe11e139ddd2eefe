"""The earliest instants on Python floats give numpy's reductions bit for bit."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from hybridteam.engine.run.schedule import FEW, earliest

#: times as the engine schedules them, and the values where numpy's rules show: ties of
#: zeros of both signs, infinities, NaN
TIMES = st.one_of(
    st.sampled_from([0.0, -0.0, np.inf, np.nan, 0.1, 0.30000000000000004]),
    st.floats(-1e3, 1e3, allow_nan=False),
    st.floats(allow_nan=True),
)


def by_numpy(instants: np.ndarray, n_at: int) -> tuple[np.ndarray, ...]:
    return (
        np.minimum.reduce(instants, axis=0),
        np.fmin.reduce(instants[:n_at], axis=0),
        np.fmin.reduce(instants[n_at:], axis=0),
    )


@settings(max_examples=300, deadline=None)
@given(data=st.data(), rows=st.integers(2, 9), n=st.integers(1, FEW))
def test_few_instances_on_floats_equal_the_reductions(data, rows: int, n: int) -> None:
    n_at = data.draw(st.integers(1, rows - 1))
    values = data.draw(st.lists(TIMES, min_size=rows * n, max_size=rows * n))
    instants = np.array(values, float).reshape(rows, n)
    got, want = earliest(instants, n_at), by_numpy(instants, n_at)
    for g, w in zip(got, want, strict=True):
        assert g.dtype == w.dtype and g.shape == w.shape
        # the same values: NaN where numpy gives NaN (no time reaches it), else equal
        # (a tie of 0.0 and -0.0 may keep either sign, as numpy's reductions themselves
        # do depending on the length; see the module)
        nan = np.isnan(w)
        assert (np.isnan(g) == nan).all()
        assert (g[~nan] == w[~nan]).all()
        same_sign = w[~nan] != 0
        assert g[~nan][same_sign].tobytes() == w[~nan][same_sign].tobytes()


def test_a_signed_zero_tie_never_reaches_the_clock() -> None:
    """Either zero as the earliest instant gives the clock's own zero as the step's end,
    as the simulator takes it: ``np.maximum(first, t)``."""
    t = np.zeros(2)
    for instants in (
        np.array([[0.0, -0.0], [-0.0, 0.0], [1.0, 1.0]]),
        np.array([[-0.0, -0.0], [-0.0, -0.0], [1.0, 1.0]]),
    ):
        first = earliest(instants, 2)[0]
        t1 = np.maximum(first, t)
        assert t1.tobytes() == t.tobytes()
        assert (t1 >= earliest(instants, 2)[1]).all()


def test_many_instances_take_the_array_reductions() -> None:
    instants = np.random.default_rng(1).uniform(0, 10, (5, FEW + 3))
    instants[2, 4] = np.nan
    got, want = earliest(instants, 3), by_numpy(instants, 3)
    for g, w in zip(got, want, strict=True):
        np.testing.assert_array_equal(g, w)
    assert np.isnan(got[0][4]) and not np.isnan(got[1][4])
