"""A recording drawn over its model's replay (issue 45, item 4: ``timeline`` and ``plot``
overlay log and model), asserted on the drawn artists.

The answers are known without the views: the mutated handover's Labmate leads from the
offer's arrival, 3 + 0.03 s, where the model accepts (test_conformance); the square log
is the closed form of a unicycle driving a 1 m square (test_logs), so the model's path is
that square at the log's 0.1 s samples, and a logged pose moved by 0.2 m is the largest
deviation, 0.2 m at its time.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from matplotlib.collections import Collection

import hybridteam as ht
from hybridteam.cli import main
from hybridteam.export.overlay import overlay_plot_figure, overlay_timeline_figure
from hybridteam.logs.conformance import conformance
from hybridteam.trace import Trace
from tests.logs.test_conformance import mutated_handover, square_log

OFFER_ARRIVES = 3.0 + 0.03  # the XR4000 resigns at 3 s; the offer takes 30 ms


@pytest.fixture(scope="module")
def mutated(tmp_path_factory):
    """The mutant's run (the log), its team files, and its conformance to the real team."""
    resign, mutant = mutated_handover(tmp_path_factory.mktemp("mutated"))
    run = ht.simulate(ht.load(mutant))
    trace = resign.parent / "trace.json"
    run.to_json(trace)
    return resign, trace, run, conformance(run, ht.load(resign))


def drawn_bars(ax, lane: int) -> list[tuple[float, float]]:
    """(start, end) of every bar drawn in lane ``lane``, by start."""
    out = []
    for c in ax.collections:
        if isinstance(c, Collection) and c.get_gid() == f"bars:{lane}":
            for path in c.get_paths():
                (x0, _), (x1, _) = path.get_extents().get_points()
                out.append((float(x0), float(x1)))
    return sorted(out)


def intervals(trace: Trace, agent: str, modes: set[str]) -> list[tuple[float, float]]:
    iv = trace.intervals.where(agent=agent)
    return sorted(
        (float(s), float(e))
        for m, s, e in zip(iv["mode"], iv["start"], iv["end"], strict=True)
        if m in modes
    )


def test_the_timeline_draws_the_logs_and_the_models_bars_and_the_first_divergence(mutated):
    """Per agent a lane of the log and one of the model: the Labmate's log lane has the
    log's stays (Follow to 3.03 s, then Lead), its model lane the replay's (Follow to
    3.03 s, then Accepting), bar for bar; the first divergence is a line at 3.03 s across
    the Labmate's two lanes, labelled with both modes, and named in the legend."""
    _resign, _trace, run, result = mutated
    fig, data = overlay_timeline_figure(result)
    ax = fig.axes[0]
    labels = [t.get_text() for t in ax.get_yticklabels()]
    assert labels == [
        f"{a} — {side}" for a in ("xr4000", "labmate", "operator") for side in ("log", "model")
    ]
    log_lane, model_lane = labels.index("labmate — log"), labels.index("labmate — model")
    leaves = {"Transport.Follow", "Transport.Lead", "Transport.Accepting", "Transport.Operated"}
    for lane, trace in ((log_lane, run), (model_lane, result.model)):
        # zero-length stays are drawn as a sliver of 0.2 % of the span: compare the starts
        want = intervals(trace, "labmate", leaves)
        got = drawn_bars(ax, lane)
        assert [s for s, _ in got] == pytest.approx([s for s, _ in want], abs=1e-9)
        assert [e for _, e in got] == pytest.approx(
            [max(e, s + 0.002 * data.span[1]) for s, e in want], abs=1e-9
        )
    seen = {
        lane: [(b.mode, b.start) for b in data.bars if b.lane == lane]
        for lane in (log_lane, model_lane)
    }
    assert seen[log_lane][:2] == [
        ("Transport.Follow", 0.0),
        ("Transport.Lead", pytest.approx(OFFER_ARRIVES, abs=1e-12)),
    ]
    assert seen[model_lane][:2] == [
        ("Transport.Follow", 0.0),
        ("Transport.Accepting", pytest.approx(OFFER_ARRIVES, abs=1e-12)),
    ]
    (line,) = [a for a in ax.lines if a.get_gid() == "divergence"]
    assert list(line.get_xdata()) == pytest.approx([OFFER_ARRIVES] * 2, abs=1e-12)
    lanes = (data.lanes[log_lane], data.lanes[model_lane])
    y0, y1 = sorted(line.get_ydata())
    assert y0 < lanes[1].y - lanes[1].height / 2 and y1 > lanes[0].y + lanes[0].height / 2
    (label,) = [t for t in ax.texts if t.get_gid() == "divergence-label"]
    assert label.get_text() == "t=3.03 s: model Accepting, log Lead"
    assert "first divergence" in [t.get_text() for t in ax.get_legend().get_texts()]
    assert "first divergence at t=3.03 s, labmate" in ax.get_title()


def test_a_conformant_recording_has_no_divergence_mark(tmp_path):
    """The square log against its team: conformant, said in the title; nothing marked."""
    team, run = square_log(tmp_path)
    fig, _ = overlay_timeline_figure(conformance(run, team))
    ax = fig.axes[0]
    assert not [a for a in ax.lines if a.get_gid() == "divergence"]
    assert "conformant" in ax.get_title()


def test_the_plot_draws_the_models_path_and_the_largest_deviation(tmp_path):
    """The square log with the pose at t = 1.5 s (0.75, 0) moved 0.2 m to (0.75, 0.2):
    the model's path, dashed, is the square's closed form at the log's samples (to float
    rounding), and the largest deviation is a segment from (0.75, 0.2) to (0.75, 0),
    labelled 0.2 m at t=1.5 s; the log has the square's commands, so the plant under
    them is the same square, dotted, and its largest deviation is the same segment (its
    label below the logged end, the replay's above); the legend names the paths and the
    marks."""
    from tests.logs.test_logs import square_pose

    team, run = square_log(tmp_path)
    samples = {k: v.copy() for k, v in run.samples.items()}
    samples["robot"][15, 0, 1] += 0.2
    run = Trace(
        run.meta,
        run.diagnostics,
        run.transitions,
        run.intervals,
        run.messages,
        run.sample_times,
        samples,
    )
    fig = overlay_plot_figure(conformance(run, team))
    ax = fig.axes[0]
    (model,) = [a for a in ax.lines if a.get_gid() == "model-path:robot"]
    (logged,) = [a for a in ax.lines if a.get_gid() == "path:robot"]
    square = np.array([square_pose(k)[:2] for k in range(121)])
    assert np.max(np.abs(model.get_xydata() - square)) <= 1e-9
    assert model.get_linestyle() != logged.get_linestyle()
    assert model.get_color() == logged.get_color()
    (mark,) = [a for a in ax.lines if a.get_gid() == "deviation:robot"]
    assert mark.get_xydata() == pytest.approx(np.array([[0.75, 0.2], [0.75, 0.0]]), abs=1e-9)
    (label,) = [t for t in ax.texts if t.get_gid() == "deviation-label:robot"]
    assert label.get_text() == "0.2 m at t=1.5 s"
    legend = ax.get_legend() or fig.legends[0]
    texts = [t.get_text() for t in legend.get_texts()]
    assert texts[:5] == [
        "robot",
        "robot (model)",
        "robot (under logged commands)",
        "largest deviation, log to model",
        "largest deviation, log to logged commands",
    ]
    (plant,) = [a for a in ax.lines if a.get_gid() == "commanded-path:robot"]
    assert np.max(np.abs(plant.get_xydata() - square)) <= 1e-9
    assert plant.get_color() == logged.get_color()
    assert plant.get_linestyle() != logged.get_linestyle()
    (mark,) = [a for a in ax.lines if a.get_gid() == "commanded-deviation:robot"]
    assert mark.get_xydata() == pytest.approx(np.array([[0.75, 0.2], [0.75, 0.0]]), abs=1e-9)
    (below,) = [t for t in ax.texts if t.get_gid() == "commanded-deviation-label:robot"]
    assert below.get_text() == "0.2 m at t=1.5 s"
    assert below.xyann[1] < 0 < label.xyann[1]  # the two labels do not overlap


def test_no_deviation_no_mark(tmp_path):
    """The square log as recorded: the model is where the log is (to float rounding
    under 1e-9 m), and only a deviation that is not exactly zero is marked, at its
    size."""
    team, run = square_log(tmp_path)
    result = conformance(run, team)
    worst = result.deviation("robot")
    assert worst is not None and worst.distance <= 1e-9
    marks = [
        a for a in overlay_plot_figure(result).axes[0].lines if a.get_gid() == "deviation:robot"
    ]
    assert len(marks) == (worst.distance > 0)


def test_the_plot_draws_the_plant_under_the_logged_commands_apart_from_the_model(tmp_path):
    """test_conformance's turn between samples: the robot drives along x at 0.5 m/s,
    turns a quarter in place from 1.03 s for 1 s and drives along y; its model drives
    straight along x. The plant under the logged commands (dotted) turns 0.1 - 0.03 s
    late: it ends at (0.5 * 1.1, 0.5 * (4 - 2.1)) = (0.55, 0.95), and its mark joins the
    log to it where they are sqrt(2) * 0.5 * 0.07 m apart; the replay's (dashed) runs
    along x to (2, 0) at t = 4, the log's farthest point from it being its end,
    (0.515, 0.985). The plane covers all three."""
    from tests.logs.test_conformance import V, commanded_log

    d, t1 = 0.03, 1.03

    def truth(t: float) -> tuple[float, float, float]:
        if t < t1:
            return V * t, 0.0, 0.0
        if t < t1 + 1.0:
            return V * t1, 0.0, np.pi / 2 * (t - t1)
        return V * t1, V * (t - t1 - 1.0), np.pi / 2

    def given(t: float) -> tuple[float, float]:
        return (0.0, np.pi / 2) if t1 <= t < t1 + 1.0 else (V, 0.0)

    team, run = commanded_log(tmp_path, truth, given)
    fig = overlay_plot_figure(conformance(run, team))
    ax = fig.axes[0]
    (plant,) = [a for a in ax.lines if a.get_gid() == "commanded-path:robot"]
    assert plant.get_xydata()[-1] == pytest.approx([0.55, 0.95], abs=1e-12)
    (mark,) = [a for a in ax.lines if a.get_gid() == "commanded-deviation:robot"]
    (x0, y0), (x1, y1) = mark.get_xydata()
    assert np.hypot(x1 - x0, y1 - y0) == pytest.approx(np.sqrt(2) * V * (0.1 - d), abs=1e-12)
    (label,) = [t for t in ax.texts if t.get_gid() == "commanded-deviation-label:robot"]
    assert label.get_text() == "0.0495 m at t=" + label.get_text().split("t=")[1]
    (replay,) = [a for a in ax.lines if a.get_gid() == "deviation:robot"]
    assert replay.get_xydata() == pytest.approx(np.array([[0.515, 0.985], [2.0, 0.0]]), abs=1e-9)
    x_lo, x_hi = ax.get_xlim()
    y_lo, y_hi = ax.get_ylim()
    assert x_lo <= 0.0 and x_hi >= 2.0 and y_lo <= 0.0 and y_hi >= 0.985


# ---------------------------------------------------------------------- the commands
def test_timeline_and_plot_against_a_team(mutated, tmp_path, capsys):
    """``timeline TRACE --against TEAM.yaml`` and ``plot ... --against``: the overlaid
    figures, written; the Python methods give the same files."""
    resign, trace, _run, result = mutated
    for view in ("timeline", "plot"):
        out = tmp_path / f"{view}.svg"
        assert main([view, str(trace), "--against", str(resign), "-o", str(out)]) == 0
        assert capsys.readouterr().out.strip() == f"wrote {out}"
        text = out.read_text()
        assert ("labmate — model" if view == "timeline" else "xr4000 (model)") in text
    result.write_timeline(tmp_path / "py.svg")
    assert (tmp_path / "py.svg").read_bytes() == (tmp_path / "timeline.svg").read_bytes()


def test_views_against_a_rosbag2_with_a_mapping(tmp_path, capsys):
    """A robot's bag read through its mapping file, as ``check`` reads it."""
    square_log(tmp_path)  # writes square.yaml, map.yaml and the bag
    out = tmp_path / "t.png"
    assert (
        main(
            [
                "timeline",
                str(tmp_path / "bag"),
                "--against",
                str(tmp_path / "square.yaml"),
                "--map",
                str(tmp_path / "map.yaml"),
                "-o",
                str(out),
            ]
        )
        == 0
    )
    assert out.stat().st_size > 0


def _one_line(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    return err


@pytest.mark.parametrize(
    "extra, says",
    [
        (["--map", "m.yaml"], "--map goes with --against"),
        (["--tolerance", "0.5"], "--tolerance goes with --against"),
        (["--against", "TEAM", "--tolerance", "-1"], "--tolerance -1: a number of seconds >= 0"),
        (["--against", "TEAM", "--tolerance", "nan"], "--tolerance nan"),
        (["--against", "TEAM", "--data", "d.csv"], "--data"),
    ],
)
def test_bad_arguments_are_one_line_and_exit_2(mutated, tmp_path, capsys, extra, says):
    resign, trace, _run, _result = mutated
    extra = [str(resign) if e == "TEAM" else e for e in extra]
    out = tmp_path / "t.png"
    assert main(["timeline", str(trace), *extra, "-o", str(out)]) == 2
    assert says in _one_line(capsys)
    assert not out.exists()


def test_a_recording_of_another_team_is_one_line_and_exit_2(mutated, tmp_path, capsys):
    _resign, trace, _run, _result = mutated
    other = Path(__file__).parents[2] / "tests" / "fixtures" / "live" / "handshake.yaml"
    out = tmp_path / "p.png"
    assert main(["plot", str(trace), "--against", str(other), "-o", str(out)]) == 2
    assert "a run of team 'handover', not 'live handshake'" in _one_line(capsys)
    assert not out.exists()
