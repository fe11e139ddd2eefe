"""The transport laws of the architecture paper (Chaimowicz et al., Sec. 3.2), one per robot.

Follow and Dock are the paper's equations; what it leaves open is decided here and stated
in README.md: the arm terms f, g, h are linear with signed gains (``k_x``, ``k_y``,
``k_th``; see :func:`.leader.arm_terms`), the holonomic follower's set point uses the
leader's heading and feeds its velocity forward, and a follower with no estimate of its
leader yet stands still. Every law is vectorized over the ensemble's instances and returns
the plant's inputs: unicycle (v, omega), holonomic world-frame (vx, vy, omega). Actuator
limits are the plant's, not the law's.

Lead is not a law: a Lead role is a composite mode of constant ``inputs:`` and ``after:``
transitions (the paper's open-loop planner), see README.md.
"""

from __future__ import annotations

import numpy as np

from hybridteam.library import LawContext, law
from hybridteam.world.geometry import relative_pose

from .leader import LeaderState, arm_terms, leader_estimate, stack_inputs, wrap

#: Arm-feedback gains shared by every law that holds a grasp. x_a, y_a are robot minus
#: grasp point, so negative gains pull the robot back onto its grasp (for a unicycle, k_y
#: < 0 assumes the grasp is mounted ahead of the wheel axle: turning right moves it right);
#: θ_a is payload minus robot, so a positive gain turns the robot after the payload.
ARM = {"k_x": -1.0, "k_y": -1.0, "k_th": 1.0}


@law("transport.follow", plants=("unicycle",), params={"D": 1.0, "capture": 0.0, **ARM})
def follow(ctx: LawContext) -> np.ndarray:
    """The Labmate's Follow: u1 = v̂_l cos(θ̂_l − θ) + f, u2 = (v̂_l/D) sin(θ̂_l − θ) + g + h.

    D is signed: the leader sits at distance |D| along this robot's heading, ahead for
    D > 0, behind for D < 0. These are the velocities that keep a rigid link of length D
    from this robot to its leader intact: the leader's velocity split into this robot's
    forward speed and the link's turn rate. The heading term aligns the link with the
    leader's velocity (θ̂_l − θ → 0, or π for a leader facing this robot), which is stable
    while the leader moves away from this robot (pulls; v̂_l / D > 0 when θ̂_l ≈ θ) and
    unstable while it pushes, when only the arm terms hold the box. Stands still until a
    copy of the leader's stream arrives.

    ``capture`` = 1 replaces D by the leader's distance along this robot's heading when the
    first copy from a new leader arrives: after a change of leader the link is the one this
    robot has to the new leader, not D to whichever robot leads.
    """
    D = ctx["D"]
    if np.any(D == 0):
        raise ValueError("transport.follow: D (the distance to the leader, signed) must not be 0")
    lead = leader_estimate(ctx)
    on = ctx["capture"] > 0
    if on.any():
        th = ctx["theta"]
        link = np.cos(th) * (lead.x - ctx["x"]) + np.sin(th) * (lead.y - ctx["y"])
        kept = ctx.capture("link", lead.who, {"D": link}, on & lead.ok)["D"]
        D = np.where(on & np.isfinite(kept) & (np.abs(kept) > 1e-9), kept, D)
    f, g, h = arm_terms(ctx)
    err = lead.theta - ctx["theta"]
    v = lead.v * np.cos(err) + f
    omega = lead.v / D * np.sin(err) + g + h
    return np.where(lead.ok[:, None], stack_inputs(ctx, {"v": v, "omega": omega}), 0.0)


@law(
    "transport.follow_holonomic",
    plants=("holonomic",),
    params={
        "D": 1.0,
        "phi": 0.0,
        "capture": 0.0,
        "k1": 1.0,
        "k2": 1.0,
        "k3": 1.0,
        "k_ff": 1.0,
        **ARM,
    },
)
def follow_holonomic(ctx: LawContext) -> np.ndarray:
    """The XR4000's Follow: u = K (x^d − x) + k_ff ẋ^d + arm terms (f, g rotated, and h).

    The set point is the paper's, with the leader's heading: x^d = x̂_l + D cos θ̂_l,
    y^d = ŷ_l + D sin θ̂_l, θ^d = θ̂_l + phi — the place |D| along the leader's heading,
    ahead of it for D > 0. The paper's law is proportional only, so a moving leader leaves
    a lag of |ẋ^d|/k; ``k_ff`` = 1 feeds forward the set point's velocity, the leader's
    plus ω̂_l × (x^d − x̂_l) (the set point swings round the leader as it turns), and the
    error then decays like exp(−k t) whatever the leader does at constant velocity;
    ``k_ff`` = 0 is the paper's law exactly. The arm reading is in the robot frame and is
    rotated into the world. Stands still until a copy of the leader's stream arrives.

    ``capture`` = 1 replaces (D, phi) by the place this robot holds in its leader's frame
    when the first copy from a new leader arrives (kept as the law's memory): in a team
    where any robot may lead — the Scout of experiment 3 — the XR4000 keeps its place
    relative to whoever leads instead of driving to D ahead of a robot it is not linked to.
    """
    lead = leader_estimate(ctx)
    ahead, left, phi = _station(ctx, lead, ctx["D"], np.zeros(ctx.size))
    ff = ctx["k_ff"]
    c, s = np.cos(lead.theta), np.sin(lead.theta)
    xd, yd = lead.x + ahead * c - left * s, lead.y + ahead * s + left * c
    thd = lead.theta + phi
    # d/dt of the set point: leader velocity plus omega x (its offset from the leader)
    dxd = lead.vx - lead.omega * (ahead * s + left * c)
    dyd = lead.vy + lead.omega * (ahead * c - left * s)
    f, g, h = arm_terms(ctx)
    th = ctx["theta"]
    ct, st = np.cos(th), np.sin(th)
    vx = ctx["k1"] * (xd - ctx["x"]) + ff * dxd + ct * f - st * g
    vy = ctx["k2"] * (yd - ctx["y"]) + ff * dyd + st * f + ct * g
    omega = ctx["k3"] * wrap(thd - th) + ff * lead.omega + h
    u = stack_inputs(ctx, {"vx": vx, "vy": vy, "omega": omega})
    return np.where(lead.ok[:, None], u, 0.0)


def _station(
    ctx: LawContext, lead: LeaderState, ahead: np.ndarray, left: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(ahead, left, phi): the follower's place and heading offset in the leader's frame —
    as given (phi from the parameters), or captured from the poses at the first copy of a
    new leader's stream where ``capture`` is set."""
    given = (np.asarray(ahead, float), np.asarray(left, float), np.asarray(ctx["phi"], float))
    on = ctx["capture"] > 0
    if not on.any():
        return given
    here = relative_pose(ctx["x"], ctx["y"], ctx["theta"], lead.x, lead.y, lead.theta)
    kept = ctx.capture(
        "station", lead.who, dict(zip(("ahead", "left", "phi"), here, strict=True)), on & lead.ok
    )
    use = on & np.isfinite(kept["ahead"])
    return tuple(
        np.where(use, kept[k], g)  # type: ignore[return-value]  # (three names, three)
        for k, g in zip(("ahead", "left", "phi"), given, strict=True)
    )


@law(
    "transport.match",
    plants=("unicycle",),
    params={
        "k_form": 1.0,
        "k_cross": 30.0,
        "k_heading": 8.0,
        "capture": 1.0,
        "ahead": -1.0,
        "left": 0.0,
        "phi": 0.0,
    },
)
def match(ctx: LawContext) -> np.ndarray:
    """The Scout's Follow: the paper's u = (v̂_l, ω̂_l) with ``k_form`` = 0; by default it
    also closes the loop on its place in the team.

    The place is (``ahead``, ``left``) in the leader's frame, or with ``capture`` (the
    default) the place the Scout held when the first copy of a new leader's stream arrived,
    so a change of leader does not send it across the team. The place moves on a path of
    its own (v_d = v̂_l + ω̂_l × offset); the Scout tracks it as a reference unicycle that
    drives along that path (forwards, or backwards when the path points away from the
    leader's heading + ``phi``; standing, that heading) with Kanayama's law:
    u1 = v_r cos e_θ + k_form e_x, u2 = ω̂_l + v_r k_cross e_y + |v_r| k_heading sin e_θ,
    where (e_x, e_y) is the place's offset in the Scout's frame, e_θ the reference heading
    minus the Scout's, v_r the place's signed speed. With V = (e_x² + e_y²)/2 +
    (1 − cos e_θ)/k_cross, dV/dt = −k_form e_x² − (k_heading/k_cross)|v_r| sin² e_θ ≤ 0 for
    a leader at constant velocity, forwards or backwards. Stands still until a copy of the
    leader's stream arrives.
    """
    lead = leader_estimate(ctx)
    k = ctx["k_form"]
    copy = stack_inputs(ctx, {"v": lead.v, "omega": lead.omega})
    if not np.any(k > 0):
        return np.where(lead.ok[:, None], copy, 0.0)
    ahead, left, phi = _station(ctx, lead, ctx["ahead"], ctx["left"])
    x, y, th = ctx["x"], ctx["y"], ctx["theta"]
    c, s = np.cos(lead.theta), np.sin(lead.theta)
    ox, oy = ahead * c - left * s, ahead * s + left * c  # the place's offset, world frame
    ex, ey = lead.x + ox - x, lead.y + oy - y
    ct, st = np.cos(th), np.sin(th)
    along, cross = ex * ct + ey * st, -ex * st + ey * ct
    dx, dy = lead.vx - lead.omega * oy, lead.vy + lead.omega * ox  # the place's velocity
    speed, path = np.hypot(dx, dy), np.arctan2(dy, dx)
    nominal = lead.theta + phi
    back = np.cos(path - nominal) < 0
    moving = speed > 1e-9
    ref = np.where(moving, np.where(back, path + np.pi, path), nominal)
    vr = np.where(back, -speed, speed)
    e_th = wrap(ref - th)
    v = vr * np.cos(e_th) + k * along
    omega = lead.omega + vr * ctx["k_cross"] * cross + np.abs(vr) * ctx["k_heading"] * np.sin(e_th)
    track = stack_inputs(ctx, {"v": v, "omega": omega})
    return np.where(lead.ok[:, None], np.where((k > 0)[:, None], track, copy), 0.0)


@law("transport.dock_arm", plants=("unicycle",), params=dict(ARM))
def dock_arm(ctx: LawContext) -> np.ndarray:
    """The Labmate's Dock: u1 = f(x_a) = k_x x_a, u2 = g(x_a) = k_y y_a + k_th θ_a.

    Drives the grasp's offset to zero (with the default signs, see ``ARM``): a robot whose
    mount is ahead of its grasp point (x_a > 0) backs up, one left of it (y_a > 0) turns
    right. Nothing is saturated here — the plant's limits do that. No arm: stands still.
    """
    f, g, h = arm_terms(ctx)
    return stack_inputs(ctx, {"v": f, "omega": g + h})
