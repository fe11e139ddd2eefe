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
from matplotlib.figure import Figure
from matplotlib.patches import Circle
from PIL import Image

from hybridteam.export.scene import draw_world, flow_agents, planar_agents, pose
from hybridteam.export.style import FONT, HALO, PALETTE
from hybridteam.export.timeline import agent_meta, end_time
from hybridteam.export.trajectories import draw_flow, main_lane_intervals
from hybridteam.trace import Trace, temp_path

MAX_FRAMES = 300
FORMATS = (".gif", ".mp4")


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


def write_animation(trace: Trace, path: str | os.PathLike, instance: int = 0, fps: int = 20,
                    duration: float | None = None) -> Path:
    """Write a .gif (Pillow) or .mp4 (ffmpeg) of the run; ``duration`` is the playback
    length in seconds (default: a frame per sample, at most ``MAX_FRAMES``)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in FORMATS:
        raise ValueError(f"{path}: unsupported animation format {suffix or '(none)'}; "
                         f"use one of {', '.join(FORMATS)}")
    if suffix == ".mp4" and shutil.which("ffmpeg") is None:
        raise RuntimeError("ffmpeg is not installed; write a .gif instead")
    times = frame_times(trace, instance, fps, duration)
    with rc_context({"font.family": FONT}):
        fig, update, trails, moving = _build(trace, instance)
        canvas = fig.canvas
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
    return np.asarray(fig.canvas.buffer_rgba())[..., :3]


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
            self._images.append(image.quantize(colors=255, method=Image.Quantize.MEDIANCUT))
        else:
            self._images.append(image.quantize(palette=self._images[0],
                                               dither=Image.Dither.NONE))

    def finish(self) -> None:
        self._images[0].save(self.outfile, save_all=True, append_images=self._images[1:],
                             duration=int(1000 / self.fps), loop=0, optimize=False)


class _CanvasFFMpegWriter(FFMpegWriter):
    """FFMpegWriter piping the blitted canvas (raw RGBA, the writer's frame format)."""

    def grab_frame(self, **savefig_kwargs: Any) -> None:
        self._proc.stdin.write(np.asarray(self.fig.canvas.buffer_rgba()).tobytes())


def _build(trace: Trace, instance: int) -> tuple[Figure, Any, list[Any], list[Any]]:
    """The figure with its static parts drawn, a function moving it to time t, the artists
    that accumulate (trails: each frame adds the stretch since the previous one, so a frame
    costs the same late in a long run as early) and those redrawn every frame."""
    planar, flows = planar_agents(trace), flow_agents(trace)
    heights = ([3.0] if planar else []) + [1.5] * len(flows)
    fig = Figure(figsize=(6.4, 0.6 + max(sum(heights), 2.0)), dpi=80)
    FigureCanvasAgg(fig)
    grid = fig.add_gridspec(max(len(heights), 1), 1, height_ratios=heights or [1])
    updates, trails, moving = [], [], []
    if planar:
        fn, trails, artists = _planar(fig.add_subplot(grid[0]), trace, instance, planar)
        updates.append(fn)
        moving += artists
    for k, agent in enumerate(flows):
        ax = fig.add_subplot(grid[(1 if planar else 0) + k])
        fn, artists = _flow(ax, trace, instance, agent)
        updates.append(fn)
        moving += artists
    stamp = fig.text(0.01, 0.99, "", ha="left", va="top", fontsize=9, family="monospace")
    fig.suptitle(str(trace.meta.get("team", "")), fontsize=10)
    fig.set_layout_engine("constrained")
    fig.canvas.draw()  # lay out once, then freeze: every frame keeps the same geometry
    fig.set_layout_engine(None)  # None, not "none": a placeholder engine costs a 2nd draw

    def update(t: float) -> None:
        k = max(int(np.searchsorted(trace.sample_times, t, side="right")) - 1, 0)
        for fn in updates:
            fn(t, k)
        stamp.set_text(f"t = {t:8.3f} s")

    return fig, update, trails, [*moving, stamp]


def _planar(ax: Any, trace: Trace, instance: int, agents: list[str]
            ) -> tuple[Any, list[Any], list[Any]]:
    draw_world(ax, trace.meta.get("world"))
    poses = {a: pose(trace, a, instance) for a in agents}
    pts = np.concatenate([p[:, :2] for p in poses.values()])
    pts = pts[~np.isnan(pts).any(axis=1)]
    extent = float(np.ptp(pts, axis=0).max()) if len(pts) else 1.0
    robots = []
    for i, a in enumerate(agents):
        p, color = poses[a], PALETTE[i % len(PALETTE)]
        ax.plot(p[:, 0], p[:, 1], color=color, linewidth=0.8, alpha=0.25)  # where it will go
        radius = (agent_meta(trace, a).get("footprint") or {}).get("radius")
        r = float(radius) if radius else 0.03 * max(extent, 1e-9)
        trail = ax.plot([], [], color=color, linewidth=1.6, zorder=4)[0]
        body = ax.add_patch(Circle((np.nan, np.nan), r, facecolor=color, alpha=0.35,
                                   edgecolor=color, zorder=5))
        head = ax.plot([], [], color=color, linewidth=1.6, zorder=6)[0]
        label = ax.text(np.nan, np.nan, "", fontsize=8, color=color, path_effects=HALO,
                        zorder=7)
        valid = ~np.isnan(p[:, 0])
        last = np.maximum.accumulate(np.where(valid, np.arange(len(p)), -1))
        robots.append((a, p, last, r, trail, body, head, label, _Mode(trace, instance, a)))
    done = [0] * len(robots)  # trail drawn up to this sample
    ax.set_aspect("equal", adjustable="datalim")
    ax.margins(0.08)
    ax.autoscale_view()
    ax.grid(color="#E0E0E0", linewidth=0.6)

    def update(t: float, k: int) -> None:
        for i, (a, p, last, r, trail, body, head, label, mode) in enumerate(robots):
            j = last[min(k, len(last) - 1)]
            if j < 0:
                continue
            x, y, th = p[j]
            trail.set_data(p[done[i] : j + 1, 0], p[done[i] : j + 1, 1])
            done[i] = j
            body.set_center((x, y))
            head.set_data([x, x + r * 1.6 * np.cos(th)], [y, y + r * 1.6 * np.sin(th)])
            label.set_position((x + r * 1.2, y + r * 1.2))
            label.set_text(f"{a}: {mode.at(t)}")

    return update, [r[4] for r in robots], [x for r in robots for x in r[5:8]]


def _flow(ax: Any, trace: Trace, instance: int, agent: str) -> tuple[Any, list[Any]]:
    draw_flow(ax, trace, instance, agent)
    cursor = ax.axvline(0.0, color="#CC0000", linewidth=1.0, zorder=6)
    label = ax.text(0.99, 0.95, "", transform=ax.transAxes, ha="right", va="top", fontsize=8,
                    path_effects=HALO, zorder=7)
    mode = _Mode(trace, instance, agent)

    def update(t: float, k: int) -> None:
        cursor.set_xdata([t, t])
        label.set_text(f"mode: {mode.at(t)}")

    return update, [cursor, label]
