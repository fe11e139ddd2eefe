"""Output samples: the trace's regular time grid, recorded without stopping the run there.

Samples that fall inside a step are read off the step (dense output for flows, the exact
arc for kinematic plants); samples at the step's end are taken after its instant. How far
each instance has got along the grid is :class:`OutputSampling`'s, which the ensemble owns
(``ens.sampling``) and which only its own methods move on.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from hybridteam.arrays import every, gather, some, where_true
from hybridteam.engine.run.step import AgentStep, state_at

if TYPE_CHECKING:
    from hybridteam.engine.run.ensemble import Ensemble


def output_times(t_end: float, dt: float) -> np.ndarray:
    """Output sample times ``0, dt, 2 dt, ...`` up to ``t_end``, which is always included."""
    k = int(np.floor(t_end / dt + 1e-9)) + 1
    times = np.arange(k) * dt
    if times[-1] < t_end - 1e-12 * max(1.0, t_end):
        times = np.append(times, t_end)
    return times


class OutputSampling:
    """The sample grid and each instance's place on it: ``times`` (the grid), ``k`` (each
    instance's next sample) and ``next`` (its time, inf once past the last; a row of the
    ensemble's scheduled instants where samples are instants, see
    :meth:`.Ensemble._gather_instants`). :meth:`interpolate` and :meth:`record` take the
    samples and move ``k`` and ``next`` on; nothing else writes them."""

    __slots__ = ("after", "k", "next", "times")

    def __init__(self, times: np.ndarray, n: int) -> None:
        self.times = times
        #: the grid followed by inf: ``after[k]`` is the time of sample ``k``, or inf
        self.after = np.append(times, np.inf)
        self.k = np.zeros(n, np.intp)
        self.next = np.full(n, self.after[0])

    def interpolate(
        self, ens: Ensemble, idx: np.ndarray, t1: np.ndarray, steps: list[AgentStep]
    ) -> None:
        """Record output samples that fall strictly inside this step, without stopping there.

        Outputs do not constrain the integrator: flows are read off the step's dense
        output, kinematic plants off their exact arcs, all samples of a step in one call.
        Samples exactly at the step's end are taken after that instant's discrete steps,
        by :meth:`record`.
        """
        upcoming = self.next if idx.size == ens.n else self.next[idx]
        if not some(upcoming < t1):  # the next sample of each is not before t1
            return
        first = self.k[idx]
        last = np.searchsorted(self.times, t1, side="left")  # samples < t1
        count = np.maximum(last - first, 0)
        rows = np.repeat(np.arange(idx.size), count)
        k = np.repeat(first, count) + (
            np.arange(rows.size) - np.repeat(np.cumsum(count) - count, count)
        )
        due = idx[rows]
        tau = self.times[k] - ens.t0[due]
        for a, st in enumerate(ens.states):
            x = state_at(ens, a, due, tau, steps[a], rows=rows, dense=True)
            ens.rec.sample(k, due, st.ca.name, x)
        moved = idx[count > 0]
        self.k[moved] = last[count > 0]
        self.next[moved] = self.after[self.k[moved]]

    def record(
        self,
        ens: Ensemble,
        idx: np.ndarray,
        taken: tuple[np.ndarray, dict[str, np.ndarray]] | None,
    ) -> None:
        """Record the output samples due at the current time of instances ``idx``, after
        the instant's discrete steps. ``taken``: the world's series as this instant's
        snapshot read them, ``(instances, values)`` (None: none), the same values for the
        same instances."""
        due = (
            where_true(ens.t >= self.next)
            if idx.size == ens.n
            else idx[ens.t[idx] >= self.next[idx]]
        )
        if due.size == 0:
            return
        world = (
            taken[1]
            if taken is not None and taken[0].shape == due.shape and every(taken[0] == due)
            else ens.world.sample(due)
        )
        if due.size == 1:  # a single run's sample: its row by Python ints, no index arrays
            i = due.item(0)
            k = self.k.item(i)
            for st in ens.states:
                ens.rec.sample_one(k, i, st.ca.name, st.x[i])
            for name, values in world.items():
                ens.rec.sample_one(k, i, name, values[0])
            self.k[i] = k + 1
            self.next[i] = self.after[k + 1]
            return
        ks = self.k[due]
        for st in ens.states:
            ens.rec.sample(ks, due, st.ca.name, gather(st.x, due))
        for name, values in world.items():
            ens.rec.sample(ks, due, name, values)
        self.k[due] += 1
        self.next[due] = self.after[self.k[due]]
