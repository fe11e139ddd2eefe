"""A unicycle that keeps a place in its leader's frame, using what it hears of the leader.

The leader's pose and velocity come from the ``state`` stream of the role-assignment
protocol (the architecture paper's x̂_l, v̂_l), read from the sender named by the follower's
``leader`` variable and dead-reckoned over the copy's age. The follower's place is
``(ahead, left)`` in the leader's frame (``ahead = -1``: one metre behind), heading
``phi`` from the leader's; with ``capture`` it is instead the place the follower held when
the first copy of a new leader's stream arrived, so a change of leader keeps the team's
shape. Control: the leader's velocity as feed-forward, plus proportional terms on the
along-track and cross-track errors and on the heading difference. Without any estimate
yet, it stands still.
"""

from __future__ import annotations

import numpy as np

from hybridteam.library import LawContext, law
from hybridteam.world.geometry import relative_pose


@law(
    "formation.follow",
    plants=("unicycle",),
    params={
        "ahead": -1.0,
        "left": 0.0,
        "phi": 0.0,
        "capture": 0.0,
        "k_along": 1.0,
        "k_cross": 1.0,
        "k_heading": 2.0,
    },
)
def follow(ctx: LawContext) -> np.ndarray:
    """Keep station at (ahead, left, phi) in the leader's frame, from the leader's stream
    (``capture`` = 1: the station held when a new leader's first copy arrived)."""
    leader = ctx.get("leader", -1.0)
    who = np.where(leader >= 0, np.rint(leader), -1).astype(np.intp)
    est = ctx.estimate("state", sender=np.where(who >= 0, who, 0), extrapolate=True)
    ok = (who >= 0) & est.valid & np.isfinite(est["x"])
    x, y, th = ctx["x"], ctx["y"], ctx["theta"]
    lth = est["theta"]
    c, s = np.cos(lth), np.sin(lth)
    ahead, left, phi = ctx["ahead"], ctx["left"], ctx["phi"]
    on = ctx["capture"] > 0
    if on.any():
        here = relative_pose(x, y, th, est["x"], est["y"], lth)
        kept = ctx.capture(
            "station", who, dict(zip(("ahead", "left", "phi"), here, strict=True)), on & ok
        )
        use = on & np.isfinite(kept["ahead"])
        ahead, left, phi = (
            np.where(use, kept[k], g) for k, g in (("ahead", ahead), ("left", left), ("phi", phi))
        )
    px = est["x"] + ahead * c - left * s
    py = est["y"] + ahead * s + left * c
    ex, ey = px - x, py - y
    along = ex * np.cos(th) + ey * np.sin(th)
    cross = -ex * np.sin(th) + ey * np.cos(th)
    v = est["v"] * np.cos(lth + phi - th) + ctx["k_along"] * along
    w = est["omega"] + ctx["k_heading"] * np.sin(lth + phi - th) + ctx["k_cross"] * cross
    u = np.stack([v, w], axis=1)
    return np.where(ok[:, None], np.nan_to_num(u), 0.0)
