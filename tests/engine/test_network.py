"""The network against known answers: latency, jitter, loss, rate limits, fields, replies."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

import hybridteam as ht
from hybridteam.io.loader import InputErrors

HANDSHAKE = """
team: handshake
parameters: {{d: {d}, p_loss: {loss}, timeout: 1.0, priority: {priority}}}
network: {{latency: d, loss: p_loss}}
agents:
  follower:
    plant: {{kind: flow, state: {{c: 0}}}}
    initial: Follow
    modes:
      Follow:
        transitions:
          - to: Requesting
            after: 1.0
            do: [{{send: request, to: leader, fields: {{priority: priority}}}}]
      Requesting:
        transitions:
          - {{to: Lead, on: grant}}
          - {{to: Refused, on: deny}}
          - {{to: Stalled, after: timeout}}
      Lead: {{final: true}}
      Refused: {{final: true}}
      Stalled: {{final: true}}
  leader:
    plant: {{kind: flow, state: {{c: 0}}}}
    initial: Lead
    modes:
      Lead:
        transitions:
          - {{to: Follow, on: request, guard: msg_priority > 1, do: [{{send: grant, to: sender}}]}}
          - {{to: Declined, on: request, guard: msg_priority <= 1,
              do: [{{send: deny, to: sender}}]}}
      Follow: {{final: true}}
      Declined: {{final: true}}
"""


def handshake(team_from_yaml, d=0.03, loss=0.0, priority=2):
    return team_from_yaml(HANDSHAKE.format(d=d, loss=loss, priority=priority))


def when(run, agent, target):
    rows = [r.t for r in run.transitions if r.agent == agent and r.target == target]
    return rows[0] if rows else None


@pytest.mark.parametrize("d", [0.0, 0.03, 0.25])
def test_handover_takes_one_latency_each_way(team_from_yaml, d):
    run = ht.simulate(handshake(team_from_yaml, d=d))
    t_a = when(run, "follower", "Requesting")
    t_b = when(run, "leader", "Follow")
    t_c = when(run, "follower", "Lead")
    assert t_a == 1.0
    assert t_b - t_a == pytest.approx(d, abs=1e-12)
    assert t_c - t_b == pytest.approx(d, abs=1e-12)
    msgs = [(m.sender, m.receiver, m.type, m.t_send, m.t_recv, m.status) for m in run.messages]
    assert msgs == [
        ("follower", "leader", "request", 1.0, 1.0 + d, "delivered"),
        ("leader", "follower", "grant", t_b, t_b + d, "delivered"),
    ]
    assert run.outcome == "ok"


def test_message_fields_and_replies(team_from_yaml):
    run = ht.simulate(handshake(team_from_yaml, priority=0))
    assert when(run, "leader", "Declined") == pytest.approx(1.03)
    assert when(run, "follower", "Refused") == pytest.approx(1.06)
    assert [m.type for m in run.messages] == ["request", "deny"]


def test_dead_link_is_detected_by_the_timeout(team_from_yaml):
    run = ht.simulate(handshake(team_from_yaml, loss=1.0))
    assert when(run, "follower", "Stalled") == pytest.approx(2.0)
    (msg,) = list(run.messages)
    assert (msg.type, msg.status, msg.reason) == ("request", "lost", "loss")
    assert math.isnan(msg.t_recv)


BEACON = """
team: beacon
parameters: {{period: {period}, d: 0.1, j: {jitter}, p: {loss}}}
network:
  latency: d
  jitter: j
  loss: p
  rate_limits: {{listener: {limits}}}
agents:
  beacon:
    plant: {{kind: flow, state: {{c: 0}}}}
    initial: Send
    modes:
      Send:
        transitions:
          - {{to: Send, after: period, do: [{{send: ping, socket: data,
              fields: {{k: t}}}}]}}
  listener:
    plant: {{kind: flow, state: {{c: 0}}}}
    variables: {{heard: 0, last: -1}}
    initial: Listen
    modes:
      Listen:
        transitions:
          - {{to: Listen, on: ping, do: ["heard += 1", "last = msg_k"]}}
simulation: {{duration: {duration}}}
"""


def beacon(team_from_yaml, period=0.01, jitter=0.0, loss=0.0, limits="{}", duration=10.0):
    return team_from_yaml(
        BEACON.format(period=period, jitter=jitter, loss=loss, limits=limits, duration=duration)
    )


def test_jitter_is_uniform_on_top_of_the_latency(team_from_yaml):
    run = ht.simulate(beacon(team_from_yaml, jitter=0.05))
    sends = len(run.transitions.where(agent="beacon", cause="after"))
    m = run.messages.where(status="delivered")
    assert sends == 1000  # every 0.01 s up to t = 10 s
    assert len(m) + len(run.messages.where(reason="run ended")) == sends
    delay = m["t_recv"] - m["t_send"]
    assert len(delay) >= 985  # the last 0.1-0.15 s of sends are still in flight
    assert delay.min() >= 0.1 - 1e-12 and delay.max() <= 0.15 + 1e-12
    assert stats.kstest((delay - 0.1) / 0.05, "uniform").pvalue > 1e-3


def test_loss_rate_is_the_declared_probability(team_from_yaml):
    run = ht.simulate(beacon(team_from_yaml, loss=0.3))
    m = run.messages
    resolved = m.filter(m["reason"] != "run ended")
    lost = np.sum(resolved["reason"] == "loss")
    n = len(resolved)
    assert n >= 990
    assert abs(lost / n - 0.3) < 4 * math.sqrt(0.3 * 0.7 / n)
    # what the listener heard is exactly what was delivered
    heard = run.transitions.where(agent="listener", cause="message:ping")
    assert len(heard) == np.sum(resolved["status"] == "delivered")


def test_same_seed_same_losses_other_seed_other_losses(team_from_yaml):
    team = beacon(team_from_yaml, loss=0.5, duration=2.0)
    a = ht.simulate(team, seed=1).messages["status"]
    b = ht.simulate(team, seed=1).messages["status"]
    c = ht.simulate(team, seed=2).messages["status"]
    assert list(a) == list(b) and list(a) != list(c)


def test_receiver_limited_to_8_hz_drops_the_excess_of_a_20_hz_stream(team_from_yaml):
    run = ht.simulate(beacon(team_from_yaml, period=0.05, limits="{data: 8}", duration=10.0))
    sends = len(run.transitions.where(agent="beacon", cause="after"))
    m = run.messages.filter(run.messages["reason"] != "run ended")
    kept = m.where(status="delivered")["t_recv"]
    dropped = m.where(reason="rate limit")
    assert len(kept) + len(dropped) == len(m) == sends - len(run.messages.where(reason="run ended"))
    assert np.all(np.diff(kept) >= 1 / 8 - 1e-9)
    # each drop arrived while the receiver was still busy with the last accepted message
    for t in dropped["t_recv"]:
        before = kept[kept <= t]
        assert before.size and t - before[-1] < 1 / 8
    # arrivals every 0.05 s and a receiver busy for 1/8 s: it accepts every third one
    assert abs(len(kept) - len(m) / 3) <= 1 and len(kept) / 10.0 <= 8
    assert np.all(dropped["status"] == "lost")
    heard = run.transitions.where(agent="listener", cause="message:ping")
    assert len(heard) == len(kept)


def test_messages_in_flight_at_the_end_are_recorded(team_from_yaml):
    run = ht.simulate(beacon(team_from_yaml, period=0.5, duration=1.05))
    last = list(run.messages)[-1]
    assert (last.status, last.reason) == ("lost", "run ended") and last.t_send == 1.0


def test_ensemble_over_loss_rates_equals_single_runs(team_from_yaml):
    team = beacon(team_from_yaml, loss=0.0, duration=3.0)
    rates = np.linspace(0.0, 0.5, 6)
    ens = ht.simulate(team, n=6, seed=4, overrides={"p": rates})
    for i, p in enumerate(rates):
        one = ht.simulate(team, seed=4, overrides={"p": p})
        mine = ens.instance(i)
        assert list(mine.messages["status"]) == list(one.messages["status"])
        np.testing.assert_array_equal(mine.messages["t_recv"], one.messages["t_recv"])
        assert list(mine.transitions["t"]) == list(one.transitions["t"])
    lost = [np.mean(ens.instance(i).messages["reason"] == "loss") for i in range(6)]
    assert lost[0] == 0 and lost[-1] > 0.3


def test_network_errors_are_located(team_from_yaml):
    bad = HANDSHAKE.format(d=0.03, loss=0.0, priority=2).replace(
        "network: {latency: d, loss: p_loss}",
        "network: {latency: dd, loss: p_loss, links: {'leader->folower': {loss: 0.5}}}",
    )
    with pytest.raises(InputErrors) as err:
        team_from_yaml(bad)
    text = str(err.value)
    assert "network.latency: unknown name 'dd'; did you mean 'd'?" in text
    assert "unknown agent 'folower' in link; did you mean 'follower'?" in text


def test_reply_needs_a_triggering_message(team_from_yaml):
    bad = HANDSHAKE.format(d=0.03, loss=0.0, priority=2).replace(
        "{send: request, to: leader,", "{send: request, to: sender,"
    )
    with pytest.raises(InputErrors, match="'to: sender' replies to the sender"):
        team_from_yaml(bad)


PING = """
team: ping
messages:
  ping: {ack: {timeout: 0.1, retries: 2}}
network:
  latency: 0.02
  links:
    a -> b: {latency: 0.02, loss: {loss}}
agents:
  a:
    plant: {kind: flow, state: {x: 0}}
    initial: Send
    modes:
      Send: {transitions: [{to: Wait, after: 1.0, do: [{send: ping, to: b}]}]}
      Wait: {transitions: [{to: Failed, on: ping_undeliverable}]}
      Failed: {final: true}
  b:
    plant: {kind: flow, state: {x: 0}}
    initial: Listen
    modes:
      Listen: {transitions: [{to: Heard, on: ping}]}
      Heard: {final: true}
simulation: {duration: 2.0}
"""


def test_a_team_declares_its_own_acknowledged_message(team_from_yaml):
    """A team's own ``messages:`` work like a protocol's: a dead link gives up after the
    first send and 2 resends, each waited for 0.1 s (1.0 + 3 * 0.1); a live one is heard
    once, and acknowledged."""
    run = ht.simulate(team_from_yaml(PING.replace("{loss}", "1.0")))
    tr = run.transitions.where(agent="a")
    (failed,) = [t for t, g in zip(tr["t"], tr["target"], strict=True) if g == "Failed"]
    assert failed == pytest.approx(1.3)
    m = run.messages
    pings = np.asarray(m["type"]) == "ping"
    np.testing.assert_allclose(np.asarray(m["t_send"])[pings], [1.0, 1.1, 1.2])
    run = ht.simulate(team_from_yaml(PING.replace("{loss}", "0.0")))
    tr = run.transitions.where(agent="b")
    assert [(t, g) for t, g in zip(tr["t"], tr["target"], strict=True)][-1] == (
        pytest.approx(1.02),
        "Heard",
    )
    assert sorted(run.messages["type"].tolist()) == ["ack", "ping"]


# ------------------------------------------------------------ network settings as overrides
def _messages_equal(a, b) -> bool:
    return list(a.messages["status"]) == list(b.messages["status"]) and np.array_equal(
        a.messages["t_recv"], b.messages["t_recv"], equal_nan=True
    )


def test_network_settings_are_override_keys(team_from_yaml, tmp_path):
    """``network.jitter`` replaces the file's number per instance: a run with it set to 0
    is the run of the same file saying ``jitter: 0``, and the other instance of the
    ensemble is the file's own run."""
    text = BEACON.format(period=0.05, jitter=0, loss=0, limits="{}", duration=2.0).replace(
        "loss: p", "loss: 0.2"
    )
    jittery = team_from_yaml(text.replace("jitter: j", "jitter: 0.05"), "jittery.yaml")
    calm = team_from_yaml(text.replace("jitter: j", "jitter: 0"), "calm.yaml")
    own, still = ht.simulate(jittery, seed=3), ht.simulate(calm, seed=3)
    assert not _messages_equal(own, still)  # the jitter matters in this team
    assert _messages_equal(ht.simulate(jittery, seed=3, overrides={"network.jitter": 0}), still)
    both = ht.simulate(jittery, n=2, seed=3, overrides={"network.jitter": [0.0, 0.05]})
    assert _messages_equal(both.instance(0), still) and _messages_equal(both.instance(1), own)
    sure = ht.simulate(jittery, seed=3, overrides={"network.loss": 0}).messages
    assert set(sure["reason"]) <= {"", "run ended"} and "loss" in set(own.messages["reason"])
    # the command line sets them with --set
    from hybridteam.cli import main

    out = tmp_path / "out"
    assert (
        main(
            [
                "run",
                str(tmp_path / "jittery.yaml"),
                "-o",
                str(out),
                "--seed",
                "3",
                "--quiet",
                "--no-views",
                "--set",
                "network.jitter=0",
            ]
        )
        == 0
    )
    assert _messages_equal(ht.Run.load(out / "trace.json"), still)


def test_a_declared_links_settings_are_override_keys(team_from_yaml):
    """A link the team declares: ``network.links.beacon->listener.latency`` (no jitter:
    every copy takes exactly that long); a link it does not declare is no key."""
    text = BEACON.format(period=0.25, jitter=0, loss=0, limits="{}", duration=2.0).replace(
        "  rate_limits:", '  links: {"beacon -> listener": {latency: 0.3}}\n  rate_limits:'
    )
    team = team_from_yaml(text)
    m = ht.simulate(team, overrides={"network.links.beacon->listener.latency": 0.2}).messages.where(
        status="delivered"
    )
    assert len(m) == 7 and np.allclose(m["t_recv"] - m["t_send"], 0.2, rtol=0, atol=1e-12)
    with pytest.raises(
        ValueError,
        match=r"override 'network.links.listener->beacon.latency' "
        r"names no network setting; did you mean "
        r"'network.links.beacon->listener.latency'\?",
    ):
        ht.simulate(team, overrides={"network.links.listener->beacon.latency": 0.2})


@pytest.mark.parametrize(
    ("key", "value", "words"),
    [
        (
            "network.jiter",
            0.0,
            "override 'network.jiter' names no network setting; did you mean 'network.jitter'?",
        ),
        (
            "network.loss",
            1.5,
            "override 'network.loss' is 1.5 in instance 0; it must be a number in [0, 1]",
        ),
        (
            "network.latency",
            -0.1,
            "override 'network.latency' is -0.1 in instance 0; it must be a number >= 0",
        ),
        ("jitter", 0.0, "override 'jitter' names no parameter; did you mean 'network.jitter'?"),
    ],
)
def test_bad_network_overrides_say_why(team_from_yaml, key, value, words):
    team = beacon(team_from_yaml, duration=0.1)
    with pytest.raises(ValueError) as err:
        ht.simulate(team, overrides={key: value})
    assert str(err.value) == words
