"""Messages in a timeline: arrows from send to receipt time, their labels, lost copies.

Kept apart from :mod:`.timeline` (lanes and bars) because the rules for what a close-up
says about messages are their own: control messages are the story, data streams background,
nearly parallel arrows share a label, and every message kind is named before repeats and
acks.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from matplotlib.collections import PolyCollection

from hybridteam.export.style import HALO, text_color

if TYPE_CHECKING:
    from hybridteam.export.timeline import TimelineArrow, TimelineData

ACK = "ack"  # the reliable layer's acknowledgement: labelled after the messages it answers


def latency_text(latency: float) -> str:
    ms = latency * 1000.0
    return f"+{ms:.0f} ms" if abs(ms) >= 1 or ms == 0 else f"+{ms:.2g} ms"


def loss_text(data: TimelineData) -> str:
    """`` — 2 messages lost (×), 2500 data copies dropped`` (empty when nothing was)."""
    parts = [f"{data.lost} message{'s' * (data.lost != 1)} lost (×)"] * bool(data.lost)
    parts += [f"{data.dropped} data cop{'ies' if data.dropped != 1 else 'y'} dropped"] * bool(
        data.dropped
    )
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
        keep = [
            a for a in data.arrows if not (a.lost or math.isnan(a.t_recv)) and a.y_send != a.y_recv
        ]
        cols = np.array([(a.t_send, a.t_recv, a.y_send, a.y_recv) for a in keep], float).reshape(
            -1, 4
        )
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
                backings.append(
                    np.array(
                        [
                            (mid - half, lane.y - h),
                            (mid + half, lane.y - h),
                            (mid + half, lane.y + h),
                            (mid - half, lane.y + h),
                        ]
                    )
                )
                backing_colors.append(b.color)
            ax.text(
                (lo + hi) / 2,
                lane.y,
                b.label,
                ha="center",
                va="center",
                fontsize=size,
                color=text_color(b.color),
                clip_on=True,
                zorder=6,
                gid="mode-label",
            )
    if backings:
        ax.add_collection(
            PolyCollection(
                backings,
                facecolors=backing_colors,
                edgecolors="none",
                zorder=5,
                gid="mode-backings",
            )
        )


def gap_centres(data: TimelineData) -> list[float]:
    """The middle of each white gap between two lanes (lanes are stacked downwards)."""
    lanes = sorted(data.lanes, key=lambda lane: -lane.y)
    return [((a.y - a.height / 2) + (b.y + b.height / 2)) / 2 for a, b in itertools.pairwise(lanes)]


def label_rows(data: TimelineData, centre: float) -> list[float]:
    """The heights of the label rows in the gap centred at ``centre``: one, or two where
    the gap is a close-up's (two labels of 7 pt, 0.34 lane units apart, stack there)."""
    return [centre + 0.17, centre - 0.17] if data.gap >= 0.6 else [centre]


@dataclass
class Bundle:
    """Delivered control arrows close enough to read as one (same lanes, send and receipt
    times within two label characters of each other), labelled once: a grant and the ack of
    the request it answers leave at one instant and, with jitter, arrive milliseconds
    apart — two nearly parallel arrows that would get two labels on one spot."""

    arrows: list[TimelineArrow]
    types: list[str] = field(default_factory=list)

    @property
    def content(self) -> bool:
        """Whether it carries more than acks: the messages a close-up is about."""
        return any(t != ACK for t in self.types)

    def text(self) -> str:
        """``accept + ack +80–82 ms``: content names first, acks last, each once."""
        names = sorted(self.types, key=lambda t: t == ACK)  # stable: content in send order
        took = [a.t_recv - a.t_send for a in self.arrows]
        low, high = latency_text(min(took)), latency_text(max(took))
        span = low if low == high else f"{low.removesuffix(' ms')}–{high.removeprefix('+')}"
        return f"{' + '.join(names)} {span}"


def bundles(arrows: list[TimelineArrow], tolerance: float) -> list[Bundle]:
    """Delivered control arrows grouped into :class:`Bundle` s, in send order: an arrow
    joins the first bundle between the same lanes whose first arrow left and arrived
    within ``tolerance`` seconds of it."""
    out: list[Bundle] = []
    open_: dict[tuple[float, float], list[Bundle]] = {}
    for a in sorted(arrows, key=lambda a: (a.t_send, a.t_recv)):
        mine = open_.setdefault((a.y_send, a.y_recv), [])
        while mine and a.t_send - mine[0].arrows[0].t_send > tolerance:
            mine.pop(0)  # sorted by send time: bundles left behind stay closed
        home = next((b for b in mine if abs(a.t_recv - b.arrows[0].t_recv) <= tolerance), None)
        if home is None:
            home = Bundle([])
            mine.append(home)
            out.append(home)
        home.arrows.append(a)
        if a.type not in home.types:
            home.types.append(a.type)
    return out


def label_order(found: list[Bundle]) -> list[tuple[Bundle, bool]]:
    """The order labels claim their spots, each bundle with whether it brings a message
    kind no earlier bundle carried: those first (so every kind in the close-up is named),
    then the other content (a retransmitted copy), acks last; each group in send order."""
    first: dict[str, int] = {}
    for k, b in enumerate(found):
        for t in b.types:
            first.setdefault(t, k)
    news = set(first.values())
    return [
        (b, k in news)
        for k, b in sorted(
            enumerate(found), key=lambda kb: (not kb[1].content, kb[0] not in news, kb[0])
        )
    ]


class Rows:
    """The label rows of a close-up (the white gaps between lanes) and the time spans
    already labelled in each; a label goes where its text meets no other."""

    def __init__(self, data: TimelineData, char_width: float) -> None:
        self.data = data
        self.gaps = gap_centres(data)
        self.char = char_width
        self.span = data.span
        self.taken: dict[float, list[tuple[float, float]]] = {}

    def spots(self, b: Bundle, width: float, edge: bool = False) -> list[tuple[float, float]]:
        """Where ``b``'s label may start (time, row): beside the bundle where it crosses
        each gap it spans, right of it then left, the gap nearest its middle first; inside
        the window, and with ``edge`` (the first of a kind) then the spots it runs out of,
        where it is cut at the window's edge rather than left out."""
        a = b.arrows[0]
        lo, hi = sorted((a.y_send, a.y_recv))
        rows = [g for g in self.gaps if lo <= g <= hi] or (
            [min(self.gaps, key=lambda g: abs(g - (lo + hi) / 2))] if self.gaps else [(lo + hi) / 2]
        )
        rows.sort(key=lambda g: abs(g - (lo + hi) / 2))
        out = []
        for gap in rows:
            beside: tuple[list[tuple[float, float]], ...] = ([], [])  # right, left
            for y in label_rows(self.data, gap):
                cross = [
                    float(time_at(c.t_send, c.t_recv, c.y_send, c.y_recv, y)) for c in b.arrows
                ]
                beside[0].append((max(cross) + 0.6 * self.char, y))
                beside[1].append((min(cross) - 0.6 * self.char - width, y))
            out += beside[0] + beside[1]
        inside = [s for s in out if self.span[0] <= s[0] and s[0] + width <= self.span[1]]
        return inside + [s for s in out if s not in inside] * edge

    def claim(self, spots: list[tuple[float, float]], width: float) -> tuple[float, float] | None:
        """The first of ``spots`` whose span (with a character's room) meets no label."""
        for x, y in spots:
            lo, hi = x - 0.5 * self.char, x + width + 0.5 * self.char
            if all(hi <= a or b <= lo for a, b in self.taken.get(y, [])):
                self.taken.setdefault(y, []).append((lo, hi))
                return x, y
        return None


def draw_messages(ax: Any, data: TimelineData, char_width: float) -> None:
    """Arrows for all messages, and labels where they meet no other label
    (``char_width``: seconds per character of label text).

    Control messages are the story of a close-up (request, grant, their acks): black, and
    nearly parallel ones share one label (:class:`Bundle`), ``grant + ack +30 ms``. Every
    message kind gets a label before a second copy or an ack does (:func:`label_order`);
    a label that finds no free spot beside its arrows is left out. Periodic data (a pose
    stream on the ``data`` socket) is drawn thin and light, unlabelled, so it shows
    without hiding them.
    """
    lost: list[tuple[float, float]] = []
    drawn: set[tuple[float, float, float, float]] = set()
    delivered: list[TimelineArrow] = []
    faint_lost: list[tuple[float, float]] = []
    for a in data.arrows:
        if a.lost and a.socket == "data":
            faint_lost.append((a.t_send, a.y_send))
            continue
        if a.lost:
            lost.append((a.t_send, a.y_send))
            if data.window:
                ax.annotate(
                    a.type,
                    (a.t_send, a.y_send),
                    xytext=(5, 6),
                    textcoords="offset points",
                    fontsize=7,
                    color="#CC0000",
                    path_effects=HALO,
                    gid="lost-label",
                )
            continue
        faint = a.socket == "data"
        key = (a.t_send, a.t_recv, a.y_send, a.y_recv)
        if not faint:
            delivered.append(a)
            if key in drawn:  # one arrow for all it carries
                continue
            drawn.add(key)
        # an annotation keeps its end points as data (xyann -> xy), exactly send -> receipt
        ax.annotate(
            "",
            xy=(a.t_recv, a.y_recv),
            xytext=(a.t_send, a.y_send),
            zorder=3 if faint else 4,
            gid="data-message" if faint else "message",
            arrowprops={
                "arrowstyle": "-|>",
                "mutation_scale": 6 if faint else 9,
                "shrinkA": 0,
                "shrinkB": 0,
                "color": "#BBBBBB" if faint else "#333333",
                "linewidth": 0.5 if faint else 0.9,
            },
        )
    rows = Rows(data, char_width)
    for b, new in label_order(bundles(delivered, 2 * char_width)):
        text = b.text()
        width = len(text) * char_width
        at = rows.claim(rows.spots(b, width, new), width)
        if at is not None:
            ax.text(
                *at,
                text,
                fontsize=7,
                ha="left",
                va="center",
                zorder=7,
                path_effects=HALO,
                clip_on=True,
                gid="message-label",
            )
    if faint_lost:
        ax.plot(
            *zip(*faint_lost, strict=True),
            linestyle="none",
            marker="x",
            color="#999999",
            markersize=4,
            markeredgewidth=0.8,
            zorder=3,
            gid="data-lost",
        )
    if lost:
        ax.plot(
            *zip(*lost, strict=True),
            linestyle="none",
            marker="X",
            color="#CC0000",
            markersize=8,
            markeredgecolor="white",
            markeredgewidth=0.5,
            zorder=6,
            gid="lost",
        )
