"""A run's tables as pandas DataFrames (pandas is an optional extra: ``hybridteam[pandas]``).

What a researcher does next with a run is usually pandas: group transitions by agent, join
message latencies, plot a state against time. These functions give the trace's tables as
frames with the trace's own column names, and the samples *tidy* — one row per instance,
time, series (an agent or a world series such as a payload) and variable — or *wide*, one
row per instance and time with a column per ``series.variable``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    import pandas as pd

    from hybridteam.trace import Table, Trace


def pandas():
    """The pandas module, or an ImportError saying how to install it."""
    try:
        import pandas as pd
    except ImportError:
        raise ImportError("this needs pandas: pip install 'hybridteam[pandas]'") from None
    return pd


def table_frame(table: Table) -> pd.DataFrame:
    return table.to_pandas()


def samples_frame(trace: Trace, wide: bool = False) -> pd.DataFrame:
    """The sampled states (and world series), tidy or wide; times with no sample of an
    instance (it ended earlier) are left out."""
    pd = pandas()
    series = [(a, trace.state_names(a)) for a in trace.agents]
    series += [(name, list(cols)) for name, cols in trace.meta.get("series", {}).items()]
    k, n = len(trace.sample_times), trace.n
    parts: list[dict[str, Any]] = []
    for name, cols in series:
        values = trace.samples[name]  # (K, n, d)
        for j, var in enumerate(cols):
            parts.append(
                {
                    "instance": np.tile(np.arange(n), k),
                    "t": np.repeat(trace.sample_times, n),
                    "series": name,
                    "variable": var,
                    "value": values[:, :, j].reshape(-1),
                }
            )
    if not parts:
        return pd.DataFrame(columns=["instance", "t", "series", "variable", "value"])
    tidy = pd.concat([pd.DataFrame(p) for p in parts], ignore_index=True)
    tidy = tidy[~tidy["value"].isna()].reset_index(drop=True)
    if not wide:
        return tidy
    tidy["column"] = tidy["series"] + "." + tidy["variable"]
    out = tidy.pivot_table(index=["instance", "t"], columns="column", values="value", sort=False)
    out.columns.name = None
    return out.reset_index()


def run_frames(trace: Trace) -> dict[str, pd.DataFrame]:
    """Every table of a run: ``modes`` (time in each mode), ``transitions``, ``messages``,
    ``samples`` (tidy) and ``outcomes`` (one row per instance)."""
    pd = pandas()
    records = getattr(trace, "diagnostics", trace.outcomes)  # a Run's outcomes are names
    outcomes = pd.DataFrame(
        [
            {
                "instance": o["instance"],
                "outcome": o["outcome"],
                "t_end": o["t"],
                "message": o["message"],
                **o.get("stats", {}),
            }
            for o in records
        ]
    )
    return {
        "modes": table_frame(trace.intervals),
        "transitions": table_frame(trace.transitions),
        "messages": table_frame(trace.messages),
        "samples": samples_frame(trace),
        "outcomes": outcomes,
    }
