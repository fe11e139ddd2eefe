"""Messages in a timeline: arrows from send to receipt time, their labels, lost copies.

Kept apart from :mod:`.timeline` (lanes and bars) because the rules for what a close-up
says about messages are their own: control messages are the story, data streams background,
and messages that share an arrow share a label.
"""

from __future__ import annotations

import itertools
import math
from typing import TYPE_CHECKING, Any

import numpy as np
from matplotlib.collections import PolyCollection

from hybridteam.export.style import HALO, text_color

if TYPE_CHECKING:
    from hybridteam.export.timeline import TimelineData


def latency_text(latency: float) -> str:
    ms = latency * 1000.0
    return f"+{ms:.0f} ms" if abs(ms) >= 1 or ms == 0 else f"+{ms:.2g} ms"


def loss_text(data: TimelineData) -> str:
    """`` — 2 messages lost (×), 2500 data copies dropped`` (empty when nothing was)."""
    parts = [f"{data.lost} message{'s' * (data.lost != 1)} lost (×)"] * bool(data.lost)
    parts += [f"{data.dropped} data cop{'ies' if data.dropped != 1 else 'y'} dropped"
              ] * bool(data.dropped)
    return " — " + ", ".join(parts) if parts else ""


def time_at(t_send: Any, t_recv: Any, y_send: Any, y_recv: Any, y: float) -> Any:
    """When an arrow from (t_send, y_send) to (t_recv, y_recv) is at height ``y`` (clipped
    to its ends; its middle when it is flat). Numbers, or arrays of arrows."""
    rise = np.subtract(y_recv, y_send)
    with np.errstate(divide="ignore", invalid="ignore"):
        frac = np.where(rise != 0, (y - np.asarray(y_send)) / rise, 0.5)
    return t_send + np.clip(frac, 0.0, 1.0) * np.subtract(t_recv, t_send)


class Crossings:
    """Which delivered message arrows pass a height within a time span. The arrows are
    gathered once per timeline, then each mode name asks with numpy instead of a loop over
    every arrow (a close-up asks it for every name it draws)."""

    def __init__(self, data: TimelineData) -> None:
        keep = [a for a in data.arrows
                if not (a.lost or math.isnan(a.t_recv)) and a.y_send != a.y_recv]
        cols = np.array([(a.t_send, a.t_recv, a.y_send, a.y_recv) for a in keep],
                        float).reshape(-1, 4)
        self.ts, self.tr, self.ys, self.yr = cols.T

    def __call__(self, y: float, t0: float, t1: float) -> bool:
        """Whether an arrow passes height ``y`` between ``t0`` and ``t1``."""
        span = (np.minimum(self.ys, self.yr) <= y) & (y <= np.maximum(self.ys, self.yr))
        if not span.any():
            return False
        t = time_at(self.ts[span], self.tr[span], self.ys[span], self.yr[span], y)
        return bool(((t0 <= t) & (t <= t1)).any())


def draw_mode_names(ax: Any, fig: Any, data: TimelineData, px_per_s: float) -> None:
    """Each stay's mode name where it fits in its bar (``px_per_s``: pixels per second).
    Where a message arrow crosses a name, a patch of the bar's colour goes under the name,
    over the arrow, so the arrow stops short of the letters instead of striking them out;
    the patches are one collection (a text's own bbox would cost a layout per name)."""
    t0, t1 = data.span
    first, last = data.lanes[0], data.lanes[-1]
    y_span = (first.y + first.height / 2 + 0.2) - (last.y - last.height / 2 - 0.2)
    px_per_y = ax.get_position().height * fig.get_figheight() * fig.dpi / y_span
    crossed = Crossings(data)
    backings: list[np.ndarray] = []
    backing_colors: list[str] = []
    for b in data.bars:
        lane = data.lanes[b.lane]
        size = 6.5 if lane.top else 8.0
        lo, hi = max(b.start, t0), min(b.end, t1)
        text_px = len(b.label) * size * 0.62 * fig.dpi / 72  # the name's width, about
        if (hi - lo) * px_per_s > text_px + 4:
            half = text_px / px_per_s / 2
            mid = (lo + hi) / 2
            if crossed(lane.y, mid - half, mid + half):
                # over the message arrows, on a patch of the bar's colour where an arrow
                # crosses the name: it stops short of the letters instead of striking them
                # out (all patches one collection: a bbox per text costs a layout each)
                h = 0.62 * size * fig.dpi / 72 / px_per_y
                backings.append(np.array([(mid - half, lane.y - h), (mid + half, lane.y - h),
                                          (mid + half, lane.y + h), (mid - half, lane.y + h)]))
                backing_colors.append(b.color)
            ax.text((lo + hi) / 2, lane.y, b.label, ha="center", va="center", fontsize=size,
                    color=text_color(b.color), clip_on=True, zorder=6, gid="mode-label")
    if backings:
        ax.add_collection(PolyCollection(backings, facecolors=backing_colors,
                                         edgecolors="none", zorder=5, gid="mode-backings"))


def gap_centres(data: TimelineData) -> list[float]:
    """The middle of each white gap between two lanes (lanes are stacked downwards)."""
    lanes = sorted(data.lanes, key=lambda lane: -lane.y)
    return [((a.y - a.height / 2) + (b.y + b.height / 2)) / 2
            for a, b in itertools.pairwise(lanes)]


def draw_messages(ax: Any, data: TimelineData, char_width: float) -> None:
    """Arrows for all messages; a label only where it does not run into the previous one
    at the same height (``char_width``: seconds per character of label text).

    Control messages are the story of a close-up (request, grant, their acks): black, and
    messages sharing an arrow (a grant and the ack of the request it answers, sent at the
    same instant) share one label, ``grant + ack +30 ms``. Periodic data (a pose stream on
    the ``data`` socket) is drawn thin and light, unlabelled, so it shows without hiding them.
    """
    lost: list[tuple[float, float]] = []
    free_from: dict[float, float] = {}  # label row (y) -> time where it is free again
    shared: dict[tuple[float, float, float, float], list[str]] = {}
    faint_lost: list[tuple[float, float]] = []
    for a in data.arrows:
        if a.lost and a.socket == "data":
            faint_lost.append((a.t_send, a.y_send))
            continue
        if a.lost:
            lost.append((a.t_send, a.y_send))
            if data.window:
                ax.annotate(a.type, (a.t_send, a.y_send), xytext=(5, 6),
                            textcoords="offset points", fontsize=7, color="#CC0000",
                            path_effects=HALO, gid="lost-label")
            continue
        faint = a.socket == "data"
        key = (a.t_send, a.t_recv, a.y_send, a.y_recv)
        if not faint and key in shared:  # one arrow, one label for all it carries
            if a.type not in shared[key]:
                shared[key].append(a.type)
            continue
        # an annotation keeps its end points as data (xyann -> xy), exactly send -> receipt
        ax.annotate("", xy=(a.t_recv, a.y_recv), xytext=(a.t_send, a.y_send),
                    zorder=3 if faint else 4, gid="data-message" if faint else "message",
                    arrowprops={"arrowstyle": "-|>", "mutation_scale": 6 if faint else 9,
                                "shrinkA": 0, "shrinkB": 0,
                                "color": "#BBBBBB" if faint else "#333333",
                                "linewidth": 0.5 if faint else 0.9})
        if not faint:
            shared[key] = [a.type]
    gaps = gap_centres(data)
    for (t_send, t_recv, y_send, y_recv), types in shared.items():
        # in the white gap between lanes nearest the arrow's middle, where the arrow
        # crosses it (never on a bar, where it would cover a mode's name)
        y = min(gaps, key=lambda g: abs(g - (y_send + y_recv) / 2)) if gaps else \
            (y_send + y_recv) / 2
        x = time_at(t_send, t_recv, y_send, y_recv, y) + 0.6 * char_width
        text = f"{' + '.join(types)} {latency_text(t_recv - t_send)}"
        if x >= free_from.get(y, -math.inf):
            free_from[y] = x + (len(text) + 1) * char_width
            ax.text(x, y, text, fontsize=7, ha="left", va="center", zorder=7, path_effects=HALO,
                    clip_on=True, gid="message-label")
    if faint_lost:
        ax.plot(*zip(*faint_lost, strict=True), linestyle="none", marker="x", color="#999999",
                markersize=4, markeredgewidth=0.8, zorder=3, gid="data-lost")
    if lost:
        ax.plot(*zip(*lost, strict=True), linestyle="none", marker="X", color="#CC0000",
                markersize=8, markeredgecolor="white", markeredgewidth=0.5, zorder=6, gid="lost")
