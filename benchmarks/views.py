"""Wall time of the run views on a large trace: timeline, close-up, trajectories, animation.

A synthetic trace of 4 robots with composite modes (Dock with A/D/L/W, Transport), 2,500
transitions each (10,000 in all), 25,000 sample times (100,000 agent samples) and 2,000
messages — a long mission. Views must stay interactive at that size: budget a few seconds in
total, which is why bars go in one collection per colour, ticks in one collection, and the
animation blits 100 frames instead of redrawing the figure.

    python benchmarks/views.py [OUT_DIR]
"""

from __future__ import annotations

import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from hybridteam.export.animate import write_animation
from hybridteam.export.timeline import write_timeline
from hybridteam.export.trajectories import write_trajectories
from hybridteam.trace import INTERVAL_COLUMNS, MESSAGE_COLUMNS, TRANSITION_COLUMNS, Table, Trace

AGENTS = ("alpha", "bravo", "charlie", "delta")
CYCLE = ("Dock.A", "Dock.D", "Dock.L", "Dock.W", "Transport")
SWITCHES, SAMPLES, MESSAGES = 2_500, 25_000, 2_000
DURATION = 2_500.0


def synthetic_trace(seed: int = 0) -> Trace:
    """Robots cycling through the modes at random times, driving Lissajous-like paths."""
    rng = np.random.default_rng(seed)
    times = np.linspace(0.0, DURATION, SAMPLES)
    modes = [{"path": "Dock", "depth": 1, "kind": "or", "final": False}]
    modes += [{"path": p, "depth": 2, "kind": "leaf", "final": False} for p in CYCLE[:4]]
    modes += [{"path": "Transport", "depth": 1, "kind": "leaf", "final": False}]
    meta = {
        "team": "views-benchmark",
        "n": 1,
        "seed": seed,
        "duration": DURATION,
        "agents": [
            {
                "name": a,
                "plant": "unicycle",
                "state": ["x", "y", "theta"],
                "inputs": ["v", "omega"],
                "modes": modes,
                "footprint": {"radius": 0.3},
            }
            for a in AGENTS
        ],
    }
    tr: dict[str, list] = {c: [] for c in TRANSITION_COLUMNS}
    iv: dict[str, list] = {c: [] for c in INTERVAL_COLUMNS}
    samples = {}
    for k, agent in enumerate(AGENTS):
        switch = np.sort(rng.uniform(0.0, DURATION, SWITCHES - 1))
        starts = np.r_[0.0, switch]
        ends = np.r_[switch, DURATION]
        leaves = [CYCLE[j % len(CYCLE)] for j in range(SWITCHES)]
        for j, (leaf, s, e) in enumerate(zip(leaves, starts, ends, strict=True)):
            source = "" if j == 0 else leaves[j - 1]
            tr_row = (0, agent, s, 0, source, leaf, "init" if j == 0 else "after", "")
            for col, v in zip(TRANSITION_COLUMNS, tr_row, strict=True):
                tr[col].append(v)
            for col, v in zip(
                INTERVAL_COLUMNS, (0, agent, leaf, leaf.count(".") + 1, s, e), strict=True
            ):
                iv[col].append(v)
        docked = np.array([leaf.startswith("Dock") for leaf in leaves])
        first = np.flatnonzero(docked & ~np.r_[False, docked[:-1]])  # Dock entered
        last = np.flatnonzero(docked & ~np.r_[docked[1:], False])  # ... and left
        for a, b in zip(first, last, strict=True):
            for col, v in zip(
                INTERVAL_COLUMNS, (0, agent, "Dock", 1, starts[a], ends[b]), strict=True
            ):
                iv[col].append(v)
        phase = times / DURATION * 2 * np.pi * 40
        x = 10 * np.cos(phase + k) + k
        y = 6 * np.sin(1.5 * phase + k)
        theta = np.arctan2(np.gradient(y), np.gradient(x))
        samples[agent] = np.c_[x, y, theta][:, None, :]
    sent = np.sort(rng.uniform(0.0, DURATION, MESSAGES))
    latency = rng.uniform(0.01, 0.2, MESSAGES)
    lost = rng.random(MESSAGES) < 0.05
    senders = rng.integers(0, len(AGENTS), MESSAGES)
    msgs = {
        "instance": np.zeros(MESSAGES, int),
        "seq": np.arange(MESSAGES),
        "sender": [AGENTS[s] for s in senders],
        "receiver": [AGENTS[(s + 1) % len(AGENTS)] for s in senders],
        "socket": ["control"] * MESSAGES,
        "type": ["status"] * MESSAGES,
        "t_send": sent,
        "t_recv": np.where(lost, np.nan, sent + latency),
        "status": np.where(lost, "lost", "delivered"),
        "reason": np.where(lost, "drop", ""),
        "msg_id": np.full(MESSAGES, -1),
    }
    outcomes = [{"instance": 0, "outcome": "ok", "t": DURATION, "message": ""}]
    return Trace(
        meta,
        outcomes,
        Table(TRANSITION_COLUMNS, tr),
        Table(INTERVAL_COLUMNS, iv),
        Table(MESSAGE_COLUMNS, msgs),
        times,
        samples,
    )


def timed(label: str, fn: Callable[[], object]) -> float:
    t0 = time.perf_counter()
    fn()
    dt = time.perf_counter() - t0
    print(f"  {label:<28} {dt:7.3f} s")
    return dt


def main() -> None:
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp(prefix="views-"))
    t0 = time.perf_counter()
    trace = synthetic_trace()
    build = time.perf_counter() - t0
    print(
        f"trace: {len(trace.transitions)} transitions, {len(trace.intervals)} intervals, "
        f"{sum(s.shape[0] for s in trace.samples.values())} samples, "
        f"{len(trace.messages)} messages (built in {build:.2f} s)"
    )
    total = sum(
        [
            timed("timeline (png)", lambda: write_timeline(trace, out / "timeline.png")),
            timed(
                "close-up 100 s (png)",
                lambda: write_timeline(trace, out / "closeup.png", window=(1000.0, 1100.0)),
            ),
            timed("trajectories (png)", lambda: write_trajectories(trace, out / "paths.png")),
            timed(
                "animation, 100 frames (gif)",
                lambda: write_animation(trace, out / "run.gif", fps=20, duration=5.0),
            ),
        ]
    )
    print(f"  {'total':<28} {total:7.3f} s   (files in {out})")


if __name__ == "__main__":
    main()
