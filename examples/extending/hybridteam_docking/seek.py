"""The ``docking.seek`` law, and the velocity rule the batch fast path shares with it."""

from __future__ import annotations

import numpy as np

from hybridteam.library import LawContext, law


def seek_velocity(
    x: np.ndarray,
    y: np.ndarray,
    dock_x: np.ndarray,
    dock_y: np.ndarray,
    gain: np.ndarray,
    vmax: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """World-frame velocity toward the dock: ``gain`` times the offset, scaled down to
    ``vmax`` when faster. One function for the law and the fast path, so both compute the
    same numbers."""
    dx, dy = dock_x - x, dock_y - y
    speed = gain * np.hypot(dx, dy)
    scale = np.where(speed > vmax, vmax / np.where(speed > 0, speed, 1.0), 1.0)
    return gain * dx * scale, gain * dy * scale


@law("docking.seek", plants=("holonomic",), params={"gain": 1.0, "vmax": 0.5})
def seek(ctx: LawContext) -> np.ndarray:
    """Drive an omni-directional robot straight at the dock (``ctx.sense("dock")``)."""
    dock = ctx.sense("dock")
    vx, vy = seek_velocity(ctx["x"], ctx["y"], dock[:, 0], dock[:, 1], ctx["gain"], ctx["vmax"])
    return np.column_stack([vx, vy, np.zeros(ctx.size)])
