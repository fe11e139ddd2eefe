"""The timeline's legend: modes grouped by robot, each by its shortest unambiguous name."""

from __future__ import annotations

from typing import Any

from matplotlib.patches import Patch


def short_names(paths: list[str]) -> dict[str, str]:
    """Each path by its shortest suffix that no other path of the list ends with:
    ``Transport.Lead.Curve`` is ``Curve`` unless ``Transport.Offering.Curve`` is listed too,
    when the two are ``Lead.Curve`` and ``Offering.Curve``."""
    out: dict[str, str] = {}
    for path in paths:
        parts = path.split(".")
        for k in range(1, len(parts) + 1):
            tail = ".".join(parts[-k:])
            if not any(o != path and (o == tail or o.endswith("." + tail)) for o in paths):
                break
        out[path] = tail
    return out


def legend_handles(legend: dict[str, dict[str, str]]) -> tuple[list[Any], list[int]]:
    """The legend grouped by robot: the robot's name (a heading, at the returned positions;
    none for a single robot), then its modes by short name (a mode two robots share appears
    under each, in the same colour); robots whose modes are all the same share a group,
    headed by their names."""
    handles: list[Any] = []
    heads: list[int] = []
    same: dict[tuple, list[str]] = {}  # robots with the very same modes share one group
    for agent, modes in legend.items():
        same.setdefault(tuple(modes.items()), []).append(agent)
    for key, agents in same.items():
        modes = dict(key)
        if len(legend) > 1:
            heads.append(len(handles))
            handles.append(Patch(facecolor="none", edgecolor="none", label=", ".join(agents)))
        short = short_names(list(modes))
        handles += [Patch(facecolor=c, label=short[path]) for path, c in modes.items()]
    return handles, heads
