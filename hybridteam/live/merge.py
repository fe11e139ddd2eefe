"""One team trace from the traces of a live team's processes (``hybridteam launch``, and
``hybridteam merge`` for the folders of processes started by hand or on other machines).

Each process records on its own clock: run time 0 is its start, ``meta.live.wall_start``
on its wall clock. The merged trace puts every row on one clock, run time 0 where the
process that started first started: a process that started ``d`` wall seconds later has
its times (transitions, mode intervals, the messages it received, its outcome) moved by
``K d`` run seconds, and its agents' samples read at the common sample times by linear
interpolation (NaN outside what it recorded); ``meta.live.offsets`` says what each move
was. The processes of one machine read one wall clock, so their starts give ``d`` exactly
to its resolution; across machines the clocks differ, and ``d`` takes the estimate of that
difference from the messages (*Aligning clocks* below). Each agent's modes and samples
come from the process that hosts it.

The merged outcome is the team's end as its processes saw it: the end rule's hosts each
ended (by the rule, or otherwise: the first such outcome in agent order is the team's),
at the latest of their ends; every process's own outcome is in the message. Each process
records the rule's agents (``meta.live.ending``), so a merge needs no team file.

Traces are read back from files anyone may have edited: :func:`process_problem` checks
what the merge reads of a process's ``meta.live`` before anything is merged.

**Aligning clocks** (``align``). ``"wall"`` takes every process's wall clock for one
clock: exact when they ran on one machine (``launch``). ``"messages"`` (``hybridteam
merge``: processes on several machines) estimates each clock's offset from the messages.

Process ``k``'s clock reads true time ``T`` as ``T + c_k``; it started at true ``S_k``, which
it recorded as ``s_k = S_k + c_k`` (``wall_start``); ``K_k`` is its time scale. A row it
records at ``T`` has run time ``K_k (T - S_k)`` (its monotonic clock since its start), and
a copy from process ``p`` it records with ``t_send = K_k (T_s + c_p - s_k)`` (the sender's
wall clock at the send, converted with this process's start) and ``t_recv = K_k (T_r -
S_k)``. Take a reference process ``r`` and ``d_k = c_k - c_r``: on ``r``'s clock ``k``
started at ``s_k - d_k``, the merged origin is ``w0 = min_k (s_k - d_k)`` (``wall_start``
of the merged trace) and the merged time of ``T`` is ``K (T + c_r - w0)``. Then

* a row of process ``q`` moves by ``K_q (s_q - d_q - w0)`` (``offsets``):
  ``K_q (T - S_q) + K_q (s_q - d_q - w0) = K_q (T + c_r - w0)``;
* a copy's ``t_send`` in ``q``'s trace, sent by ``p``, moves by ``K_q (s_q - d_p - w0)``,
  i.e. ``q``'s offset plus ``K_q (d_q - d_p)``: ``K_q (T_s + c_p - s_q) + K_q (s_q - d_p
  - w0) = K_q (T_s + c_r - w0)``.

``"wall"`` takes every ``d_k = 0``. ``"messages"`` estimates them. For a copy from ``p``
to ``q``, ``(t_recv - t_send) / K_q = L + c_q - c_p`` with a latency ``L >= 0``: the least
such difference each way bounds ``c_q - c_p`` to ``[lo, hi]`` (:func:`clock_bounds`;
``hi = L_pq + c_q - c_p``, ``lo = c_q - c_p - L_qp`` for the two least latencies). Its
midpoint ``c_q - c_p + (L_pq - L_qp) / 2`` is the estimate (exact when those two
latencies are equal: the symmetric-latency assumption), and its half-width ``(L_pq +
L_qp) / 2`` bounds the estimate's error, whatever the latencies. A process linked to the
reference only through others takes the path over pairs bounded both ways whose summed
half-widths are least (Dijkstra's shortest path): its ``d_k`` is the sum of the midpoints
along it, its error bound the sum of the half-widths. The reference is the process that
reaches the most others so (the first such, in the order given). A process with no such
path keeps ``d_k = 0`` (its wall clock taken for the reference's) and its error is unknown
(None). A pair whose bounds contradict each other (``lo > hi``: a clock stepped or drifted
during the run) links nothing. ``"wall"`` records every error as 0 (one clock, its
assumption). A process's rows are then within ``K e_q``
run seconds of where the reference's clock puts them (``e_q``: its error bound), two
processes' rows within ``K (e_p + e_q)`` of each other; the origin's own error moves every
row alike.
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Sequence

import numpy as np

from hybridteam.trace import Table, Trace

#: Outcomes a process has when something else than its own run decided its end.
STOPPED = "stopped"

#: How the merge aligns the processes' clocks (module docstring): one machine's wall
#: clock, or offsets estimated from the messages.
ALIGNMENTS = ("wall", "messages")


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
        if (
            isinstance(value, bool)
            or not isinstance(value, int | float)
            or not least < value < math.inf
        ):
            return f"meta.live.{key} is not a finite number" + (" > 0" if least == 0 else "")
    ending = live.get("ending", [])
    if not (isinstance(ending, list) and all(a in names for a in ending)):
        return "meta.live.ending is not a list of the team's agents"
    return None


def merge_traces(traces: Sequence[Trace], ending: Sequence[str] = (), align: str = "wall") -> Trace:
    """The team trace of one live run's process traces; ``ending``: the agents of the
    team's end rule (their processes' outcomes make the team's); ``align``: how their
    clocks are aligned (one of :data:`ALIGNMENTS`; module docstring)."""
    if align not in ALIGNMENTS:
        raise ValueError(f"align must be one of {ALIGNMENTS}, got {align!r}")
    if not traces:
        raise MergeError("no trace to merge")
    first = traces[0]
    names = first.agents
    for tr in traces:
        problem = process_problem(tr)
        if problem is not None:
            raise MergeError(problem)
    for tr in traces:
        if (
            tr.agents != names
            or tr.meta["team"] != first.meta["team"]
            or tr.meta["live"]["digest"] != first.meta["live"]["digest"]
        ):
            raise MergeError("the traces are not the processes of one live team")
    hosts = [a for tr in traces for a in tr.meta["live"]["agents"]]
    if sorted(hosts) != sorted(set(hosts)):
        raise MergeError("an agent is hosted by two of the processes")
    if align == "messages":
        reference, clock, errors = aligned_clocks(traces)
    else:
        reference, clock, errors = 0, [0.0] * len(traces), [0.0] * len(traces)
    # (the starts, near 2e9 s, relative to the earliest before the clocks' offsets are
    # taken: their differences are exact, an offset's microseconds are not rounded away)
    earliest = min(tr.meta["live"]["wall_start"] for tr in traces)
    starts = [
        tr.meta["live"]["wall_start"] - earliest - d for tr, d in zip(traces, clock, strict=True)
    ]
    origin = min(starts)
    wall0 = earliest + origin
    scales = [tr.meta["live"]["time_scale"] for tr in traces]
    offsets = [(start - origin) * k for start, k in zip(starts, scales, strict=True)]
    times = first.sample_times
    # (the world's series are the world process's: the agents' processes have none)
    world = next((tr for tr in traces if tr.meta["live"].get("world")), None)
    samples = {
        k: np.full((times.size, *v.shape[1:]), np.nan)
        for tr in traces
        for k, v in tr.samples.items()
    }
    for tr, off in zip(traces, offsets, strict=True):
        for key, values in tr.samples.items():
            if key.split("#")[0] in tr.meta["live"]["agents"] or (
                tr is world and key.split("#")[0] not in names
            ):
                samples[key] = _resampled(tr.sample_times + off, values, times)
    transitions = _concat(
        [_shift(tr.transitions, off, ("t",)) for tr, off in zip(traces, offsets, strict=True)], "t"
    )
    outcome = _outcome(traces, offsets, names, ending)
    intervals = _concat(
        [
            _held(_shift(tr.intervals, off, ("start", "end")), tr.outcomes[0], off, outcome["t"])
            for tr, off in zip(traces, offsets, strict=True)
        ],
        "start",
    )
    # a copy's send time was read on its sender's clock: moved by the sender's offset
    clock_of = {
        a: d for tr, d in zip(traces, clock, strict=True) for a in tr.meta["live"]["agents"]
    }
    messages = _concat(
        [
            _shift_messages(tr.messages, off, k * d, k, clock_of)
            for tr, off, d, k in zip(traces, offsets, clock, scales, strict=True)
        ],
        "t_recv",
    )
    meta = {k: v for k, v in (world or first).meta.items() if k != "live"}
    meta["live"] = {
        "processes": [tr.meta["live"] for tr in traces],
        "offsets": offsets,
        "wall_start": wall0,
        "clock_bounds": clock_bounds(traces),
        "align": align,
        "clock_reference": reference,
        "clock_offsets_s": clock,
        "clock_errors_s": errors,
    }
    return Trace(meta, [outcome], transitions, intervals, messages, times, samples)


def aligned_clocks(traces: Sequence[Trace]) -> tuple[int, list[float], list[float | None]]:
    """The reference process, and each process's clock offset from the reference's
    (wall seconds, its clock minus the reference's) with the bound of that estimate's
    error, as the messages show (module docstring): None where no path of pairs bounded
    both ways links it to the reference (its offset is then 0, its wall clock's)."""
    n = len(traces)
    edges: dict[int, list[tuple[int, float, float]]] = {k: [] for k in range(n)}
    for (p, q), (lo, hi) in _pair_bounds(traces).items():
        if lo is not None and hi is not None and lo <= hi:
            mid, half = (lo + hi) / 2, (hi - lo) / 2
            edges[p].append((q, mid, half))
            edges[q].append((p, -mid, half))
    paths = [_tightest_paths(edges, k) for k in range(n)]
    reference = max(range(n), key=lambda k: (len(paths[k]), -k))
    reached = paths[reference]
    return (
        reference,
        [reached[k][1] if k in reached else 0.0 for k in range(n)],
        [reached[k][0] if k in reached else None for k in range(n)],
    )


def _tightest_paths(
    edges: dict[int, list[tuple[int, float, float]]], start: int
) -> dict[int, tuple[float, float]]:
    """Every process reachable from ``start``: ``(error, offset)`` along the path whose
    summed half-widths (``error``) are least, ``offset`` its summed midpoints (Dijkstra;
    equal errors go to the lower process index: one answer for one input)."""
    done: dict[int, tuple[float, float]] = {}
    heap = [(0.0, start, 0.0)]
    while heap:
        error, k, offset = heapq.heappop(heap)
        if k in done:
            continue
        done[k] = (error, offset)
        for j, mid, half in edges[k]:
            if j not in done:
                heapq.heappush(heap, (error + half, j, offset + mid))
    return done


def clock_bounds(traces: Sequence[Trace]) -> list[dict]:
    """How far apart the processes' wall clocks can be, as their messages show.

    A copy from process ``p`` to ``q`` is recorded by ``q`` with its send time read on
    ``p``'s wall clock and its arrival on ``q``'s, so ``t_recv - t_send`` (over ``q``'s
    time scale) is the latency plus how far ``q``'s clock is ahead of ``p``'s. Latencies
    are not negative, so the least such difference bounds that lead from above, and the
    least one the other way bounds it from below. Per pair of processes that exchanged
    messages: ``offset_s`` = ``[lo, hi]`` (wall seconds, None where no message bounds it)
    for ``q``'s clock minus ``p``'s. ``"wall"`` alignment assumes 0 (one machine's clock);
    across machines these say by how much its times could be off, and ``"messages"``
    alignment estimates each offset from them (module docstring)."""
    return [
        {
            "from": traces[p].meta["live"]["agents"],
            "to": traces[q].meta["live"]["agents"],
            "offset_s": [lo, hi],
        }
        for (p, q), (lo, hi) in _pair_bounds(traces).items()
    ]


def _pair_bounds(
    traces: Sequence[Trace],
) -> dict[tuple[int, int], tuple[float | None, float | None]]:
    """:func:`clock_bounds` by process index: ``{(p, q): (lo, hi)}``, ``p < q``, in order."""
    host = {a: k for k, tr in enumerate(traces) for a in tr.meta["live"]["agents"]}
    least: dict[tuple[int, int], float] = {}
    for q, tr in enumerate(traces):
        m = tr.messages
        ok = m["status"] == "delivered"
        scale = tr.meta["live"]["time_scale"]
        for sender, d in zip(
            m["sender"][ok].tolist(), (m["t_recv"] - m["t_send"])[ok].tolist(), strict=True
        ):
            p = host.get(sender)
            if p is not None and p != q:
                least[(p, q)] = min(least.get((p, q), float("inf")), d / scale)
    out = {}
    for p, q in sorted({tuple(sorted(k)) for k in least}):
        hi, lo = least.get((p, q)), least.get((q, p))
        out[(p, q)] = (None if lo is None else -lo, hi)
    return out


def clock_error(bounds: Sequence[dict]) -> float | None:
    """The most two processes' merged times can be off, as :func:`clock_bounds` bounds
    their clocks: ``"wall"`` alignment takes them for one clock (offset 0), and a pair's offset lies
    in its ``offset_s``, so it is off by at most the larger end's size. The largest over
    the pairs bounded both ways; None if no pair is."""
    ends = [
        max(abs(lo), abs(hi))
        for lo, hi in (b["offset_s"] for b in bounds)
        if lo is not None and hi is not None
    ]
    return max(ends) if ends else None


def _held(intervals: Table, ended: dict, offset: float, end: float) -> Table:
    """A process's mode intervals, those still open at its own end held to the team's
    ``end`` where its run ended by the end rule (its agents in their final modes, which
    they never leave: the process stops recording, the agents stay), as a simulation's
    last intervals reach its end. A process stopped, or ended otherwise, keeps its own."""
    if ended["outcome"] != "ok" or not ended["t"] + offset < end:
        return intervals
    data = dict(intervals.columns)
    last: dict[tuple, int] = {}  # per agent and depth, the latest interval: the open one
    for k, key in enumerate(
        zip(data["instance"].tolist(), data["agent"].tolist(), data["depth"].tolist(), strict=True)
    ):
        if key not in last or data["start"][k] >= data["start"][last[key]]:
            last[key] = k
    open_ = np.zeros(len(data["end"]), bool)
    open_[list(last.values())] = True
    data["end"] = np.where(open_ & (data["end"] == ended["t"] + offset), end, data["end"])
    return Table(intervals.names, data)


def _shift(table: Table, offset: float, columns: tuple[str, ...]) -> Table:
    data = dict(table.columns)
    for c in columns:
        data[c] = data[c] + offset
    return Table(table.names, data)


def _shift_messages(
    table: Table, offset: float, own: float, scale: float, clock_of: dict[str, float]
) -> Table:
    """A process's message rows moved to the merged clock (module docstring): ``t_recv``
    by its ``offset``, ``t_send`` (its sender's clock) by ``offset`` plus its own clock's
    offset ``own`` (run seconds) minus the sender's (``clock_of``, wall seconds; 0 for a
    sender no merged process hosts, whose clock nothing tells)."""
    data = dict(table.columns)
    sender = np.array([clock_of.get(s, 0.0) for s in table["sender"].tolist()], float)
    data["t_send"] = data["t_send"] + offset + own - scale * sender
    data["t_recv"] = data["t_recv"] + offset
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


def _outcome(
    traces: Sequence[Trace], offsets: list[float], names: list[str], ending: Sequence[str]
) -> dict:
    ends = [
        (tr.outcomes[0], off, tr.meta["live"]["agents"])
        for tr, off in zip(traces, offsets, strict=True)
    ]
    deciding = [e for e in ends if set(e[2]) & set(ending)] or ends
    deciding.sort(key=lambda e: min((names.index(a) for a in e[2]), default=len(names)))
    kind = next((o["outcome"] for o, _, _ in deciding if o["outcome"] != "ok"), "ok")
    t = max(o["t"] + off for o, off, _ in deciding)
    parts = [
        f"{', '.join(agents) or 'the world'}: {o['outcome']} at t={o['t'] + off:.6g} "
        f"({o['message']})"
        for o, off, agents in ends
    ]
    return {"instance": 0, "outcome": kind, "t": t, "message": "; ".join(parts)}
