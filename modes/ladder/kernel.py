"""Run n pairs through the corridor at once: the vectorized stepper and its statistics.

Each iteration judges the state every live pair has reached (link broken, arrived,
stuck), then moves the others one control period, with :mod:`.law` evaluated for both
robots on the same start-of-period state (synchronous update; ``Settings.update`` may
instead move one robot and then evaluate the other on the state it left, a link broken in
between breaking). A pair that has finished
is frozen: its motion is zero from then on, and it leaves the working arrays when a
quarter of them have finished (compacting on every finish would cost more than it saves).

The statistics are the paper's (Sec. 4): total steps, steps with the ladder meeting the
corner square, path lengths in total and in the corner, plus each robot's largest offset.
Every per-pair quantity is computed elementwise in a fixed order, so a pair's result is
the same, bit for bit, whatever else is in the batch.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hybridteam.library import Ops
from hybridteam.world.geometry import Corridor, corridor_with_turn

from . import law
from .frame import CornerFrame
from .params import Pairs, Settings
from .scene import Scene, build

#: Outcome codes of :attr:`Result.outcome`.
RUNNING, SUCCESS, STUCK, LINK_BROKEN = 0, 1, 2, 3
OUTCOMES = ("running", "success", "stuck", "link_broken")

#: Safety distance of the skip tests in `_run` (far above rounding at corridor scale).
_SLACK = 1e-6

_PAIR = ("length", "best", "improved_at", "outcome", "steps", "corner_steps", "cracked")
_ROBOT = (
    "x",
    "y",
    "idx",
    "base",
    "gx",
    "gy",
    "path",
    "corner_path",
    "max_offset",
    "v_max",
    "ahead",
    "share",
    "coef",
    "orsp",
    "olim",
    "kr",
    "radius",
    "margin",
    "hx",
    "hy",
)

#: Robot rows moving first and second in each period, by ``Settings.update``.
ORDERS = {"synchronous": None, "front_first": (0, 1), "rear_first": (1, 0)}


@dataclass
class Result:
    """What n runs produced; robot axes are ordered (front R1, rear R2), world coordinates."""

    outcome: np.ndarray  # (n,) codes, see OUTCOMES
    steps: np.ndarray  # (n,) control periods taken
    corner_steps: np.ndarray  # (n,) of which with the ladder meeting the corner square
    path: np.ndarray  # (n, 2) distance travelled by each robot
    corner_path: np.ndarray  # (n, 2) of which while the ladder met the corner square
    max_offset: np.ndarray  # (n, 2) largest |o_i| seen
    position: np.ndarray  # (n, 2, 2) final robot positions
    scene: Scene  # starts, goals, guide paths
    trajectory: np.ndarray | None = None  # (T + 1, n, 2, 2) robot positions, if recorded
    tips: np.ndarray | None = None  # (T + 1, n, 2, 2) ladder ends, if recorded

    @property
    def outcome_names(self) -> list[str]:
        return [OUTCOMES[int(c)] for c in self.outcome]


def in_corner(
    ax: np.ndarray,
    ay: np.ndarray,
    bx: np.ndarray,
    by: np.ndarray,
    width_in: float,
    width_out: float,
    ops: Ops = np,
) -> np.ndarray:
    """Whether the ladder ``a -> b`` meets the closed corner square (frame coordinates).

    Separating axes: the square's two axes (bounding boxes overlap) and the ladder's normal
    (the square's centre is within its half-extent of the ladder's line). Written once over
    ``ops``: its float form is the corridor's instant's for a few rows (:mod:`.world_one`).
    """
    overlap = (
        (ops.minimum(ax, bx) <= 0.0)
        & (ops.maximum(ax, bx) >= -width_in)
        & (ops.minimum(ay, by) <= 0.0)
        & (ops.maximum(ay, by) >= -width_out)
    )
    dx = bx - ax
    dy = by - ay
    s = dx * (-0.5 * width_out - ay) - dy * (-0.5 * width_in - ax)
    return overlap & (abs(s) <= 0.5 * width_in * abs(dy) + 0.5 * width_out * abs(dx))


def _initial(
    pairs: Pairs, start: np.ndarray, goal: np.ndarray, settings: Settings
) -> dict[str, np.ndarray]:
    """Full-size state arrays in the corner frame: robot ones ``(2, n)``, pair ones ``(n,)``."""
    n = pairs.size
    r = pairs.robot
    sc = r["sc"]
    hx = goal[..., 0] - goal[::-1, :, 0]
    hy = goal[..., 1] - goal[::-1, :, 1]
    hn = law.norm(hx, hy)
    return {
        "length": pairs.length.astype(float).copy(),
        "best": np.full(n, np.inf),
        "improved_at": np.zeros(n, dtype=np.int64),
        "outcome": np.zeros(n, dtype=np.int8),
        "steps": np.zeros(n, dtype=np.int64),
        "corner_steps": np.zeros(n, dtype=np.int64),
        "cracked": np.zeros(n, dtype=bool),
        "x": start[..., 0].copy(),
        "y": start[..., 1].copy(),
        "idx": np.zeros((2, n), dtype=np.int64),
        "base": np.arange(2 * n, dtype=np.int64).reshape(2, n)
        * (settings.path_points + 2 * settings.window),
        "gx": goal[..., 0].copy(),
        "gy": goal[..., 1].copy(),
        "path": np.zeros((2, n)),
        "corner_path": np.zeros((2, n)),
        "max_offset": np.zeros((2, n)),
        "v_max": r["v_max"].copy(),
        "ahead": np.maximum(r["lookahead"].astype(np.int64), 1),
        "share": sc[::-1] / (sc + sc[::-1]),
        "coef": law.correction_coefficient(r["kc"], r["olim"], r["orsp"]),
        "orsp": r["orsp"].copy(),
        "olim": r["olim"].copy(),
        "kr": r["kr"].copy(),
        "radius": r["radius"].copy(),
        "margin": r["ladder_margin"].copy(),
        "hx": hx / hn,
        "hy": hy / hn,
    }


def simulate(
    pairs: Pairs,
    corridor: Corridor | None = None,
    settings: Settings | None = None,
    *,
    record: bool = False,
    start: np.ndarray | None = None,
) -> Result:
    """Run every pair to success, stuck or a broken link, and collect the statistics.

    ``start`` ``(2, n, 2)`` (front row first) places the robots; by default they start on
    the centre line as :func:`.scene.placements` says.
    """
    corridor = corridor or corridor_with_turn()
    settings = settings or Settings()
    pairs.check()
    settings.check()
    scene = build(pairs, corridor, settings, start)
    frame = CornerFrame.of(corridor)
    window, last = settings.window, settings.path_points - 1
    path_x, path_y = law.pad_paths(frame.to_frame(scene.paths), window)
    windows = law.search_windows(path_x, path_y, window)
    full = _initial(pairs, frame.to_frame(scene.start), frame.to_frame(scene.goal), settings)
    frames: list[np.ndarray] | None = [] if record else None
    snap = np.full((2, 2, pairs.size, 2), np.nan) if record else None  # (pos|tip, robot, n, xy)
    act = np.arange(pairs.size)
    work = {k: v.copy() for k, v in full.items()}
    step = 0
    while True:
        step, live = _run(
            work, step, path_x, path_y, windows, frame, settings, window, last, frames, snap, act
        )
        for k in _PAIR:
            full[k][act] = work[k]
        for k in _ROBOT:
            full[k][:, act] = work[k]
        if live is None:
            break
        keep = np.flatnonzero(live)
        act = act[keep]
        work = {k: (v[keep] if k in _PAIR else v[:, keep]) for k, v in work.items()}
    to_world = frame.to_world
    position = to_world(np.stack([full["x"], full["y"]], axis=-1))
    trajectory = tips = None
    if frames is not None:
        stacked = to_world(np.stack(frames))  # (T + 1, 2 [pos, tip], 2, n, 2)
        trajectory = stacked[:, 0].transpose(0, 2, 1, 3).copy()
        tips = stacked[:, 1].transpose(0, 2, 1, 3).copy()
    return Result(
        outcome=full["outcome"],
        steps=full["steps"],
        corner_steps=full["corner_steps"],
        path=full["path"].T.copy(),
        corner_path=full["corner_path"].T.copy(),
        max_offset=full["max_offset"].T.copy(),
        position=position.transpose(1, 0, 2).copy(),
        scene=scene,
        trajectory=trajectory,
        tips=tips,
    )


def _run(
    work: dict[str, np.ndarray],
    step: int,
    path_x: np.ndarray,
    path_y: np.ndarray,
    windows: tuple[np.ndarray, np.ndarray],
    frame: CornerFrame,
    settings: Settings,
    window: int,
    last: int,
    frames: list[np.ndarray] | None,
    snap: np.ndarray | None,
    act: np.ndarray,
) -> tuple[int, np.ndarray | None]:
    """Step the working pairs until all have finished (returns ``(step, None)``) or enough
    have finished to compact them (returns ``(step, live mask)``). Updates in place."""
    length, best, improved_at = work["length"], work["best"], work["improved_at"]
    outcome, steps, corner_steps = work["outcome"], work["steps"], work["corner_steps"]
    x, y, idx, gx, gy = (work[k] for k in ("x", "y", "idx", "gx", "gy"))
    path, corner_path, max_offset = work["path"], work["corner_path"], work["max_offset"]
    share, olim, cracked = work["share"], work["olim"], work["cracked"]
    w_in, w_out = frame.width_in, frame.width_out
    stuck_tol, arrive_tol = settings.stuck_tol, settings.arrive_tol
    stuck_window, max_steps = settings.stuck_window, settings.max_steps
    motion = _motion_of(work, path_x, path_y, windows, frame, window, last, settings.correction)
    order = ORDERS[settings.update]
    m = length.size
    live = np.ones(m, dtype=bool)
    dead = None
    while True:
        ox, oy, dist = law.spring_offsets(x, y, x[::-1], y[::-1], length, share)
        no = law.norm(ox, oy)
        ax = x + ox
        ay = y + oy
        if frames is not None and len(frames) == step:
            assert snap is not None  # (recorded with the frames)
            pos, tip = snap
            pos[:, act, 0], pos[:, act, 1], tip[:, act, 0], tip[:, act, 1] = x, y, ax, ay
            frames.append(snap.copy())
        # Judge the state reached after `step` periods.
        np.maximum(max_offset, no, out=max_offset)
        dgoal = law.norm(gx - x, gy - y)
        progress = dgoal[0] + dgoal[1]
        better = progress < best - stuck_tol
        np.copyto(best, progress, where=better)
        np.copyto(improved_at, step, where=better)
        broken = no > olim
        broken = broken[0] | broken[1] | cracked
        arrived = dgoal <= arrive_tol
        arrived = arrived[0] & arrived[1]
        ended = broken | arrived
        ended |= improved_at <= step - stuck_window
        if step >= max_steps:
            ended[:] = True
        if dead is not None:
            ended &= live
        if np.count_nonzero(ended):
            code = np.where(broken, LINK_BROKEN, np.where(arrived, SUCCESS, STUCK))
            np.copyto(outcome, code, where=ended)
            np.copyto(steps, step, where=ended)
            live &= ~ended
            dead = ~live
            alive = np.count_nonzero(live)
            if alive == 0:
                return step, None
            if 4 * alive <= 3 * m:
                return step, live
        # Move every live pair one period.
        mx, my, nearest = motion(x, y, ox, oy, no, ax, ay, dist, dgoal)
        if dead is not None:
            np.copyto(mx, 0.0, where=dead)
            np.copyto(my, 0.0, where=dead)
        if order is not None:
            first, second = order
            x1 = x.copy()
            y1 = y.copy()
            x1[first] += mx[first]
            y1[first] += my[first]
            ox1, oy1, dist1 = law.spring_offsets(x1, y1, x1[::-1], y1[::-1], length, share)
            no1 = law.norm(ox1, oy1)
            np.maximum(max_offset, no1, out=max_offset)
            between = no1 > olim
            cracked |= between[0] | between[1]
            mx1, my1, _ = motion(
                x1, y1, ox1, oy1, no1, x1 + ox1, y1 + oy1, dist1, law.norm(gx - x1, gy - y1)
            )
            mx[second] = mx1[second]
            my[second] = my1[second]
            if dead is not None:
                np.copyto(mx, 0.0, where=dead)
                np.copyto(my, 0.0, where=dead)
        # A ladder with both ends beyond y = 0 (or x = 0) misses the corner square.
        xa, ya, xb, yb = ax[0], ay[0], ax[1], ay[1]
        corner = ~(((ya > 0.0) & (yb > 0.0)) | ((xa > 0.0) & (xb > 0.0)))
        if np.count_nonzero(corner):
            corner &= in_corner(xa, ya, xb, yb, w_in, w_out)
        if dead is not None:
            corner &= live
        moved = law.norm(mx, my)
        x += mx
        y += my
        np.copyto(idx, nearest)
        path += moved
        np.add(corner_path, moved, out=corner_path, where=corner)
        np.add(corner_steps, 1, out=corner_steps, where=corner)
        step += 1


def _motion_of(
    work: dict[str, np.ndarray],
    path_x: np.ndarray,
    path_y: np.ndarray,
    windows: tuple[np.ndarray, np.ndarray],
    frame: CornerFrame,
    window: int,
    last: int,
    correction: str,
):
    """The law for both robots of the working pairs, as a function of their positions
    (and what the judge already computed from them): ``(mx, my, nearest)``."""
    idx, base, hx, hy = work["idx"], work["base"], work["hx"], work["hy"]
    v_max, ahead, coef, orsp = work["v_max"], work["ahead"], work["coef"], work["orsp"]
    kr, radius, margin = work["kr"], work["radius"], work["margin"]
    w_in, w_out = frame.width_in, frame.width_out
    rotate = (kr != 0.0) if np.count_nonzero(kr) else None
    half_length = 0.5 * work["length"]
    reach = radius + v_max + _SLACK
    far_ladder = -margin - _SLACK

    def motion(x, y, ox, oy, no, ax, ay, dist, dgoal):
        nearest = law.nearest_on_path(x, y, windows, base, idx, window, last)
        tx, ty = law.target_vector(x, y, path_x, path_y, base, nearest, ahead, last, window)
        rx = ry = None
        if rotate is not None:
            rx, ry = law.rotation_vector(
                x, y, x[::-1], y[::-1], dist, dgoal, hx, hy, kr, half_length
            )
        cx, cy = law.correction_vector(ox, oy, no, orsp, coef)
        mx, my = law.combine(
            tx, ty, rx, ry, law.arrival_factor(dgoal, v_max), cx, cy, v_max, rotate, correction
        )
        # The wall rules, skipped where they provably change nothing: a ladder with all
        # x (or all y) below -margin is farther than that from the inside of the turn; a
        # robot farther than radius + v_max from a wall cannot reach it in one step. The
        # bounds carry a slack far above rounding, so a skip never depends on the batch.
        if np.count_nonzero(
            (np.maximum(ax, ax[::-1]) >= far_ladder) & (np.maximum(ay, ay[::-1]) >= far_ladder)
        ):
            clear = law.ladder_clearance(ax, ay, ax[::-1], ay[::-1])
            mx, my = law.avoid_ladder_collision(mx, my, clear, margin)
        if np.count_nonzero(np.minimum(x + w_in, y + w_out) < reach):
            mx, my = law.avoid_outer_walls(x, y, mx, my, radius, w_in, w_out)
        d_inner = law.inner_wall_distance(x, y)
        if np.count_nonzero(d_inner < reach):
            mx, my = law.avoid_inner_walls(x, y, mx, my, radius, d_inner)
        return mx, my, nearest

    return motion
