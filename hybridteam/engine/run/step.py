"""One integration step of one agent: where it started, what moved it, and states inside it.

The simulator advances every agent of the live instances over ``[t0, t0 + h]`` at once. A
kinematic plant under a held input moves on its exact arc; a flow (or a continuous law)
takes one Dormand–Prince step. :class:`AgentStep` records what the rest of the step's work
needs — the crossing search, the output samples that fall inside the step, the state at a
located crossing — so nothing is integrated twice: the start states and inputs, which rows
flow, and the Runge–Kutta step with its dense output.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import numpy as np

from hybridteam.arrays import every, filled, gather, some, where_true
from hybridteam.dynamics import rk
from hybridteam.dynamics.rk import Step as RKStep
from hybridteam.engine.run.drivers import derivative

if TYPE_CHECKING:
    from hybridteam.engine.run.ensemble import Ensemble


@dataclass(slots=True)
class AgentStep:
    """Agent ``a``'s step over the live instances (rows aligned with the step's index).

    ``x0`` start states (m, d), ``u`` held inputs (m, k), ``rk`` which rows flow under a
    Runge–Kutta step; for those, ``rk_step`` (its dense output), ``rk_pos`` (row ->
    position in ``rk_step``, -1 for rows that move exactly), ``err`` (the step's error
    norm per row, 0 for exact rows; inf where the result is not a finite number, so the
    step is rejected) and ``start_bad`` (rows whose derivative at the start state is not a
    finite number: no step size can help them).
    """

    x0: np.ndarray
    u: np.ndarray
    rk: np.ndarray
    rk_step: RKStep | None = None  # (``rk`` the field hides ``rk`` the module here)
    rk_pos: np.ndarray | None = None
    err: np.ndarray | None = None
    start_bad: np.ndarray | None = None


def take_step(
    ens: Ensemble,
    a: int,
    idx: np.ndarray,
    sel: slice | np.ndarray,
    h: np.ndarray,
    err: np.ndarray | None,
) -> tuple[np.ndarray, AgentStep]:
    """Agent ``a``'s states at the end of the step for instances ``idx`` (``sel`` selects
    them: a slice when all are live), and its step record; RK error estimates are folded
    into ``err`` (the largest over agents decides acceptance; NaN counts as largest; None
    where no agent of the team can flow)."""
    st = ens.states[a]
    x0, u, is_rk = gather(st.x, sel), gather(st.u, sel), st.rk[sel]
    step = AgentStep(x0, u, is_rk)
    if err is None or not some(is_rk):  # (None: no agent of the team can flow)
        return st.ca.plant.propagate(x0, u, h), step
    xe = np.empty_like(x0)
    ex = ~is_rk
    if some(ex):
        xe[ex] = st.ca.plant.propagate(x0[ex], u[ex], h[ex])
    r = where_true(is_rk)
    sub = idx[r]
    s = rk.step(
        derivative(ens, a, sub), ens.t[sub], x0[r], h[r], ens.settings.rtol, ens.settings.atol
    )
    xe[r] = s.x1
    mine = np.zeros(idx.size)
    s_err = s.err
    assert s_err is not None, "rk.step estimates its error unless told not to"
    mine[r] = np.where(
        np.logical_and.reduce(np.isfinite(s.x1), axis=1) & ~np.isnan(s_err), s_err, np.inf
    )
    assert err is not None, "a flowing row in a team the simulator found no flow in"
    np.maximum(err, mine, out=err)
    start_bad = np.zeros(idx.size, bool)
    start_bad[r] = ~np.logical_and.reduce(np.isfinite(s.k[0]), axis=1)
    pos = filled(idx.size, -1, np.intp)
    pos[r] = np.arange(r.size)
    step.rk_step, step.rk_pos, step.err, step.start_bad = s, pos, mine, start_bad
    return xe, step


def state_at(
    ens: Ensemble,
    a: int,
    idx: np.ndarray,
    tau: np.ndarray,
    step: AgentStep,
    *,
    dense: bool = False,
    rows: np.ndarray | None = None,
) -> np.ndarray:
    """Agent ``a``'s state ``tau`` after the step start, for instances ``idx``.

    ``rows`` are the positions of ``idx`` in the step's arrays (all when None). Flowing
    rows are read off the dense output when ``dense``, else integrated afresh from the
    step start (what a located crossing needs: a state as accurate as a step).
    """
    if rows is None:
        rows = np.arange(idx.size)
    is_rk = step.rk[rows]
    if dense and every(is_rk):  # every row flows (a flow mode's search): no sorting out
        return _dense(step, rows, tau)
    x0, u = gather(step.x0, rows), gather(step.u, rows)
    plant = ens.states[a].ca.plant
    if not some(is_rk):
        return plant.propagate(x0, u, tau)
    out = np.empty_like(x0)
    ex = ~is_rk
    if some(ex):
        out[ex] = plant.propagate(x0[ex], u[ex], tau[ex])
    r = where_true(is_rk)
    if dense:
        out[r] = _dense(step, rows[r], tau[r])
    else:
        sub = idx[r]
        s = rk.step(
            derivative(ens, a, sub),
            ens.t0[sub],
            x0[r],
            tau[r],
            ens.settings.rtol,
            ens.settings.atol,
            estimate=False,
        )
        ens.costs.true_steps += 1
        out[r] = s.x1
    return out


def _dense(step: AgentStep, rows: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """States of the flowing ``rows`` of the step, ``tau`` after its start, off its dense
    output."""
    return dense_reader(step, rows)(tau)


class DenseRead(Protocol):
    """The reader :func:`dense_reader` returns: ``read(tau, pos=None)``."""

    def __call__(self, tau: np.ndarray, pos: np.ndarray | None = None) -> np.ndarray: ...


def dense_reader(step: AgentStep, rows: np.ndarray) -> DenseRead:
    """``read(tau, pos=None)``: states of the flowing ``rows[pos]`` (all ``rows`` when None)
    of the step, ``tau`` after its start, off its dense output (a zero-length step reads
    its start). The rows' places in the step and their step sizes are looked up once, for
    a crossing search that reads the same rows at many trial points."""
    s = step.rk_step
    assert s is not None and step.rk_pos is not None
    at = step.rk_pos[rows]
    h = s.h[at]
    span = np.where(h > 0, h, 1.0)

    def read(tau: np.ndarray, pos: np.ndarray | None = None) -> np.ndarray:
        if pos is None:
            return s.dense(tau / span, at)
        return s.dense(tau / span[pos], at[pos])

    return read
