"""The crossing search's bracket narrowing: a few brackets finished on Python floats give
the bits the array rounds give, and every bracket closes on the analytic root."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from hybridteam.engine.run.crossing.illinois import illinois, illinois_one


def _cubic(root: np.ndarray, slope: np.ndarray, curve: np.ndarray, flat: np.ndarray):
    """``ev`` of the atom ``m(t) > 0`` with ``m(t) = slope (t - root) + curve (t - root)^2
    + flat (t - root)^3``, per row: one root in the brackets drawn below (``slope`` > 0 and
    the other terms too small to add one), so its crossing is known."""

    def ev(pos: np.ndarray, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        d = tau - root[pos]
        margin = slope[pos] * d + curve[pos] * d * d + flat[pos] * d * d * d
        return margin > 0, margin

    return ev


problems = st.lists(
    st.tuples(
        st.floats(0.0, 10.0),
        st.floats(1e-6, 5.0),
        st.floats(0.0, 0.99),
        st.floats(-0.2, 0.2),
        st.floats(-0.1, 0.1),
        st.sampled_from([1e-12, 1e-9, 1e-6]),
    ),
    min_size=1,
    max_size=5,
)


def _coefficients(rows) -> tuple[np.ndarray, np.ndarray]:
    """The drawn cubics' quadratic and cubic coefficients, kept from adding roots within
    the brackets."""
    _, span, _, curve, flat, _ = (np.array(c, dtype=float) for c in zip(*rows, strict=True))
    return curve / np.maximum(span, 1.0), flat / np.maximum(span, 1.0) ** 2


def _problem(rows):
    """The drawn brackets as ``(ev, lo, hi, truth0, tol, root)``: a cubic's crossing in
    each, original truth false at ``lo``."""
    start, span, where, _, _, tol = (np.array(c, dtype=float) for c in zip(*rows, strict=True))
    lo, hi = start, start + span
    root = lo + where * span
    ev = _cubic(root, np.ones_like(lo), *_coefficients(rows))
    return ev, lo, hi, np.zeros(lo.size, bool), tol, root


def _alone(ev, i: int, lo, hi, truth0, tol, **options) -> tuple[float, float]:
    """Bracket ``i`` narrowed on its own (the evaluator still sees its row ``i``)."""
    with np.errstate(all="ignore"):  # as the run is: secants through equal margins are NaN
        a, b = illinois(
            lambda p, t: ev(np.full(p.size, i), t),
            lo[i : i + 1].copy(),
            hi[i : i + 1].copy(),
            truth0[i : i + 1],
            tol[i : i + 1],
            **options,
        )
    return a[0], b[0]


@settings(max_examples=200, deadline=None)
@given(problems)
def test_one_bracket_on_floats_equals_the_array_rounds_bit_for_bit(rows) -> None:
    ev, lo, hi, truth0, tol, _ = _problem(rows)
    for i in range(lo.size):
        fast = _alone(ev, i, lo, hi, truth0, tol)
        slow = _alone(ev, i, lo, hi, truth0, tol, scalar=False)
        assert np.array(fast).tobytes() == np.array(slow).tobytes()


@settings(max_examples=200, deadline=None)
@given(problems)
def test_one_bracket_evaluated_on_floats_gives_the_same_bits(rows) -> None:
    """``one``: the evaluator of a single run's bracket on Python floats, the same
    arithmetic as the array ``ev``; the bracket closes on the same bits, through
    ``illinois`` or on floats throughout (``illinois_one``)."""
    ev, lo, hi, truth0, tol, root = _problem(rows)
    slope, curve, flat = 1.0, *(c.tolist() for c in _coefficients(rows))
    for i in range(lo.size):

        def one(tau: float, i=i) -> tuple[bool, float]:
            d = tau - float(root[i])
            margin = slope * d + curve[i] * d * d + flat[i] * d * d * d
            return margin > 0, margin

        fast = _alone(ev, i, lo, hi, truth0, tol, one=one)
        slow = _alone(ev, i, lo, hi, truth0, tol, scalar=False)
        assert np.array(fast).tobytes() == np.array(slow).tobytes()
        alone = illinois_one(one, float(lo[i]), float(hi[i]), False, float(tol[i]))
        assert np.array(alone).tobytes() == np.array(slow).tobytes()


@settings(max_examples=200, deadline=None)
@given(problems)
def test_few_brackets_on_floats_equal_the_array_rounds_bit_for_bit(rows) -> None:
    """Several brackets finished together on floats (an ensemble's few crossings in one
    step): each closes in its own number of rounds, while the others go on."""
    ev, lo, hi, truth0, tol, _ = _problem(rows)
    with np.errstate(all="ignore"):
        fast = illinois(ev, lo.copy(), hi.copy(), truth0, tol)
        slow = illinois(ev, lo.copy(), hi.copy(), truth0, tol, scalar=False)
    assert np.array(fast).tobytes() == np.array(slow).tobytes()


@settings(max_examples=200, deadline=None)
@given(problems)
def test_brackets_close_on_the_root_and_equal_their_single_runs(rows) -> None:
    ev, lo, hi, truth0, tol, root = _problem(rows)
    with np.errstate(all="ignore"):
        a, b = illinois(ev, lo.copy(), hi.copy(), truth0, tol)
    assert np.all(b - a <= tol)
    # the ends keep their truths, so the root (up to the margin's rounding) lies between
    assert not ev(np.arange(lo.size), a)[0].any()
    assert ev(np.arange(lo.size), b)[0].all()
    fuzz = 8 * np.finfo(float).eps * (1 + np.abs(root))
    assert np.all((a <= root + fuzz) & (root - fuzz <= b))
    for i in range(lo.size):  # a row's result does not depend on the others
        assert _alone(ev, i, lo, hi, truth0, tol) == (a[i], b[i])
