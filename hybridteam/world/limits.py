"""How long a bar carried by two disk robots can be and still get round a 90° corner.

The bar's ends are the centres of disks of radius ``r`` that must keep ``r`` away from
every wall; the bar itself is a segment of no thickness that must not cross a wall (it
may graze the inner vertex). Shrinking the corridor by ``r`` gives the region the ends
live in. Its outer walls move inward by ``r``, so the inner vertex is ``w_a - r`` from
the shifted outer wall of leg a and ``w_b - r`` from that of leg b. The shifted inner
walls do not matter: the bar only touches the inner walls at the vertex, and the ends,
on the shifted outer walls, are ``w - r >= r`` from the inner walls when ``w >= 2r``.

To get round, the bar must pass through every direction between the two legs. At angle
``phi`` to leg a, the longest bar through the vertex with both ends in the region is
``a / sin(phi) + b / cos(phi)`` with ``a = w_a - r`` and ``b = w_b - r``; the bar fits iff
it is no longer than the minimum over ``phi`` of that chord, which is the classic

    L_max = (a^(2/3) + b^(2/3))^(3/2),     attained at tan(phi) = (a / b)^(1/3).

For equal widths that is ``2 * sqrt(2) * (w - r)`` (at 45°): 494.97 for the paper's
corridor (w = 200) and r = 25, 486.48 for r = 28. A bar held through springs can be longer
by the springs' slack (see :func:`hybridteam.world.payload.two_grasp_slack`): the robots'
centres obey this bound, the bar's ends may overhang them.
"""

from __future__ import annotations

import math


def effective_widths(width_a: float, width_b: float, radius: float) -> tuple[float, float]:
    """Distances from the inner vertex to the outer walls shifted inward by ``radius``."""
    if radius < 0:
        raise ValueError("radius must be non-negative")
    if min(width_a, width_b) < 2.0 * radius:
        raise ValueError("a disk of this radius does not fit in the corridor")
    return width_a - radius, width_b - radius


def longest_ladder(width_a: float, width_b: float, radius: float = 0.0) -> float:
    """Longest bar whose ends keep ``radius`` from the walls that passes a 90° turn."""
    a, b = effective_widths(width_a, width_b, radius)
    return (a ** (2.0 / 3.0) + b ** (2.0 / 3.0)) ** 1.5


def critical_angle(width_a: float, width_b: float, radius: float = 0.0) -> float:
    """Angle (radians, to leg a) at which the longest bar is tightest: tan = (a/b)^(1/3)."""
    a, b = effective_widths(width_a, width_b, radius)
    return math.atan((a / b) ** (1.0 / 3.0))
