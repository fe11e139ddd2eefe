"""Dormand–Prince 8(5,3) steps vectorized over the ensemble, with per-instance step sizes.

Why our own Runge–Kutta driver rather than ``scipy.integrate.solve_ivp``: the engine
advances ``n`` independent instances in lockstep, and an instance's result must not depend
on its neighbours. ``solve_ivp`` takes one step size for the whole state vector, which would
couple the instances (one fast instance would shrink everybody's steps and change their
round-off). Here every array has a leading instance axis and ``h`` is an array, so each
instance gets the step size its own error estimate asks for.

The method is Hairer's DOP853 (order 8, error estimators of orders 5 and 3, and a
7th-order continuous extension), which takes few steps at the tight tolerances exact event
times need. Its coefficient tables are scipy's (``scipy.integrate._ivp.dop853_coefficients``,
the numbers of Hairer's Fortran code); the vectorized stepping, error norm per instance and
dense output are ours.
"""

from __future__ import annotations

import importlib.util
from collections.abc import Callable
from pathlib import Path
from types import ModuleType

import numpy as np

from hybridteam.floatpaths import FLOAT_PATHS


def _dop853_tables() -> ModuleType:
    """scipy's DOP853 coefficient module, loaded on its own.

    ``import scipy.integrate`` costs ~0.3 s (quadrature, BVP, docstring processing), a third
    of a CLI call; the tables are a plain module that only needs numpy.
    """
    spec = importlib.util.find_spec("scipy")
    if spec and spec.submodule_search_locations:
        path = Path(
            spec.submodule_search_locations[0], "integrate", "_ivp", "dop853_coefficients.py"
        )
        if path.is_file():
            mspec = importlib.util.spec_from_file_location("_hybridteam_dop853", path)
            if mspec and mspec.loader:
                module = importlib.util.module_from_spec(mspec)
                mspec.loader.exec_module(module)
                return module
    from scipy.integrate._ivp import dop853_coefficients  # pragma: no cover

    return dop853_coefficients  # pragma: no cover


_c = _dop853_tables()

Derivative = Callable[[np.ndarray, np.ndarray], np.ndarray]
"""``f(t, x) -> dx/dt`` with ``t`` of shape (m,) and ``x`` of shape (m, d)."""

N_STAGES = _c.N_STAGES  # 12
A = _c.A[:N_STAGES, :N_STAGES]
B = _c.B
C = _c.C[:N_STAGES]
E3 = _c.E3
E5 = _c.E5
D = _c.D
A_EXTRA = _c.A[N_STAGES + 1 :]
C_EXTRA = _c.C[N_STAGES + 1 :]


def _row(coefs: np.ndarray) -> np.ndarray:
    """Coefficients up to the last nonzero one, shaped to broadcast over (stage, m, d)."""
    nz = np.flatnonzero(coefs)
    return np.asarray(coefs[: nz[-1] + 1], dtype=float)[:, None, None]


B_TERMS, E3_TERMS, E5_TERMS = _row(B), _row(E3), _row(E5)
EXTRA_ROWS = [_row(a[:s]) for s, a in enumerate(A_EXTRA, start=N_STAGES + 1)]
D_TERMS = [_row(row) for row in D]


def _sums_table() -> tuple[list[np.ndarray], int]:
    """Column ``j`` of every stage sum a step needs, for :func:`step`'s running sums.

    Every sum ``sum_j c_j k[j]`` of the method is accumulated strictly in stage order, for
    every element. Not ``einsum``/``tensordot``/``sum``: their summation order depends on
    the array sizes (pairwise or blocked sums), so an instance's result would change in
    the last bits — which adaptive step-size control amplifies — with the number of its
    neighbours in the ensemble.

    Rows: the stage inputs ``A[s, :s]`` (s = 1 .. 11, row ``s - 1``), then the solution
    weights ``B`` and the error weights ``E5``, ``E3``. Every one of these sums ends at or
    before ``k[11]`` and row ``s - 1`` of ``A`` ends exactly at ``k[s - 1]`` (checked here),
    so adding ``column[j] * k[j]`` into the rows that are still open, for ``j = 0, 1, ...``,
    adds each sum's terms one at a time from ``j = 0`` up to its last nonzero coefficient
    (zero coefficients inside included): the textbook sum, with its bits.
    """
    rows = [A[s, :s] for s in range(1, N_STAGES)] + [
        B_TERMS.ravel(),
        E5_TERMS.ravel(),
        E3_TERMS.ravel(),
    ]
    assert all(r.size == s and r[-1] != 0 for s, r in enumerate(rows[: N_STAGES - 1], 1))
    assert all(r.size <= N_STAGES for r in rows)
    table = np.zeros((len(rows), N_STAGES))
    for i, r in enumerate(rows):
        table[i, : r.size] = r
    # column j feeds the stage rows s - 1 >= j and the three weight rows
    return [table[j:, j, None, None].copy() for j in range(N_STAGES)], len(rows)


SUM_COLUMNS, N_SUMS = _sums_table()
B_SUM, E5_SUM, E3_SUM = N_SUMS - 3, N_SUMS - 2, N_SUMS - 1
C_COLUMN = C[:, None]


def _dense_table() -> tuple[np.ndarray, list[np.ndarray]]:
    """The dense output's seven sums (extra stages 13, 14, 15, then the rows of ``D``):
    their coefficients of the step's stages 0..12, shaped (7, 13, 1, 1), and the column of
    each extra stage ``13 + s`` over the sums after its own (rows ``s + 1 ..``).

    Stage ``13 + s`` ends at ``k[12 + s]`` and every ``D`` row at ``k[15]`` (checked), so
    summing stages 0..12 at once (``add.accumulate``: a running sum by definition) and
    then adding each extra stage's term adds each sum's terms in stage order, as
    :func:`_sums_table` explains.
    """
    rows = [r.ravel() for r in EXTRA_ROWS] + [r.ravel() for r in D_TERMS]
    assert all(r.size == N_STAGES + 1 + s for s, r in enumerate(rows[: len(C_EXTRA)]))
    assert all(r.size == N_STAGES + 1 + len(C_EXTRA) for r in rows[len(C_EXTRA) :])
    table = np.zeros((len(rows), N_STAGES + 1 + len(C_EXTRA)))
    for i, r in enumerate(rows):
        table[i, : r.size] = r
    start = table[:, : N_STAGES + 1, None, None].copy()
    columns = [table[s + 1 :, N_STAGES + 1 + s, None, None].copy() for s in range(len(C_EXTRA))]
    return start, columns


DENSE_START, DENSE_COLUMNS = _dense_table()
ERROR_ORDER = 7
SAFETY = 0.9
MIN_FACTOR = 0.2
MAX_FACTOR = 10.0
#: Largest number of values :meth:`Step.dense` computes on Python floats (about 1 µs
#: each, against 16 array operations of about 1 µs whatever their size), while the float
#: paths are on (:data:`hybridteam.floatpaths.FLOAT_PATHS`).
SMALL_DENSE = 8


class Step:
    """One attempted step: the new state, its stages (for dense output), the error norm."""

    __slots__ = ("_F", "_last", "_small", "err", "f", "h", "k", "t0", "x0", "x1")

    def __init__(
        self,
        f: Derivative,
        t0: np.ndarray,
        x0: np.ndarray,
        x1: np.ndarray,
        k: np.ndarray,
        h: np.ndarray,
        err: np.ndarray | None,
        last_stage: bool = True,
    ) -> None:
        """``last_stage`` false: ``k[N_STAGES]`` (the derivative at the new state, which
        only the error estimate and the dense output read) is not computed yet."""
        self.f, self.t0, self.x0, self.x1, self.k, self.h, self.err = f, t0, x0, x1, k, h, err
        self._last = last_stage
        self._F: np.ndarray | None = None
        # per row read on floats: its start values and coefficients, last first
        self._small: dict[int, list[tuple[float, list[float]]]] = {}

    def _coefficients(self) -> np.ndarray:
        """The interpolant's coefficients (3 more stages, computed once, when first needed).

        Its seven sums (the three stages' inputs, the four coefficient rows) all start with
        the step's 13 stages: their terms are summed for all seven in one running sum,
        then each new stage's term is added to the sums still open (see
        :func:`_dense_table`): the additions of summing each afresh, in the same order.
        """
        if self._F is None:
            if not self._last:
                self.k[N_STAGES] = self.f(self.t0 + self.h, self.x1)
                self._last = True
            m, d = self.x0.shape
            k = np.empty((_c.N_STAGES_EXTENDED, m, d))
            k[: N_STAGES + 1] = self.k
            hc = self.h[:, None]
            first = N_STAGES + 1
            sums = np.add.accumulate(DENSE_START * self.k, axis=1)[:, -1]  # (7, m, d)
            for s, c in enumerate(C_EXTRA):
                k[first + s] = self.f(self.t0 + c * self.h, self.x0 + hc * sums[s])
                sums[s + 1 :] += DENSE_COLUMNS[s] * k[first + s]
            F = np.empty((_c.INTERPOLATOR_POWER, m, d))
            dy = self.x1 - self.x0
            F[0] = dy
            F[1] = hc * k[0] - dy
            F[2] = 2 * dy - hc * (k[N_STAGES] + k[0])
            F[3:] = hc * sums[len(C_EXTRA) :]
            self._F = F
        return self._F

    def dense(self, theta: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        """State at ``t0 + theta*h`` (theta in [0, 1], one per row), 7th order accurate;
        ``rows`` selects instances of this step.

        A few values (a single run's crossing search reads one or two states of a small
        flow) are computed on Python floats: numpy's cost is per call, 16 calls whatever
        the size, and the same IEEE operations in the same order give the same bits.
        """
        theta = np.asarray(theta, dtype=float)
        if theta.size * self.x0.shape[1] <= SMALL_DENSE and FLOAT_PATHS.on:
            return self._dense_small(theta, rows)
        F, x0 = self._coefficients(), self.x0
        if rows is not None and not (rows.size == 1 == x0.shape[0]):  # (the one row: as is)
            F, x0 = F[:, rows], x0[rows]
        x = theta[:, None]
        factors = (x, 1 - x)
        y = np.zeros(x0.shape)
        for i, coef in enumerate(reversed(F)):
            y += coef
            y *= factors[i % 2]
        return x0 + y

    def _dense_small(self, theta: np.ndarray, rows: np.ndarray | None) -> np.ndarray:
        """:meth:`dense` on Python floats (:meth:`dense_row` for each value)."""
        picks = range(theta.size) if rows is None else rows.tolist()
        out = [self.dense_row(th, r) for r, th in zip(picks, theta.tolist(), strict=True)]
        return np.array(out, dtype=float).reshape(theta.size, self.x0.shape[1])

    def dense_row(self, theta: float, r: int) -> list[float]:
        """Row ``r``'s state at ``t0 + theta*h`` as a list of floats: :meth:`dense` element
        by element, ``y = 0; y += coef; y *= factor`` from the last coefficient, then
        ``x0 + y``, as the array loop does it (the same bits; ``tests/dynamics/test_rk.py``
        compares them through the switch).

        Written out rather than calling one polynomial function for both forms: a call per
        component costs a third more per read, about 1 % of the bouncing ball's run, whose
        ratio to ``solve_ivp`` is at its budget."""
        table = self._small
        if r not in table:
            F = self._coefficients()
            table[r] = list(zip(self.x0[r].tolist(), F[::-1, r].T.tolist(), strict=True))
        factors = (theta, 1 - theta)
        out = []
        for x0_j, coefs in table[r]:
            y = 0.0
            for i, coef in enumerate(coefs):
                y += coef
                y *= factors[i % 2]
            out.append(x0_j + y)
        return out


def step(
    f: Derivative,
    t: np.ndarray,
    x: np.ndarray,
    h: np.ndarray,
    rtol: float,
    atol: float,
    f0: np.ndarray | None = None,
    estimate: bool = True,
) -> Step:
    """Attempt one DOP853 step of size ``h`` (per instance) from ``(t, x)``.

    ``err`` is each instance's scaled error norm (accept where ``err <= 1``); with
    ``estimate=False`` it is not computed (None), nor the derivative at the new state until
    the dense output asks for it — a crossing search that integrates to a trial point only
    wants the state there, which is the same either way.

    The stage sums are kept running (``sums``): once ``k[j]`` is known, its term is added
    to every sum that uses it, one array operation for all of them (see
    :func:`_sums_table`). At the handful of instances a single run has, numpy's cost is
    per call, and this needs a third of the calls of summing each stage afresh; the
    additions, and so the bits, are those of the textbook sums.
    """
    m, d = x.shape
    k = np.empty((N_STAGES + 1, m, d))
    k[0] = f(t, x) if f0 is None else f0
    hc = h[:, None]
    ts = t + C_COLUMN * h  # every stage's time at once (each element as t + C[s] * h)
    sums = SUM_COLUMNS[0] * k[0]
    for s in range(1, N_STAGES):
        k[s] = f(ts[s], x + hc * sums[s - 1])
        sums[s:] += SUM_COLUMNS[s] * k[s]
    x1 = x + hc * sums[B_SUM]
    if not estimate:  # (a trial point: its stages past the new state are read if ever)
        return Step(f, t, x, x1, k, h, None, last_stage=False)
    k[N_STAGES] = f(t + h, x1)
    scale = atol + rtol * np.maximum(np.abs(x), np.abs(x1))
    err5 = sums[E5_SUM] / scale
    err3 = sums[E3_SUM] / scale
    # np.sum's own reduction without its Python-level wrapper (about 5 µs a call), and the
    # norm divided only where its denominator is positive (0 elsewhere), so no error state
    # is needed (a context costs about 3 µs): the same values, at a single run's size
    e5 = np.add.reduce(err5 * err5, axis=1)
    e3 = np.add.reduce(err3 * err3, axis=1)
    denom = e5 + 0.01 * e3
    err = np.zeros(m)
    np.divide(np.abs(h) * e5, np.sqrt(denom * max(d, 1)), out=err, where=denom > 0)
    return Step(f, t, x, x1, k, h, err)


def next_step_size(h: np.ndarray, err: np.ndarray) -> np.ndarray:
    """The classical controller ``h * safety * err^(-1/(q+1))``, growth clamped.

    Rejected steps (``err > 1``) never grow; accepted ones grow at most ``MAX_FACTOR``.
    """
    with np.errstate(divide="ignore"):
        factor = np.where(err == 0, MAX_FACTOR, SAFETY * err ** (-1.0 / (ERROR_ORDER + 1)))
    # np.clip's values (NaN stays NaN) without its Python-level wrapper
    factor = np.minimum(np.maximum(factor, MIN_FACTOR), MAX_FACTOR)
    factor = np.where(err > 1, np.minimum(factor, 1.0), factor)
    return h * factor


def initial_step_size(
    f: Derivative, t: np.ndarray, x: np.ndarray, rtol: float, atol: float, max_step: float
) -> np.ndarray:
    """Hairer–Nørsett–Wanner's starting step estimate, per instance."""
    f0 = f(t, x)
    scale = atol + np.abs(x) * rtol
    d = x.shape[1]
    if d == 0:
        return np.full(x.shape[0], max_step)
    d0 = np.sqrt(np.mean((x / scale) ** 2, axis=1))
    d1 = np.sqrt(np.mean((f0 / scale) ** 2, axis=1))
    h0 = np.where((d0 < 1e-5) | (d1 < 1e-5), 1e-6, 0.01 * d0 / np.maximum(d1, 1e-300))
    x1 = x + h0[:, None] * f0
    f1 = f(t + h0, x1)
    d2 = np.sqrt(np.mean(((f1 - f0) / scale) ** 2, axis=1)) / h0
    big = np.maximum(d1, d2)
    h1 = np.where(
        big <= 1e-15,
        np.maximum(1e-6, h0 * 1e-3),
        (0.01 / np.maximum(big, 1e-300)) ** (1 / (ERROR_ORDER + 1)),
    )
    return np.minimum(np.minimum(100 * h0, h1), max_step)
