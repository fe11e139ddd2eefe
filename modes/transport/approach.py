"""The XR4000's Approach (Dock submode A): close in on the box by infrared until the arm can
deploy — the paper's u = (f(x_s), g(x_s), h(x_s)) with x_s the IR ring's readings.

The paper gives no f, g, h; these are the simplest that do the job and are easy to reason
about. The beams around the heading form the front sector (the centre beam and ``beams``
on each side). Its nearest reading r is the gap to the box: the robot moves along its
heading at k (r − stand_off), clipped to ``speed``, and stops — every input exactly 0 —
once |r − stand_off| <= ``tol``, so the Approach mode can end (on a timeout, or on an
event of the sensing component) with the robot at rest. Nothing seen reads ``max_range``,
so a robot that sees nothing yet keeps coming: Approach assumes the box is ahead.

Centring uses the sector's two halves: the box off to the left shortens the left beams and
leaves the right ones long, so the robot slides left at k_lat (mean right − mean left),
clipped to ``speed``. The same difference also means "the face is turned toward the left",
so a heading term k_head (mean right − mean left) could square the robot up; the two cannot
be told apart from one ring, so turning is off by default (k_head = 0).
"""

from __future__ import annotations

import numpy as np

from hybridteam.library import LawContext, law

from .leader import stack_inputs


@law(
    "transport.approach",
    plants=("holonomic",),
    params={
        "stand_off": 0.1,
        "k": 1.0,
        "speed": 0.1,
        "beams": 1.0,
        "k_lat": 0.5,
        "k_head": 0.0,
        "tol": 0.005,
        "offset_deg": 0.0,
    },
)
def approach(ctx: LawContext) -> np.ndarray:
    """Drive along the heading to ``stand_off`` from what the front IR beams see.

    ``ctx.sense("ir")`` is ``(m, count)``: beam i looks at ``offset_deg + i 360/count``
    degrees from the heading, counter-clockwise, and reads the gap from the ring (the hull)
    to the first thing it meets, ``max_range`` where it meets nothing. ``offset_deg`` must be
    the ring's (the XR4000 preset's IR ring has 0) so the law knows which beam looks ahead.
    """
    ranges = np.asarray(ctx.sense("ir"), dtype=float)
    m, count = ranges.shape
    width = _half_width(ctx["beams"], count)
    step = 360.0 / count
    front = np.rint(-ctx["offset_deg"] / step).astype(np.intp) % count
    offsets = np.arange(-width, width + 1)
    sector = np.take_along_axis(ranges, (front[:, None] + offsets[None, :]) % count, axis=1)
    gap = np.min(sector, axis=1)
    if width > 0:
        # beam offsets > 0 are counter-clockwise of the heading: the robot's left
        skew = sector[:, :width].mean(axis=1) - sector[:, width + 1 :].mean(axis=1)
    else:
        skew = np.zeros(m)
    speed = ctx["speed"]
    forward = np.clip(ctx["k"] * (gap - ctx["stand_off"]), -speed, speed)
    lateral = np.clip(ctx["k_lat"] * skew, -speed, speed)
    omega = ctx["k_head"] * skew
    th = ctx["theta"]
    c, s = np.cos(th), np.sin(th)
    u = stack_inputs(
        ctx, {"vx": forward * c - lateral * s, "vy": forward * s + lateral * c, "omega": omega}
    )
    there = np.abs(gap - ctx["stand_off"]) <= ctx["tol"]
    return np.where(there[:, None], 0.0, np.nan_to_num(u))


def _half_width(beams: np.ndarray, count: int) -> int:
    """``beams`` as one integer for the whole ensemble (the sector's shape is shared)."""
    values = np.unique(np.rint(np.asarray(beams, dtype=float)))
    if values.size > 1:
        raise ValueError("transport.approach: 'beams' must be the same in every instance")
    width = int(values[0]) if values.size else 0
    if width < 0 or 2 * width + 1 > count:
        raise ValueError(
            f"transport.approach: 'beams' = {width} does not fit a ring of "
            f"{count} beams (0 <= beams <= {(count - 1) // 2})"
        )
    return width
