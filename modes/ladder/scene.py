"""Where a run starts and ends, and the guide paths that join the two (paper Sec. 2, 3.1).

The paper puts the ladder "parallel to and right down the middle of the corridor, with
R1 in front of R2" at the start and at the goal, without distances. Here the rear
robot starts ``start_gap`` after the entrance line and the front robot ends ``goal_gap``
before the exit line (:class:`~hybridteam.modes.ladder.params.Settings`); the partner is
one ladder length behind or ahead on the centre line, so the ladder starts and ends with
no offset.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from hybridteam.world.geometry import Corridor

from .guide import guide_paths
from .params import Pairs, Settings


class Scene(NamedTuple):
    """Start and goal positions ``(2, n, 2)`` (row 0 front) and guide paths ``(2, n, P, 2)``."""

    start: np.ndarray
    goal: np.ndarray
    paths: np.ndarray


def placements(
    corridor: Corridor, length: np.ndarray, settings: Settings
) -> tuple[np.ndarray, np.ndarray]:
    """Start and goal positions ``(2, n, 2)`` of n pairs carrying ladders of ``length``."""
    length = np.asarray(length, dtype=float)
    rear_start = corridor.leg_point("in", settings.start_gap + 0.0 * length)
    front_start = corridor.leg_point("in", settings.start_gap + length)
    front_goal = corridor.leg_point("out", settings.goal_gap + 0.0 * length)
    rear_goal = corridor.leg_point("out", settings.goal_gap + length)
    return np.stack([front_start, rear_start]), np.stack([front_goal, rear_goal])


def build(
    pairs: Pairs, corridor: Corridor, settings: Settings, start: np.ndarray | None = None
) -> Scene:
    """Starts, goals and both robots' guide paths for every pair (``start`` ``(2, n, 2)``
    replaces the default placement of the robots)."""
    placed, goal = placements(corridor, pairs.length, settings)
    start = placed if start is None else np.asarray(start, dtype=float)
    paths = np.stack(
        [
            guide_paths(
                corridor,
                start[r],
                goal[r],
                pairs.robot["alpha"][r],
                count=settings.path_points,
                tension=settings.tension,
                approach=settings.approach,
                inset=settings.alpha_inset,
            )
            for r in range(2)
        ]
    )
    return Scene(start, goal, paths)


def law_params(pairs: Pairs, scene: Scene, row: int) -> dict[str, np.ndarray]:
    """The ``params`` of :func:`.law.step` for robot ``row`` (0 front, 1 rear) of every pair."""
    r, other = pairs.robot, 1 - row
    heading = scene.goal[row] - scene.goal[other]
    heading = heading / np.hypot(heading[:, 0], heading[:, 1])[:, None]
    out = {
        k: r[k][row].copy()
        for k in ("v_max", "lookahead", "olim", "orsp", "kc", "kr", "sc", "radius", "ladder_margin")
    }
    out.update(length=pairs.length.copy(), sc_partner=r["sc"][other].copy(), goal_heading=heading)
    return out
