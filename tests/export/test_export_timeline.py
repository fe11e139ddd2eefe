"""Timeline view: lanes, bars, transition ticks and message arrows, checked against the run."""

from __future__ import annotations

import csv
import io
import json
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from matplotlib.image import imread

import hybridteam as ht
from hybridteam.cli import main
from hybridteam.export.style import mode_colors
from hybridteam.export.timeline import timeline_data, timeline_figure, write_timeline
from tests.conftest import EXAMPLES

AUTOMATA = sorted((EXAMPLES / "automata").glob("*.yaml"))
PNG = b"\x89PNG\r\n\x1a\n"

REGIONS = """
    team: regions
    agents:
      a:
        plant: {kind: flow, state: {c: 0}}
        initial: Both
        modes:
          Both:
            parallel: true
            transitions: [{to: Stop, after: 3.2}]
            modes:
              Left:
                initial: L1
                modes:
                  L1: {transitions: [{to: L2, after: 1}]}
                  L2: {transitions: [{to: L1, after: 1}]}
              Right:
                initial: R1
                modes:
                  R1: {transitions: [{to: R2, after: 1}]}
                  R2: {transitions: [{to: R3, after: 0.5}]}
                  R3: {}
          Stop: {final: true}
    simulation: {duration: 10}
"""

DOCKING = """
    team: docking
    agents:
      x:
        plant: {kind: flow, state: {c: 0}}
        initial: Dock
        modes:
          Dock:
            initial: A
            modes:
              A: {transitions: [{to: D, after: 1}]}
              D: {transitions: [{to: W, after: 1.5}]}
              W: {transitions: [{to: Transport, after: 0.5}]}
          Transport:
            transitions: [{to: Dock, after: 2}]
    simulation: {duration: 7.5}
"""


def svg_text(path) -> str:
    root = ET.parse(path).getroot()
    return " ".join("".join(el.itertext()) for el in root.iter() if el.tag.endswith("text"))


def relay_with_latencies(latencies=(0.030, 0.120)):
    """The relay run, its two messages delayed by the given latencies (t_recv rewritten)."""
    run = ht.simulate(ht.load(EXAMPLES / "automata" / "relay.yaml"))
    msgs = run.messages
    msgs.columns["t_recv"] = msgs["t_send"] + np.asarray(latencies)
    return run


@pytest.mark.parametrize("example", AUTOMATA, ids=lambda p: p.stem)
def test_every_example_writes_a_timeline_png_svg_and_close_up(example, tmp_path):
    run = ht.simulate(ht.load(example), duration=10.0)
    png = write_timeline(run, tmp_path / "t.png", data_path=tmp_path / "t.csv")
    svg = write_timeline(run, tmp_path / "t.svg", data_path=tmp_path / "t.json")
    end = max(float(np.max(run.intervals["end"])), 1.0)
    close = write_timeline(run, tmp_path / "close.png", window=(0.25 * end, 0.75 * end))
    for p in (png, close):
        assert p.read_bytes()[:8] == PNG
        h, w, channels = imread(p).shape
        assert h > 100 and w > 300 and channels in (3, 4)
    text = svg_text(svg)
    assert all(agent in text for agent in run.agents)
    rows = list(csv.DictReader(io.StringIO((tmp_path / "t.csv").read_text())))
    assert list(rows[0]) == ["lane", "agent", "region", "mode", "start", "end"]
    assert len(rows) == len(run.intervals.where(depth=1))  # flat models: every interval
    data = json.loads((tmp_path / "t.json").read_text())
    assert set(data) == {"lanes", "bars", "marks", "arrows"}
    assert len(data["marks"]) == len(run.transitions)
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "close.png",
        "t.csv",
        "t.json",
        "t.png",
        "t.svg",
    ]  # no temporary files left


def test_unicycle_square_bars_and_ticks_follow_the_transitions():
    run = ht.simulate(ht.load(EXAMPLES / "automata" / "unicycle_square.yaml"))
    data = timeline_data(run)
    assert [(lane.agent, lane.region, lane.top) for lane in data.lanes] == [("robot", "", False)]
    bars = [(b.mode, b.start, b.end) for b in data.bars]
    # wait 1 s, then four times (drive 2 m at 0.5 m/s = 4 s, quarter turn at pi/4 rad/s = 2 s)
    expected = [("Wait", 0.0, 1.0)]
    for k in range(4):
        t = 1.0 + 6.0 * k
        expected += [("Drive", t, t + 4.0), ("Turn", t + 4.0, t + 6.0)]
    expected.append(("Done", 25.0, 25.0))
    assert [m for m, _, _ in bars] == [m for m, _, _ in expected]
    np.testing.assert_allclose([b[1:] for b in bars], [e[1:] for e in expected], atol=1e-9)
    assert [m.t for m in data.marks] == run.transitions["t"].tolist()
    assert {m.lane for m in data.marks} == {0}
    colors = mode_colors(["Wait", "Drive", "Turn", "Done"], ["Done"])
    assert all(b.color == colors[b.mode] for b in data.bars)


def test_bars_are_drawn_one_collection_per_lane_and_colour_with_ticks_at_transitions():
    run = ht.simulate(ht.load(EXAMPLES / "automata" / "unicycle_square.yaml"))
    fig, data = timeline_figure(run)
    ax = fig.axes[0]
    bars = [c for c in ax.collections if (c.get_gid() or "").startswith("bars:")]
    assert len(bars) == len({(b.lane, b.color) for b in data.bars}) == 4
    assert sum(len(c.get_paths()) for c in bars) == len(data.bars)
    ticks = next(c for c in ax.collections if c.get_gid() == "transitions")
    xs = sorted(seg[0, 0] for seg in ticks.get_segments())
    assert xs == sorted(run.transitions["t"].tolist())
    assert [t.get_text() for t in ax.get_yticklabels()] == ["robot"]
    assert {t.get_text() for t in ax.get_legend().get_texts()} == {"Wait", "Drive", "Turn", "Done"}


def test_parallel_regions_get_one_lane_each_with_their_intervals(team_from_yaml):
    run = ht.simulate(team_from_yaml(REGIONS))
    data = timeline_data(run)
    assert [(lane.agent, lane.region) for lane in data.lanes] == [
        ("a", ""),
        ("a", "Both.Left"),
        ("a", "Both.Right"),
    ]
    per_lane = {
        k: sorted((b.mode, b.start, b.end) for b in data.bars if b.lane == k) for k in range(3)
    }
    assert per_lane[0] == [("Both", 0.0, 3.2), ("Stop", 3.2, 3.2)]
    assert per_lane[1] == [
        ("Both.Left.L1", 0.0, 1.0),
        ("Both.Left.L1", 2.0, 3.0),
        ("Both.Left.L2", 1.0, 2.0),
        ("Both.Left.L2", 3.0, 3.2),
    ]
    assert per_lane[2] == [
        ("Both.Right.R1", 0.0, 1.0),
        ("Both.Right.R2", 1.0, 1.5),
        ("Both.Right.R3", 1.5, 3.2),
    ]
    marks = sorted((m.lane, m.t) for m in data.marks)
    assert marks == [(0, 3.2), (1, 0.0), (1, 1.0), (1, 2.0), (1, 3.0), (2, 0.0), (2, 1.0), (2, 1.5)]
    # lanes are stacked top to bottom without overlap
    ys = [lane.y for lane in data.lanes]
    assert ys == sorted(ys, reverse=True) and min(np.diff(ys)) <= -0.8


def test_composite_modes_add_a_top_row_with_the_top_level_modes(team_from_yaml):
    run = ht.simulate(team_from_yaml(DOCKING))
    data = timeline_data(run)
    assert [(lane.region, lane.top) for lane in data.lanes] == [("", True), ("", False)]
    assert data.lanes[0].height < data.lanes[1].height and data.lanes[0].y > data.lanes[1].y
    top = [(b.mode, b.start, b.end) for b in data.bars if b.lane == 0]
    main = [(b.mode, b.start, b.end) for b in data.bars if b.lane == 1]
    assert top == [("Dock", 0.0, 3.0), ("Transport", 3.0, 5.0), ("Dock", 5.0, 7.5)]
    assert main[:4] == [
        ("Dock.A", 0.0, 1.0),
        ("Dock.D", 1.0, 2.5),
        ("Dock.W", 2.5, 3.0),
        ("Transport", 3.0, 5.0),
    ]
    assert all(m.lane == 1 for m in data.marks)  # ticks on the leaf lane


def test_close_up_draws_message_arrows_at_send_and_receipt_times_with_latency():
    run = relay_with_latencies()
    fig, data = timeline_figure(run, window=(4.0, 9.0))
    fig.canvas.draw()
    ax = fig.axes[0]
    assert ax.get_xlim() == (4.0, 9.0)
    y = {lane.agent: lane.y for lane in data.lanes}
    arrows = [t for t in ax.texts if t.get_gid() == "message"]
    assert len(arrows) == 2
    got = sorted((a.xyann, a.xy) for a in arrows)
    sends = run.messages["t_send"]
    expected = [
        ((sends[0], y["runner"]), (sends[0] + 0.030, y["anchor"])),
        ((sends[1], y["anchor"]), (sends[1] + 0.120, y["runner"])),
    ]
    for (start, end), (start_x, end_x) in zip(got, expected, strict=True):
        np.testing.assert_allclose(start, start_x, atol=1e-9, rtol=0)
        np.testing.assert_allclose(end, end_x, atol=1e-9, rtol=0)
    # the drawn arrow path starts exactly at the send point
    for a in arrows:
        first = ax.transData.inverted().transform(a.arrow_patch.get_path().vertices[:1])[0]
        np.testing.assert_allclose(first, a.xyann, atol=1e-9)
    labels = sorted(t.get_text() for t in ax.texts if t.get_gid() == "message-label")
    assert labels == ["baton +30 ms", "done +120 ms"]
    assert [round(a.latency, 12) for a in data.arrows] == [0.03, 0.12]


def test_a_lost_message_is_a_red_x_at_its_send_time(tmp_path):
    run = relay_with_latencies()
    msgs = run.messages
    msgs.columns["status"] = np.array(["delivered", "lost"], dtype=object)
    msgs.columns["t_recv"] = np.array([msgs["t_recv"][0], np.nan])
    fig, data = timeline_figure(run, window=(4.0, 9.0))
    ax = fig.axes[0]
    assert len([t for t in ax.texts if t.get_gid() == "message"]) == 1
    (lost,) = [ln for ln in ax.lines if ln.get_gid() == "lost"]
    assert lost.get_marker() == "X"
    anchor_y = next(lane.y for lane in data.lanes if lane.agent == "anchor")
    np.testing.assert_allclose(lost.get_xydata(), [[msgs["t_send"][1], anchor_y]], atol=1e-12)
    assert [t.get_text() for t in ax.texts if t.get_gid() == "lost-label"] == ["done"]
    # without a window: no arrows, the loss counted in the title, JSON with null latency
    fig, data = timeline_figure(run)
    assert not [t for t in fig.axes[0].texts if t.get_gid() == "message"]
    assert "1 message lost" in fig.axes[0].get_title()
    write_timeline(run, tmp_path / "t.png", data_path=tmp_path / "t.json")
    arrows = json.loads((tmp_path / "t.json").read_text())["arrows"]
    anchor_y = next(lane.y for lane in data.lanes if lane.agent == "anchor")  # no close-up
    assert arrows == [
        {
            "y_send": anchor_y,
            "y_recv": data.arrows[0].y_recv,
            "t_send": msgs["t_send"][1],
            "t_recv": None,
            "type": "done",
            "latency": None,
            "lost": True,
            "sender": "anchor",
            "receiver": "runner",
            "socket": "control",
        }
    ]


def test_agents_picks_lanes_and_keeps_the_team_colours(tmp_path, capsys):
    run = relay_with_latencies()
    whole = timeline_data(run)
    only = timeline_data(run, window=(4.0, 9.0), agents=["anchor"])
    assert [lane.agent for lane in only.lanes] == ["anchor"]
    assert only.arrows == []  # the other end of every message is not drawn
    colour = {b.mode: b.color for b in whole.bars}
    assert all(colour[b.mode] == b.color for b in only.bars)
    with pytest.raises(ValueError, match="did you mean 'anchor'"):
        timeline_data(run, agents=["anchr"])
    path = tmp_path / "trace.json"
    run.to_json(path)
    assert main(["timeline", str(path), "--agents", "anchr", "-o", str(tmp_path / "t.png")]) == 2
    assert "--agents: no agent 'anchr'" in capsys.readouterr().err
    assert not (tmp_path / "t.png").exists()


def test_window_keeps_only_what_overlaps_it():
    run = ht.simulate(ht.load(EXAMPLES / "automata" / "unicycle_square.yaml"))
    data = timeline_data(run, window=(6.0, 12.0))
    assert [(b.mode, b.start) for b in data.bars] == [("Turn", 5.0), ("Drive", 7.0), ("Turn", 11.0)]
    assert [m.t for m in data.marks] == [7.0, 11.0]


def test_ensemble_instance_and_bad_extensions(tmp_path):
    team = ht.load(EXAMPLES / "automata" / "thermostat.yaml")
    run = ht.simulate(team, n=2, duration=20.0, overrides={"thermostat.K": [0.1, 0.2]})
    one = timeline_data(run, instance=1)
    alone = timeline_data(run.instance(1))
    assert [(b.mode, b.start, b.end) for b in one.bars] == [
        (b.mode, b.start, b.end) for b in alone.bars
    ]
    with pytest.raises(ValueError, match="unsupported format"):
        write_timeline(run, tmp_path / "t.jpg")
    with pytest.raises(ValueError, match="unsupported format"):
        write_timeline(run, tmp_path / "t.png", data_path=tmp_path / "t.xml")
    assert list(tmp_path.iterdir()) == []


ONE_PHASE = """
    team: one-phase
    agents:
      r:
        plant: {kind: flow, state: {c: 0}}
        initial: Go
        modes:
          Go:
            initial: A
            transitions: [{to: Done, after: 2}]
            modes:
              A: {transitions: [{to: B, after: 1}]}
              B: {}
          Done: {final: true, outcome: success}
          Fail: {final: true, outcome: stuck}
    simulation: {duration: 5}
"""


def test_the_top_row_is_drawn_only_where_an_agent_has_phases(team_from_yaml):
    """One composite top mode and final leaves: the top row would repeat the lane (off by
    default, on with top=True); Dock and Transport are two phases: on by default, off with
    top=False."""
    one = ht.simulate(team_from_yaml(ONE_PHASE))
    assert [lane.top for lane in timeline_data(one).lanes] == [False]
    assert [lane.top for lane in timeline_data(one, top=True).lanes] == [True, False]
    two = ht.simulate(team_from_yaml(DOCKING))
    assert [lane.top for lane in timeline_data(two).lanes] == [True, False]
    assert [lane.top for lane in timeline_data(two, top=False).lanes] == [False]


def test_final_modes_get_distinct_colours():
    colors = mode_colors(["Go", "Done", "Fail", "Parked"], finals=["Done", "Fail", "Parked"])
    assert len({colors["Done"], colors["Fail"], colors["Parked"]}) == 3
    assert colors["Go"] not in {colors["Done"], colors["Fail"], colors["Parked"]}


def test_the_legend_is_grouped_by_robot_with_short_names(team_from_yaml):
    """Two robots: each name heads its modes (bold), modes by their shortest unambiguous
    suffix — Lead.Curve and Offering.Curve stay apart, Follow is just Follow."""
    from hybridteam.export.legend import short_names

    assert short_names(
        ["Transport.Lead.Curve", "Transport.Offering.Curve", "Transport.Follow"]
    ) == {
        "Transport.Lead.Curve": "Lead.Curve",
        "Transport.Offering.Curve": "Offering.Curve",
        "Transport.Follow": "Follow",
    }
    run = ht.simulate(ht.load(EXAMPLES / "protocols" / "handover.yaml"))
    fig, _ = timeline_figure(run)
    texts = fig.axes[0].get_legend().get_texts()
    labels = [t.get_text() for t in texts]
    bold = [t.get_text() for t in texts if t.get_fontweight() == "bold"]
    assert bold == ["xr4000", "labmate", "operator"]
    assert labels[: labels.index("labmate")] == ["xr4000", "Lead", "Follow"]
    assert "Transport.Lead" not in labels


BLINK = """
    team: blink
    agents:
      a:
        plant: {kind: flow, state: {c: 0}}
        initial: Wait
        modes:
          Wait: {transitions: [{to: Pass, after: 1}]}
          Pass: {transitions: [{to: Hold, after: 0}]}
          Hold: {transitions: [{to: Done, after: 2}]}
          Done: {final: true}
    simulation: {duration: 5}
"""


def test_a_mode_entered_and_left_at_once_is_not_in_the_legend(team_from_yaml):
    """Pass is entered at t = 1 and left at t = 1: no stay a reader could find, so the
    legend leaves it out; Done, reached as the run ends at t = 3, is zero-long too but is
    where the run ended, and stays in."""
    run = ht.simulate(team_from_yaml(BLINK))
    assert [(r.mode, r.start, r.end) for r in run.intervals] == [
        ("Wait", 0.0, 1.0),
        ("Pass", 1.0, 1.0),
        ("Hold", 1.0, 3.0),
        ("Done", 3.0, 3.0),
    ]
    fig, data = timeline_figure(run)
    legend = fig.axes[0].get_legend()
    assert [t.get_text() for t in legend.get_texts()] == ["Wait", "Hold", "Done"]
    assert list(data.legend["a"]) == ["Wait", "Hold", "Done"]


def jittery_handover(team_from_yaml):
    """The hand-over example with 80 ms latency, 10 ms jitter and, after the request at
    3 s, a resignation at 5 s: offer, accept, confirm and announce, each acknowledged."""
    text = (EXAMPLES / "protocols" / "handover.yaml").read_text()
    text = text.replace("  latency: 0.03\n", "  latency: 0.08\n  jitter: 0.01\n")
    text = text.replace(
        "raise: want_lead}\n", "raise: want_lead}\n  - {at: 5.0, agent: labmate, raise: resign}\n"
    )
    assert "jitter" in text and "resign" in text
    return ht.simulate(team_from_yaml(text))


def test_nearly_parallel_arrows_share_one_label_content_first():
    """An accept and an ack leave xr4000 at one instant and arrive 2 ms apart: one label,
    the content named first, the latencies as a range; a message the other way, or one
    sent a label's width later, is labelled on its own."""
    from hybridteam.export.arrows import bundles
    from hybridteam.export.timeline import TimelineArrow

    ack = TimelineArrow(0.0, -1.0, 5.0, 5.080, "ack", 0.080, False)
    accept = TimelineArrow(0.0, -1.0, 5.0, 5.082, "accept", 0.082, False)
    back = TimelineArrow(-1.0, 0.0, 5.0, 5.085, "offer", 0.085, False)
    later = TimelineArrow(0.0, -1.0, 5.02, 5.101, "ack", 0.081, False)
    found = bundles([ack, accept, back, later], tolerance=0.005)
    assert [b.text() for b in found] == ["accept + ack +80–82 ms", "offer +85 ms", "ack +81 ms"]
    assert found[0].arrows == [ack, accept]


def test_labels_claim_spots_new_kinds_first_then_repeats_then_acks():
    """Send order: an ack, an offer, its repeat, an accept. The offer and the accept are
    new kinds and claim first (in send order), then the repeat; the ack comes last."""
    from hybridteam.export.arrows import bundles, label_order
    from hybridteam.export.timeline import TimelineArrow

    sent = [
        TimelineArrow(0.0, -1.0, t, t + 0.08, kind, 0.08, False)
        for t, kind in ((1.0, "ack"), (2.0, "offer"), (3.0, "offer"), (4.0, "accept"))
    ]
    order = [(b.types, new) for b, new in label_order(bundles(sent, 0.01))]
    assert order == [(["offer"], True), (["accept"], True), (["offer"], False), (["ack"], True)]


def test_every_message_kind_of_a_jittery_hand_over_is_labelled(team_from_yaml):
    """With jitter an ack and a reply sent together arrive milliseconds apart; the close-up
    of the resignation still names offer, accept, confirm and announce (the hand-over's
    messages), every label in a white gap between lanes and clear of every other."""
    run = jittery_handover(team_from_yaml)
    window = (4.95, 5.6)
    msgs = run.messages
    sent = (
        (msgs["socket"].astype(str) == "control")
        & (msgs["t_send"] >= window[0])
        & (msgs["t_send"] <= window[1])
    )
    kinds = set(msgs["type"][sent].tolist())
    assert kinds == {"offer", "accept", "confirm", "announce", "ack"}
    fig, data = timeline_figure(run, window=window)
    renderer = fig.canvas.get_renderer()
    ax = fig.axes[0]
    labels = [t for t in ax.texts if t.get_gid() == "message-label"]
    named = {name for t in labels for name in t.get_text().rsplit(" +", 1)[0].split(" + ")}
    assert named == kinds
    boxes = [t.get_window_extent(renderer) for t in labels]
    for i, a in enumerate(boxes):
        for b in boxes[i + 1 :]:
            assert not a.overlaps(b)
    bands = [(lane.y - lane.height / 2, lane.y + lane.height / 2) for lane in data.lanes]
    for t in labels:
        y = t.get_position()[1]
        assert not any(lo <= y <= hi for lo, hi in bands)
