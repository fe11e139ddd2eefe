"""A data stream's copies are due at ``start + k / rate``, counted from its start; a
law's estimate reads the newest copy.

Adding ``1 / rate`` to the last copy's time drifts by a rounding per copy, which set a
20 Hz stream started at 0 a femtosecond beside a 20 Hz law's ticks: two instants where
the model has one. The expected send times here are computed independently, as ``k``
times the period (the float of a law's ``k``-th tick at that period).
"""

from __future__ import annotations

import numpy as np
import pytest

import hybridteam as ht
from hybridteam.engine.run.network import Message
from hybridteam.engine.run.streams import Inbox
from tests.engine.test_protocols import team


def sends(run, sender):
    m = run.messages
    rows = (m["sender"] == sender) & (m["type"] == "state") & (m["receiver"] == "operator")
    return m["t_send"][rows]


@pytest.mark.parametrize("rate", [20, 7, 3])
def test_copies_are_counted_from_the_start_not_summed(team_from_yaml, rate):
    run = ht.simulate(team(team_from_yaml, rate=rate, duration=6.0))
    period = 1 / rate
    got = sends(run, "r1")
    k = np.arange(got.size, dtype=float)
    assert got.size == int(6.0 * rate) + 1  # at 0, then every period up to the end
    np.testing.assert_array_equal(got, k * period)  # bit for bit
    # what summing would give: it drifts away from k * period as copies accumulate
    summed = np.cumsum(np.r_[0.0, np.full(got.size - 1, period)])
    assert np.any(summed != got)


def test_a_20_hz_stream_shares_the_instants_of_20_hz_laws(team_from_yaml):
    """Every robot runs its law at 20 Hz and streams its state at 20 Hz from t = 0: each
    copy leaves at a law tick, none a hair beside one."""
    run = ht.simulate(team(team_from_yaml, rate=20, duration=3.0))
    ticks = np.arange(61) * 0.05
    for sender in ("r1", "r2", "r3"):
        got = sends(run, sender)
        assert np.isin(got, ticks).all(), got[~np.isin(got, ticks)]


def test_a_laws_estimate_reads_every_field_of_the_chosen_copy():
    """``InboxView.fields`` (one gather for all fields, what ``ctx.estimate`` reads) gives
    each field of the chosen sender's newest copy, NaN where none has arrived."""
    box = Inbox(n=3, agents=3, fields={"state": ["x", "y", "theta"]})
    box.deliver(0, Message(1, 0, 0, 0.1, "data", "state", {"x": 1.0, "y": 2.0, "theta": 3.0}))
    box.deliver(0, Message(1, 0, 1, 0.2, "data", "state", {"x": 4.0, "y": 5.0}))
    box.deliver(2, Message(2, 0, 0, 0.1, "data", "state", {"x": 7.0, "y": 8.0, "theta": 9.0}))
    view = box.view(np.arange(3))
    got = view.fields("state", view.sender("state", np.array([1, 1, 2])))
    np.testing.assert_array_equal(got["x"], [4.0, np.nan, 7.0])
    np.testing.assert_array_equal(got["y"], [5.0, np.nan, 8.0])
    np.testing.assert_array_equal(got["theta"], [np.nan, np.nan, 9.0])  # not in the newest
    latest = view.fields("state", view.sender("state"))  # the most recent sender, if any
    np.testing.assert_array_equal(latest["x"], [4.0, np.nan, 7.0])


RATE_PROTOCOL = """\
kind: protocol
protocol: beacon
streams:
  - {message: ping, rate: hz, fields: {x: x}}
region:
  roles: [go]
  initial: Going
  modes:
    Going: {role: go}
"""

RATE_TEAM = """\
team: beacon
network: {latency: 0.01}
agents:
  r:
    plant: {kind: unicycle, state: {x: 0, y: 0, theta: 0}}
    variables: {hz: 10}
    modes:
      Run:
        protocol: beacon.yaml
        roles: {go: {inputs: {v: 0, omega: 0}, period: 0.1}}
        transitions: [{after: 1.0, guard: hz == 10, do: [hz = 20]}]
  s:
    plant: {kind: unicycle, state: {x: 1, y: 0, theta: 0}}
    modes:
      Idle: {inputs: {v: 0, omega: 0}, period: 0.1}
simulation: {duration: 2.0}
"""


def test_a_rate_that_changes_counts_again_from_the_change(tmp_path):
    """``rate: hz`` reads a variable, 10 until t = 1 s, then 20: copies at k * 0.1 up to
    1.0 s (that one already at the new rate, which the transition at 1.0 s set first),
    then one new period on and counted from there, 1.0 + k * 0.05."""
    (tmp_path / "beacon.yaml").write_text(RATE_PROTOCOL)
    (tmp_path / "team.yaml").write_text(RATE_TEAM)
    run = ht.simulate(ht.load(tmp_path / "team.yaml"))
    m = run.messages
    got = m["t_send"][(m["sender"] == "r") & (m["receiver"] == "s")]
    want = np.r_[np.arange(11) * 0.1, 1.0 + np.arange(1, 21) * 0.05]
    np.testing.assert_array_equal(got, want)
