"""What a run will cost, checked before anything is allocated: memory and control periods.

A tiny ``sample_period``, a duration of ``1e12`` s or ``-n 1000000000`` asks for more memory
than the machine has, or for more control periods than anyone will wait for; without a
check the run allocates tens of GiB and dies, or silently computes for days. The estimate
is deliberately simple — output samples and per-instance arrays for memory, the fastest
sampled law (or data stream) for control periods — and the error says what drives it and
how to lower it, or how to raise the limit.

Limits: ``max_memory`` bytes (default 4 GB, ``--max-memory`` on the command line,
``HYBRIDTEAM_MAX_MEMORY_GB``), ``max_periods`` control periods per instance (default
``1e8``, ``--max-periods``).
"""

from __future__ import annotations

import math
import os

from hybridteam.engine.compiled import CTeam

DEFAULT_MAX_MEMORY = 4e9
DEFAULT_MAX_PERIODS = 1e8


class ResourceError(ValueError):
    """A run that would exceed a resource limit; the message says by how much and why."""


def _size(nbytes: float) -> str:
    for unit, scale in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6)):
        if nbytes >= scale:
            return f"{nbytes / scale:.3g} {unit}"
    return f"{nbytes / 1e3:.3g} kB"


def memory_estimate(cteam: CTeam, n: int, t_end: float, dt: float) -> tuple[float, float]:
    """``(bytes, samples)``: memory of a run (the sampled trace dominates; per-instance
    arrays of every agent and mode count too) and its number of output samples."""
    samples = math.floor(t_end / dt + 1e-9) + 2
    values = sum(len(ca.plant.state_names) for ca in cteam.agents) + 3 * len(cteam.team.world)
    per_instance = 0
    for ca in cteam.agents:
        m = len(ca.modes)
        per_instance += (len(ca.plant.state_names) * 2 + len(ca.plant.input_names)
                         + len(ca.var_index) + len(ca.param_index) + 4 * m
                         + len(ca.after) + 2 * len(ca.watches) + 40)
    return 8.0 * n * (samples * values + per_instance), float(samples)


def _fastest_period(cteam: CTeam) -> float:
    """The shortest control period of any sampled law or ``inputs:`` (inf if none)."""
    periods = [d.period for ca in cteam.agents for d in ca.drivers
               if d.kind == "sampled" and d.period > 0]
    return min(periods, default=math.inf)


def check_budget(cteam: CTeam, n: int, t_end: float, dt: float,
                 max_memory: float | None = None, max_periods: float | None = None) -> None:
    """ResourceError if the run would need more memory or control periods than allowed."""
    if max_memory is None:
        env = os.environ.get("HYBRIDTEAM_MAX_MEMORY_GB")
        max_memory = float(env) * 1e9 if env else DEFAULT_MAX_MEMORY
    if max_periods is None:
        max_periods = DEFAULT_MAX_PERIODS
    nbytes, samples = memory_estimate(cteam, n, t_end, dt)
    if nbytes > max_memory:
        raise ResourceError(
            f"this run would need about {_size(nbytes)} of memory ({samples:,.0f} output "
            f"samples of {n:,} instance(s), every {dt:g} s over {t_end:g} s), more than the "
            f"limit of {_size(max_memory)}: raise simulation.sample_period, shorten the run "
            "or the ensemble, or raise the limit (--max-memory GB)")
    fastest = _fastest_period(cteam)
    periods = t_end / fastest
    if periods > max_periods:
        raise ResourceError(
            f"this run would take about {periods:.3g} control periods per instance (a "
            f"{fastest:g} s law over {t_end:g} s), more than the limit of {max_periods:.3g}: "
            "shorten the run, or raise the limit (--max-periods N)")
