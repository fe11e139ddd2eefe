"""What a run will cost, checked before anything is allocated: memory and control periods.

A tiny ``sample_period``, a duration of ``1e12`` s or ``-n 1000000000`` asks for more memory
than the machine has, or for more control periods than anyone will wait for; without a
check the run allocates tens of GiB and dies, or silently computes for days. The estimate
is deliberately simple — output samples and per-instance arrays for memory, the fastest
sampled law or ``inputs:`` for control periods — and the error says what drives it and
how to lower it, or how to raise the limit.

Limits: ``max_memory`` bytes (default 4 GB, ``--max-memory`` on the command line,
``HYBRIDTEAM_MAX_MEMORY_GB``), ``max_periods`` control periods per instance (default
``1e8``, ``--max-periods``).

What no estimate can tell in advance — how many events a flow will produce — is watched
while the run goes (:class:`Pace`): once it has run a few seconds, a run whose pace says it
would need more than ``max_wall`` (default 24 h, ``--max-wall``) stops with the projection,
instead of computing for days. Whether a run stops this way depends on the machine, but a
run that finishes is the same run bit for bit.
"""

from __future__ import annotations

import math
import os
import time

from hybridteam.engine.compile.compiled import CTeam
from hybridteam.engine.compile.protocols import stream_fields

DEFAULT_MAX_MEMORY = 4e9
DEFAULT_MAX_PERIODS = 1e8
DEFAULT_MAX_WALL = 24 * 3600.0
#: wall seconds a run goes before its pace is judged (a slow start is not a slow run)
GRACE = 2.0


class ResourceError(ValueError):
    """A run that would exceed a resource limit; the message says by how much and why."""


def _size(nbytes: float) -> str:
    for unit, scale in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6)):
        if nbytes >= scale:
            return f"{nbytes / scale:.3g} {unit}"
    return f"{nbytes / 1e3:.3g} kB"


def memory_limit(max_memory: float | None = None) -> float:
    """The memory limit in bytes: ``max_memory`` if given, else ``HYBRIDTEAM_MAX_MEMORY_GB``,
    else the default (4 GB)."""
    if max_memory is not None:
        return max_memory
    env = os.environ.get("HYBRIDTEAM_MAX_MEMORY_GB")
    if not env:
        return DEFAULT_MAX_MEMORY
    try:
        limit = float(env)
    except ValueError:
        limit = math.nan
    if not 0 < limit < math.inf:  # a typo must not become no limit, nor a traceback
        raise ResourceError(f"HYBRIDTEAM_MAX_MEMORY_GB={env!r} must be a number of gigabytes > 0")
    return limit * 1e9


def resident_bytes() -> float | None:
    """This process's resident memory in bytes, where the system tells it (Linux's
    ``/proc``; None elsewhere): what a search that grows as it goes is bounded by."""
    try:
        with open("/proc/self/statm") as f:
            pages = int(f.read().split()[1])
    except (OSError, ValueError, IndexError):
        return None
    return float(pages * os.sysconf("SC_PAGE_SIZE"))


#: bytes the trace's writers hold per output row (one sample time of one instance) while
#: ``trace.json`` and ``samples.csv`` are written, and per value in the row: the rows are
#: Python lists of floats and their text (measured: 478, 667 and 939 bytes for rows of 1,
#: 3 and 6 values, written with ``samples.csv``, which costs more than ``trace.json``)
WRITE_ROW_BYTES, WRITE_VALUE_BYTES = 400, 100


def memory_estimate(
    cteam: CTeam, n: int, t_end: float, dt: float, written: bool = False
) -> tuple[float, float]:
    """``(bytes, samples)``: memory of a run (the sampled trace dominates; per-instance
    arrays of every agent and mode count too, each agent's ring of its last
    ``zeno.max_transitions`` transition times, and each agent's stream inbox, which holds
    a copy per sender: agents squared, what a team of hundreds pays) and its number of
    output samples. With ``written``, the writing of the trace's files counts too
    (``hybridteam run``)."""
    samples = math.floor(t_end / dt + 1e-9) + 2
    values = sum(len(ca.plant.state_names) for ca in cteam.agents) + 3 * len(cteam.team.world)
    ring = cteam.team.simulation.zeno.max_transitions
    per_instance = _inbox_values(cteam)
    for ca in cteam.agents:
        m = len(ca.modes)
        per_instance += (
            len(ca.plant.state_names) * 2
            + len(ca.plant.input_names)
            + len(ca.var_index)
            + len(ca.param_index)
            + 4 * m
            + len(ca.after)
            + 2 * len(ca.watches)
            + 40
            + ring
        )
    nbytes = 8.0 * n * (samples * values + per_instance)
    if written:
        nbytes += n * samples * (WRITE_ROW_BYTES + WRITE_VALUE_BYTES * values)
    return nbytes, float(samples)


def instances_within(
    cteam: CTeam, wanted: int, max_memory: float, what: str, share: float = 1.0
) -> int:
    """How many instances of ``cteam`` (at most ``wanted``) fit in ``share`` of
    ``max_memory`` bytes, by :func:`memory_estimate` of a zero-length run; ResourceError,
    naming ``what`` needs them, if not even one does. A search that loads its candidates
    into an ensemble (``verify``'s batches) takes fewer at a time instead of allocating
    what it cannot hold."""
    one = memory_estimate(cteam, 1, 0.0, 1.0)[0]
    room = share * max_memory
    if one > room:
        part = "" if share == 1.0 else f"{share:.0%} of "
        raise ResourceError(
            f"{what} would need about {_size(one)} of memory for the engine's arrays of a "
            f"single instance of this team ({len(cteam.agents):,} agents; stream inboxes "
            f"grow with the square of the agents), more than {part}the limit of "
            f"{_size(max_memory)}: raise the limit (--max-memory GB)"
        )
    return max(1, min(wanted, int(room // one)))


def _inbox_values(cteam: CTeam) -> int:
    """Numbers per instance in the agents' stream inboxes (:class:`~.streams.Inbox`): per
    receiving agent, per stream type and sender, its fields and the send time."""
    k = len(cteam.agents)  # (no streams declared: no inbox, an empty sum)
    return k * k * sum(len(fs) + 1 for fs in stream_fields(cteam.team).values())


def _fastest_period(cteam: CTeam) -> float:
    """The shortest control period of any sampled law or ``inputs:`` (inf if none)."""
    periods = [
        d.period for ca in cteam.agents for d in ca.drivers if d.kind == "sampled" and d.period > 0
    ]
    return min(periods, default=math.inf)


def check_budget(
    cteam: CTeam,
    n: int,
    t_end: float,
    dt: float,
    max_memory: float | None = None,
    max_periods: float | None = None,
    written: bool = False,
) -> None:
    """ResourceError if the run would need more memory or control periods than allowed
    (``written``: counting the writing of its trace, see :func:`memory_estimate`)."""
    max_memory = memory_limit(max_memory)
    if max_periods is None:
        max_periods = DEFAULT_MAX_PERIODS
    nbytes, samples = memory_estimate(cteam, n, t_end, dt, written)
    if nbytes > max_memory:
        ring = cteam.team.simulation.zeno.max_transitions
        if 8.0 * n * len(cteam.agents) * ring > nbytes / 2:  # the Zeno check's rings
            what = (
                f"{n:,} instance(s) of {len(cteam.agents):,} agent(s) remembering their "
                f"last {ring:,} transition times (simulation.zeno.max_transitions)"
            )
            lower = "lower simulation.zeno.max_transitions, shorten the ensemble"
        else:
            what = (
                f"{samples:,.0f} output samples of {n:,} instance(s), every {dt:g} s over "
                f"{t_end:g} s" + (", written as trace.json and samples.csv" if written else "")
            )
            lower = "raise simulation.sample_period, shorten the run or the ensemble"
        raise ResourceError(
            f"this run would need about {_size(nbytes)} of memory ({what}), more than the "
            f"limit of {_size(max_memory)}: {lower}, or raise the limit (--max-memory GB)"
        )
    fastest = _fastest_period(cteam)
    periods = t_end / fastest
    if periods > max_periods:
        raise ResourceError(
            f"this run would take about {periods:.3g} control periods per instance (a "
            f"{fastest:g} s law over {t_end:g} s), more than the limit of {max_periods:.3g}: "
            "shorten the run, or raise the limit (--max-periods N)"
        )


class Pace:
    """Projects a running simulation's wall time from its progress (see the module)."""

    def __init__(self, t_end: float, max_wall: float | None) -> None:
        self.t_end = t_end
        self.max_wall = DEFAULT_MAX_WALL if max_wall is None else max_wall
        self.start = time.perf_counter()

    def check(self, fraction: float) -> None:
        """ResourceError if, after the grace period, the projected wall time exceeds the
        limit; ``fraction`` is the share of the run the slowest live instance has done."""
        elapsed = time.perf_counter() - self.start
        if elapsed < GRACE:
            return
        projected = elapsed / fraction if fraction > 0 else math.inf
        if projected > self.max_wall:
            raise ResourceError(
                f"this run would take about {_duration(projected)} of wall time at its pace "
                f"({fraction:.2g} of {self.t_end:g} simulated seconds in {elapsed:.1f} s), "
                f"more than the limit of {_duration(self.max_wall)}: shorten the run, or "
                "raise the limit (--max-wall HOURS)"
            )


def _duration(seconds: float) -> str:
    if not math.isfinite(seconds):
        return "forever"
    for unit, scale in (
        ("years", 365.25 * 86400),
        ("days", 86400),
        ("hours", 3600),
        ("minutes", 60),
    ):
        if seconds >= scale:
            value = f"{seconds / scale:.3g}"
            return f"{value} {unit if value != '1' else unit[:-1]}"
    return f"{seconds:.3g} s"
