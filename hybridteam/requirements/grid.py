"""Per-instance time grids of a whole ensemble, built and searched without a loop over
instances.

Every instance's grid is the trace's sample times up to its end merged with its own extra
instants (transitions, snapshots, messages, the run's end). A Python loop per instance
costs tens of microseconds each, which for a 1000-instance ensemble is more than all the
monitoring arithmetic; here the merge is done with integer bookkeeping over the whole
ensemble: an extra instant's position is the number of samples before it plus its rank
among its instance's extras, and a sample's position is its index plus the number of its
instance's extras before it. Searches answer exactly (integer counts, no float offsets).
"""

from __future__ import annotations

from typing import Literal

import numpy as np


class Grid:
    """Rows of increasing times, ``t`` of shape ``(n, W)``, padded with ``+inf``."""

    def __init__(
        self,
        sample_times: np.ndarray,
        ends: np.ndarray,
        extra_instances: np.ndarray,
        extra_times: np.ndarray,
    ) -> None:
        st = np.asarray(sample_times, float)
        ends = np.asarray(ends, float)
        n, s = len(ends), len(st)
        self.st, self.n = st, n
        self.kept = np.searchsorted(st, ends, "right")  # samples up to each instance's end
        ei = np.asarray(extra_instances, np.intp)
        et = np.asarray(extra_times, float)
        ok = np.isfinite(et) & (et <= ends[ei])
        ei, et = ei[ok], et[ok]
        k = np.searchsorted(st, et, "left")  # samples strictly before each extra
        on_sample = (
            (k < self.kept[ei]) & (st[np.minimum(k, max(s - 1, 0))] == et)
            if s
            else np.zeros(len(et), bool)
        )
        ei, et, k = ei[~on_sample], et[~on_sample], k[~on_sample]
        order = np.lexsort((et, ei))
        ei, et, k = ei[order], et[order], k[order]
        new = np.ones(len(ei), bool)
        new[1:] = (ei[1:] != ei[:-1]) | (et[1:] != et[:-1])
        ei, et, k = ei[new], et[new], k[new]
        count = np.bincount(ei, minlength=n)
        self.first = np.concatenate([[0], np.cumsum(count)[:-1]]).astype(np.intp)
        self.ext_inst, self.ext_t = ei, et
        ext_pos = k + np.arange(len(ei)) - self.first[ei]
        # a sample's shift: its instance's extras before it (those with k_e <= j)
        hist = np.bincount(ei * (s + 1) + k, minlength=n * (s + 1)).reshape(n, s + 1)
        self.length = self.kept + count
        width = int(self.length.max(initial=0))
        #: where sample j of row i goes; ``width`` (a spare column) for samples past its end
        self.sample_pos = np.where(
            np.arange(s) < self.kept[:, None], np.arange(s) + np.cumsum(hist, axis=1)[:, :s], width
        )
        self.t = self.place(np.broadcast_to(st, (n, s)), np.inf)
        self.t[ei, ext_pos] = et
        self.shape = self.t.shape
        self._keys: np.ndarray | None = None  # search keys, built on the first search

    def place(self, samples: np.ndarray, fill: float) -> np.ndarray:
        """An ``(n, W)`` array holding ``samples`` (``(n, S)``, one row per instance) at
        the samples' grid positions and ``fill`` elsewhere: one scatter along rows."""
        out = np.full((self.n, int(self.length.max(initial=0)) + 1), fill)
        np.put_along_axis(out, self.sample_pos, samples, axis=1)
        return out[:, :-1]

    def search(
        self, instances: np.ndarray, times: np.ndarray, side: Literal["left", "right"] = "left"
    ) -> np.ndarray:
        """Per query, ``np.searchsorted(row, time, side)`` on its instance's row."""
        inst = np.asarray(instances, np.intp)
        q = np.asarray(times, float)
        samples = np.minimum(np.searchsorted(self.st, q, side), self.kept[inst])
        # extras of the same instance before q, by exact integer keys: an extra's time is
        # below q (side left; at most q, side right) iff its rank among the distinct extra
        # times is below the count of distinct extra times below (at most) q
        if self._keys is None:
            self._values = np.unique(self.ext_t)
            self._scale = len(self._values) + 1
            self._keys = self.ext_inst * self._scale + np.searchsorted(self._values, self.ext_t)
        key = inst * self._scale + np.searchsorted(self._values, q, side)
        return samples + np.searchsorted(self._keys, key, "left") - self.first[inst]

    def locate(self, instances: np.ndarray, times: np.ndarray) -> np.ndarray:
        """Grid position of each ``(instance, time)``, or -1 where the time is not on the
        instance's grid."""
        inst = np.asarray(instances, np.intp)
        pos = self.search(inst, times)
        ok = pos < self.length[inst]
        ok[ok] = self.t[inst[ok], pos[ok]] == np.asarray(times, float)[ok]
        return np.where(ok, pos, -1)

    def last_records(
        self, instances: np.ndarray, times: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Where records ``(instance, time)`` (in the order they were taken) fall on the
        grid: ``(rows, cols, which)``, one per grid point that has any, ``which`` the
        index of the last record there (records off the grid are left out)."""
        inst = np.asarray(instances, np.intp)
        pos = self.locate(inst, times)
        w = self.shape[1]
        flat = np.where(pos >= 0, inst * w + pos, -1)[::-1]
        _, first = np.unique(flat, return_index=True)  # first from the end: the last taken
        first = first[flat[first] >= 0]
        rows, cols = np.divmod(flat[first], w)
        return rows, cols, len(flat) - 1 - first

    def interpolate(self, data: np.ndarray, values: np.ndarray) -> np.ndarray:
        """``values`` given where ``data`` is true, linear in between (``np.interp``'s
        formula), held before the first and after the last data point of a row; NaN on
        rows without data and at the padding."""
        w = self.shape[1]
        rows, cols = np.nonzero(~data & np.isfinite(self.t))  # few: the other instants
        prev, nxt = cols - 1, cols + 1
        while True:  # walk to the nearest data point on each side (one or two steps)
            more = (prev >= 0) & ~data[rows, np.maximum(prev, 0)]
            if not more.any():
                break
            prev[more] -= 1
        while True:
            more = (nxt < w) & ~data[rows, np.minimum(nxt, w - 1)]
            if not more.any():
                break
            nxt[more] += 1
        has = (prev >= 0) | (nxt < w)
        rows, cols, prev, nxt = rows[has], cols[has], prev[has], nxt[has]
        lo, hi = np.where(prev >= 0, prev, nxt), np.where(nxt < w, nxt, prev)
        t0, t1 = self.t[rows, lo], self.t[rows, hi]
        v0, v1 = values[rows, lo], values[rows, hi]
        out = values.copy()
        with np.errstate(invalid="ignore", divide="ignore"):
            slope = (v1 - v0) / (t1 - t0)
            out[rows, cols] = np.where(lo == hi, v0, slope * (self.t[rows, cols] - t0) + v0)
        return out
