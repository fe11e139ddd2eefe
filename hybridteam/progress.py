"""Progress of long work — a run, a study — on a terminal or in a log.

On a terminal a tqdm bar is the pleasant thing; in a non-interactive shell, a CI job or a
batch system a bar prints nothing useful (or garbage), and a five-minute study that says
nothing looks hung. :func:`reporter` picks: ``bar``, ``log`` (a line every tenth of the
work or every 30 s, with the time taken and an estimate of what is left), ``none``, or
``auto`` — a bar on a terminal, lines otherwise. Lines start after two seconds, so
quick work stays quiet. Both kinds answer ``update(k)`` and ``close()``.
"""

from __future__ import annotations

import sys
import time
from typing import TextIO

MODES = ("auto", "bar", "log", "none")


class LogProgress:
    """Progress as lines: ``hybridteam: alpha: 1,500/3,000 runs (50%), 4.2 s, ETA 4.1 s``."""

    def __init__(
        self,
        total: float,
        desc: str,
        unit: str,
        initial: float = 0,
        file: TextIO | None = None,
        step: float = 0.1,
        seconds: float = 30.0,
        grace: float = 2.0,
    ) -> None:
        self.total, self.desc, self.unit, self.n = total, desc, unit, initial
        self.file = file if file is not None else sys.stderr
        self.step, self.seconds, self.grace = step, seconds, grace
        self.spoke = False
        self.start = time.perf_counter()
        self.first = initial
        self.shown, self.shown_at = initial, self.start

    def update(self, k: float = 1) -> None:
        self.n += k
        now = time.perf_counter()
        if (
            self.total
            and now - self.start >= self.grace
            and (
                self.n - self.shown >= self.step * self.total or now - self.shown_at >= self.seconds
            )
        ):
            self._line(now)

    def close(self) -> None:
        if self.spoke and self.n != self.shown:
            self._line(time.perf_counter())

    def _line(self, now: float) -> None:
        self.shown, self.shown_at, self.spoke = self.n, now, True
        elapsed = now - self.start
        done = self.n - self.first
        left = self.total - self.n
        eta = f", ETA {elapsed / done * left:.1f} s" if done > 0 and left > 0 else ""
        share = 100.0 * self.n / self.total if self.total else 100.0
        count = (
            f"{share:.0f}% simulated"
            if self.unit == "%"
            else f"{self.n:,.0f}/{self.total:,.0f} {self.unit}s ({share:.0f}%)"
        )
        print(f"hybridteam: {self.desc}: {count}, {elapsed:.1f} s{eta}", file=self.file, flush=True)


def reporter(mode: str, total: float, desc: str, unit: str, initial: float = 0):
    """A progress reporter for ``mode`` (see the module docstring), or None for ``none``."""
    if mode == "auto":
        mode = "bar" if sys.stderr.isatty() else "log"
    if mode == "none":
        return None
    if mode == "log":
        return LogProgress(total, desc, unit, initial)
    from tqdm import tqdm

    return tqdm(
        total=total,
        initial=initial,
        unit=unit,
        desc=desc,
        file=sys.stderr,
        dynamic_ncols=True,
        smoothing=0.1,
        leave=False,
    )
