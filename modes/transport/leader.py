"""What a transport law reads besides its own state: the leader's stream and the grasp's arm.

The architecture paper's followers act on x̂_l and v̂_l, the leader's pose and velocity as
last heard, and on x_a, the state of the compliant arm that holds the box. Both come from
outside the robot and both may be missing — no copy of the leader's stream has arrived yet,
the robot holds no grasp, the team has no payload — so each law would repeat the same
guards. They live here once:

- :func:`leader_estimate` reads the ``state`` stream of the robot named by the ``leader``
  variable (role-assignment protocol), dead-reckoned over the copy's age, and says per
  instance whether it is usable;
- :func:`LeaderState` gives the velocity in both forms a law needs (speed along the heading,
  world-frame vx, vy) whichever of them the stream carries;
- :func:`arm_reading` is ``ctx.sense("arm")`` with "no arm" turned into a zero reading, so
  the paper's f(x_a), g(x_a) terms vanish instead of poisoning the input with NaN.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from hybridteam.library import FLOAT_PATHS, LawContext

#: The data stream of the role-assignment protocol that carries a robot's pose and velocity.
STREAM = "state"


@dataclass(frozen=True)
class LeaderState:
    """The leader's estimated pose and velocity, per instance (rows where ``ok`` is False
    hold zeros, never NaN, so arithmetic on them is safe and their result is discarded)."""

    ok: np.ndarray  # (m,) bool: a copy from the named leader has arrived
    who: np.ndarray  # (m,) the leader's agent index (-1: none)
    x: np.ndarray
    y: np.ndarray
    theta: np.ndarray
    v: np.ndarray  # speed along the leader's heading
    vx: np.ndarray  # world-frame velocity
    vy: np.ndarray
    omega: np.ndarray  # turn rate


def leader_estimate(ctx: LawContext) -> LeaderState:
    """The latest copy of the leader's ``state`` stream, dead-reckoned to now.

    The leader is the agent index in the ``leader`` variable (-1: none, e.g. while this
    robot leads). The stream may carry ``v`` (speed along the heading), ``vx, vy``
    (world-frame velocity) or both; a missing form is derived from the other and the
    heading, so a law written for one works with a unicycle or a holonomic leader.
    """
    leader = ctx.get("leader", -1.0)
    if ctx.size == 1 and FLOAT_PATHS.on and not leader.item(0) >= 2.0**52:
        return _leader_one(ctx, leader.item(0))
    who = np.where(np.isfinite(leader) & (leader >= 0), np.rint(leader), -1).astype(np.intp)
    est = ctx.estimate(STREAM, sender=np.where(who >= 0, who, 0), extrapolate=True)
    fields = est.fields
    x, y, th = fields["x"], fields["y"], fields["theta"]
    ok = (
        (who >= 0)
        & est.valid
        & np.isfinite(est.age)
        & np.isfinite(x)
        & np.isfinite(y)
        & np.isfinite(th)
    )
    c, s = np.cos(th), np.sin(th)
    if "vx" in fields and "vy" in fields:
        vx, vy = fields["vx"], fields["vy"]
        v = fields["v"] if "v" in fields else vx * c + vy * s
    else:
        v = fields.get("v", np.zeros(ctx.size))
        vx, vy = v * c, v * s
    omega = fields.get("omega", np.zeros(ctx.size))

    # the seven values in one array, each row cleaned as on its own (zeros where not ok,
    # nan_to_num's values where not finite): one pass instead of seven
    raw = np.empty((7, ctx.size))
    for j, a in enumerate((x, y, th, v, vx, vy, omega)):
        raw[j] = a
    out = np.where(ok, raw, 0.0)
    if not np.isfinite(out).all():  # (the usual case is finite: no nan_to_num's cost)
        out = np.where(ok, np.nan_to_num(raw), 0.0)
    return LeaderState(ok, who, *out)


def _leader_one(ctx: LawContext, leader: float) -> LeaderState:
    """:func:`leader_estimate` of one row (a single run's tick) on Python floats: the same
    operations on each number (``np.cos``, ``np.sin`` themselves; the cleaning is
    ``nan_to_num``'s), at about a third of the cost on arrays of one. A ``leader`` of 2**52
    or more (no agent index) takes the array version, whose integer conversion it is."""
    who = round(leader) if math.isfinite(leader) and leader >= 0 else -1  # (rint: to even)
    est = ctx.estimate(STREAM, sender=np.array([max(who, 0)], np.intp), extrapolate=True)
    fields = est.fields
    x, y, th = fields["x"].item(0), fields["y"].item(0), fields["theta"].item(0)
    ok = (
        who >= 0
        and bool(est.valid[0])
        and math.isfinite(est.age.item(0))
        and math.isfinite(x)
        and math.isfinite(y)
        and math.isfinite(th)
    )
    c, s = float(np.cos(th)), float(np.sin(th))
    if "vx" in fields and "vy" in fields:
        vx, vy = fields["vx"].item(0), fields["vy"].item(0)
        v = fields["v"].item(0) if "v" in fields else vx * c + vy * s
    else:
        v = fields["v"].item(0) if "v" in fields else 0.0
        vx, vy = v * c, v * s
    omega = fields["omega"].item(0) if "omega" in fields else 0.0
    values = [x, y, th, v, vx, vy, omega] if ok else [0.0] * 7
    if not all(map(math.isfinite, values)):  # nan_to_num's numbers
        values = [_finite(a) for a in values]
    out = np.array(values)[:, None]  # seven rows of one, as the array version's
    return LeaderState(np.array([ok]), np.array([who], np.intp), *out)


def _finite(a: float) -> float:
    """``np.nan_to_num`` of one float: 0 for NaN, the largest finite float for infinity."""
    if a != a:
        return 0.0
    return a if math.isfinite(a) else math.copysign(_BIG, a)


_BIG = float(np.finfo(float).max)


def arm_reading(ctx: LawContext) -> np.ndarray:
    """The grasp's x_a = [x_a, y_a, θ_a] per instance, ``(m, 3)``; zeros where there is none.

    ``payload`` (hybridteam.world.carried) gives a grasping robot its grasp offset — the
    robot's mount point minus the payload's grasp point — in the robot's frame, and the
    payload's angle relative to the robot counted from the start; a robot that holds no
    grasp reads NaN, and a team without a payload has no ``arm`` at all (KeyError). Both
    mean "no arm feedback", which for the paper's f(x_a), g(x_a) is a zero term.
    """
    try:
        arm = np.asarray(ctx.sense("arm"), dtype=float)
    except KeyError:
        return np.zeros((ctx.size, 3))
    if arm.size == 0:
        return np.zeros((ctx.size, 3))
    arm = arm.reshape(ctx.size, -1)[:, :3]
    if arm.shape[1] < 3:
        arm = np.pad(arm, ((0, 0), (0, 3 - arm.shape[1])))
    return np.where(np.isfinite(arm), arm, 0.0)  # nan_to_num's zeros, at a fifth of its cost


def arm_terms(ctx: LawContext) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The paper's f, g, h: linear in x_a, ``(k_x x_a, k_y y_a, k_th θ_a)``, robot frame.

    A holonomic robot applies f, g along its own axes and h to its turn rate; a unicycle,
    with one turn input, adds h to g. The gains are signed, one per reading, so each law
    states its convention in its defaults: x_a, y_a are *robot minus grasp*, so gains < 0
    pull the robot back onto its grasp; θ_a is *payload minus robot*, so a gain > 0 turns
    the robot after the payload.
    """
    arm = arm_reading(ctx)
    return ctx["k_x"] * arm[:, 0], ctx["k_y"] * arm[:, 1], ctx["k_th"] * arm[:, 2]


def stack_inputs(ctx: LawContext, values: Mapping[str, np.ndarray]) -> np.ndarray:
    """Plant inputs ``(m, k)`` from named columns, in the plant's input order (by name, so
    no law depends on that order). A column may be a scalar: assignment broadcasts it (the
    values ``np.stack`` of ``broadcast_to`` columns gave, at a third of the calls)."""
    out = np.empty((ctx.size, len(ctx.inputs)))
    for j, name in enumerate(ctx.inputs):
        out[:, j] = values[name]
    return out


def wrap(angle: np.ndarray) -> np.ndarray:
    """An angle in [-pi, pi): heading errors must take the short way round."""
    return (angle + np.pi) % (2 * np.pi) - np.pi
