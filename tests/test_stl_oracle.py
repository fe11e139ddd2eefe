"""The temporal operators against hand-computed answers and against rtamt.

rtamt (an STL monitoring library, a test dependency) evaluates discrete-time formulas
offline; our operators must give the same robustness, to 1e-9, on random signals and
random formulas — windows cut at the end of the trace included, which rtamt does the same
way (an empty window is +inf for always, -inf for eventually and until).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hybridteam.requirements import robustness as R

rtamt = pytest.importorskip("rtamt")


def test_a_sine_against_a_threshold():
    t = np.linspace(0.0, 2 * math.pi, 9)  # contains pi/2 (index 2) and pi (index 4)
    rho = (0.5 - np.sin(t))[None, :]
    assert R.always(t, rho, 0, math.pi)[0, 0] == pytest.approx(-0.5, abs=1e-12)
    # from pi/2 the window [pi/2, 3pi/2] peaks at 0.5 - sin(3pi/2) = 1.5
    assert R.eventually(t, rho, 0, math.pi)[0, 2] == pytest.approx(1.5, abs=1e-12)
    # [a, b] with a > 0: from 0, the points pi .. 3pi/2 (indices 4..6)
    assert R.always(t, rho, math.pi, 1.5 * math.pi)[0, 0] == pytest.approx(0.5, abs=1e-12)


def test_windows_are_cut_at_the_end_and_empty_windows_are_identities():
    t = np.array([0.0, 1.0, 2.0, 3.0])
    rho = np.array([[3.0, -1.0, 2.0, 5.0]])
    assert R.always(t, rho, 0, 1).tolist() == [[-1.0, -1.0, 2.0, 5.0]]
    assert R.eventually(t, rho, 1, 2).tolist() == [[2.0, 5.0, 5.0, -math.inf]]
    assert R.always(t, rho, 2, math.inf).tolist() == [[2.0, 5.0, math.inf, math.inf]]


def test_until_by_hand():
    # phi must hold from i up to (not at) the point where psi is taken
    t = np.array([0.0, 1.0, 2.0, 3.0])
    phi = np.array([[1.0, 2.0, -3.0, 4.0]])
    psi = np.array([[-5.0, -1.0, 6.0, 0.5]])
    # at 0, window [1, 3]: j=1: min(-1, 1) = -1; j=2: min(6, 1, 2) = 1; j=3: min(.5, -3) = -3
    assert R.until(t, phi, psi, 1, 3)[0, 0] == 1.0
    # at 0, window [0, inf): j=0 gives psi_0 = -5, the best is again j=2: 1
    assert R.until(t, phi, psi, 0, math.inf)[0, 0] == 1.0
    # at 2: j=2 is psi_2 = 6 with nothing before it
    assert R.until(t, phi, psi, 0, 1)[0, 2] == 6.0


def test_padding_and_rows_with_their_own_grids():
    t = np.array([[0.0, 0.5, 1.0, 4.0], [0.0, 2.0, np.inf, np.inf]])
    rho = np.array([[1.0, -2.0, 3.0, 0.0], [4.0, -1.0, 7.0, 7.0]])
    got = R.always(t, rho, 0, 1)
    assert got[0].tolist() == [-2.0, -2.0, 3.0, 0.0]
    assert got[1, :2].tolist() == [4.0, -1.0] and np.isnan(got[1, 2:]).all()


def test_bad_windows_are_refused():
    t, rho = np.arange(3.0), np.zeros((1, 3))
    for a, b in ((3, 1), (-1, 2), (math.nan, 1), (math.inf, math.inf)):
        with pytest.raises(ValueError, match="bad window"):
            R.always(t, rho, a, b)
    with pytest.raises(ValueError, match="shape"):
        R.always(np.arange(4.0), rho, 0, 1)


# ---------------------------------------------------------------- random formulas vs rtamt
def _formulas(period: float):
    bound = st.integers(0, 4).map(lambda k: k * period)
    atoms = st.one_of(
        st.tuples(st.just("ge"), st.sampled_from(["x", "y"]), st.floats(-1, 1).map(
            lambda c: round(c, 2))),
        st.tuples(st.just("le"), st.sampled_from(["x", "y"]), st.floats(-1, 1).map(
            lambda c: round(c, 2))))

    def window(a: float, w: float) -> tuple[float, float]:
        return a, a + w

    def extend(inner):
        return st.one_of(
            st.tuples(st.just("not"), inner),
            st.tuples(st.sampled_from(["and", "or"]), inner, inner),
            st.tuples(st.sampled_from(["always", "eventually"]),
                      st.builds(window, bound, bound), inner),
            st.tuples(st.just("until"), st.builds(window, bound, bound), inner, inner))

    return st.recursive(atoms, extend, max_leaves=4)


def _text(f) -> str:
    op = f[0]
    if op in ("ge", "le"):
        return f"({f[1]} {'>=' if op == 'ge' else '<='} {f[2]})"
    if op == "not":
        return f"(not {_text(f[1])})"
    if op in ("and", "or"):
        return f"({_text(f[1])} {op} {_text(f[2])})"
    a, b = f[1]
    if op == "until":
        return f"({_text(f[2])} until[{a:g},{b:g}] {_text(f[3])})"
    return f"({op}[{a:g},{b:g}] {_text(f[2])})"


def _ours(f, t, sig):
    op = f[0]
    if op == "ge":
        return sig[f[1]] - f[2]
    if op == "le":
        return f[2] - sig[f[1]]
    if op == "not":
        return -_ours(f[1], t, sig)
    if op in ("and", "or"):
        reduce = np.minimum if op == "and" else np.maximum
        return reduce(_ours(f[1], t, sig), _ours(f[2], t, sig))
    a, b = f[1]
    if op == "until":
        return R.until(t, _ours(f[2], t, sig), _ours(f[3], t, sig), a, b)
    return getattr(R, op)(t, _ours(f[2], t, sig), a, b)


@settings(max_examples=150, deadline=None)
@given(data=st.data())
def test_random_formulas_agree_with_rtamt(data):
    period = data.draw(st.sampled_from([1.0, 0.5]))
    k = data.draw(st.integers(5, 40))
    values = st.lists(st.floats(-2, 2).map(lambda v: round(v, 3)), min_size=k, max_size=k)
    x, y = np.array(data.draw(values)), np.array(data.draw(values))
    formula = data.draw(_formulas(period))
    t = np.arange(k) * period
    ours = _ours(formula, t, {"x": x[None, :], "y": y[None, :]})[0]

    spec = rtamt.StlDiscreteTimeSpecification()
    spec.declare_var("x", "float")
    spec.declare_var("y", "float")
    spec.set_sampling_period(period, "s", 0.1)
    spec.spec = _text(formula)
    spec.parse()
    theirs = spec.evaluate({"time": t.tolist(), "x": x.tolist(), "y": y.tolist()})
    got = np.array([r for _, r in theirs], float)
    assert got.shape == ours.shape
    same = np.isclose(ours, got, atol=1e-9, rtol=0) | (ours == got)  # equal infinities
    assert same.all(), (_text(formula), ours, got)
