"""Dormand–Prince 5(4) steps vectorized over the ensemble, with per-instance step sizes.

Why our own Runge–Kutta rather than ``scipy.integrate.solve_ivp``: the engine advances
``n`` independent instances in lockstep, and an instance's result must not depend on its
neighbours. ``solve_ivp`` takes one step size for the whole state vector, which would couple
the instances (one stiff instance would shrink everybody's steps and change their round-off).
Here every array has a leading instance axis and ``h`` is an array, so each instance gets the
step size its own error estimate asks for.

The tableau, error weights and the quartic dense-output matrix are the classical
Dormand & Prince (1980) / Shampine (1986) coefficients (the same ones scipy's ``RK45`` uses).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

Derivative = Callable[[np.ndarray, np.ndarray], np.ndarray]
"""``f(t, x) -> dx/dt`` with ``t`` of shape (m,) and ``x`` of shape (m, d)."""

C = np.array([0.0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0])
A = (
    (),
    (1 / 5,),
    (3 / 40, 9 / 40),
    (44 / 45, -56 / 15, 32 / 9),
    (19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729),
    (9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656),
)
B = np.array([35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84])
E = np.array([-71 / 57600, 0.0, 71 / 16695, -71 / 1920, 17253 / 339200, -22 / 525, 1 / 40])
P = np.array(
    [
        [1, -8048581381 / 2820520608, 8663915743 / 2820520608, -12715105075 / 11282082432],
        [0, 0, 0, 0],
        [0, 131558114200 / 32700410799, -68118460800 / 10900136933, 87487479700 / 32700410799],
        [0, -1754552775 / 470086768, 14199869525 / 1410260304, -10690763975 / 1880347072],
        [0, 127303824393 / 49829197408, -318862633887 / 49829197408,
         701980252875 / 199316789632],
        [0, -282668133 / 205662961, 2019193451 / 616988883, -1453857185 / 822651844],
        [0, 40617522 / 29380423, -110615467 / 29380423, 69997945 / 29380423],
    ]
)
ORDER = 5
SAFETY = 0.9
MIN_FACTOR = 0.2
MAX_FACTOR = 10.0


class Step:
    """One attempted step: the new state, the stages (for dense output) and the error norm."""

    __slots__ = ("err", "h", "k", "x0", "x1")

    def __init__(self, x0: np.ndarray, x1: np.ndarray, k: np.ndarray, h: np.ndarray,
                 err: np.ndarray) -> None:
        self.x0, self.x1, self.k, self.h, self.err = x0, x1, k, h, err

    def dense(self, theta: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        """State at ``t0 + theta*h`` (theta in [0, 1], one per row) from the quartic
        continuous extension; ``rows`` selects instances of this step."""
        k, x0, h = self.k, self.x0, self.h
        if rows is not None:
            k, x0, h = k[:, rows], x0[rows], h[rows]
        theta = np.asarray(theta, dtype=float)
        powers = np.stack([theta, theta**2, theta**3, theta**4], axis=-1)  # (m, 4)
        q = np.einsum("smd,sp->mpd", k, P)  # (m, 4, d)
        return x0 + h[:, None] * np.einsum("mpd,mp->md", q, powers)


def step(f: Derivative, t: np.ndarray, x: np.ndarray, h: np.ndarray, rtol: float,
         atol: float, f0: np.ndarray | None = None) -> Step:
    """Attempt one Dormand–Prince step of size ``h`` (per instance) from ``(t, x)``.

    ``err`` is the scaled RMS error norm of each instance (accept where ``err <= 1``).
    ``f0`` may pass ``f(t, x)`` when the caller already has it (first-same-as-last).
    """
    m, d = x.shape
    k = np.empty((7, m, d))
    k[0] = f(t, x) if f0 is None else f0
    hc = h[:, None]
    for s in range(1, 6):
        dx = np.zeros_like(x)
        for j, a in enumerate(A[s]):
            if a:
                dx += a * k[j]
        k[s] = f(t + C[s] * h, x + hc * dx)
    incr = np.zeros_like(x)
    for j, b in enumerate(B):
        if b:
            incr += b * k[j]
    x1 = x + hc * incr
    k[6] = f(t + h, x1)
    err_vec = hc * np.einsum("s,smd->md", E, k)
    scale = atol + rtol * np.maximum(np.abs(x), np.abs(x1))
    err = np.sqrt(np.mean((err_vec / scale) ** 2, axis=1)) if d else np.zeros(m)
    return Step(x, x1, k, h, err)


def next_step_size(h: np.ndarray, err: np.ndarray) -> np.ndarray:
    """The classical controller ``h * safety * err^(-1/order)``, with growth clamped.

    Rejected steps (``err > 1``) never grow; accepted ones grow at most ``MAX_FACTOR``.
    """
    with np.errstate(divide="ignore"):
        factor = np.where(err == 0, MAX_FACTOR, SAFETY * err ** (-1.0 / ORDER))
    factor = np.clip(factor, MIN_FACTOR, MAX_FACTOR)
    factor = np.where(err > 1, np.minimum(factor, 1.0), factor)
    return h * factor


def initial_step_size(f: Derivative, t: np.ndarray, x: np.ndarray, rtol: float,
                      atol: float, max_step: float) -> np.ndarray:
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
    h1 = np.where(big <= 1e-15, np.maximum(1e-6, h0 * 1e-3),
                  (0.01 / np.maximum(big, 1e-300)) ** (1 / ORDER))
    return np.minimum(np.minimum(100 * h0, h1), max_step)
