"""The corridor's instant for a few instances on Python floats: ``LadderCorridor.update``'s
numbers, row by row.

A single run updates one instance at every step, and the array version's ~90 numpy calls
then cost their dispatch for one number each. This twin does the same IEEE operations in
the same order (the rules and the one-row helpers are :mod:`.law_one`'s), keeps the same
statistics and calls the world (``finish``, ``raise_event``) with the same arguments in
the same order, so a run's trace has the array version's bits
(``tests/modes/test_ladder_law_one.py``). Where two robots coincide it declines, and the array
version runs. Anyone editing ``LadderCorridor.update`` must edit this twin too (its
:func:`.kernel.in_corner` is generated from the array version's source).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from hybridteam.library import float_form

from . import kernel
from .law_one import _max, norm, spring_offsets, to_frame, to_world_vector

if TYPE_CHECKING:
    from hybridteam.library import WorldAccess

    from .world import LadderCorridor


#: :func:`.kernel.in_corner` of one ladder, generated from its source.
in_corner = float_form(kernel.in_corner)


def update_few(c: LadderCorridor, world: WorldAccess, idx: np.ndarray) -> bool:
    """``c.update(world, idx)`` for a few instances, on floats. Returns False, having
    changed nothing, where two robots coincide (numpy's inf and NaN offsets, which floats
    would raise on): the caller then takes the array version."""
    frame = c.frame
    poses = [world.pose(a, idx).tolist() for a in c.robots]
    rows = []
    try:  # every row's ladder first, so that nothing is written if one cannot be had
        for j, i in enumerate(idx.tolist()):
            k = constants(c, i)
            pos = [poses[0][j][:2], poses[1][j][:2]]
            f = [to_frame(frame, *p) for p in pos]
            tips, no = [], []
            for r in (0, 1):
                ox, oy, _ = spring_offsets(*f[r], *f[1 - r], k.length, k.share[r])
                no.append(norm(ox, oy))
                tips.append((f[r][0] + ox, f[r][1] + oy))
            rows.append((i, k, pos, tips, no))
    except ZeroDivisionError:
        return False
    o0, o1 = frame.floats[:2]
    broken, arrived, stuck = [], [], []
    for i, k, pos, tips, no in rows:
        # (element by element: a numpy element write costs less than a row's from a list)
        for r in (0, 1):  # to_world: the tip on the axes, plus the origin
            tx, ty = to_world_vector(frame, *tips[r])
            c.tips[r, i, 0], c.tips[r, i, 1] = tx + o0, ty + o1
        steps = _statistics(c, i, pos)
        c.was_corner[i] = in_corner(*tips[0], *tips[1], frame.width_in, frame.width_out)
        for r in (0, 1):
            c.max_offset[r, i] = _max(c.max_offset.item(r, i), no[r])
            c.offset[r, i] = no[r]
        bad = no[0] > k.olim[0] or no[1] > k.olim[1]
        broken.append(bad)
        came, stalled = _referee(c, i, k, pos, bad, steps)
        arrived.append(came)
        stuck.append(stalled)
    _judge(c, world, idx, broken, arrived, stuck)
    return True


class Constants(NamedTuple):
    """What the corridor's instant reads of instance ``i`` that a run never changes."""

    length: float
    share: tuple[float, float]
    olim: tuple[float, float]
    goal: tuple[tuple[float, ...], ...]  # (x, y) of each robot's goal
    arrive_tol: float
    stuck_tol: float
    stuck_window: float


def constants(c: LadderCorridor, i: int) -> Constants:
    """Instance ``i``'s :class:`Constants`, read from the component's arrays at its first
    instant and kept with the component (``c.constants``): one read instead of a dozen
    numpy element reads at every step."""
    k = c.constants.get(i)
    if k is None:
        v = c.values
        k = c.constants[i] = Constants(
            float(c.length[i]),
            tuple(c.share[:, i].tolist()),
            tuple(c.olim[:, i].tolist()),
            tuple(tuple(g) for g in c.goal[:, i].tolist()),
            float(v["arrive_tol"][i]),
            float(v["stuck_tol"][i]),
            float(v["stuck_window"][i]),
        )
    return k


def _statistics(c: LadderCorridor, i: int, pos: list) -> int:
    """Path lengths and step counts of the step that led here; ``prev`` becomes ``pos``.
    Returns the step count."""
    prev = c.prev[:, i].tolist()
    steps = c.steps.item(i)
    if not math.isnan(prev[0][0]):
        corner = c.was_corner.item(i)
        for r in (0, 1):
            dist = norm(pos[r][0] - prev[r][0], pos[r][1] - prev[r][1])
            c.path[r, i] = c.path.item(r, i) + dist
            c.corner_path[r, i] = c.corner_path.item(r, i) + (dist if corner else 0.0)
        steps += 1
        c.steps[i] = steps
        c.corner_steps[i] = c.corner_steps.item(i) + corner
    c.prev[:, i] = pos
    return steps


def _referee(
    c: LadderCorridor, i: int, k: Constants, pos: list, bad: bool, step: int
) -> tuple[bool, bool]:
    """Progress toward the goals: (arrived, stuck) of instance ``i`` at step ``step``."""
    d = [norm(k.goal[r][0] - pos[r][0], k.goal[r][1] - pos[r][1]) for r in (0, 1)]
    progress = d[0] + d[1]
    improved_at = c.improved_at.item(i)
    if progress < c.best.item(i) - k.stuck_tol:
        c.best[i] = progress
        c.improved_at[i] = improved_at = step
    tol = k.arrive_tol
    came = d[0] <= tol and d[1] <= tol and not bad
    stalled = not bad and not came and improved_at <= step - k.stuck_window
    return came, stalled


def _judge(
    c: LadderCorridor, world: WorldAccess, idx: np.ndarray, broken: list, arrived: list, stuck: list
) -> None:
    """The world calls of the array version, in its order: broken links, then events."""
    if any(broken):
        c.fail(world, idx[np.array(broken)])
    for event, mask in (("arrived", arrived), ("stuck", stuck)):
        if any(mask):
            for a in c.robots:
                world.raise_event(idx[np.array(mask)], a, event)
