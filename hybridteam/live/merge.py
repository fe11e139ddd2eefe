"""One team trace from the traces of a live team's processes (``hybridteam launch``, and
``hybridteam merge`` for the folders of processes started by hand or on other machines).

Each process records on its own clock: run time 0 is its start, ``meta.live.wall_start``
on the wall clock. The merged trace puts every row on the clock of the process that
started first: a process that started ``d`` wall seconds later has its times (transitions,
mode intervals, the messages it received, its outcome) moved by ``K d`` run seconds, and
its agents' samples read at the common sample times by linear interpolation (NaN outside
what it recorded). The processes of one machine read one wall clock, so the offsets are
exact to its resolution; ``meta.live.offsets`` says what each was. Each agent's modes and
samples come from the process that hosts it.

The merged outcome is the team's end as its processes saw it: the end rule's hosts each
ended (by the rule, or otherwise: the first such outcome in agent order is the team's),
at the latest of their ends; every process's own outcome is in the message. Each process
records the rule's agents (``meta.live.ending``), so a merge needs no team file.

Traces are read back from files anyone may have edited: :func:`process_problem` checks
what the merge reads of a process's ``meta.live`` before anything is merged.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from hybridteam.trace import Table, Trace

#: Outcomes a process has when something else than its own run decided its end.
STOPPED = "stopped"


class MergeError(ValueError):
    """Traces that are not the processes of one live run (one line)."""


def process_problem(trace: Trace) -> str | None:
    """Why ``trace`` (a checked trace file) is not one live process's, as the merge reads
    it: a single run with ``meta.live`` saying its agents, its team's digest, its
    wall-clock start and time scale. None if it is."""
    live = trace.meta.get("live")
    if trace.n != 1 or not isinstance(live, dict):
        return "not a live process's trace (no meta.live)"
    agents, names = live.get("agents"), trace.agents
    if not (isinstance(agents, list) and all(a in names for a in agents)):
        return "meta.live.agents is not a list of the team's agents"
    if not isinstance(live.get("digest"), str):
        return "meta.live.digest is not the team's digest"
    for key, least in (("wall_start", -math.inf), ("time_scale", 0.0)):
        value = live.get(key)
        if isinstance(value, bool) or not isinstance(value, int | float) or \
                not least < value < math.inf:
            return f"meta.live.{key} is not a finite number" + (" > 0" if least == 0 else "")
    ending = live.get("ending", [])
    if not (isinstance(ending, list) and all(a in names for a in ending)):
        return "meta.live.ending is not a list of the team's agents"
    return None


def merge_traces(traces: Sequence[Trace], ending: Sequence[str] = ()) -> Trace:
    """The team trace of one live run's process traces; ``ending``: the agents of the
    team's end rule (their processes' outcomes make the team's)."""
    if not traces:
        raise MergeError("no trace to merge")
    first = traces[0]
    names = first.agents
    for tr in traces:
        problem = process_problem(tr)
        if problem is not None:
            raise MergeError(problem)
    for tr in traces:
        if tr.agents != names or \
                tr.meta["team"] != first.meta["team"] or \
                tr.meta["live"]["digest"] != first.meta["live"]["digest"]:
            raise MergeError("the traces are not the processes of one live team")
    hosts = [a for tr in traces for a in tr.meta["live"]["agents"]]
    if sorted(hosts) != sorted(set(hosts)):
        raise MergeError("an agent is hosted by two of the processes")
    wall0 = min(tr.meta["live"]["wall_start"] for tr in traces)
    offsets = [(tr.meta["live"]["wall_start"] - wall0) * tr.meta["live"]["time_scale"]
               for tr in traces]
    times = first.sample_times
    # (the world's series are the world process's: the agents' processes have none)
    world = next((tr for tr in traces if tr.meta["live"].get("world")), None)
    samples = {k: np.full((times.size, *v.shape[1:]), np.nan)
               for tr in traces for k, v in tr.samples.items()}
    for tr, off in zip(traces, offsets, strict=True):
        for key, values in tr.samples.items():
            if key.split("#")[0] in tr.meta["live"]["agents"] or \
                    (tr is world and key.split("#")[0] not in names):
                samples[key] = _resampled(tr.sample_times + off, values, times)
    transitions = _concat([_shift(tr.transitions, off, ("t",))
                           for tr, off in zip(traces, offsets, strict=True)], "t")
    intervals = _concat([_shift(tr.intervals, off, ("start", "end"))
                         for tr, off in zip(traces, offsets, strict=True)], "start")
    messages = _concat([_shift(tr.messages, off, ("t_send", "t_recv"))
                        for tr, off in zip(traces, offsets, strict=True)], "t_recv")
    meta = {k: v for k, v in (world or first).meta.items() if k != "live"}
    meta["live"] = {"processes": [tr.meta["live"] for tr in traces], "offsets": offsets,
                    "wall_start": wall0, "clock_bounds": clock_bounds(traces)}
    return Trace(meta, [_outcome(traces, offsets, names, ending)], transitions, intervals,
                 messages, times, samples)


def clock_bounds(traces: Sequence[Trace]) -> list[dict]:
    """How far apart the processes' wall clocks can be, as their messages show.

    A copy from process ``p`` to ``q`` is recorded by ``q`` with its send time read on
    ``p``'s wall clock and its arrival on ``q``'s, so ``t_recv - t_send`` (over ``q``'s
    time scale) is the latency plus how far ``q``'s clock is ahead of ``p``'s. Latencies
    are not negative, so the least such difference bounds that lead from above, and the
    least one the other way bounds it from below. Per pair of processes that exchanged
    messages: ``offset_s`` = ``[lo, hi]`` (wall seconds, None where no message bounds it)
    for ``q``'s clock minus ``p``'s. The merge assumes 0 (one machine's clock); across
    machines these say by how much its times could be off."""
    host = {a: k for k, tr in enumerate(traces) for a in tr.meta["live"]["agents"]}
    least: dict[tuple[int, int], float] = {}
    for q, tr in enumerate(traces):
        m = tr.messages
        ok = m["status"] == "delivered"
        scale = tr.meta["live"]["time_scale"]
        for sender, d in zip(m["sender"][ok].tolist(), (m["t_recv"] - m["t_send"])[ok].tolist(),
                             strict=True):
            p = host.get(sender)
            if p is not None and p != q:
                least[(p, q)] = min(least.get((p, q), float("inf")), d / scale)
    out = []
    for p, q in sorted({tuple(sorted(k)) for k in least}):
        hi, lo = least.get((p, q)), least.get((q, p))
        out.append({"from": traces[p].meta["live"]["agents"],
                    "to": traces[q].meta["live"]["agents"],
                    "offset_s": [None if lo is None else -lo, hi]})
    return out


def clock_error(bounds: Sequence[dict]) -> float | None:
    """The most two processes' merged times can be off, as :func:`clock_bounds` bounds
    their clocks: the merge takes them for one clock (offset 0), and a pair's offset lies
    in its ``offset_s``, so it is off by at most the larger end's size. The largest over
    the pairs bounded both ways; None if no pair is."""
    ends = [max(abs(lo), abs(hi)) for lo, hi in (b["offset_s"] for b in bounds)
            if lo is not None and hi is not None]
    return max(ends) if ends else None


def _shift(table: Table, offset: float, columns: tuple[str, ...]) -> Table:
    data = dict(table.columns)
    for c in columns:
        data[c] = data[c] + offset
    return Table(table.names, data)


def _concat(tables: list[Table], by: str) -> Table:
    """The rows of every table, in time order (``by``; a stable sort keeps each process's
    own order of equal times)."""
    names = tables[0].names
    data = {n: np.concatenate([t.columns[n] for t in tables]) for n in names}
    order = np.argsort(np.nan_to_num(data[by], nan=np.inf), kind="stable")
    return Table(names, {n: c[order] for n, c in data.items()})


def _resampled(at: np.ndarray, values: np.ndarray, times: np.ndarray) -> np.ndarray:
    """``values`` (K, 1, d) recorded at ``at``, read at ``times`` (NaN outside ``at``)."""
    out = np.full((times.size, *values.shape[1:]), np.nan)
    for j in range(values.shape[2]):
        col = values[:, 0, j]
        ok = ~np.isnan(col)
        if ok.sum() >= 1:
            out[:, 0, j] = np.interp(times, at[ok], col[ok], left=np.nan, right=np.nan)
    return out


def _outcome(traces: Sequence[Trace], offsets: list[float], names: list[str],
             ending: Sequence[str]) -> dict:
    ends = [(tr.outcomes[0], off, tr.meta["live"]["agents"])
            for tr, off in zip(traces, offsets, strict=True)]
    deciding = [e for e in ends if set(e[2]) & set(ending)] or ends
    deciding.sort(key=lambda e: min((names.index(a) for a in e[2]), default=len(names)))
    kind = next((o["outcome"] for o, _, _ in deciding if o["outcome"] != "ok"), "ok")
    t = max(o["t"] + off for o, off, _ in deciding)
    parts = [f"{', '.join(agents) or 'the world'}: {o['outcome']} at "
             f"t={o['t'] + off:.6g} ({o['message']})"
             for o, off, agents in ends]
    return {"instance": 0, "outcome": kind, "t": t, "message": "; ".join(parts)}
