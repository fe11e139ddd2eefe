"""Per-run rows -> one row per setting: counts per outcome, success rate, metric means.

The columns are ``factor, value, <one per axis>, runs, <one count per outcome>,
success_rate, mean_<metric>...``. Outcome columns are those the study lists under
``outcomes:`` (always shown, in that order), then its ``success:`` outcomes, then any other
outcome seen — the engine's own (``ok, stuck, zeno, deadlock``) first, then library ones by
name — so columns do not depend on which chunk happened to see what. Means are over the
successful runs whose value is a number (NaN when there are none) and are summed with
``math.fsum``, which is exact before its one rounding: the table is bit for bit the same
whatever order runs arrive in.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hybridteam.export.render import markdown_text
from hybridteam.sweep.plan import Plan
from hybridteam.sweep.store import finished_chunks, read_chunk
from hybridteam.sweep.worker import RUN_COLUMNS
from hybridteam.trace import write_atomic

ENGINE_OUTCOMES = ("ok", "stuck", "zeno", "deadlock")


@dataclass
class ResultTable:
    """Rows as dicts over ``columns``; numbers stay numbers until written."""

    columns: list[str]
    rows: list[dict[str, Any]]

    def to_csv(self) -> str:
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(self.columns)
        for row in self.rows:
            w.writerow([_csv_cell(row[c]) for c in self.columns])
        return buf.getvalue()

    def to_markdown(self) -> str:
        lines = [
            "| " + " | ".join(_md_cell(c) for c in self.columns) + " |",
            "|"
            + "|".join("---" if c in ("factor", "value") else "---:" for c in self.columns)
            + "|",
        ]
        lines += [
            "| " + " | ".join(_md_cell(row[c]) for c in self.columns) + " |" for row in self.rows
        ]
        return "\n".join(lines) + "\n"


def _csv_cell(v: Any) -> str:
    if isinstance(v, float):
        return "nan" if math.isnan(v) else repr(v)
    return str(v)


def _md_cell(v: Any) -> str:
    """A cell of ``results.md``: its values come from a folder anyone may hand over (a
    factor's value, a column's name), so text is made inert (:func:`markdown_text`)."""
    if isinstance(v, float):
        return "–" if math.isnan(v) else f"{v:.4g}"
    return markdown_text(str(v))


def collect_runs(plan: Plan, out: Path) -> dict[str, list[Any]]:
    """Every finished chunk's rows, in run order (chunk files may have been written in any)."""
    files = finished_chunks(out)
    cols: dict[str, list[Any]] = {}
    for chunk in plan.chunks:  # plan order is run order
        if chunk.id not in files:
            continue
        part = read_chunk(files[chunk.id])
        for name, values in part.items():
            cols.setdefault(name, []).extend(values)
    return cols


def outcome_columns(plan: Plan, seen: list[str]) -> list[str]:
    study = plan.study
    ordered = list(dict.fromkeys([*study.outcomes, *study.success]))
    rest = sorted(
        set(seen) - set(ordered),
        key=lambda o: (
            ENGINE_OUTCOMES.index(o) if o in ENGINE_OUTCOMES else len(ENGINE_OUTCOMES),
            o,
        ),
    )
    return ordered + rest


def aggregate(plan: Plan, runs: dict[str, list[Any]]) -> ResultTable:
    """One row per setting of ``plan`` from per-run columns (``run``, ``outcome``,
    ``metric_<key>``...); settings without runs get ``runs = 0``."""
    study = plan.study
    outcomes = runs.get("outcome", [])
    names = outcome_columns(plan, list(dict.fromkeys(outcomes)))
    success = set(study.success)
    by_setting: dict[int, list[int]] = {}
    for j, r in enumerate(runs.get("run", [])):
        by_setting.setdefault(int(plan.setting_of(r)), []).append(j)
    axes = [a.name for a in study.axes]
    metrics = list(study.metrics)
    reqs = requirement_names(runs)
    columns = [
        "factor",
        "value",
        *axes,
        "runs",
        *names,
        "success_rate",
        *[f"mean_{m}" for m in metrics],
        *[c for r in reqs for c in (f"{r}_satisfied", f"{r}_min_robustness")],
    ]
    rows = []
    for s in plan.settings:
        mine = by_setting.get(s.index, [])
        row: dict[str, Any] = {"factor": s.factor, "value": s.label}
        row.update({name: _number(v) for name, v in s.axes})
        row["runs"] = len(mine)
        for name in names:
            row[name] = sum(1 for j in mine if outcomes[j] == name)
        good = [j for j in mine if outcomes[j] in success]
        row["success_rate"] = len(good) / len(mine) if mine else math.nan
        for m in metrics:
            values = [float(runs[f"metric_{m}"][j]) for j in good]
            values = [v for v in values if not math.isnan(v)]
            row[f"mean_{m}"] = math.fsum(values) / len(values) if values else math.nan
        for r in reqs:  # over every run of the setting, successful or not
            ok = [runs[f"req_{r}_ok"][j] for j in mine]
            rho = [runs[f"req_{r}_rho"][j] for j in mine]
            row[f"{r}_satisfied"] = math.fsum(ok) / len(ok) if ok else math.nan
            row[f"{r}_min_robustness"] = min(rho) if rho else math.nan
        rows.append(row)
    return ResultTable(columns, rows)


def requirement_names(runs: dict[str, list[Any]]) -> list[str]:
    """The requirements whose verdicts the runs carry (``req_<name>_ok`` columns)."""
    return [c[4:-3] for c in runs if c.startswith("req_") and c.endswith("_ok")]


def _number(v: float) -> int | float:
    """Axis values as written: ``240``, not ``240.0``."""
    return int(v) if float(v).is_integer() and abs(v) < 1e15 else v


def run_table(plan: Plan, runs: dict[str, list[Any]]) -> ResultTable:
    """Per-run rows with their setting spelt out (``runs.csv``), for analyses of one's own."""
    study = plan.study
    axes = [a.name for a in study.axes]
    metrics = [f"metric_{m}" for m in study.metrics]
    columns = ["run", "factor", "value", *axes, "member", "repetition", "seed", "outcome", "t_end"]
    names = {
        m: m if m.removeprefix("metric_") in columns else m.removeprefix("metric_") for m in metrics
    }  # a metric named like a column (t_end) keeps its prefix
    columns += list(names.values())
    reqs = [c for r in requirement_names(runs) for c in (f"req_{r}_ok", f"req_{r}_rho")]
    columns += reqs
    rows = []
    for j, r in enumerate(runs.get("run", [])):
        s = plan.settings[int(plan.setting_of(r))]
        row: dict[str, Any] = {"run": r, "factor": s.factor, "value": s.label}
        row.update({name: _number(v) for name, v in s.axes})
        row.update({c: runs[c][j] for c in RUN_COLUMNS[2:]})
        row.update({names[m]: float(runs[m][j]) for m in metrics})
        row.update({c: float(runs[c][j]) for c in reqs})
        rows.append(row)
    return ResultTable(columns, rows)


def write_results(out: Path, table: ResultTable, runs: ResultTable | None = None) -> None:
    """``results.csv`` and ``results.md`` (and ``runs.csv``), each written atomically."""
    if runs is not None:
        write_atomic(out / "runs.csv", runs.to_csv())
    write_atomic(out / "results.md", table.to_markdown())
    write_atomic(out / "results.csv", table.to_csv())


def read_results(path: Path) -> ResultTable:
    """``results.csv`` back as a table (numbers parsed where they parse), for reports."""
    with Path(path).open(encoding="utf-8", newline="") as f:
        rows = list(csv.reader(f))
    if not rows:
        raise ValueError("empty file")
    columns = rows[0]
    missing = [c for c in ("factor", "value", "runs", "success_rate") if c not in columns]
    if missing:  # a results.csv of ours always has them; the report reads them
        raise ValueError(f"no '{missing[0]}' column: not a study's results")
    out = []
    for cells in rows[1:]:
        if len(cells) != len(columns):
            raise ValueError(f"a row has {len(cells)} cells, the header {len(columns)}")
        row: dict[str, Any] = {}
        for c, cell in zip(columns, cells, strict=True):
            row[c] = cell if c in ("factor", "value") else _parse(cell)
        out.append(row)
    return ResultTable(columns, out)


def _parse(cell: str) -> Any:
    try:
        return int(cell)
    except ValueError:
        pass
    try:
        return float(cell)
    except ValueError:
        return cell
