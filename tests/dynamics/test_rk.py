"""The Dormand–Prince step: its running stage sums against the textbook stage-by-stage sums
(bit for bit), its accuracy against closed forms, and what the integrator's derivative
hands a flow (``t_in_mode`` where a flow reads it)."""

from __future__ import annotations

import math

import numpy as np

import hybridteam as ht
from hybridteam.dynamics import rk
from hybridteam.floatpaths import FLOAT_PATHS


def _f(t: np.ndarray, x: np.ndarray) -> np.ndarray:
    """A nonlinear, time-dependent field with coupled components (d = 2)."""
    return np.stack(
        [np.sin(3 * x[:, 1]) + t * x[:, 0] ** 2, -np.cos(x[:, 0]) - 0.5 * x[:, 1]], axis=1
    )


def _seq(coefs: np.ndarray, k: np.ndarray) -> np.ndarray:
    """sum_j coefs[j] k[j] from j = 0 upwards, one addition at a time (up to the last
    nonzero coefficient, as the method's tables are written)."""
    last = int(np.flatnonzero(coefs)[-1])
    acc = coefs[0] * k[0]
    for j in range(1, last + 1):
        acc = acc + coefs[j] * k[j]
    return acc


def _textbook_step(f, t, x, h, rtol, atol):
    """DOP853 written stage by stage from the tables, each sum afresh."""
    m, d = x.shape
    k = np.empty((rk.N_STAGES + 1, m, d))
    k[0] = f(t, x)
    for s in range(1, rk.N_STAGES):
        k[s] = f(t + rk.C[s] * h, x + h[:, None] * _seq(rk.A[s, :s], k))
    x1 = x + h[:, None] * _seq(rk.B, k)
    k[rk.N_STAGES] = f(t + h, x1)
    scale = atol + rtol * np.maximum(np.abs(x), np.abs(x1))
    e5 = np.sum((_seq(rk.E5, k) / scale) ** 2, axis=1)
    e3 = np.sum((_seq(rk.E3, k) / scale) ** 2, axis=1)
    denom = e5 + 0.01 * e3
    return x1, k, np.abs(h) * e5 / np.sqrt(denom * d)


def _textbook_dense_coefficients(f, t, x, h, x1, k):
    """The continuous extension's coefficients, each extra stage and row summed afresh."""
    m, d = x.shape
    kk = np.concatenate([k, np.empty((len(rk.C_EXTRA), m, d))])
    for s, (a, c) in enumerate(zip(rk.A_EXTRA, rk.C_EXTRA, strict=True)):
        j = rk.N_STAGES + 1 + s
        kk[j] = f(t + c * h, x + h[:, None] * _seq(a[:j], kk))
    dy = x1 - x
    rows = [dy, h[:, None] * kk[0] - dy, 2 * dy - h[:, None] * (kk[rk.N_STAGES] + kk[0])]
    return np.stack(rows + [h[:, None] * _seq(r, kk) for r in rk.D])


def test_running_sums_give_the_textbook_step_bit_for_bit():
    rng = np.random.default_rng(5)
    m = 9
    t = rng.uniform(0, 3, m)
    x = rng.normal(size=(m, 2))
    h = rng.uniform(1e-3, 0.4, m)
    got = rk.step(_f, t, x, h, 1e-10, 1e-12)
    x1, k, err = _textbook_step(_f, t, x, h, 1e-10, 1e-12)
    assert np.array_equal(got.x1, x1)
    assert np.array_equal(got.k, k)
    assert np.array_equal(got.err, err)
    coefficients = _textbook_dense_coefficients(_f, t, x, h, x1, k)
    assert np.array_equal(got._coefficients(), coefficients)
    # each instance is its own: the same row stepped alone gives the same bits
    for i in (0, 4, 8):
        alone = rk.step(_f, t[i : i + 1], x[i : i + 1], h[i : i + 1], 1e-10, 1e-12)
        assert np.array_equal(alone.x1[0], x1[i]) and alone.err[0] == err[i]


def test_a_step_without_its_error_estimate_lands_on_the_same_state():
    rng = np.random.default_rng(6)
    t, x, h = rng.uniform(0, 1, 4), rng.normal(size=(4, 2)), rng.uniform(0.01, 0.3, 4)
    full = rk.step(_f, t, x, h, 1e-10, 1e-12)
    bare = rk.step(_f, t, x, h, 1e-10, 1e-12, estimate=False)
    assert bare.err is None
    assert np.array_equal(bare.x1, full.x1)
    assert np.array_equal(bare.k[: rk.N_STAGES], full.k[: rk.N_STAGES])
    theta = np.linspace(0.1, 0.9, 4)
    assert np.array_equal(bare.dense(theta), full.dense(theta))
    # the derivative at the new state is computed when the dense output first needs it
    assert np.array_equal(bare.k, full.k)


def test_a_few_dense_values_on_floats_equal_the_array_loop_bit_for_bit():
    """A single run's search reads one or two states off the dense output, computed on
    Python floats; they must be the array loop's bits (ends of the step included). With
    the float paths off every query goes through the array loop."""
    rng = np.random.default_rng(8)
    m = 3
    s = rk.step(
        _f, rng.uniform(0, 1, m), rng.normal(size=(m, 2)), rng.uniform(0.01, 0.3, m), 1e-10, 1e-12
    )
    queries = []
    for _ in range(300):
        every_row = rng.uniform() < 0.2  # rows None: one theta per instance
        k = m if every_row else int(rng.integers(1, 5))
        theta = rng.uniform(0, 1, k)
        theta[rng.uniform(size=k) < 0.2] = 0.0
        theta[rng.uniform(size=k) < 0.2] = 1.0
        queries.append((theta, None if every_row else rng.integers(0, m, k)))
    assert all(theta.size * 2 <= rk.SMALL_DENSE for theta, _ in queries)  # (floats while on)
    small = [s.dense(theta, rows) for theta, rows in queries]
    with FLOAT_PATHS.off():
        big = [s.dense(theta, rows) for theta, rows in queries]
    for a, b in zip(small, big, strict=True):
        assert a.shape == b.shape and a.tobytes() == b.tobytes()


def test_steps_of_linear_decay_converge_at_the_method_s_order():
    """x' = -2x from 1: the step's local error is O(h^9) and the dense output's O(h^8), so
    halving h divides them by about 512 and 256 (at least 2^8.5 and 2^7.5 here); at
    h = 0.05 the step is exact to round-off."""

    def errors(h: float) -> tuple[float, float]:
        s = rk.step(
            lambda t, x: -2.0 * x, np.zeros(1), np.ones((1, 1)), np.full(1, h), 1e-10, 1e-12
        )
        return (
            abs(s.x1[0, 0] - math.exp(-2 * h)),
            abs(s.dense(np.full(1, 0.5))[0, 0] - math.exp(-h)),
        )

    (s4, d4), (s2, d2), (s1, d1) = errors(0.4), errors(0.2), errors(0.1)
    assert s4 / s2 > 2**8.5 and s2 / s1 > 2**8.5
    assert d4 / d2 > 2**7.5 and d2 / d1 > 2**7.5
    assert errors(0.05)[0] < 1e-15


def test_a_flow_reading_time_in_mode_gets_it_and_one_that_does_not_is_unchanged(team_from_yaml):
    """B is entered at t = 1 with x = 1 and flows x' = t_in_mode, so x(3) = 1 + 2^2/2 = 3
    (reading t instead would give 1 + (9 - 1)/2 = 5); y' = 1 in both modes, so y(3) = 3."""
    team = team_from_yaml("""
        team: clock
        agents:
          c:
            plant: {kind: flow, state: {x: 0.0, y: 0.0}}
            initial: A
            modes:
              A:
                flow: {x: 1, y: 1}
                transitions: [{to: B, guard: t >= 1}]
              B:
                flow: {x: t_in_mode, y: 1}
        simulation: {duration: 3.0, sample_period: 0.5}
    """)
    run = ht.simulate(team)
    t, xy = run.sample_times, run.samples["c"][:, 0]  # (time, state) of the one run
    assert np.array_equal(t, [0, 0.5, 1, 1.5, 2, 2.5, 3])
    # in A: x = y = t; in B: x = 1 + (t - 1)^2 / 2, y = t
    expected = np.where(t <= 1, t, 1 + (t - 1) ** 2 / 2)
    np.testing.assert_allclose(xy[:, 0], expected, rtol=1e-9)
    np.testing.assert_allclose(xy[:, 1], t, rtol=1e-9)
