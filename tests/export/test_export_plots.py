"""Trajectory figures and animations: paths, numbered mode changes, worlds, payloads, files."""

from __future__ import annotations

import base64
import math
import re
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from matplotlib.collections import EllipseCollection, LineCollection, PolyCollection
from matplotlib.colors import to_rgba
from matplotlib.image import imread
from PIL import Image

import hybridteam as ht
from hybridteam.export import animate
from hybridteam.export.animate import frame_times, write_animation
from hybridteam.export.style import mode_colors
from hybridteam.export.trajectories import (
    MAX_NUMBERS,
    MAX_STACK,
    collision_labels,
    trajectory_figure,
    write_trajectories,
)
from hybridteam.trace import INTERVAL_COLUMNS, MESSAGE_COLUMNS, TRANSITION_COLUMNS, Table, Trace
from tests.conftest import EXAMPLES
from tests.world.test_collisions import TEAM as COLLISION_TEAM

AUTOMATA = sorted((EXAMPLES / "automata").glob("*.yaml"))
NUMBERED = re.compile(r"^([1-9]\d*)([A-Z]+)$")


def by_gid(artists, gid: str) -> list:
    return [a for a in artists if a.get_gid() == gid]


@pytest.mark.parametrize("example", AUTOMATA, ids=lambda p: p.stem)
def test_every_example_writes_trajectories_and_a_gif(example, tmp_path):
    run = ht.simulate(ht.load(example), duration=10.0)
    png = write_trajectories(run, tmp_path / "tr.png")
    svg = write_trajectories(run, tmp_path / "tr.svg")
    gif = write_animation(run, tmp_path / "run.gif", fps=10, duration=0.6)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    h, w, channels = imread(png).shape
    assert h > 150 and w > 300 and channels in (3, 4)
    root = ET.parse(svg).getroot()
    text = " ".join("".join(el.itertext()) for el in root.iter() if el.tag.endswith("text"))
    assert all(agent in text for agent in run.agents)
    assert gif.read_bytes()[:6] == b"GIF89a"
    with Image.open(gif) as im:
        assert im.n_frames == 6 and im.size[0] > 300
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.gif", "tr.png", "tr.svg"]


def test_relay_paths_start_labels_and_numbered_mode_changes():
    run = ht.simulate(ht.load(EXAMPLES / "automata" / "relay.yaml"))
    fig = trajectory_figure(run)
    (ax,) = fig.axes
    paths = {ln.get_gid(): ln for ln in ax.lines if (ln.get_gid() or "").startswith("path:")}
    assert set(paths) == {"path:runner", "path:anchor"}
    runner_x = paths["path:runner"].get_xdata()
    end_x = runner_x[~np.isnan(runner_x)][-1]
    samples = run.samples["runner"][:, 0, 0]
    assert end_x == samples[~np.isnan(samples)][-1] == pytest.approx(5.0, abs=1e-9)
    assert sorted(t.get_text() for t in by_gid(ax.texts, "start")) == ["0A: anchor", "0R: runner"]
    numbers = [t.get_text() for t in by_gid(ax.texts, "change")]
    leaf_changes = [r for r in run.transitions if r.cause != "init"]  # all modes are leaves
    assert len(numbers) == len(leaf_changes) == 4
    # numbered in time order across the team: runner and anchor switch at t=5 and t=8.14
    assert numbers == ["1R", "2A", "3A", "4R"]
    # each number sits where its agent was at the switch; shared spots stack the labels
    one = by_gid(ax.texts, "change")[0]
    assert one.xy == pytest.approx((5.0, 0.0), abs=1e-9)
    offsets = sorted(t.xyann[1] for t in by_gid(ax.texts, "change") if t.get_text()[-1] == "R")
    assert offsets[0] < offsets[1]
    assert ax.get_aspect() == 1.0 and ax.get_title() == "" and fig.get_suptitle() == "relay"


TILT = """
team: tilt
parameters: {g: 9.81}
agents:
  puck:
    plant: {kind: flow, state: {x: 0.0, y: 1.5, vx: 1.2, vy: 0.0}}
    parameters: {e: 0.75, slope: 0.15}
    initial: Fly
    modes:
      Fly:
        flow: {x: vx, y: vy, vx: 0, vy: -g}
        transitions:
          - to: Fly
            guard: y <= slope * x and vy < slope * vx
            do: ["vy = slope * vx - e * (vy - slope * vx)"]
simulation: {duration: 20.0, sample_period: 0.02}
"""


def test_a_zeno_pile_up_of_changes_keeps_its_labels_on_the_plot(team_from_yaml):
    """A puck bouncing down a tilted floor to its Zeno point: 154 changes, the last ones at
    one spot. Every 2nd is numbered; at the pile-up three numbers and an ellipsis stand,
    not a column of labels rising off the axes (which also collapsed the layout)."""
    run = ht.simulate(team_from_yaml(TILT))
    assert run.outcome == "zeno" and MAX_NUMBERS < len(run.transitions) <= 2 * MAX_NUMBERS
    fig = trajectory_figure(run)
    (ax,) = fig.axes
    labels = by_gid(ax.texts, "change")
    assert max(t.xyann[1] for t in labels) == 4 + 9 * MAX_STACK
    assert [t.get_text() for t in labels].count("…") >= 1
    assert len(labels) < 40
    (note,) = [t.get_text() for t in ax.texts if t.get_text().startswith("numbers shown")]
    assert note == (
        "numbers shown on every 2nd mode change; where changes crowd one spot, the first 3 and …"
    )


SCOUTS = """
    team: scouts
    agents:
      xr4000:
        plant: {kind: unicycle, state: {x: 0, y: 0, theta: 0}}
        modes: {Go: {inputs: {v: 0.5, omega: 0}, period: 0.1}}
      scout1:
        plant: {kind: unicycle, state: {x: 0, y: 1, theta: 0}}
        modes: {Go: {inputs: {v: 0.5, omega: 0}, period: 0.1}}
      scout2:
        plant: {kind: unicycle, state: {x: 0, y: 2, theta: 0}}
        modes: {Go: {inputs: {v: 0.5, omega: 0}, period: 0.1}}
    simulation: {duration: 2}
"""


def test_start_labels_name_the_robot_where_initials_clash(team_from_yaml):
    """Two Scouts get the letters S and SC (the numbered changes use them): each start
    label also names its robot, at that robot's start."""
    run = ht.simulate(team_from_yaml(SCOUTS))
    (ax,) = trajectory_figure(run).axes
    starts = {t.get_text(): tuple(t.xy) for t in by_gid(ax.texts, "start")}
    assert starts == {"0X: xr4000": (0.0, 0.0), "0S: scout1": (0.0, 1.0), "0SC: scout2": (0.0, 2.0)}


def test_robots_starting_on_the_lower_edge_get_room_for_their_start_labels():
    """The hand-over's robots start at y = 0, the lowest point of a flat scene: the plot
    reaches 18 pt below it (the start labels' depth under their start, 12 pt down), so no
    axis strikes through them; with --ylim the user's limits stay."""
    run = ht.simulate(ht.load(EXAMPLES / "protocols" / "handover.yaml"))
    fig = trajectory_figure(run)
    fig.canvas.draw()
    ax = fig.axes[0]
    starts = by_gid(ax.texts, "start")
    assert [t.xy[1] for t in starts] == [0.0, 0.0]
    bottom = ax.get_window_extent().y0
    renderer = fig.canvas.get_renderer()
    assert all(t.get_window_extent(renderer).y0 > bottom for t in starts)
    fixed = trajectory_figure(run, ylim=(-0.1, 1.0)).axes[0]
    assert fixed.get_ylim() == (-0.1, 1.0)


def test_selected_modes_restrict_the_numbering():
    run = ht.simulate(ht.load(EXAMPLES / "automata" / "unicycle_square.yaml"))
    fig = trajectory_figure(run, modes=["Turn"])
    numbers = [t.get_text() for t in by_gid(fig.axes[0].texts, "change")]
    # 4 entries into Turn and 4 exits from it (3 to Drive, 1 to Done)
    assert numbers == [f"{k}R" for k in range(1, 9)]
    fig = trajectory_figure(run, every=5.0)
    (foot,) = [c for c in fig.axes[0].collections if c.get_gid() == "footprints:robot"]
    assert len(foot.get_paths()) == 6  # t = 0, 5, 10, 15, 20, 25 while the robot is alive


def synthetic_trace() -> Trace:
    """Two robots carrying a bar through a walled room: a hand-built trace with a world."""
    times = np.linspace(0.0, 10.0, 101)
    n = len(times)
    a = np.c_[times * 0.5, np.zeros(n), np.zeros(n)]
    b = np.c_[times * 0.5, np.ones(n), np.zeros(n)]
    bar = np.c_[times * 0.5, np.full(n, 0.5), np.full(n, np.pi / 2)]
    b[90:] = np.nan  # robot b's instance part ends early
    modes = [
        {"path": "Carry", "depth": 1, "kind": "leaf", "final": False},
        {"path": "Stop", "depth": 1, "kind": "leaf", "final": True},
    ]
    agents = [
        {
            "name": name,
            "plant": "holonomic",
            "state": ["x", "y", "theta"],
            "inputs": ["vx", "vy", "omega"],
            "modes": modes,
            "footprint": {"radius": 0.2},
        }
        for name in ("alpha", "beta")
    ]
    meta = {
        "team": "carry",
        "n": 1,
        "seed": 0,
        "duration": 10.0,
        "agents": agents,
        "payloads": ["bar"],
        "payload_shapes": {"bar": {"kind": "bar", "length": 1.4}},
        "world": {
            "walls": [[-1, -1, 6, -1], [-1, 2, 6, 2], [-1, -1, -1, 2]],
            "obstacles": [
                {"kind": "circle", "x": 3, "y": -0.5, "r": 0.2},
                {"kind": "polygon", "points": [[4, 1.6], [5, 1.6], [5, 2]]},
            ],
            "regions": [{"points": [[5, 0], [6, 0], [6, 1], [5, 1]], "label": "corner"}],
        },
    }
    transitions = Table(
        TRANSITION_COLUMNS,
        {
            "instance": [0, 0, 0, 0],
            "agent": ["alpha", "beta", "beta", "alpha"],
            "t": [0.0, 0.0, 8.9, 10.0],
            "step": [0, 0, 0, 0],
            "source": ["", "", "Carry", "Carry"],
            "target": ["Carry", "Carry", "Stop", "Stop"],
            "cause": ["init", "init", "guard", "after"],
            "guard": ["", "", "", ""],
        },
    )
    intervals = Table(
        INTERVAL_COLUMNS,
        {
            "instance": [0] * 4,
            "agent": ["alpha", "beta", "beta", "alpha"],
            "mode": ["Carry", "Carry", "Stop", "Stop"],
            "depth": [1] * 4,
            "start": [0.0, 0.0, 8.9, 10.0],
            "end": [10.0, 8.9, 8.9, 10.0],
        },
    )
    outcomes = [{"instance": 0, "outcome": "ok", "t": 10.0, "message": ""}]
    return Trace(
        meta,
        outcomes,
        transitions,
        intervals,
        Table(MESSAGE_COLUMNS),
        times,
        {"alpha": a[:, None, :], "beta": b[:, None, :], "bar": bar[:, None, :]},
    )


def test_world_payload_and_footprints_are_drawn(tmp_path):
    trace = synthetic_trace()
    fig = trajectory_figure(trace, every=2.0)
    (ax,) = fig.axes  # the payload is not a robot: no extra subplot for it
    (walls,) = by_gid(ax.collections, "walls")
    assert isinstance(walls, LineCollection) and len(walls.get_segments()) == 3
    np.testing.assert_allclose(walls.get_segments()[0], [[-1, -1], [6, -1]])
    assert len(by_gid(ax.patches, "obstacle")) == 2
    assert len(by_gid(ax.patches, "region")) == 1
    assert [t.get_text() for t in by_gid(ax.texts, "region-label")] == ["corner"]
    (foot,) = by_gid(ax.collections, "footprints:alpha")
    assert isinstance(foot, EllipseCollection) and len(foot.get_offsets()) == 6
    (foot_b,) = by_gid(ax.collections, "footprints:beta")
    assert len(foot_b.get_offsets()) == 5  # beta ended at 8.9 s: 0, 2, 4, 6, 8
    (payload,) = by_gid(ax.collections, "payload:bar")
    assert isinstance(payload, PolyCollection) and len(payload.get_paths()) == 6
    # the bar is 1.4 long and turned 90 degrees: vertical, centred on the pose
    corners = payload.get_paths()[0].vertices[:4]
    assert np.ptp(corners[:, 1]) == pytest.approx(1.4)
    assert corners[:, 0].mean() == pytest.approx(0.0) and corners[:, 1].mean() == 0.5
    assert sorted(t.get_text() for t in by_gid(ax.texts, "start")) == ["0A: alpha", "0B: beta"]
    assert [t.get_text() for t in by_gid(ax.texts, "change")] == ["1B", "2A"]
    gif = write_animation(trace, tmp_path / "carry.gif", fps=10, duration=0.5)
    with Image.open(gif) as im:
        assert im.n_frames == 5


def test_without_world_nothing_extra_is_drawn():
    run = ht.simulate(ht.load(EXAMPLES / "automata" / "unicycle_square.yaml"))
    ax = trajectory_figure(run).axes[0]
    for gid in ("walls", "obstacle", "region"):
        assert not by_gid([*ax.collections, *ax.patches], gid)
    assert not [c for c in ax.collections if (c.get_gid() or "").startswith("payload")]


def test_flow_agents_plot_state_against_time_coloured_by_mode():
    team = ht.load(EXAMPLES / "automata" / "thermostat.yaml")
    run = ht.simulate(team, duration=20.0)
    fig = trajectory_figure(run)
    (ax,) = fig.axes
    (state,) = by_gid(ax.collections, "state:x")
    colors = mode_colors(["Heat", "Cool"])
    iv = run.intervals
    # one polyline per mode interval, in that interval's colour
    assert len(state.get_paths()) == len(iv)
    got = [tuple(c) for c in state.get_colors()]
    assert got == [to_rgba(colors[m]) for m in iv["mode"]]
    for path, start, end in zip(state.get_paths(), iv["start"], iv["end"], strict=True):
        t = path.vertices[:, 0]
        assert start <= t.min() and t.max() <= end
    (ticks,) = by_gid(ax.collections, "transitions")
    assert sorted(s[0, 0] for s in ticks.get_segments()) == run.transitions["t"][1:].tolist()
    assert {t.get_text() for t in ax.get_legend().get_texts()} == {"Heat", "Cool"}


def test_frames_are_capped_and_mp4_needs_ffmpeg(tmp_path, monkeypatch):
    run = ht.simulate(ht.load(EXAMPLES / "automata" / "thermostat.yaml"))
    assert len(frame_times(run, 0, 20, None)) == 300  # 1601 samples, capped
    assert len(frame_times(run, 0, 20, 2.0)) == 40
    times = frame_times(run, 0, 20, 2.0)
    assert times[0] == 0.0 and times[-1] == run.diagnostics[0]["t"]
    monkeypatch.setattr(animate.shutil, "which", lambda name: None)
    with pytest.raises(RuntimeError, match=re.escape("ffmpeg is not installed; write a .gif")):
        write_animation(run, tmp_path / "run.mp4")
    with pytest.raises(ValueError, match="unsupported animation format"):
        write_animation(run, tmp_path / "run.avi")
    assert list(tmp_path.iterdir()) == []


def test_a_robot_standing_still_is_drawn_once():
    """Footprints every 1 s of a robot that waits 5 s, drives 0.1 m/s, then turns on the
    spot: the waiting poses collapse into one; moves over 0.05 m and turns over 15 degrees
    are kept (poses at 0, then 6, 7, 8, 9, 10 s of driving; the turn at 11, 12 s)."""
    from hybridteam.export.scene import moved

    t = np.arange(13.0)
    x = np.where(t <= 5, 0.0, 0.1 * (np.minimum(t, 10) - 5))
    th = np.where(t <= 10, 0.0, np.radians(20.0) * (t - 10))
    p = np.c_[x, np.zeros_like(t), th]
    assert moved(p, np.arange(13), 0.05).tolist() == [0, 6, 7, 8, 9, 10, 11, 12]
    assert moved(p, np.arange(13), 0.15).tolist() == [0, 7, 9, 11, 12]


CORRIDOR = """
team: corridor
agents:
  r:
    model: scout
    plant: {state: {x: 0.5, y: 0.3, theta: 0}}
    modes: {Go: {inputs: {v: 0.5, omega: 0}, period: 0.1}}
world:
  - use: obstacles
    with:
      walls: [[0, -1.3, 20, -1.3], [0, 1.3, 20, 1.3]]
      circles: [[10, -0.8, 0.2]]
simulation: {duration: 38}
"""


def _spans(ax) -> tuple[float, float]:
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    return x1 - x0, y1 - y0


def test_a_long_corridor_fills_the_plot(team_from_yaml):
    """A 20 m by 2.6 m corridor: the axes span the scene within 15 % each way (equal aspect
    used to widen the short side to the figure's shape: ±4 m around a ±1.3 m corridor)."""
    run = ht.simulate(team_from_yaml(CORRIDOR))
    fig = trajectory_figure(run)
    fig.canvas.draw()
    ax = fig.axes[0]
    w, h = _spans(ax)
    assert 20.0 <= w <= 1.15 * 20.0 and 2.6 <= h <= 1.15 * 2.6
    assert ax.get_aspect() == 1.0
    (legend,) = fig.legends  # a wide scene: the legend goes below the plot
    labels = [t.get_text() for t in legend.get_texts()]
    assert labels == ["r", "0X: start of robot X", "footprint and heading, every 5 s", "obstacle"]


def test_plot_limits_and_size_are_the_users(team_from_yaml, tmp_path, capsys):
    from hybridteam.cli import main

    run = ht.simulate(team_from_yaml(CORRIDOR))
    trace = tmp_path / "trace.json"
    trace.write_text(run.to_json())
    out = tmp_path / "p.png"
    assert (
        main(
            [
                "plot",
                str(trace),
                "-o",
                str(out),
                "--xlim",
                "8",
                "12",
                "--ylim",
                "-2",
                "2",
                "--size",
                "6",
                "4",
            ]
        )
        == 0
    )
    assert imread(out).shape[:2] == (400, 600)
    fig = trajectory_figure(run, xlim=(8, 12), ylim=(-2, 2))
    assert fig.axes[0].get_xlim() == (8, 12) and fig.axes[0].get_ylim() == (-2, 2)
    capsys.readouterr()
    assert main(["plot", str(trace), "-o", str(out), "--ylim", "2", "-2"]) == 2
    assert "--ylim 2 -2: need two finite numbers, the first smaller" in capsys.readouterr().err


def test_animation_size_and_dpi_are_the_users(team_from_yaml, tmp_path, capsys):
    from hybridteam.cli import main

    run = ht.simulate(team_from_yaml(CORRIDOR), duration=4.0)
    trace = tmp_path / "trace.json"
    trace.write_text(run.to_json())
    gif = tmp_path / "a.gif"
    assert (
        main(
            [
                "animate",
                str(trace),
                "-o",
                str(gif),
                "--size",
                "6",
                "3",
                "--dpi",
                "50",
                "--fps",
                "5",
                "--speed",
                "2",
            ]
        )
        == 0
    )
    with Image.open(gif) as im:
        assert im.size == (300, 150)
        assert im.n_frames == 10  # 4 s at 2x is 2 s of playback at 5 frames a second
    capsys.readouterr()
    assert main(["animate", str(trace), "-o", str(gif), "--speed", "0"]) == 2
    assert "--speed must be a positive number, got 0" in capsys.readouterr().err


# two robots, b kept at y = b_y, through walls, told to go on (the collision tests' team)
CRASH = COLLISION_TEAM.replace("on_collision: {mode}", "on_collision: warn")


def test_collisions_under_warn_are_marked_where_and_when_they_happened(team_from_yaml, tmp_path):
    """Robot a drives at 1 m/s into the wall x = 2 (b kept away at y = 5): its 0.25 m disk
    first touches the wall at t = 1.75 s, at x = 1.75 (between its ticks: the swept test,
    docs/world.md). The run goes on through the wall; the trajectories mark that spot with
    its time, the animation from 1.75 s on, and the report shows the trajectories with the
    mark."""
    from hybridteam.export.report import write_report

    run = ht.simulate(team_from_yaml(CRASH.format(b_y=5.0, walls="[[2.0, -1.0, 2.0, 1.0]]")))
    assert run.outcome == "ok" and len(run.diagnostics[0]["stats"]["collisions"]) == 1
    (ax,) = trajectory_figure(run).axes
    (mark,) = by_gid(ax.lines, "collisions")
    np.testing.assert_allclose(mark.get_xydata(), [[1.75, 0.0]], atol=1e-12)
    (label,) = by_gid(ax.texts, "collision-label")
    assert label.get_text() == "1.75 s" and label.xy == pytest.approx((1.75, 0.0), abs=1e-12)
    box = ax.get_legend() or ax.get_figure().legends[0]  # beside a tall scene, below a wide
    legend = [t.get_text() for t in box.get_texts()]
    assert "first collision of each robot or payload, its time" in legend
    _fig, update, _trails, moving = animate._build(run, 0)
    (crash,) = [a for a in moving if a.get_gid() == "collisions"]
    update(1.7)
    assert len(crash.get_xydata()) == 0
    update(1.8)
    np.testing.assert_allclose(crash.get_xydata(), [[1.75, 0.0]], atol=1e-12)
    page = write_report(tmp_path, run, run.summary(), animation=False).read_text("utf-8")
    figure = page.split("<section id='trajectories'>", 1)[1].split("</section>", 1)[0]
    uri = re.search(r"src='data:image/svg\+xml;base64,([^']+)'", figure)
    assert uri is not None and b'id="collisions"' in base64.b64decode(uri.group(1))


def test_two_robots_that_meet_are_marked_where_their_disks_touch(team_from_yaml):
    """Head on from 3 m apart at 1 m/s each, 0.25 m disks: they first touch between two
    ticks (the swept pair test), at t = 1.25 s, a at x = 1.25 and b at 1.75; the mark is
    between them, at 1.5."""
    run = ht.simulate(team_from_yaml(CRASH.format(b_y=0.0, walls="[]")))
    (ax,) = trajectory_figure(run).axes
    (mark,) = by_gid(ax.lines, "collisions")
    np.testing.assert_allclose(mark.get_xydata(), [[1.5, 0.0]], atol=1e-12)
    assert [t.get_text() for t in by_gid(ax.texts, "collision-label")] == ["1.25 s"]


def test_marks_that_appear_mid_run_keep_their_colour_in_a_gif():
    """A GIF's frames share the first frame's palette; the red of a lost message or a
    collision, absent from the first frame, is kept in it all the same."""
    first = Image.new("RGB", (20, 20), "white")
    palette = animate._palette(first).getpalette()
    entries = [tuple(palette[k : k + 3]) for k in range(0, len(palette), 3)]
    assert (204, 0, 0) in entries and len(entries) <= 256


CONVOY = """
    team: convoy
    agents:
      scout_rear:
        plant: {kind: unicycle, state: {x: -1.2, y: 0, theta: 0}}
        modes: {Go: {inputs: {v: 0.5, omega: 0}, period: 0.1}}
      scout_front:
        plant: {kind: unicycle, state: {x: 0, y: 0, theta: 0}}
        modes: {Go: {inputs: {v: 0.5, omega: 0}, period: 0.1}}
      xr4000:
        plant: {kind: unicycle, state: {x: 1.2, y: 0, theta: 0}}
        modes: {Go: {inputs: {v: 0.5, omega: 0}, period: 0.1}}
    world:
      - use: obstacles
        with:
          walls: [[3, 0.6, 3, 4], [3, -0.6, 3, -4]]
    simulation: {duration: 8.0}
"""


def test_start_labels_of_robots_side_by_side_do_not_overprint(team_from_yaml):
    """Three robots 1.2 m apart on one line, in a scene 8 m tall: each start label names its
    robot ('0S: scout_rear', ...) and is longer than the gap between starts, so the labels
    are stacked in rows where they would meet: no two drawn labels' boxes overlap."""
    run = ht.simulate(team_from_yaml(CONVOY))
    fig = trajectory_figure(run)
    ax = fig.axes[0]
    renderer = fig.canvas.get_renderer()
    fig.draw_without_rendering()
    labels = by_gid(ax.texts, "start")
    assert sorted(t.get_text().split(": ")[1] for t in labels) == [
        "scout_front",
        "scout_rear",
        "xr4000",
    ]
    boxes = [t.get_window_extent(renderer) for t in labels]
    for i, a in enumerate(boxes):
        for b in boxes[i + 1 :]:
            assert not a.overlaps(b), (a, b)


GATE = """
    team: gate
    agents:
      lead:
        plant: {kind: unicycle, state: {x: 0, y: 0, theta: 0}}
        modes: {Go: {inputs: {v: 0.5, omega: 0}, period: 0.1}}
      tail:
        plant: {kind: unicycle, state: {x: -1, y: 0, theta: 0}}
        modes: {Go: {inputs: {v: 0.5, omega: 0}, period: 0.1}}
    world:
      - use: obstacles
        with:
          walls: [[2, 0.15, 2, 3], [2, -0.15, 2, -3]]
          radius: [[lead, 0.2], [tail, 0.2]]
          on_collision: warn
    simulation: {duration: 8.0}
"""


def test_collisions_at_one_spot_share_one_label(team_from_yaml):
    """Two 0.2 m robots, 1 m apart on y = 0, drive at 0.5 m/s through a 0.3 m gap: each
    first touches the jamb (2, 0.15) where its centre is 0.2 from it, at x = 2 -
    sqrt(0.2^2 - 0.15^2) = 1.8677 (between ticks: the swept test): the lead at 3.735 s,
    the tail at 5.735 s, both at (1.8677, 0). Two labels there hid each other; one label
    names both."""
    run = ht.simulate(team_from_yaml(GATE))
    (ax,) = trajectory_figure(run).axes
    (mark,) = by_gid(ax.lines, "collisions")
    x = 2 - math.sqrt(0.2**2 - 0.15**2)
    np.testing.assert_allclose(mark.get_xydata(), [[x, 0.0], [x, 0.0]], atol=1e-9)
    (label,) = by_gid(ax.texts, "collision-label")
    assert label.get_text() == "3.74 s lead, 5.74 s tail"


def test_collision_labels_group_by_distance():
    hits = [(1.0, 0.0, 0.0, "a"), (2.0, 0.05, 0.0, "b"), (3.0, 1.0, 0.0, "c")]
    assert collision_labels(hits, 0.1) == [(0.0, 0.0, "1 s a, 2 s b"), (1.0, 0.0, "3 s")]
    assert collision_labels(hits, 0.01) == [
        (0.0, 0.0, "1 s"),
        (0.05, 0.0, "2 s"),
        (1.0, 0.0, "3 s"),
    ]
