"""The three experiments of the architecture paper (Chaimowicz et al., ICRA 2001, Sec. 4).

Each experiment must end ``success`` — its last leader's plan reaches its final Stop, which
ends the run by the team's end rule even though the operator never finishes — with the box
never dropped (every grasp offset within the
robot model's limit), every robot and the box clear of every obstacle, and the leadership
changes the paper describes, numbered as in its Figs. 7, 8 and 11. Experiment 2 must show
Fig. 10's docking submodes in order and its request close-up (t_c − t_b = the configured
latency); experiment 3 must complete with the Scout limited to 8 data messages per second,
its dropped copies recorded in the trace.
"""

from __future__ import annotations

from functools import cache
from pathlib import Path

import numpy as np
import pytest

from hybridteam.api import load, simulate
from hybridteam.export.timeline import timeline_figure
from hybridteam.export.trajectories import mode_changes

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "transport"

#: When the last leader's plan stops (the run's end): experiment 1 the XR4000 14 s after it
#: takes the leadership back (36.23 s: docking, 14.74 s out, the Labmate's 8 s reversal and
#: four 30 ms hand-over legs); experiment 2 the Labmate's 10 s curve and 10 s straight after
#: the XR4000's detour; experiment 3 the Labmate's 12 s curve and 20 s straight.
END = {
    "experiment1": ("xr4000", 50.23),
    "experiment2": ("labmate", 47.8),
    "experiment3": ("labmate", 69.53781943115688),
}

#: Per experiment: who leads first, then who takes the lead at each numbered change.
LEADERSHIP = {
    "experiment1": ("xr4000", ["labmate", "xr4000"]),  # Fig. 7: 1X resigns, 2X gets it back
    "experiment2": ("labmate", ["xr4000", "labmate"]),  # Fig. 8: 1X requests, 2X returns
    "experiment3": ("labmate", ["scout", "labmate"]),  # Fig. 11: 1S requests, 2S returns
}


@cache
def _run(name: str):
    """Each experiment is simulated once for the whole module (each run takes seconds)."""
    team = load(EXAMPLES / f"{name}.yaml")
    return team, simulate(team)


@pytest.fixture(scope="module", params=sorted(LEADERSHIP))
def experiment(request):
    return (request.param, *_run(request.param))


def leaders_in_order(run) -> list[str]:
    """Who takes the lead at each numbered hand-over (the views' numbering)."""
    changes = mode_changes(run, 0, run.agents, None)
    out: dict[int, str] = {}
    for _t, _step, agent, target, number in changes:
        if ".Lead" in target:  # Transport.Lead or one of its plan's submodes
            out[number] = agent
    return [out[k] for k in sorted(out)]


def test_ends_in_success_with_the_box_held_and_clear_of_obstacles(experiment):
    name, team, run = experiment
    assert run.outcome == "success", run.message
    who, when = END[name]
    assert run.message == f"'{who}' reached a final mode (the end rule)"
    stop = [
        t
        for t, a, tg in zip(
            run.transitions["t"], run.transitions["agent"], run.transitions["target"], strict=True
        )
        if a == who and tg.endswith("Lead.Stop")
    ]
    assert stop == [pytest.approx(when, abs=1e-9)]
    assert run.summary()["instances"][0]["t_end"] == pytest.approx(when, abs=1e-9)
    row = run.summary()["instances"][0]
    grasps = [
        g["agent"] for g in next(w for w in team.world if w.use == "payload").values["grasps"]
    ]
    limits = [team.agent(a).preset.manipulator.limit for a in grasps]
    assert np.all(np.array(row["max_grasp_offset"]) < np.array(limits)), name
    assert min(row["min_clearance"]) > 0.0, name
    assert row["payload_clearance"] > 0.0, name


def test_leadership_changes_as_in_the_paper(experiment):
    name, _team, run = experiment
    first, then = LEADERSHIP[name]
    inits = run.transitions
    start = {
        a: t
        for a, t, c in zip(inits["agent"], inits["target"], inits["cause"], strict=True)
        if c == "init"
    }
    assert start[first].startswith(("Transport.Lead", "Dock"))
    assert leaders_in_order(run) == then, name


def test_experiment2_timeline_reproduces_fig10():
    team, run = _run("experiment2")
    tr = run.transitions
    rows = list(zip(tr["t"], tr["agent"], tr["source"], tr["target"], tr["cause"], strict=True))
    xr = [target for _t, a, _s, target, _c in rows if a == "xr4000"]
    dock = [m.split(".")[1] for m in xr if m.startswith("Dock.")]
    assert dock == ["Approach", "Deploy", "Lift", "Wait"]
    assert next(i for i, m in enumerate(xr) if m.startswith("Transport")) == len(dock)
    # the close-up: t_a the XR4000 asks, t_b the Labmate grants, t_c the XR4000 leads
    t_a = next(t for t, a, _s, tg, _c in rows if a == "xr4000" and tg.endswith("Requesting"))
    t_b = next(t for t, a, s, _tg, c in rows if a == "labmate" and c == "message:request")
    t_c = next(t for t, a, s, _tg, c in rows if a == "xr4000" and c == "message:grant")
    latency = team.parameters["latency"]
    assert t_a < t_b < t_c
    assert t_c - t_b == pytest.approx(latency, abs=1e-9)  # paper: "approximately 0.03 s"
    assert t_b - t_a == pytest.approx(latency, abs=1e-9)
    # the drawn close-up (two robots): the request; the grant and the request's ack on one
    # arrow t_b -> t_c; at t_c the announce and the grant's ack; one label per arrow, the
    # message named before the ack, and the 20 Hz pose stream faint and unlabelled
    fig, data = timeline_figure(run, window=(t_a - 0.02, t_c + 0.02), agents=["xr4000", "labmate"])
    assert [lane.agent for lane in data.lanes if not lane.top] == ["xr4000", "labmate"]
    texts = fig.axes[0].texts
    labels = sorted(t.get_text() for t in texts if t.get_gid() == "message-label")
    assert labels == ["announce + ack +30 ms", "grant + ack +30 ms", "request +30 ms"]
    grant = [t for t in texts if t.get_gid() == "message" and t.xyann[0] == pytest.approx(t_b)]
    assert [(a.xyann[0], a.xy[0]) for a in grant] == [(pytest.approx(t_b), pytest.approx(t_c))]
    assert [t for t in texts if t.get_gid() == "data-message"]


def test_experiment3_scout_at_8_hz_drops_data_copies():
    _team, run = _run("experiment3")
    assert run.outcome == "success", run.message
    m = run.messages
    to_scout = np.asarray(m["receiver"]) == "scout"
    data = np.asarray(m["type"]) == "state"
    status = np.asarray(m["status"])
    reason = np.asarray(m["reason"]).astype(str)
    dropped = to_scout & data & (status == "lost") & np.char.startswith(reason, "rate limit")
    taken = to_scout & data & (status == "delivered")
    assert dropped.sum() > 0
    # the Scout takes at most 8 copies per second, whatever the others send at 20 Hz
    t = np.sort(np.asarray(m["t_recv"])[taken])
    assert np.all(np.diff(t) >= 1 / 8 - 1e-9)


def test_trajectories_fit_the_scene_and_explain_their_marks(experiment):
    """The plane's axes span the robots' footprints, the box and the obstacles within
    15 %, and the legend says what the box snapshots, numbers and obstacles are."""
    from hybridteam.export.trajectories import trajectory_figure

    name, team, run = experiment
    pts = []
    for agent in ("labmate", "xr4000", "scout"):
        if agent in run.samples:
            xy = run.samples[agent][:, 0, :2]
            r = team.agent(agent).preset.footprint.radius
            pts += [xy - r, xy + r]
    box = run.samples["box"][:, 0, :2]
    pts += [box - 0.48, box + 0.48]  # the box's half diagonal: hypot(0.4, 0.25) = 0.47
    for ob in run.meta["world"]["obstacles"]:  # circles: [x, y, r] in the team file
        pts.append(
            np.array(
                [[ob["x"] - ob["r"], ob["y"] - ob["r"]], [ob["x"] + ob["r"], ob["y"] + ob["r"]]]
            )
        )
    xy = np.concatenate(pts)
    xy = xy[np.isfinite(xy).all(axis=1)]
    span = xy.max(axis=0) - xy.min(axis=0)
    fig = trajectory_figure(run)
    ax = fig.axes[0]
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    assert x0 <= xy[:, 0].min() and x1 >= xy[:, 0].max(), name
    assert x1 - x0 <= 1.15 * span[0] and y1 - y0 <= 1.15 * span[1], name
    legend = fig.legends[0] if fig.legends else ax.get_legend()  # below a wide scene
    labels = {t.get_text() for t in legend.get_texts()}
    assert {"obstacle", "nX: n-th mode change, by robot X"} <= labels, name
    assert any(label.startswith("box, every ") for label in labels), name


def _overlaps(boxes) -> list[tuple[int, int]]:
    return [
        (i, j)
        for i in range(len(boxes))
        for j in range(i + 1, len(boxes))
        if boxes[i].overlaps(boxes[j])
    ]


def test_experiment2_animation_shows_the_box_in_every_frame_and_no_label_overlaps():
    """Every frame draws the box at its sampled pose (true size and heading); the texts of a
    frame (time, robot names, modes) never overlap, whatever the robots do."""
    from hybridteam.export import animate
    from hybridteam.export.scene import payload_outline, payload_shape, pose
    from hybridteam.world.scene import BoxShape

    _team, run = _run("experiment2")
    times = animate.frame_times(run, 0, 10, None)
    fig, update, _trails, _moving = animate._build(run, 0, None, 100.0, 0.3)
    (box,) = [p for ax in fig.axes for p in ax.patches if p.get_gid() == "payload:box"]
    samples = pose(run, "box", 0)
    shape = payload_shape(run, "box")
    assert shape == BoxShape(width=0.8, depth=0.5)  # as experiment2.yaml declares it
    renderer = fig.canvas.get_renderer()
    for t in times[::10]:
        update(float(t))
        k = max(int(np.searchsorted(run.sample_times, t, side="right")) - 1, 0)
        assert box.get_visible(), t
        np.testing.assert_allclose(box.get_xy()[:4], payload_outline(shape, *samples[k]))
        texts = [x for ax in fig.axes for x in ax.texts if x.get_visible() and x.get_text()]
        boxes = [x.get_window_extent(renderer) for x in texts]
        assert not _overlaps(boxes), (t, [texts[i].get_text() for i, _ in _overlaps(boxes)])


def test_close_ups_of_every_hand_over_have_no_overlapping_text(experiment):
    """Each experiment's first hand-over, 20 ms before its first control message to 150 ms
    after (the Fig. 10 close-up): mode names, message labels and lost-message labels are
    all drawn, none over another."""
    name, _team, run = experiment
    m = run.messages
    control = [
        (t, s, r)
        for t, s, r, k, ty in zip(
            m["t_send"], m["sender"], m["receiver"], m["socket"], m["type"], strict=True
        )
        if k == "control" and ty in ("request", "offer")
    ]
    t0, sender, receiver = control[0]
    fig, _data = timeline_figure(
        run,
        window=(t0 - 0.02, t0 + 0.15),
        agents=[a for a in run.agents if a in (sender, receiver)],
    )
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    texts = [x for x in fig.axes[0].texts if x.get_visible() and x.get_text()]
    assert {x.get_gid() for x in texts} >= {"mode-label", "message-label"}, name
    boxes = [x.get_window_extent(renderer) for x in texts]
    assert not _overlaps(boxes), (
        name,
        [(texts[i].get_text(), texts[j].get_text()) for i, j in _overlaps(boxes)],
    )
