"""A finished study's report: success rate against each factor, and ``report.md``.

Reads only the output folder (``study.json`` and ``results.csv``), so a report can be
redrawn from results copied off a cluster without the study or team files. One plot per
factor: success rate against the factor's values, one line per value of the first axis
(per combination of the axes when there are several), so the paper's "success against α,
one line per ladder length" is a single call. Factors whose values are not numbers (a
value per key, like ``(1.5, 0.5)``) are drawn at evenly spaced positions with their labels.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

from hybridteam.export.render import markdown_text
from hybridteam.sweep.store import FORMAT, StudyError
from hybridteam.sweep.table import ResultTable, read_results
from hybridteam.trace import write_atomic


def load_results(out: Path) -> tuple[dict[str, Any], ResultTable]:
    """The study record and its table; :class:`StudyError` if the study is not finished."""
    record_path, table_path = out / "study.json", out / "results.csv"
    if not record_path.is_file():
        raise StudyError(f"{out}: no study.json here; give the output folder of 'hybridteam sweep'")
    try:
        record = json.loads(record_path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise StudyError(f"{record_path}: cannot read ({exc})") from None
    if not isinstance(record, dict) or record.get("format") != FORMAT:
        raise StudyError(f"{record_path}: not a hybridteam study record")
    if not table_path.is_file() or record.get("status") != "complete":
        raise StudyError(
            f"{out}: the study is not finished (no results.csv); run the same "
            "'hybridteam sweep' command again to resume it"
        )
    try:
        table = read_results(table_path)
    except (OSError, ValueError) as exc:
        raise StudyError(f"{table_path}: cannot read ({exc})") from None
    return record, table


def _number(text: str) -> float | None:
    try:
        return float(text)
    except ValueError:
        return None


def _file_name(factor: str) -> str:
    return "success_" + re.sub(r"[^A-Za-z0-9_.-]+", "_", factor)


def plot_factor(table: ResultTable, factor: str, axes: list[str]):
    """The figure of one factor: success rate against its values, a line per axis point."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    rows = [r for r in table.rows if r["factor"] == factor]
    labels = list(dict.fromkeys(r["value"] for r in rows))
    numbers = [_number(v) for v in labels]
    numeric = all(x is not None for x in numbers)
    where = dict(zip(labels, numbers if numeric else range(len(labels)), strict=True))
    lines: dict[tuple[Any, ...], list[tuple[float, float]]] = {}
    for r in rows:
        lines.setdefault(tuple(r[a] for a in axes), []).append(
            (where[r["value"]], r["success_rate"])
        )
    fig = Figure(figsize=(6.4, 4.2), dpi=100)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    for point, xy in lines.items():
        xy.sort()
        label = ", ".join(f"{a} = {v}" for a, v in zip(axes, point, strict=True)) or None
        ax.plot([x for x, _ in xy], [100 * y for _, y in xy], marker="o", label=label)
    if not numeric:
        # Category labels (value pairs) overlap once their total width passes the axis:
        # tilt them then, right-aligned under their ticks.
        crowded = sum(len(str(v)) for v in labels) > 60
        ax.set_xticks(
            range(len(labels)),
            labels,
            rotation=35 if crowded else 0,
            ha="right" if crowded else "center",
        )
    ax.set_xlabel(factor)
    ax.set_ylabel("success rate (%)")
    ax.set_ylim(-3, 103)
    ax.grid(True, alpha=0.3)
    if axes:
        ax.legend(fontsize="small")
    ax.set_title(f"success rate against {factor}")
    fig.tight_layout()
    return fig


def write_plots(out: Path, record: dict[str, Any], table: ResultTable) -> list[Path]:
    """``plots/success_<factor>.png`` and ``.svg`` for every factor; the PNG paths."""
    from hybridteam.export.figures import save_figure

    axes = [a for a in record.get("axes", []) if a in table.columns]
    factors = list(dict.fromkeys(r["factor"] for r in table.rows))
    written = []
    for factor in factors:
        if len({r["value"] for r in table.rows if r["factor"] == factor}) < 2 and not axes:
            continue  # a single point (the base setting alone): nothing to draw
        fig = plot_factor(table, factor, axes)
        try:
            stem = out / "plots" / _file_name(factor)
            save_figure(fig, stem.with_suffix(".svg"))
            written.append(save_figure(fig, stem.with_suffix(".png")))
        finally:
            fig.clear()
    return written


def write_report(out: str | Path) -> Path:
    """Plots and ``report.md`` (the table, the plots embedded) for a finished study."""
    out = Path(out)
    record, table = load_results(out)
    plots = write_plots(out, record, table)

    def text(key: str, default: Any = "?") -> str:  # a value of study.json, made inert
        return markdown_text(str(record.get(key, default)))

    found = record.get("versions")
    versions = ", ".join(
        markdown_text(f"{k} {v}") for k, v in (found.items() if isinstance(found, dict) else ())
    )
    success = record.get("success", ["ok"])
    lines = [
        f"# {text('name', 'study')}",
        "",
        f"Team {markdown_text(Path(str(record.get('team', '?'))).name)}, {text('runs')} runs "
        f"in {text('chunks')} chunks of at most {text('chunk')}, study seed {text('seed')}; "
        "success means outcome "
        + " or ".join(
            markdown_text(str(s)) for s in (success if isinstance(success, list) else [success])
        )
        + ".",
        "",
        "Means are over the successful runs (– when there are none).",
        "",
        "## Results",
        "",
        table.to_markdown(),  # from the results read back, not the folder's results.md as is
    ]
    if plots:
        lines += ["## Success rate against each factor", ""]
        for png in plots:
            factor = png.stem.removeprefix("success_")
            lines += [f"![success rate against {markdown_text(factor)}](plots/{png.name})", ""]
    lines += ["## Versions", "", versions or "not recorded", ""]
    return write_atomic(out / "report.md", "\n".join(lines))
