"""The record of a run: mode intervals, transitions with their cause, messages, samples.

Tables are column-oriented (numpy arrays and lists), because an ensemble run of a thousand
instances records hundreds of thousands of rows and users mostly filter and plot columns.
Iterating a table yields named rows for the occasional reader.

The JSON form is the reference format: floats are written with ``repr`` (shortest
round-trip digits), so ``load(save(trace))`` gives back the same numbers, bit for bit, and the
same model and seed give byte-identical files (nothing in it depends on wall time or paths).
"""

from __future__ import annotations

import csv
import functools
import io
import json
import math
import os
from collections import namedtuple
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

FORMAT = "hybridteam.trace"
VERSION = 1

TRANSITION_COLUMNS = ("instance", "agent", "t", "step", "source", "target", "cause", "guard")
INTERVAL_COLUMNS = ("instance", "agent", "mode", "depth", "start", "end")
MESSAGE_COLUMNS = (
    "instance",
    "seq",
    "sender",
    "receiver",
    "socket",
    "type",
    "t_send",
    "t_recv",
    "status",
    "reason",
    "msg_id",
)
_INT_COLUMNS = {"instance", "step", "depth", "seq", "msg_id"}
_FLOAT_COLUMNS = {"t", "start", "end", "t_send", "t_recv"}


@functools.lru_cache(maxsize=64)
def command_series(agent: str) -> str:
    """The trace series holding the commands an agent's plant was given (its inputs, held
    from one instant to the next): a robot log's ``Twist`` topic imported, or a live run's
    robot (``--plant ros2``). ``meta.series`` names its columns, the plant's inputs."""
    return f"{agent}.cmd"


def _row_type(names: tuple[str, ...]) -> type:
    """The row type of a table with these columns, made once: building a namedtuple
    class costs about 100 µs, a third of what a short run spends on its trace."""
    return namedtuple("Row", names)


class Table:
    """Named columns of equal length; ``table["t"]`` is a column, iteration yields rows."""

    def __init__(self, columns: Sequence[str], data: Mapping[str, Any] | None = None) -> None:
        self.names = tuple(columns)
        data = data or {}
        self.columns: dict[str, np.ndarray] = {}
        for name in self.names:
            values = data.get(name, [])
            if name in _INT_COLUMNS:
                self.columns[name] = np.asarray(values, dtype=np.int64).reshape(-1)
            elif name in _FLOAT_COLUMNS:
                self.columns[name] = np.asarray(values, dtype=float).reshape(-1)
            else:
                self.columns[name] = np.asarray(values, dtype=object).reshape(-1)
        lengths = {len(c) for c in self.columns.values()}
        if len(lengths) > 1:
            raise ValueError(f"columns of unequal length: {lengths}")
        self._row = _row_type(self.names)

    def __len__(self) -> int:
        return len(self.columns[self.names[0]]) if self.names else 0

    def __getitem__(self, name: str) -> np.ndarray:
        return self.columns[name]

    def __iter__(self) -> Iterator[Any]:
        cols = [self._plain(self.columns[n]) for n in self.names]
        for values in zip(*cols, strict=True):
            yield self._row(*values)

    def __repr__(self) -> str:
        return f"Table({len(self)} rows: {', '.join(self.names)})"

    def to_pandas(self):
        """The table as a pandas DataFrame (``pip install 'hybridteam[pandas]'``)."""
        try:
            import pandas as pd
        except ImportError:
            raise ImportError("this needs pandas: pip install 'hybridteam[pandas]'") from None
        return pd.DataFrame({name: self.columns[name] for name in self.names})

    @staticmethod
    def _plain(col: np.ndarray) -> list:
        return col.tolist()

    def filter(self, mask: np.ndarray) -> Table:
        return Table(self.names, {n: c[mask] for n, c in self.columns.items()})

    def where(self, **equal: Any) -> Table:
        """Rows whose columns equal the given values: ``run.transitions.where(agent="a")``."""
        mask = np.ones(len(self), bool)
        for name, value in equal.items():
            mask &= self.columns[name] == value
        return self.filter(mask)

    def to_json_dict(self) -> dict[str, list]:
        # NaN (a lost message's arrival time) is not JSON: null, read back as NaN
        return {
            n: _nan_to_none(c.tolist()) if c.dtype == float else c.tolist()
            for n, c in self.columns.items()
        }

    def to_csv(self) -> str:
        out = io.StringIO()
        writer = csv.writer(out, lineterminator="\n")
        writer.writerow(self.names)
        for row in self:
            writer.writerow([repr(v) if isinstance(v, float) else v for v in row])
        return out.getvalue()


def _nan_to_none(values: Any) -> Any:
    if isinstance(values, list):
        return [_nan_to_none(v) for v in values]
    if isinstance(values, float) and math.isnan(values):
        return None
    return values


def _sample_list(values: np.ndarray) -> list:
    """Samples as nested lists, NaN (no sample) as None; without NaN, numpy's own fast
    ``tolist`` (a large team's trace is millions of values)."""
    if not np.isnan(values).any():
        return values.tolist()
    out = values.astype(object)
    out[np.isnan(values)] = None
    return out.tolist()


def _none_to_nan(values: Any) -> Any:
    if isinstance(values, list):
        return [_none_to_nan(v) for v in values]
    return math.nan if values is None else values


class Trace:
    """Everything a run recorded, for ``n`` instances of one team."""

    def __init__(
        self,
        meta: dict[str, Any],
        outcomes: list[dict[str, Any]],
        transitions: Table,
        intervals: Table,
        messages: Table,
        sample_times: np.ndarray,
        samples: dict[str, np.ndarray],
    ) -> None:
        self.meta = meta
        self.outcomes = outcomes
        self.transitions = transitions
        self.intervals = intervals
        self.messages = messages
        self.sample_times = sample_times
        self.samples = samples  # agent -> (K, n, d)

    # ------------------------------------------------------------------ summaries
    @property
    def n(self) -> int:
        return int(self.meta["n"])

    @property
    def agents(self) -> list[str]:
        return [a["name"] for a in self.meta["agents"]]

    def state_names(self, agent: str) -> list[str]:
        for a in self.meta["agents"]:
            if a["name"] == agent:
                return list(a["state"])
        raise KeyError(agent)

    # ------------------------------------------------------------------ JSON
    def to_dict(self) -> dict[str, Any]:
        return {
            "format": FORMAT,
            "version": VERSION,
            "meta": self.meta,
            "outcomes": self.outcomes,
            "transitions": self.transitions.to_json_dict(),
            "intervals": self.intervals.to_json_dict(),
            "messages": self.messages.to_json_dict(),
            "samples": {
                "t": self.sample_times.tolist(),
                "agents": {a: _sample_list(s) for a, s in self.samples.items()},
            },
        }

    def to_json(self, path: str | os.PathLike | None = None) -> str:
        """The trace as JSON text; also written (atomically) to ``path`` when given."""
        text = json.dumps(self.to_dict(), allow_nan=False, separators=(",", ":"))
        if path is not None:
            write_atomic(Path(path), text)
        return text

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Trace:
        if data.get("format") != FORMAT:
            raise ValueError("not a hybridteam trace (missing format marker)")
        if data.get("version") != VERSION:
            raise ValueError(f"trace version {data.get('version')} is not supported")
        samples = {
            a: np.asarray(_none_to_nan(v), dtype=float)
            for a, v in data["samples"]["agents"].items()
        }
        return cls(
            data["meta"],
            data["outcomes"],
            Table(TRANSITION_COLUMNS, data["transitions"]),
            Table(INTERVAL_COLUMNS, data["intervals"]),
            Table(MESSAGE_COLUMNS, data["messages"]),
            np.asarray(data["samples"]["t"], dtype=float),
            samples,
        )

    @classmethod
    def load(cls, path: str | os.PathLike) -> Trace:
        with open(path, encoding="utf-8") as fh:
            return cls.from_dict(json.load(fh))

    # ------------------------------------------------------------------ CSV
    def samples_table(self) -> tuple[list[str], list[list[Any]]]:
        """Samples of agents' states and of world series (a payload's pose), one row per
        time and instance; rows with a missing value are left out."""
        header = ["t", "instance"]
        series = [(a, self.state_names(a)) for a in self.agents]
        series += [(name, list(cols)) for name, cols in self.meta.get("series", {}).items()]
        for name, cols in series:
            header += [f"{name}.{s}" for s in cols]
        rows = []
        for k, tk in enumerate(self.sample_times.tolist()):
            for i in range(self.n):
                row: list[Any] = [tk, i]
                for name, _cols in series:
                    row += self.samples[name][k, i].tolist()
                if not any(isinstance(v, float) and math.isnan(v) for v in row[2:]):
                    rows.append(row)
        return header, rows

    def write_csv(self, folder: str | os.PathLike) -> list[Path]:
        """``modes.csv``, ``transitions.csv``, ``messages.csv`` and ``samples.csv``."""
        folder = Path(folder)
        written = []
        for name, table in (
            ("modes", self.intervals),
            ("transitions", self.transitions),
            ("messages", self.messages),
        ):
            written.append(write_atomic(folder / f"{name}.csv", table.to_csv()))
        header, rows = self.samples_table()
        out = io.StringIO()
        writer = csv.writer(out, lineterminator="\n")
        writer.writerow(header)
        writer.writerows([[repr(v) if isinstance(v, float) else v for v in r] for r in rows])
        written.append(write_atomic(folder / "samples.csv", out.getvalue()))
        return written


def temp_path(path: Path) -> Path:
    """A hidden name beside ``path`` keeping its extension (writers pick formats by it)."""
    return path.with_name(f".{path.stem}.tmp-{os.getpid()}{path.suffix}")


def write_atomic(path: Path, content: str | bytes) -> Path:
    """Write to a temporary name beside ``path``, then rename: never a half-written file."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = temp_path(path)
    try:
        if isinstance(content, str):
            tmp.write_text(content, encoding="utf-8")
        else:
            tmp.write_bytes(content)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    return path
