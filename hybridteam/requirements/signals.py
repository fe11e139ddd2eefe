"""A run's signals on the time grid requirements are evaluated on.

Each instance gets its own grid: the trace's sample times up to its end, every transition
instant, the instants of the messages a formula reads, the located crossings of
requirement comparisons (``crossings``: where a margin is exactly zero), and the run's end.
On that grid:

- states and world series are piecewise linear between samples (held after the last
  sample, up to the run's end);
- modes, roles and counts are piecewise constant, right-continuous: at a transition
  instant the configuration is the one after it (a mode entered and left within one
  instant is not seen);
- ``received``/``sent`` hold exactly at the instants of the messages;
- parameters are constant per instance (after a study's overrides).

Arrays are ``(n, K)`` with ``K`` the longest grid; shorter grids are padded with ``inf``
times, which the temporal operators ignore.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np


class Signals:
    """Signals of ``run`` (a :class:`~hybridteam.trace.Trace`) on per-instance grids."""

    def __init__(self, run: Any, params: Mapping[str, tuple[list[str], np.ndarray]],
                 events: Iterable[str] = (),
                 snapshots: Mapping[str, tuple[np.ndarray, np.ndarray, np.ndarray]] | None
                 = None) -> None:
        self.run, self._params = run, params
        self._snaps = dict(snapshots or {})
        snap_inst, snap_t = _instants(self._snaps)
        n = run.n
        ends = [float(o["t"]) for o in run.diagnostics] if hasattr(run, "diagnostics") \
            else [float(o["t"]) for o in run.outcomes]
        self.t_end = np.asarray(ends)
        st = run.sample_times
        tr, ms = run.transitions, run.messages
        wanted = np.isin(ms["type"], list(events)) if len(ms) else np.zeros(0, bool)
        grids = []
        for i in range(n):
            parts = [st[st <= ends[i]], tr["t"][tr["instance"] == i], [0.0, ends[i]]]
            mine = wanted & (ms["instance"] == i)
            if mine.any():
                parts += [ms["t_send"][mine], ms["t_recv"][mine]]
            if snap_t.size:
                parts.append(snap_t[snap_inst == i])
            g = np.unique(np.concatenate([np.asarray(p, float) for p in parts]))
            grids.append(g[np.isfinite(g) & (g <= ends[i])])
        width = max(len(g) for g in grids)
        self.t = np.full((n, width), np.inf)
        for i, g in enumerate(grids):
            self.t[i, : len(g)] = g
        self.grids = grids
        self.shape = self.t.shape
        self.memo: dict[Any, np.ndarray] = {}

    @property
    def n(self) -> int:
        return self.shape[0]

    # -- continuous signals ---------------------------------------------------------------
    def _sampled(self, key: str, j: int) -> np.ndarray:
        memo = ("sampled", key, j)
        if memo not in self.memo:
            st, values = self.run.sample_times, self.run.samples[key][:, :, j]
            snap = self._snaps.get(key)
            out = np.full(self.shape, np.nan)
            for i, g in enumerate(self.grids):
                ok = ~np.isnan(values[:, i])
                times, vals = st[ok], values[ok, i]
                if snap is not None:  # exact states at instants; the last one at a time wins
                    mine = np.flatnonzero(snap[0] == i)[::-1]
                    times = np.concatenate([snap[1][mine], times])
                    vals = np.concatenate([snap[2][mine, j], vals])
                    order = np.argsort(times, kind="stable")
                    times, first = np.unique(times[order], return_index=True)
                    vals = vals[order][first]
                if times.size:
                    out[i, : len(g)] = np.interp(g, times, vals)
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
        out = np.zeros(self.shape, bool)
        inst, start, end = iv["instance"][rows], iv["start"][rows], iv["end"][rows]
        for i, g in enumerate(self.grids):
            sel = inst == i
            if not sel.any():
                continue
            lo = np.searchsorted(g, start[sel], "left")
            last = end[sel] >= self.t_end[i]  # the run's end belongs to the last stay
            hi = np.where(last, np.searchsorted(g, end[sel], "right"),
                          np.searchsorted(g, end[sel], "left"))
            mark = np.zeros(len(g) + 1, int)
            np.add.at(mark, lo, 1)
            np.add.at(mark, hi, -1)
            out[i, : len(g)] = np.cumsum(mark[:-1]) > 0
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
        times = times[rows]
        for i, g in enumerate(self.grids):
            at = times[inst == i]
            k = np.searchsorted(g, at)
            ok = k < len(g)
            k = k[ok][g[k[ok]] == at[ok]]
            out[i, k] = True
        self.memo[memo] = out
        return out


def _instants(snaps: Mapping[str, tuple[np.ndarray, np.ndarray, np.ndarray]]
              ) -> tuple[np.ndarray, np.ndarray]:
    """(instances, times) of the snapshots (every series is taken at the same instants)."""
    for inst, t, _ in snaps.values():
        return inst, t
    return np.zeros(0, np.intp), np.zeros(0)
