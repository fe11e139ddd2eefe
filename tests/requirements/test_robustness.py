"""STL temporal operators (:mod:`hybridteam.requirements.robustness`) against answers known
independently of the implementation: cases worked out by hand, a brute-force evaluation of
the definitions on irregular padded grids, and rtamt (an STL library, test dependency) on
random formulas over random signals.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hybridteam.requirements import robustness as R

INF = math.inf
Q = math.pi / 4  # sine grid step: multiples of pi/4 hit pi/2, pi, 3pi/2 on the grid


def row(x) -> np.ndarray:
    return np.asarray([x], dtype=float)


# ------------------------------------------------------------------------ by hand
def test_a_sine_against_a_threshold():
    t = np.arange(17) * Q  # 0 .. 4 pi
    rho = row(0.5 - np.sin(t))  # "sin(t) <= 0.5": 0.5 at 0, -0.5 at pi/2, 1.5 at 3pi/2
    # [0, pi] from 0 holds t = 0, pi/4, pi/2, 3pi/4, pi: worst at pi/2, 0.5 - 1
    assert R.always(t, rho, 0, math.pi)[0, 0] == pytest.approx(-0.5, abs=1e-9)
    # from pi the window [pi, 2pi] is where sin <= 0: worst at pi and 2pi, 0.5 - 0
    assert R.always(t, rho, 0, math.pi)[0, 4] == pytest.approx(0.5, abs=1e-9)
    # best in [0, pi] is t = 0 (0.5); from pi/2 the window reaches 3pi/2 (1.5)
    assert R.eventually(t, rho, 0, math.pi)[0, 0] == pytest.approx(0.5, abs=1e-9)
    assert R.eventually(t, rho, 0, math.pi)[0, 2] == pytest.approx(1.5, abs=1e-9)
    # a > 0: from 0, [pi, 3pi/2] holds pi, 5pi/4, 3pi/2: worst 0.5 - sin(pi) = 0.5
    assert R.always(t, rho, math.pi, 1.5 * math.pi)[0, 0] == pytest.approx(0.5, abs=1e-9)
    # unbounded: the whole rest of the trace, min -0.5 / max 1.5 from anywhere before 7pi/2
    assert R.always(t, rho, 0, INF)[0, 0] == pytest.approx(-0.5, abs=1e-9)
    assert R.eventually(t, rho, 0, INF)[0, 9] == pytest.approx(1.5, abs=1e-9)
    # from 15pi/4 only 15pi/4 (0.5 + sqrt(2)/2) and 4pi (0.5) remain
    assert R.always(t, rho, 0, INF)[0, 15] == pytest.approx(0.5, abs=1e-9)
    assert R.eventually(t, rho, 0, INF)[0, 15] == pytest.approx(0.5 + 0.5**0.5, abs=1e-9)
    # a window between two samples holds no grid point: empty everywhere
    assert (R.eventually(t, rho, 0.1, 0.2) == -INF).all()
    assert (R.always(t, rho, 0.1, 0.2) == INF).all()


def test_windows_with_a_positive_start_cut_at_the_end():
    t = np.arange(6.0)
    rho = row([3, -1, 2, 5, 0, 4])
    # [1, 2] from i: points i+1, i+2 that exist; from 4 only 5; from 5 nothing (identity)
    assert R.always(t, rho, 1, 2).tolist() == [[-1, 2, 0, 0, 4, INF]]
    assert R.eventually(t, rho, 1, 2).tolist() == [[2, 5, 5, 4, 4, -INF]]
    # [2, inf): everything from i + 2 on
    assert R.always(t, rho, 2, INF).tolist() == [[0, 0, 0, 4, INF, INF]]
    assert R.eventually(t, rho, 2, INF).tolist() == [[5, 5, 4, 4, -INF, -INF]]
    # [0, 0] is the point itself; [0.5, 0.9] holds no grid point
    assert R.eventually(t, rho, 0, 0).tolist() == rho.tolist()
    assert R.always(t, rho, 0.5, 0.9).tolist() == [[INF] * 6]


def test_until_by_hand():
    t = np.arange(5.0)
    phi = row([3, 2, 4, 1, 5])
    psi = row([-1, -2, 0, 6, -4])
    # U_i = max over j in the window of min(psi_j, phi_i .. phi_{j-1}); phi_j itself does
    # not count. [0, inf):
    #   i=0: j=0 -1 | j=1 min(-2, 3) | j=2 min(0, 3, 2) = 0 | j=3 min(6, 3, 2, 4) = 2 | j=4 -4
    #   i=1: -2 | min(0, 2) = 0 | min(6, 2, 4) = 2 | -4          -> 2
    #   i=2: 0 | min(6, 4) = 4 | min(-4, ..) = -4                -> 4
    #   i=3: 6 (phi_3 = 1 is not needed at j = 3) | -4           -> 6
    #   i=4: -4
    assert R.until(t, phi, psi, 0, INF).tolist() == [[2, 2, 4, 6, -4]]
    # [0, 1]: j in {i, i+1}; from 4 only j = 4 (cut at the end)
    assert R.until(t, phi, psi, 0, 1).tolist() == [[-1, 0, 4, 6, -4]]
    # [2, 3]: i=0: j=2 0, j=3 2 -> 2 | i=1: j=3 min(6, 2, 4) = 2, j=4 -4 -> 2
    #         i=2: j=4 min(-4, 4, 1) = -4 | i=3, 4: no j -> -inf
    assert R.until(t, phi, psi, 2, 3).tolist() == [[2, 2, -4, -INF, -INF]]
    # phi before the window still counts: phi_0 = 1 caps i=0 at 1 (j=3: min(6, 1, 2, 4))
    low = row([1, 2, 4, 1, 5])
    assert R.until(t, low, psi, 2, 3)[0, 0] == 1
    # infinities pass through min/max untouched: psi only at t = 2 (7), phi always true
    assert R.until(t, row([INF] * 5), row([-INF, -INF, 7, -INF, -INF]), 0, 2).tolist() == [
        [7, 7, 7, -INF, -INF]
    ]


def test_a_sine_on_nine_points_to_1e_12():
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


def test_until_by_hand_with_phi_failing_inside_the_window():
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


def test_padded_rows_match_their_unpadded_grids():
    t = np.array([[0.0, 1.0, 2.0, 3.0, 4.0], [0.0, 0.5, 2.0, INF, INF]])
    rho = np.array([[1.0, -2.0, 3.0, 0.5, 2.0], [4.0, -1.0, 7.0, np.nan, -1e300]])
    psi = np.array([[0.0, 1.0, -3.0, 2.0, 1.0], [-2.0, 3.0, 1.0, np.nan, 1e300]])
    for a, b in ((0, 1), (0.5, 2), (1, INF), (0, 0)):
        both = (R.always(t, rho, a, b), R.eventually(t, rho, a, b), R.until(t, rho, psi, a, b))
        for r, size in ((0, 5), (1, 3)):
            g, p, q = t[r, :size], rho[r : r + 1, :size], psi[r : r + 1, :size]
            alone = (R.always(g, p, a, b), R.eventually(g, p, a, b), R.until(g, p, q, a, b))
            for got, want in zip(both, alone, strict=True):
                assert got[r, :size].tolist() == want[0].tolist()
                assert np.isnan(got[r, size:]).all()
    # by hand for row 1, always[0, 1]: {0, 0.5} -> -1, {0.5} -> -1, {2} -> 7
    assert R.always(t, rho, 0, 1)[1, :3].tolist() == [-1, -1, 7]


def test_each_row_has_its_own_grid():
    t = np.array([[0.0, 1.0, 2.0, 3.0], [0.0, 0.5, 1.0, 1.5]])
    rho = np.array([[4.0, 3.0, 2.0, 1.0]] * 2)
    # [0, 1] holds two samples on the first grid, three on the second
    assert R.always(t, rho, 0, 1).tolist() == [[3, 2, 1, 1], [2, 1, 1, 1]]
    assert R.eventually(t, -rho, 1, 1).tolist() == [[-3, -2, -1, -INF], [-2, -1, -INF, -INF]]
    # a shared (K,) grid, padded or not, is the same as that grid on every row
    for grid in (t[1], np.array([0.0, 0.5, 1.0, INF])):
        for op in (R.always, R.eventually):
            assert np.array_equal(
                op(grid, rho, 0.5, 1), op(np.tile(grid, (2, 1)), rho, 0.5, 1), equal_nan=True
            )
        assert np.array_equal(
            R.until(grid, rho, 2.5 - rho, 0.5, 1),
            R.until(np.tile(grid, (2, 1)), rho, 2.5 - rho, 0.5, 1),
            equal_nan=True,
        )


def test_empty_ensembles_and_grids_keep_their_shape():
    for n, k in ((0, 4), (3, 0)):
        t, rho = np.arange(float(k)), np.zeros((n, k))
        assert R.always(t, rho, 0, 1).shape == (n, k)
        assert R.until(np.tile(t, (n, 1)), rho, rho, 1, INF).shape == (n, k)


# ------------------------------------------------------------ brute force, many rows
def _brute(t: np.ndarray, phi: np.ndarray, psi: np.ndarray, a: float, b: float) -> dict:
    """The definitions, point by point (row grids padded with inf)."""
    n, k = phi.shape
    out = {op: np.full((n, k), np.nan) for op in ("always", "eventually", "until")}
    for r in range(n):
        g = t[r][np.isfinite(t[r])]
        for i in range(len(g)):
            win = [j for j in range(len(g)) if g[i] + a <= g[j] <= g[i] + b]
            out["always"][r, i] = min((phi[r, j] for j in win), default=INF)
            out["eventually"][r, i] = max((phi[r, j] for j in win), default=-INF)
            out["until"][r, i] = max((min([psi[r, j], *phi[r, i:j]]) for j in win), default=-INF)
    return out


def test_irregular_padded_grids_against_the_definitions():
    small = 4000  # several row chunks per call
    rng = np.random.default_rng(7)
    for case in range(24):
        n, k = 5, int(rng.integers(1, 70))
        t = np.cumsum(rng.choice([0.25, 0.5, 1.0, 3.0], (n, k)), axis=1)
        for r in range(n):
            t[r, int(rng.integers(1, k + 1)) :] = INF
        values = [-2.0, -1.0, 0.0, 1.5, INF, -INF] if case % 2 else [INF, -INF]  # Boolean
        phi, psi = (rng.choice(values, (n, k)) for _ in "ab")
        a = float(rng.choice([0.0, 0.25, 1.0, 2.0]))
        b = a + float(rng.choice([0.0, 0.5, 1.0, 4.0, 20.0, INF]))
        want = _brute(t, phi, psi, a, b)
        got = {
            "always": R.always(t, phi, a, b, chunk_bytes=small),
            "eventually": R.eventually(t, phi, a, b, chunk_bytes=small),
            "until": R.until(t, phi, psi, a, b, chunk_bytes=small),
        }
        for op, values in got.items():
            assert np.array_equal(values, want[op], equal_nan=True), op


# ------------------------------------------------------------------ rtamt as oracle
def _formulas(period: float, depth: int) -> st.SearchStrategy:
    """Formula trees as tuples; a window is (a, b) in multiples of the period, or None
    for the unbounded operator (rtamt's ``always(phi)``, ``phi until psi``)."""
    const = st.integers(-100, 100).map(lambda c: c / 100)
    atoms = st.tuples(st.sampled_from(["ge", "le"]), st.sampled_from(["x", "y"]), const)
    if depth == 0:
        return atoms
    sub = _formulas(period, depth - 1)
    # b up to 12 periods: windows reach past the end of short traces (K >= 5)
    window = st.one_of(
        st.none(),
        st.tuples(st.integers(0, 6), st.integers(0, 6)).map(
            lambda aw: (aw[0] * period, (aw[0] + aw[1]) * period)
        ),
    )
    return st.one_of(
        atoms,
        st.tuples(st.just("not"), sub),
        st.tuples(st.sampled_from(["and", "or"]), sub, sub),
        st.tuples(st.sampled_from(["always", "eventually"]), window, sub),
        st.tuples(st.just("until"), window, sub, sub),
    )


def _text(f: tuple) -> str:
    op = f[0]
    if op in ("ge", "le"):
        return f"({f[1]} {'>=' if op == 'ge' else '<='} {f[2]})"
    if op == "not":
        return f"(not {_text(f[1])})"
    if op in ("and", "or"):
        return f"({_text(f[1])} {op} {_text(f[2])})"
    bounds = "" if f[1] is None else f"[{f[1][0]:g},{f[1][1]:g}]"
    if op == "until":
        return f"({_text(f[2])} until{bounds} {_text(f[3])})"
    return f"({op}{bounds}{_text(f[2])})"


def _ours(f: tuple, t: np.ndarray, sig: dict) -> np.ndarray:
    op = f[0]
    if op == "ge":
        return sig[f[1]] - f[2]
    if op == "le":
        return f[2] - sig[f[1]]
    if op == "not":
        return -_ours(f[1], t, sig)
    if op in ("and", "or"):
        pick = np.minimum if op == "and" else np.maximum
        return pick(_ours(f[1], t, sig), _ours(f[2], t, sig))
    a, b = f[1] or (0.0, INF)
    if op == "until":
        return R.until(t, _ours(f[2], t, sig), _ours(f[3], t, sig), a, b)
    return getattr(R, op)(t, _ours(f[2], t, sig), a, b)


@settings(max_examples=150, deadline=None)
@given(data=st.data())
def test_random_formulas_agree_with_rtamt(data):
    rtamt = pytest.importorskip("rtamt")
    period = data.draw(st.sampled_from([1.0, 0.5]))
    k = data.draw(st.integers(5, 40))
    value = st.one_of(
        st.integers(-200, 200).map(lambda v: v / 100), st.floats(-2, 2).map(lambda v: round(v, 3))
    )
    values = st.lists(value, min_size=k, max_size=k)
    x, y = np.array(data.draw(values)), np.array(data.draw(values))
    formula = data.draw(_formulas(period, 3))
    t = np.arange(k) * period
    ours = _ours(formula, t, {"x": x[None, :], "y": y[None, :]})[0]

    # rtamt's pattern: declare, sampling period (unit, tolerance), spec text, parse, then
    # evaluate a dict of lists with "time"; it returns [[time, robustness], ...]. It works
    # on sample indices (a bound must be a multiple of the period), so t = k * period.
    spec = rtamt.StlDiscreteTimeSpecification()
    spec.declare_var("x", "float")
    spec.declare_var("y", "float")
    spec.set_sampling_period(period, "s", 0.1)
    spec.spec = _text(formula)
    spec.parse()
    theirs = spec.evaluate({"time": t.tolist(), "x": x.tolist(), "y": y.tolist()})
    got = np.array([r for _, r in theirs], dtype=float)
    # Compared at every point, the end of the trace included: rtamt's offline visitor pads
    # past the end with the identities (+inf for always and phi of until, -inf for
    # eventually and psi of until; its untimed operators start from those), which is our
    # cut window with an empty window's identity, so the two agree there by construction.
    assert got.shape == ours.shape
    same = np.isclose(ours, got, rtol=0, atol=1e-9) | (ours == got)  # equal infinities
    assert same.all(), (_text(formula), ours.tolist(), got.tolist())


# --------------------------------------------------------------------- bad arguments
@pytest.mark.parametrize(
    "a, b", [(3, 1), (-1, 2), (math.nan, 1), (0, math.nan), (INF, INF), ("x", 1)]
)
def test_bad_windows_are_refused(a, b):
    t, rho = np.arange(3.0), np.zeros((1, 3))
    for call in (
        lambda: R.always(t, rho, a, b),
        lambda: R.eventually(t, rho, a, b),
        lambda: R.until(t, rho, rho, a, b),
    ):
        with pytest.raises(ValueError, match="bad window"):
            call()


def test_bad_shapes_and_grids_are_refused():
    rho = np.zeros((2, 3))
    with pytest.raises(ValueError, match=r"times of shape \(4,\)"):
        R.always(np.arange(4.0), rho, 0, 1)
    with pytest.raises(ValueError, match=r"times of shape \(3, 3\)"):
        R.always(np.zeros((3, 3)), rho, 0, 1)
    with pytest.raises(ValueError, match=r"\(n, K\)"):
        R.eventually(np.arange(3.0), np.zeros(3), 0, 1)
    with pytest.raises(ValueError, match="differ"):
        R.until(np.arange(3.0), rho, np.zeros((1, 3)), 0, 1)
    for grid, why in (
        ([0.0, np.nan, 2.0], "NaN"),
        ([0.0, -INF, 2.0], "NaN"),
        ([0.0, 2.0, 1.0], "increase"),
        ([0.0, 1.0, 1.0], "increase"),
        ([0.0, INF, 2.0], "increase"),
    ):
        with pytest.raises(ValueError, match=why):
            R.always(np.array(grid), rho, 0, 1)
