"""Requirement verdicts for people: one line per requirement, and per-setting aggregates
for study tables (satisfaction rate, minimum robustness)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any


def robustness_value(v: Any) -> float:
    """A verdict's robustness as a float (``"inf"``/``"-inf"``/``"nan"`` as written in
    JSON)."""
    if not isinstance(v, str):
        return float(v)
    return {"inf": math.inf, "nan": math.nan}.get(v, -math.inf)


def _num(x: float) -> str:
    return "inf" if x == math.inf else "-inf" if x == -math.inf else f"{x:.6g}"


def verdict_lines(instances: Sequence[dict[str, Any]]) -> list[str]:
    """One line per requirement over a run's instances (``summary.json``'s rows)."""
    names = list(instances[0].get("requirements", {})) if instances else []
    lines = []
    for name in names:
        vs = [inst["requirements"][name] for inst in instances]
        held = sum(bool(v["satisfied"]) for v in vs)
        worst = min(range(len(vs)), key=lambda i: robustness_value(vs[i]["robustness"]))
        w = vs[worst]
        rho = _num(robustness_value(w["robustness"]))
        if len(vs) == 1:
            if w["satisfied"]:
                lines.append(f"requirement {name}: holds (robustness {rho})")
            elif "violated_at" not in w:  # a NaN robustness: a signal was not a number
                lines.append(
                    f"requirement {name}: does not hold (robustness {rho}: a value "
                    "it compares is not a number)"
                )
            else:
                lines.append(
                    f"requirement {name}: VIOLATED at t={w['violated_at']:.9g} by "
                    f"{w['failed']} (robustness {rho})"
                )
            continue
        text = f"requirement {name}: holds in {held} of {len(vs)}, min robustness {rho}"
        if not w["satisfied"] and "violated_at" in w:
            text += f" (instance {worst}: violated at t={w['violated_at']:.9g} by {w['failed']})"
        lines.append(text)
    return lines


def aggregate(rows: Sequence[dict[str, Any]]) -> dict[str, dict[str, float]]:
    """Per requirement over ``rows`` (per-instance results of one setting): the share that
    held and the minimum robustness."""
    out: dict[str, dict[str, float]] = {}
    for row in rows:
        for name, v in (row.get("requirements") or {}).items():
            agg = out.setdefault(name, {"held": 0.0, "runs": 0.0, "min_robustness": math.inf})
            agg["held"] += bool(v["satisfied"])
            agg["runs"] += 1
            agg["min_robustness"] = min(agg["min_robustness"], robustness_value(v["robustness"]))
    return {
        name: {"satisfied": a["held"] / a["runs"], "min_robustness": a["min_robustness"]}
        for name, a in out.items()
    }
