"""A run's signals on the time grid requirements are evaluated on.

Each instance gets its own grid: the trace's sample times up to its end, every transition
instant, the instants of the messages a formula reads, the located crossings of
requirement comparisons (``crossings``: where a margin is exactly zero), and the run's end.
On that grid:

- states and world series are piecewise linear between samples (held after the last
  sample, up to the run's end);
- modes, roles, counts and discrete variables are piecewise constant, right-continuous:
  at a transition instant the configuration is the one after it (a mode entered and left,
  or a value set and reset, within one instant is not seen);
- ``received``/``sent`` hold exactly at the instants of the messages;
- parameters are constant per instance (after a study's overrides).

Arrays are ``(n, K)`` with ``K`` the longest grid; shorter grids are padded with ``inf``
times, which the temporal operators ignore. The grids of a whole ensemble are built and
searched at once (:mod:`.grid`): a loop over a thousand instances would cost more than
the monitoring itself.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np

from hybridteam.engine.run.record import variables_key
from hybridteam.requirements.grid import Grid


class Signals:
    """Signals of ``run`` (a :class:`~hybridteam.trace.Trace`) on per-instance grids."""

    def __init__(
        self,
        run: Any,
        params: Mapping[str, tuple[list[str], np.ndarray]],
        events: Iterable[str] = (),
        snapshots: Mapping[str, tuple[np.ndarray, np.ndarray, np.ndarray]] | None = None,
    ) -> None:
        self.run, self._params = run, params
        self._snaps = dict(snapshots or {})
        snap_inst, snap_t = _instants(self._snaps)
        n = run.n
        outcomes = run.diagnostics if hasattr(run, "diagnostics") else run.outcomes
        self.t_end = np.array([float(o["t"]) for o in outcomes])
        tr, ms = run.transitions, run.messages
        wanted = np.isin(ms["type"], list(events)) if len(ms) else np.zeros(0, bool)
        inst = [
            tr["instance"],
            np.arange(n),
            np.arange(n),
            snap_inst,
            ms["instance"][wanted],
            ms["instance"][wanted],
        ]
        times = [
            tr["t"],
            np.zeros(n),
            self.t_end,
            snap_t,
            ms["t_send"][wanted],
            ms["t_recv"][wanted],
        ]
        self.grid = Grid(
            run.sample_times,
            self.t_end,
            np.concatenate([np.asarray(x, np.intp) for x in inst]),
            np.concatenate([np.asarray(x, float) for x in times]),
        )
        self.t = self.grid.t
        self.shape = self.t.shape
        self.memo: dict[Any, np.ndarray] = {}

    @property
    def n(self) -> int:
        return self.shape[0]

    # -- continuous signals ---------------------------------------------------------------
    def _sampled(self, key: str, j: int) -> np.ndarray:
        memo = ("sampled", key, j)
        if memo not in self.memo:
            g = self.grid
            values = g.place(self.run.samples[key][:, :, j].T, np.nan)
            snap = self._snaps.get(key)
            if snap is not None:  # exact states at instants; the last one at a time wins
                rows, cols, which = g.last_records(snap[0], snap[1])
                values[rows, cols] = snap[2][which, j]
            self.memo[memo] = g.interpolate(~np.isnan(values), values)
        return self.memo[memo]

    def variable(self, agent: str, j: int) -> np.ndarray:
        """A discrete variable: piecewise constant, right-continuous: at each grid point
        the value after the last instant at or before it (variables change only at
        instants, and the engine records them after each)."""
        memo = ("variable", agent, j)
        if memo not in self.memo:
            inst, t, values = self._snaps[variables_key(agent)]
            rows, cols, which = self.grid.last_records(inst, t)
            known = np.zeros(self.shape, bool)
            known[rows, cols] = True
            out = np.full(self.shape, np.nan)
            out[rows, cols] = values[which, j]
            idx = np.maximum.accumulate(np.where(known, np.arange(self.shape[1]), 0), axis=1)
            out = np.take_along_axis(out, idx, axis=1)
            out[~np.isfinite(self.t)] = np.nan
            self.memo[memo] = out
        return self.memo[memo]

    def state(self, agent: str, j: int) -> np.ndarray:
        return self._sampled(agent, j)

    def series(self, name: str, j: int) -> np.ndarray:
        return self._sampled(name, j)

    def param(self, agent: str, name: str) -> np.ndarray:
        names, values = self._params[agent]
        return values[:, names.index(name)][:, None]

    def team_param(self, name: str) -> np.ndarray:
        for names, values in self._params.values():
            if name in names:
                return values[:, names.index(name)][:, None]
        raise KeyError(name)  # the catalog only hands out declared names

    # -- discrete signals -----------------------------------------------------------------
    def in_modes(self, agent: str, modes: list[int]) -> np.ndarray:
        memo = ("modes", agent, tuple(modes))
        if memo in self.memo:
            return self.memo[memo]
        iv = self.run.intervals
        paths = self._paths(agent)
        wanted = [paths[m] for m in modes]
        rows = (iv["agent"] == agent) & np.isin(iv["mode"], wanted)
        inst, start, end = iv["instance"][rows], iv["start"][rows], iv["end"][rows]
        last = end >= self.t_end[inst]  # the run's end belongs to the last stay
        lo = self.grid.search(inst, start, "left")
        hi = np.where(
            last, self.grid.search(inst, end, "right"), self.grid.search(inst, end, "left")
        )
        w = self.shape[1] + 1
        mark = (
            np.bincount(inst * w + lo, minlength=self.n * w)
            - np.bincount(inst * w + hi, minlength=self.n * w)
        ).reshape(self.n, w)
        out = np.cumsum(mark, axis=1)[:, :-1] > 0
        self.memo[memo] = out
        return out

    def _paths(self, agent: str) -> list[str]:
        meta = next(a for a in self.run.meta["agents"] if a["name"] == agent)
        return ["", *(m["path"] for m in meta["modes"])]

    def event(self, kind: str, agent: str | None, message: str) -> np.ndarray:
        memo = ("event", kind, agent, message)
        if memo in self.memo:
            return self.memo[memo]
        ms = self.run.messages
        rows = ms["type"] == message
        if kind == "received":
            rows &= ms["status"] == "delivered"
            if agent is not None:
                rows &= ms["receiver"] == agent
            times = ms["t_recv"]
        else:
            if agent is not None:
                rows &= ms["sender"] == agent
            times = ms["t_send"]
        out = np.zeros(self.shape, bool)
        inst = ms["instance"][rows]
        pos = self.grid.locate(inst, times[rows])
        out[inst[pos >= 0], pos[pos >= 0]] = True
        self.memo[memo] = out
        return out


def _instants(
    snaps: Mapping[str, tuple[np.ndarray, np.ndarray, np.ndarray]],
) -> tuple[np.ndarray, np.ndarray]:
    """(instances, times) of the snapshots (every series is taken at the same instants)."""
    for inst, t, _ in snaps.values():
        return inst, t
    return np.zeros(0, np.intp), np.zeros(0)
