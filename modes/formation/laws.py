"""A unicycle that keeps a place in its leader's frame, using what it hears of the leader.

The leader's pose and velocity come from the ``state`` stream of the role-assignment
protocol (the architecture paper's x̂_l, v̂_l), read from the sender named by the follower's
``leader`` variable and dead-reckoned over the copy's age. The follower's place is
``(ahead, left)`` in the leader's frame (``ahead = -1``: one metre behind). Control: the
leader's velocity as feed-forward, plus proportional terms on the along-track and
cross-track errors and on the heading difference. Without any estimate yet, it stands still.
"""

from __future__ import annotations

import numpy as np

from hybridteam.library import LawContext, law


@law("formation.follow", plants=("unicycle",),
     params={"ahead": -1.0, "left": 0.0, "k_along": 1.0, "k_cross": 1.0, "k_heading": 2.0})
def follow(ctx: LawContext) -> np.ndarray:
    """Keep station at (ahead, left) in the leader's frame, from the leader's stream."""
    leader = ctx.get("leader", -1.0)
    who = np.where(leader >= 0, np.rint(leader), -1).astype(np.intp)
    est = ctx.estimate("state", sender=np.where(who >= 0, who, 0), extrapolate=True)
    ok = (who >= 0) & est.valid & np.isfinite(est["x"])
    x, y, th = ctx["x"], ctx["y"], ctx["theta"]
    lth = est["theta"]
    c, s = np.cos(lth), np.sin(lth)
    px = est["x"] + ctx["ahead"] * c - ctx["left"] * s
    py = est["y"] + ctx["ahead"] * s + ctx["left"] * c
    ex, ey = px - x, py - y
    along = ex * np.cos(th) + ey * np.sin(th)
    cross = -ex * np.sin(th) + ey * np.cos(th)
    v = est["v"] * np.cos(lth - th) + ctx["k_along"] * along
    w = est["omega"] + ctx["k_heading"] * np.sin(lth - th) + ctx["k_cross"] * cross
    u = np.stack([v, w], axis=1)
    return np.where(ok[:, None], np.nan_to_num(u), 0.0)
