"""Requirement violations drawn on a time axis (the timeline marks where each began)."""

from __future__ import annotations

from typing import Any

from matplotlib import patheffects

VIOLATION_COLOR = "#C62828"


def violations(trace: Any, instance: int) -> list[tuple[float, str, str]]:
    """(time, requirement, failed sub-formula) of each violated requirement, by time."""
    outcomes = getattr(trace, "diagnostics", trace.outcomes)
    if instance >= len(outcomes) or not isinstance(outcomes[instance], dict):
        return []
    verdicts = outcomes[instance].get("requirements") or {}
    found = [
        (float(v["violated_at"]), name, str(v.get("failed", "")))
        for name, v in verdicts.items()
        if not v["satisfied"] and "violated_at" in v
    ]
    return sorted(found)


def draw_violations(ax: Any, trace: Any, instance: int, span: tuple[float, float]) -> bool:
    """A dashed red line at each violation inside ``span``, labelled with the requirement's
    name along the top edge (labels of nearby lines step down so they do not overlap; near
    the right edge a label sits left of its line, clear of the legend).
    Returns whether anything was drawn (the caller adds a legend entry)."""
    t0, t1 = span
    shown = [v for v in violations(trace, instance) if t0 <= v[0] <= t1]
    last_t, level = -float("inf"), 0
    width = max(t1 - t0, 1e-9)
    for t, name, _failed in shown:
        level = level + 1 if t - last_t < 0.08 * width else 0
        last_t = t
        ax.axvline(
            t,
            color=VIOLATION_COLOR,
            linestyle="--",
            linewidth=1.3,
            zorder=7,
            gid="requirement-violation",  # a white halo: visible on any bar colour
            path_effects=[patheffects.withStroke(linewidth=3, foreground="white")],
        )
        right = t > t0 + 0.8 * width  # near the right edge: the label goes to the left
        ax.text(
            t,
            0.99 - 0.06 * (level % 4),
            f"{name} " if right else f" {name}",
            transform=ax.get_xaxis_transform(),
            ha="right" if right else "left",
            va="top",
            fontsize=7.5,
            color=VIOLATION_COLOR,
            zorder=8,
            gid="violation-label",
            bbox={"boxstyle": "square,pad=0.1", "fc": "white", "ec": "none", "alpha": 0.85},
        )
    return bool(shown)
