"""A run as a moving picture: robots with their footprint, heading, trail and current mode.

Stills show where robots went; an animation shows *when* — who waited for whom, which mode
each robot was in as it passed a point. Flow agents get their state plot with a moving
cursor. Frames are drawn by updating a handful of artists on one figure (no re-plotting),
and a run is subsampled to at most ``MAX_FRAMES`` frames so files stay small and fast.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib import rc_context
from matplotlib.animation import FFMpegWriter, PillowWriter
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from matplotlib.patches import Circle, Polygon
from PIL import Image

from hybridteam.export.scene import (
    COLLISION_MARK,
    collision_marks,
    draw_guides,
    draw_world,
    flow_agents,
    payload_names,
    payload_outline,
    payload_shape,
    planar_agents,
    pose,
    scene_extent,
    scene_of,
)
from hybridteam.export.style import FONT, HALO, PALETTE
from hybridteam.export.timeline import end_time, pick
from hybridteam.export.trajectories import draw_flow, main_lane_intervals
from hybridteam.trace import Trace, temp_path

MAX_FRAMES = 300
FORMATS = (".gif", ".mp4")
#: colours of marks that may first appear after the first frame (lost messages, collisions):
#: a GIF's palette is the first frame's, which would show them in the nearest other colour
RESERVED = ("#CC0000",)


class _Mode:
    """The agent's current (own-lane) mode at any time, by binary search."""

    def __init__(self, trace: Trace, instance: int, agent: str) -> None:
        iv = main_lane_intervals(trace, instance, agent)
        self.starts = np.asarray(iv["start"], float)
        self.modes = iv["mode"].tolist()

    def at(self, t: float) -> str:
        k = int(np.searchsorted(self.starts, t, side="right")) - 1
        return self.modes[k] if 0 <= k < len(self.modes) else ""


def frame_times(trace: Trace, instance: int, fps: float, duration: float | None) -> np.ndarray:
    """Evenly spaced simulation times: ``fps * duration`` frames (the playback length), by
    default one per sample; never more than ``MAX_FRAMES``."""
    t0 = float(trace.sample_times[0]) if len(trace.sample_times) else 0.0
    t1 = max(end_time(trace, instance), t0)
    if duration is not None:
        count = round(fps * duration)
    else:
        count = int(np.sum((trace.sample_times >= t0) & (trace.sample_times <= t1)))
    return np.linspace(t0, t1, int(np.clip(count, 2, MAX_FRAMES)))


def write_animation(
    trace: Trace,
    path: str | os.PathLike,
    instance: int = 0,
    fps: int = 20,
    duration: float | None = None,
    speed: float | None = None,
    size: tuple[float, float] | None = None,
    dpi: float = 100.0,
) -> Path:
    """Write a .gif (Pillow) or .mp4 (ffmpeg) of the run; ``duration`` is the playback
    length in seconds, or ``speed`` simulated seconds per second of playback (default: a
    frame per sample, at most ``MAX_FRAMES``); ``size`` in inches and ``dpi`` set the
    frame's pixels (default 8 inches wide at 100 dpi)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in FORMATS:
        raise ValueError(
            f"{path}: unsupported animation format {suffix or '(none)'}; "
            f"use one of {', '.join(FORMATS)}"
        )
    if suffix == ".mp4" and shutil.which("ffmpeg") is None:
        raise RuntimeError("ffmpeg is not installed; write a .gif instead")
    if speed is not None:
        t0 = float(trace.sample_times[0]) if len(trace.sample_times) else 0.0
        duration = max(end_time(trace, instance) - t0, 0.0) / speed
    times = frame_times(trace, instance, fps, duration)
    linger = 1.5 * float(times[1] - times[0]) if len(times) > 1 else 0.0
    with rc_context({"font.family": FONT}):
        fig, update, trails, moving = _build(trace, instance, size, dpi, linger)
        canvas = fig.canvas
        assert isinstance(canvas, FigureCanvasAgg)  # (_build gives the figure one)
        for artist in [*trails, *moving]:
            artist.set_animated(True)  # left out of the background, drawn per frame
        canvas.draw()
        background = canvas.copy_from_bbox(fig.bbox)
        writer = _CanvasGifWriter(fps=fps) if suffix == ".gif" else _CanvasFFMpegWriter(fps=fps)
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = temp_path(path)
        try:
            with writer.saving(fig, str(tmp), dpi=fig.dpi):
                for t in times:
                    update(float(t))
                    canvas.restore_region(background)
                    for artist in trails:  # only the stretch since the last frame...
                        fig.draw_artist(artist)
                    background = canvas.copy_from_bbox(fig.bbox)  # ...kept from now on
                    for artist in moving:
                        fig.draw_artist(artist)
                    writer.grab_frame()
            os.replace(tmp, path)
        finally:
            tmp.unlink(missing_ok=True)
            fig.clear()
    return path


def _canvas_rgb(fig: Figure) -> np.ndarray:
    canvas = fig.canvas
    assert isinstance(canvas, FigureCanvasAgg)  # (the figures here are drawn by Agg)
    return np.asarray(canvas.buffer_rgba())[..., :3]


class _CanvasGifWriter(PillowWriter):
    """PillowWriter fed from the blitted canvas: a savefig per frame would redraw the whole
    figure (axes, ticks, static paths) and cost ten times more than the moving parts.

    Frames share the first frame's palette, so colours do not flicker between frames and
    quantizing is a lookup rather than a palette search per frame.
    """

    def setup(self, fig: Figure, outfile: Any, dpi: float | None = None) -> None:
        super().setup(fig, outfile, dpi=dpi)
        self._images: list[Image.Image] = []

    def grab_frame(self, **savefig_kwargs: Any) -> None:
        image = Image.fromarray(np.ascontiguousarray(_canvas_rgb(self.fig)))
        if not self._images:
            self._palette = _palette(image)
        self._images.append(image.quantize(palette=self._palette, dither=Image.Dither.NONE))

    def finish(self) -> None:
        self._images[0].save(
            self.outfile,
            save_all=True,
            append_images=self._images[1:],
            duration=int(1000 / self.fps),
            loop=0,
            optimize=False,
        )


def _palette(first: Image.Image) -> Image.Image:
    """The palette of every frame: the first frame's colours (median cut) and the
    :data:`RESERVED` ones."""
    size = 255 - len(RESERVED)
    colours = first.quantize(colors=size, method=Image.Quantize.MEDIANCUT).getpalette() or []
    colours = (colours[: 3 * size] + [0] * 3 * size)[: 3 * size]
    for c in RESERVED:
        colours += [int(c[k : k + 2], 16) for k in (1, 3, 5)]
    out = Image.new("P", (1, 1))
    out.putpalette(colours)
    return out


class _CanvasFFMpegWriter(FFMpegWriter):
    """FFMpegWriter piping the blitted canvas (raw RGBA, the writer's frame format)."""

    def grab_frame(self, **savefig_kwargs: Any) -> None:
        # (_proc: the ffmpeg process MovieWriter starts, not in matplotlib's stubs; the
        # canvas is Agg's, whose buffer_rgba the base canvas type does not declare)
        frame = np.asarray(self.fig.canvas.buffer_rgba())  # type: ignore[attr-defined]
        self._proc.stdin.write(frame.tobytes())  # type: ignore[attr-defined]


def _build(
    trace: Trace,
    instance: int,
    size: tuple[float, float] | None = None,
    dpi: float = 100.0,
    linger: float = 0.0,
) -> tuple[Figure, Any, list[Any], list[Any]]:
    """The figure with its static parts drawn, a function moving it to time t, the artists
    that accumulate (trails: each frame adds the stretch since the previous one, so a frame
    costs the same late in a long run as early) and those redrawn every frame.

    The plane is fitted to the scene at equal aspect; a panel beside it holds the time and
    each robot's current mode, one line per robot, so no label ever sits on another.
    """
    planar, flows = planar_agents(trace), flow_agents(trace)
    limits = scene_extent(trace, instance) if planar else None
    aspect = (limits[3] - limits[2]) / max(limits[1] - limits[0], 1e-12) if limits else 0.5
    width = size[0] if size else 9.0
    panel_w = 2.1  # the time and one line pair per robot
    plane_h = (width - panel_w - 0.9) * float(np.clip(aspect, 0.2, 1.4)) if planar else 0.0
    heights = ([max(plane_h, 1.6)] if planar else []) + [1.5] * len(flows)
    fig = Figure(figsize=(width, size[1] if size else 1.3 + max(sum(heights), 1.8)), dpi=dpi)
    FigureCanvasAgg(fig)
    grid = fig.add_gridspec(
        max(len(heights), 1),
        2,
        height_ratios=heights or [1],
        width_ratios=[width - panel_w, panel_w],
    )
    panel = fig.add_subplot(grid[:, 1])
    panel.axis("off")
    updates: list[Any] = []  # per panel: its update(t)
    trails: list[Any] = []  # artists that only grow (blitted onto the background)
    moving: list[Any] = []  # artists redrawn every frame
    if planar and limits is not None:  # (limits: the planar robots' scene)
        fn, trails, artists = _planar(
            fig.add_subplot(grid[0, 0]), trace, instance, planar, limits, linger
        )
        updates.append(fn)
        moving += artists
    for k, agent in enumerate(flows):
        ax = fig.add_subplot(grid[(1 if planar else 0) + k, 0])
        fn, artists = _flow(ax, trace, instance, agent)
        updates.append(fn)
        moving += artists
    stamp = panel.text(
        0.0,
        1.0,
        "",
        ha="left",
        va="top",
        fontsize=10,
        family="monospace",
        transform=panel.transAxes,
        gid="time",
    )
    rows = [
        (a, PALETTE[i % len(PALETTE)], _Mode(trace, instance, a))
        for i, a in enumerate(planar + [f for f in flows if f not in planar])
    ]
    lines = []
    tall = fig.get_figheight() * 0.85  # the panel's height in inches, about
    step = min(0.5 / tall, 0.85 / max(len(rows), 1))  # a row: name and mode, 0.5 in
    for k, (a, color, _mode) in enumerate(rows):  # fixed rows: texts cannot overlap
        y = 0.88 - k * step
        panel.text(
            0.0,
            y,
            a,
            ha="left",
            va="top",
            fontsize=9,
            fontweight="bold",
            color=color,
            transform=panel.transAxes,
            gid="robot",
        )
        lines.append(
            panel.text(
                0.0,
                y - 0.42 * step,
                "",
                ha="left",
                va="top",
                fontsize=8,
                color="#222222",
                transform=panel.transAxes,
                gid="mode",
            )
        )
    fig.suptitle(str(trace.meta.get("team", "")), fontsize=11)
    fig.set_layout_engine("constrained")
    fig.canvas.draw()  # lay out once, then freeze: every frame keeps the same geometry
    fig.set_layout_engine(None)  # None, not "none": a placeholder engine costs a 2nd draw

    def update(t: float) -> None:
        k = max(int(np.searchsorted(trace.sample_times, t, side="right")) - 1, 0)
        for fn in updates:
            fn(t, k)
        stamp.set_text(f"t = {t:.2f} s")
        for line, (_a, _c, mode) in zip(lines, rows, strict=True):
            line.set_text(_fit(mode.at(t), 30))

    return fig, update, trails, [*moving, stamp, *lines]


def _fit(text: str, width: int) -> str:
    """A mode path cut from the left to ``width`` characters (the leaf matters most)."""
    return text if len(text) <= width else "…" + text[-(width - 1) :]


def _planar(
    ax: Any,
    trace: Trace,
    instance: int,
    agents: list[str],
    limits: tuple[float, float, float, float],
    linger: float,
) -> tuple[Any, list[Any], list[Any]]:
    """Walls, obstacles and guide paths; per robot its path to come (faint), its trail, its
    footprint at true size with a heading line; the payloads at their poses; control
    messages as lines from sender to receiver while in flight (and ``linger`` seconds after
    they were sent, so a 30 ms message is seen at all), lost ones dashed red; a red star
    where a robot or payload collided, from that moment on."""
    scene = scene_of(trace)
    draw_world(ax, scene)
    draw_guides(ax, scene, instance, agents)
    poses = {a: pose(trace, a, instance) for a in agents}
    extent = max(limits[1] - limits[0], limits[3] - limits[2])
    robots = []
    for i, a in enumerate(agents):
        p, color = poses[a], PALETTE[i % len(PALETTE)]
        ax.plot(p[:, 0], p[:, 1], color=color, linewidth=0.8, alpha=0.25)  # where it will go
        foot = scene.footprints.get(a)
        radius = foot.radius if foot else None
        r = float(radius) if radius else 0.02 * max(extent, 1e-9)
        trail = ax.plot([], [], color=color, linewidth=1.6, zorder=4)[0]
        body = ax.add_patch(
            Circle(
                (np.nan, np.nan),
                r,
                facecolor=color,
                alpha=0.35,
                edgecolor=color,
                zorder=5,
                gid=f"robot:{a}",
            )
        )
        head = ax.plot([], [], color=color, linewidth=1.6, zorder=6)[0]
        valid = ~np.isnan(p[:, 0])
        last = np.maximum.accumulate(np.where(valid, np.arange(len(p)), -1))
        robots.append((p, last, r, trail, body, head))
    loads = _payloads(ax, trace, instance)
    flashes = _messages(ax, trace, instance, agents, poses, linger)
    hits = np.array([h[:3] for h in collision_marks(trace, instance)], float).reshape(-1, 3)
    crashes = ax.plot([], [], zorder=9, gid="collisions", **COLLISION_MARK)[0]
    done = [0] * len(robots)  # trail drawn up to this sample
    ax.set_xlim(limits[0], limits[1])
    ax.set_ylim(limits[2], limits[3])
    ax.set_aspect("equal", adjustable="box")
    ax.grid(color="#E0E0E0", linewidth=0.6)
    unit = scene.unit
    ax.set_xlabel(f"x ({unit})" if unit else "x")
    ax.set_ylabel(f"y ({unit})" if unit else "y")

    def update(t: float, k: int) -> None:
        for i, (p, last, r, trail, body, head) in enumerate(robots):
            j = last[min(k, len(last) - 1)]
            if j < 0:
                continue
            x, y, th = p[j]
            trail.set_data(p[done[i] : j + 1, 0], p[done[i] : j + 1, 1])
            done[i] = j
            body.set_center((x, y))
            head.set_data([x, x + r * 1.4 * np.cos(th)], [y, y + r * 1.4 * np.sin(th)])
        for fn in (loads[0], flashes[0]):
            fn(t, k)
        seen = hits[hits[:, 0] <= t]  # each collision marked from when it happens on
        crashes.set_data(seen[:, 1], seen[:, 2])

    moving = [x for r in robots for x in r[4:]] + loads[1] + flashes[1] + [crashes]
    return update, [r[3] for r in robots], moving


def _payloads(ax: Any, trace: Trace, instance: int) -> tuple[Any, list[Any]]:
    """One outline per payload, moved to its pose at every frame."""
    items = []
    for k, name in enumerate(payload_names(trace)):
        shape = payload_shape(trace, name)
        patch = ax.add_patch(
            Polygon(
                np.zeros((4, 2)),
                closed=True,
                visible=False,
                facecolor=PALETTE[(k + 5) % len(PALETTE)],
                alpha=0.55,
                edgecolor="#333333",
                linewidth=0.8,
                zorder=4.5,
                gid=f"payload:{name}",
            )
        )
        items.append((pose(trace, name, instance), shape, patch))

    def update(t: float, k: int) -> None:
        for p, shape, patch in items:
            j = min(k, len(p) - 1)
            ok = bool(np.isfinite(p[j]).all())
            patch.set_visible(ok)
            if ok:
                patch.set_xy(payload_outline(shape, *p[j]))

    return update, [patch for _p, _s, patch in items]


def _messages(
    ax: Any,
    trace: Trace,
    instance: int,
    agents: list[str],
    poses: dict[str, np.ndarray],
    linger: float,
) -> tuple[Any, list[Any]]:
    """Control messages between drawn robots: (t_send, t_shown_until, sender, receiver,
    lost) rows, drawn as one collection per frame."""
    msgs = pick(trace.messages, instance)
    rows = []
    times = trace.sample_times
    if len(msgs):
        for m in msgs:
            if (
                m.socket == "data"
                or m.sender not in poses
                or m.receiver not in poses
                or m.reason == "run ended"
            ):
                continue
            lost = m.status == "lost"
            arrive = m.t_send if lost or m.t_recv is None else float(m.t_recv)
            rows.append(
                (float(m.t_send), max(arrive, m.t_send + linger), m.sender, m.receiver, lost)
            )
    sent = LineCollection([], colors="#222222", linewidths=1.0, zorder=8, gid="messages")
    gone = LineCollection(
        [], colors="#CC0000", linewidths=1.0, linestyles="dashed", zorder=8, gid="lost-messages"
    )
    ax.add_collection(sent)
    ax.add_collection(gone)

    def at(name: str, t: float) -> np.ndarray:
        p = poses[name]
        return np.array([np.interp(t, times, p[:, 0]), np.interp(t, times, p[:, 1])])

    def update(t: float, k: int) -> None:
        live = [r for r in rows if r[0] <= t <= r[1]]
        sent.set_segments([[at(r[2], t), at(r[3], t)] for r in live if not r[4]])
        gone.set_segments([[at(r[2], t), at(r[3], t)] for r in live if r[4]])

    return update, [sent, gone]


def _flow(ax: Any, trace: Trace, instance: int, agent: str) -> tuple[Any, list[Any]]:
    draw_flow(ax, trace, instance, agent)
    cursor = ax.axvline(0.0, color="#CC0000", linewidth=1.0, zorder=6)
    label = ax.text(
        0.99,
        0.95,
        "",
        transform=ax.transAxes,
        ha="right",
        va="top",
        fontsize=8,
        path_effects=HALO,
        zorder=7,
    )
    mode = _Mode(trace, instance, agent)

    def update(t: float, k: int) -> None:
        cursor.set_xdata([t, t])
        label.set_text(f"mode: {mode.at(t)}")

    return update, [cursor, label]
