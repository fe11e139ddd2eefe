"""Runge–Kutta step sizes: the first one, and the error control after each step.

Only instances where some agent flows (a flow plant, or a continuous law) have a step
size; elsewhere a step ends at the next scheduled instant.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from hybridteam.arrays import some, where_true
from hybridteam.dynamics import rk
from hybridteam.engine.run.drivers import derivative
from hybridteam.engine.run.numerics import step_floor, stop_collapsed_steps

if TYPE_CHECKING:
    from hybridteam.engine.run.ensemble import Ensemble
    from hybridteam.engine.run.step import AgentStep


def control_step_size(
    ens: Ensemble,
    idx: np.ndarray,
    sel: slice | np.ndarray,
    t1: np.ndarray,
    any_rk: np.ndarray,
    limited: np.ndarray,
    err: np.ndarray,
    x_end: list[np.ndarray],
    steps: list[AgentStep],
) -> None:
    """Runge–Kutta error control: a rejected step is taken back (the instance stays
    where it was, ``h`` = 0) and retried smaller; an accepted step that the error
    control limited proposes the next size. A step size that collapses ends the
    instance (``stiff``, :mod:`.numerics`)."""
    rows_rk = any_rk[sel]
    h = ens.h[sel]
    new_h = rk.next_step_size(h, err)
    reject = rows_rk & (err > 1)
    grow = rows_rk & ~reject & limited[sel]
    upd = reject | grow
    ens.h_rk[idx[upd]] = new_h[upd]
    if some(reject):
        # a derivative that is not a number at the start is a numerical error, not a
        # step too large: stop_broken_states reports it
        hopeless = np.zeros(idx.size, bool)
        for s in steps:
            if s.start_bad is not None:
                hopeless |= s.start_bad
        dead = stop_collapsed_steps(ens, idx, steps, where_true(reject & ~hopeless))
        reject[dead] = True  # (already) taken back: nothing of the step is kept
        back = idx[reject]
        t1[back] = ens.t[back]
        ens.h[back] = 0.0
        for a in range(len(ens.states)):
            x_end[a][reject] = steps[a].x0[reject]


def initial_step_sizes(ens: Ensemble, idx: np.ndarray) -> None:
    """Each flowing instance's first Runge–Kutta step size (``ens.h_rk``), from the
    derivative at its state (the smallest over its flowing agents)."""
    if idx.size == 0:
        return
    h = np.full(idx.size, np.inf)
    for a, st in enumerate(ens.states):
        rows = where_true(st.rk[idx])
        if rows.size == 0:
            continue
        sub = idx[rows]
        h0 = rk.initial_step_size(
            derivative(ens, a, sub),
            ens.t[sub],
            st.x[sub],
            ens.settings.rtol,
            ens.settings.atol,
            min(ens.max_step, ens.t_end or 1.0),
        )
        # a derivative that is not a number gives no estimate: take the smallest
        # step, whose first stage reports it (numerical_error)
        h0 = np.where(h0 > 0, h0, step_floor(ens, ens.t[sub]))
        h[rows] = np.minimum(h[rows], h0)
    ens.h_rk[idx] = h
