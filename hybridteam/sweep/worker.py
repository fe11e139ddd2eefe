"""One chunk, run as one ensemble: the only code that executes on a worker.

Kept to a plain module-level function of picklable arguments (a team and a :class:`Task`)
so a process pool and a Dask cluster can ship it as is; it reads no files, so a remote
worker needs only ``hybridteam`` installed, not the study's folder.
"""

from __future__ import annotations

import math
import os
import sys
from typing import Any

import numpy as np

from hybridteam.model import Team
from hybridteam.sweep.plan import Task

#: Columns of a chunk's per-run rows, besides one ``metric_<key>`` column per metric.
RUN_COLUMNS = ("run", "setting", "member", "repetition", "seed", "outcome", "t_end")


#: glibc's malloc parameters (mallopt) and the values its adaptive thresholds reach on
#: 64-bit Linux: blocks up to 32 MiB from the heap, the heap trimmed past 64 MiB free
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3
_MMAP_MAX, _TRIM_AT = 32 << 20, 64 << 20
_tuned: bool | None = None


def restore_malloc() -> bool:
    """Give glibc back its adaptive behaviour where the environment turned it off.

    A Dask nanny starts workers with ``MALLOC_TRIM_THRESHOLD_=65536``; setting any malloc
    threshold turns off glibc's adaptive mmap threshold, so every numpy temporary over
    128 KiB is mapped and unmapped and the heap top trimmed again and again: measured here,
    a ladder chunk cost 2.9 s of CPU in such a worker and 1.4 s in a plain process. Fixing
    the thresholds at the values adaptation reaches (32 MiB, trim past 64 MiB) restores the
    plain process's speed (1.2–1.3 s). Once per process, only when such a variable is set,
    never with ``HYBRIDTEAM_KEEP_MALLOC=1``, and a no-op where there is no glibc. Returns
    whether it changed anything.
    """
    global _tuned
    if _tuned is not None:
        return _tuned
    _tuned = False
    env = os.environ
    if env.get("HYBRIDTEAM_KEEP_MALLOC") or not sys.platform.startswith("linux") or not any(
            k in env for k in ("MALLOC_TRIM_THRESHOLD_", "MALLOC_MMAP_THRESHOLD_")):
        return _tuned
    try:
        import ctypes

        mallopt = ctypes.CDLL("libc.so.6").mallopt
    except (OSError, AttributeError):  # not glibc (musl): nothing to restore
        return _tuned
    _tuned = bool(mallopt(_M_MMAP_THRESHOLD, _MMAP_MAX)) and \
        bool(mallopt(_M_TRIM_THRESHOLD, _TRIM_AT))
    return _tuned


def run_chunk(team: Team, task: Task) -> dict[str, list[Any]]:
    """Simulate a chunk's runs in one ensemble; one row per run, as columns.

    Through :func:`hybridteam.api.summaries`: per-instance summaries without a trace, and a
    mode library's batch simulator when it has one for this team (``task.accelerate``).
    """
    from hybridteam.api import summaries

    restore_malloc()
    chunk = task.chunk
    per = summaries(team, chunk.size, task.overrides, task.seeds, accelerate=task.accelerate)
    runs = np.arange(chunk.start, chunk.stop)
    cols: dict[str, list[Any]] = {
        "run": runs.tolist(),
        "setting": list(task.settings),
        "member": list(task.members),
        "repetition": list(task.repetitions),
        "seed": list(task.seeds),
        "outcome": [p["outcome"] for p in per],
        "t_end": [float(p["t_end"]) for p in per],
    }
    for key in task.metrics:
        cols[f"metric_{key}"] = [metric_value(p.get(key)) for p in per]
    cols.update(requirement_columns(per))
    return cols


def requirement_columns(per: list[dict[str, Any]]) -> dict[str, list[float]]:
    """``req_<name>_ok`` (1 where the requirement held) and ``req_<name>_rho`` (its
    robustness) per run, for the team's requirements."""
    from hybridteam.requirements.report import robustness_value

    cols: dict[str, list[float]] = {}
    for name in (per[0].get("requirements") or {}) if per else ():
        cols[f"req_{name}_ok"] = [float(p["requirements"][name]["satisfied"]) for p in per]
        cols[f"req_{name}_rho"] = [robustness_value(p["requirements"][name]["robustness"])
                                   for p in per]
    return cols


def metric_value(value: Any) -> float:
    """A per-instance summary value as one number: lists (one entry per robot, say) are
    averaged over their elements; missing or non-numeric values are NaN."""
    if isinstance(value, list | tuple | np.ndarray):
        items = [metric_value(v) for v in value]
        items = [v for v in items if not math.isnan(v)]
        return math.fsum(items) / len(items) if items else math.nan
    if isinstance(value, bool | int | float | np.integer | np.floating):
        return float(value)
    return math.nan
