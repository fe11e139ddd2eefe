"""One chunk, run as one ensemble: the only code that executes on a worker.

Kept to a plain module-level function of picklable arguments (a team and a :class:`Task`)
so a process pool and a Dask cluster can ship it as is; it reads no files, so a remote
worker needs only ``hybridteam`` installed, not the study's folder.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from hybridteam.model import Team
from hybridteam.sweep.plan import Task
from hybridteam.sweep.tuning import profiler_paused, restore_malloc

#: Columns of a chunk's per-run rows, besides one ``metric_<key>`` column per metric.
RUN_COLUMNS = ("run", "setting", "member", "repetition", "seed", "outcome", "t_end")


def run_chunk(team: Team, task: Task) -> dict[str, list[Any]]:
    """Simulate a chunk's runs in one ensemble; one row per run, as columns.

    Through :func:`hybridteam.api.summaries`: per-instance summaries without a trace, and a
    mode library's batch simulator when it has one for this team (``task.accelerate``).
    """
    from hybridteam.api import summaries

    restore_malloc()
    chunk = task.chunk
    with profiler_paused():
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
        cols[f"req_{name}_rho"] = [
            robustness_value(p["requirements"][name]["robustness"]) for p in per
        ]
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
