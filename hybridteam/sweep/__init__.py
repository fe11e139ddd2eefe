"""Parameter studies: a base team run over a random population, factors and axes.

Modules, one job each: :mod:`.schema` (the study file's shape), :mod:`.study` (loading and
checking it against the team), :mod:`.plan` (runs, seeds, chunks), :mod:`.worker` (one
chunk as one ensemble), :mod:`.store` (the output folder), :mod:`.run` (executors,
progress, resuming), :mod:`.table` (the per-setting table), :mod:`.report` (plots and the
Markdown report), :mod:`.cli` (``hybridteam sweep`` and ``hybridteam report``).

>>> from hybridteam.sweep import load_study, run_study
>>> result = run_study(load_study("study.yaml"), "out/study", workers=2)

Names are imported on first use, so the command line stays quick to start.
"""

from __future__ import annotations

from typing import Any

_EXPORTS = {
    "load_study": "hybridteam.sweep.study",
    "restrict": "hybridteam.sweep.study",
    "Study": "hybridteam.sweep.study",
    "Plan": "hybridteam.sweep.plan",
    "run_study": "hybridteam.sweep.run",
    "StudyError": "hybridteam.sweep.store",
    "aggregate": "hybridteam.sweep.table",
    "write_report": "hybridteam.sweep.report",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    if name in _EXPORTS:
        import importlib

        return getattr(importlib.import_module(_EXPORTS[name]), name)
    raise AttributeError(f"module 'hybridteam.sweep' has no attribute {name!r}")
