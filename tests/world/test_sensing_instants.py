"""When the world is read: at each robot's sensing instants (its law ticks), not at every
instant of the run, so traffic between other robots moves no detection, break or collision.

Each case runs a fixture as it is and with two more robots, P and Q, that have nothing to
do with it: P sends Q a ``ping`` every 0.1 s over a 0.07 s link, so copies arrive at
``0.1 k + 0.07`` — between the fixture's law ticks, one of them inside the window between
the crossing and the tick that reports it (the test checks it does). Reading the world at
every instant reported the crossing at that arrival instead.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hybridteam import load, simulate
from hybridteam.world.carried import CarriedPayload

FIXTURES = Path(__file__).parents[1] / "fixtures" / "world"

#: P and Q, far from everything, and the link between them (inserted before the fixture's
#: own agents); Q has no transition on ping: an arrival that changes nothing in anyone
TRAFFIC = """network: {latency: 0.07}
agents:
  P:
    plant: {kind: holonomic, state: {x: 0, y: 10, theta: 0}}
    initial: Talk
    modes:
      Talk:
        inputs: {vx: 0, vy: 0, omega: 0}
        transitions:
          - {to: Talk, after: 0.1, do: [{send: ping, to: Q}]}
  Q:
    plant: {kind: holonomic, state: {x: 0, y: 12, theta: 0}}
    modes:
      Listen: {inputs: {vx: 0, vy: 0, omega: 0}}
"""


def run_both(tmp_path, text: str):
    """The team of ``text`` run as it is and with P's pings to Q."""
    runs = []
    for name, body in (("alone", text), ("traffic", text.replace("agents:\n", TRAFFIC, 1))):
        path = tmp_path / f"{name}.yaml"
        path.write_text(body)
        runs.append(simulate(load(path)))
    return runs


def arrivals(run) -> np.ndarray:
    m = run.messages
    return np.asarray(m["t_recv"], float)[np.asarray(m["status"]) == "delivered"]


def fired(run, cause: str) -> list[float]:
    return [row.t for row in run.transitions if row.cause == cause]


@pytest.mark.parametrize(("period", "tick"), [(0.1, 14.5), (0.3, 14.7)])
def test_a_detection_comes_at_its_robots_first_tick_past_the_crossing(tmp_path, period, tick):
    """IR wall: beam 0 reads 1.7 - 0.1 t, below 0.255 from t* = 14.45 on; R's ticks are
    multiples of its period, so the rule fires at 14.5 (period 0.1) or 14.7 (0.3: 14.4 is
    before t*), where R stops at x = 0.1 tick, 2 - 0.1 tick - 0.3 from the wall — with or
    without a copy arriving at 14.47 in between."""
    text = (FIXTURES / "ir_wall.yaml").read_text().replace("period: 0.1", f"period: {period}")
    alone, traffic = run_both(tmp_path, text)
    got = arrivals(traffic)
    assert ((got > 14.45) & (got < tick)).any()  # an arrival inside the window
    for run in (alone, traffic):
        (t,) = fired(run, "event:obstacle_detected")
        assert abs(t - tick) < 1e-9
        stats = run._outcomes[0]["stats"]
        np.testing.assert_allclose(stats["min_clearance"][-1], 2 - 0.1 * tick - 0.3, atol=1e-9)
        assert abs(run.samples["R"][-1, 0, 0] - 0.1 * tick) < 1e-9
    assert fired(alone, "event:obstacle_detected") == fired(traffic, "event:obstacle_detected")


def test_a_grasp_breaks_at_its_carriers_tick_not_at_an_arrival(tmp_path):
    """Bar pull: A's grasp takes 3/4 of the stretch 0.1 t and passes its limit 0.31 at
    t* = 4.1333; the carriers tick every 0.1 s, so the bar drops at 4.2 with A's offset
    0.075 * 4.2 = 0.315 and B's 0.025 * 4.2 = 0.105 — not at the copy arriving at 4.17."""
    alone, traffic = run_both(tmp_path, (FIXTURES / "bar_pull.yaml").read_text())
    got = arrivals(traffic)
    assert ((got > 4.1334) & (got < 4.2)).any()
    for run in (alone, traffic):
        out = run._outcomes[0]
        assert out["outcome"] == "link_broken" and abs(out["t"] - 4.2) < 1e-9
        assert "offset 0.315 > limit 0.31" in out["message"]
        np.testing.assert_allclose(out["stats"]["max_grasp_offset"], [0.315, 0.105], atol=1e-9)


def test_a_collision_is_seen_at_the_robots_tick(tmp_path):
    """IR wall with R at 0.3 and its rule on the beam behind (it never fires): R's
    footprint (0.3) meets the wall on x = 2 when 0.3 t = 1.7, t* = 5.667 (the first
    contact, found over the motion between ticks); seen at the tick 5.7, overlapping by
    0.3 * 5.7 - 1.7 = 0.01 — not at the copy arriving at 5.67."""
    text = (
        (FIXTURES / "ir_wall.yaml")
        .read_text()
        .replace("vx: 0.1", "vx: 0.3")
        .replace("beams: [0]", "beams: [2]")
    )
    alone, traffic = run_both(tmp_path, text)
    got = arrivals(traffic)
    assert ((got > 5.667) & (got < 5.7)).any()
    for run in (alone, traffic):
        out = run._outcomes[0]
        assert out["outcome"] == "collision" and abs(out["t"] - 5.7) < 1e-9
        assert "overlapping it by up to 0.01 by its tick at t=5.7" in out["message"]
        contact = float(out["message"].rsplit("first touching it at t=", 1)[1])
        assert contact == pytest.approx(1.7 / 0.3, abs=1e-9)


def test_a_payload_settles_only_where_it_is_read(tmp_path, monkeypatch):
    """With P's pings arriving between the ticks, the bar settles at its carriers' ticks
    (multiples of 0.1, where the samples are taken too) and at no arrival."""
    times: list[float] = []
    settle = CarriedPayload._settle

    def counted(self, world, idx):
        times.extend(world.t[idx].tolist())
        return settle(self, world, idx)

    monkeypatch.setattr(CarriedPayload, "_settle", counted)
    _, traffic = run_both(tmp_path, (FIXTURES / "bar_pull.yaml").read_text())
    assert len(arrivals(traffic)) > 30
    alone = len(times) // 2  # (both runs settle alike: the first half is the plain run's)
    ticks = np.asarray(times[alone:]) / 0.1
    np.testing.assert_allclose(ticks, np.round(ticks), atol=1e-6)
    # the start, then once at each tick 0, 0.1, ..., 4.2
    assert len(times) - alone == 1 + 43


CLEARANCE = """\
team: clear
agents:
  A:
    plant: {kind: holonomic, state: {x: 0, y: -1.5, theta: 0}}
    modes:
      Go: {inputs: {vx: 0.1, vy: 0, omega: 0}, period: 0.3}
world:
  - use: obstacles
    with:
      walls: [[2, -2, 2, 1]]
      radius: [[A, 0.2]]
      clearance: true
requirements:
  robot_clear: always(robot_clearance.A > 1.0)
simulation: {duration: 4.95, sample_period: 0.5}
"""


def test_a_clearance_series_holds_its_robots_last_reading_between_its_ticks(tmp_path):
    """A's footprint is 1.8 - 0.1 t from the wall; it ticks every 0.3 s, so the series
    reads 1.8 - 0.1 * 0.3 floor(t / 0.3) — at the samples every 0.5 s (off its grid) and
    at the end, 4.95, where it still holds the tick 4.8's 1.32: the requirement's
    robustness is 0.32 with or without P's pings (read at every instant it was
    1.8 - 0.495 - 1, and each arrival added a value)."""
    alone, traffic = run_both(tmp_path, CLEARANCE)
    for run in (alone, traffic):
        t = run.sample_times
        held = 1.8 - 0.1 * 0.3 * np.floor(t / 0.3 + 1e-9)
        column = run.meta["series"]["robot_clearance"].index("A")
        got = run.samples["robot_clearance"][:, 0, column]
        read = ~np.isnan(got)  # (a sample inside a step, at no instant, has no world series)
        np.testing.assert_allclose(got[read], held[read], atol=1e-12)
        verdict = run.summary()["instances"][0]["requirements"]["robot_clear"]
        assert verdict["satisfied"] and abs(verdict["robustness"] - 0.32) < 1e-9
        assert abs(run._outcomes[0]["stats"]["min_clearance"][-1] - 1.32) < 1e-9
    # P's timer makes 0.5 an instant: A's series there holds its tick 0.3's 1.77
    got = traffic.samples["robot_clearance"][1, 0, column]
    assert abs(got - 1.77) < 1e-12


def test_an_ensemble_whose_instances_hear_copies_at_different_instants_equals_its_runs(tmp_path):
    """Two instances of the IR wall with P's pings over links of 0.07 and 0.03 s: their
    arrival instants differ (each instant runs only its instance), their detections do
    not (14.5, R's tick), and each equals its single run."""
    path = tmp_path / "traffic.yaml"
    path.write_text((FIXTURES / "ir_wall.yaml").read_text().replace("agents:\n", TRAFFIC, 1))
    team = load(path)
    latencies = [0.07, 0.03]
    both = simulate(team, n=2, overrides={"network.latency": latencies})
    for i, latency in enumerate(latencies):
        one = simulate(team, overrides={"network.latency": latency})
        mine = [r for r in both.transitions if r.instance == i]
        assert [(r.agent, r.t, r.target) for r in mine] == [
            (r.agent, r.t, r.target) for r in one.transitions
        ]
        assert fired(one, "event:obstacle_detected") == [pytest.approx(14.5, abs=1e-9)]
        assert both._outcomes[i]["stats"] == one._outcomes[0]["stats"]
