"""Role assignment over the lossy network: handover timing, acks, deadlock, streams."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import hybridteam as ht
from hybridteam.cli import main
from hybridteam.dynamics.plants import make_plant
from hybridteam.laws import _dead_reckon

LEADING = ("Transport.Lead", "Transport.Offering")

TEAM = """
team: roles
parameters: {{d: {d}, jitter: {jitter}, p_loss: {loss}, state_rate: {rate},
             ack_timeout: {ack}}}
network:
  latency: d
  jitter: jitter
  loss: p_loss
  links:
    r1 -> operator: {{latency: d}}
    r2 -> operator: {{latency: d}}
    r3 -> operator: {{latency: d}}
    operator -> r1: {{latency: d}}
    operator -> r2: {{latency: d}}
    operator -> r3: {{latency: d}}
{extra_network}
agents:
  r1:
    plant: {{kind: unicycle, state: {{x: 2.0, y: 0.0, theta: 0.0}}}}
    parameters: {{priority: 0}}
    modes:
      Transport:
        protocol: role_assignment
        initial: Lead
        roles:
          lead: {{inputs: {{v: 0.3, omega: 0}}, period: 0.05}}
          follow: {{law: {{use: formation.follow, period: 0.05, with: {{ahead: 1.0}}}}}}
  r2:
    plant: {{kind: unicycle, state: {{x: 1.0, y: 0.0, theta: 0.0}}}}
    parameters: {{priority: 1}}
    variables: {{leader: id_r1}}
    modes:
      Transport:
        protocol: role_assignment
        roles:
          lead: {{inputs: {{v: 0.3, omega: 0}}, period: 0.05}}
          follow: {{law: {{use: formation.follow, period: 0.05, with: {{ahead: -1.0}}}}}}
  r3:
    plant: {{kind: unicycle, state: {{x: 0.0, y: 0.0, theta: 0.0}}}}
    parameters: {{priority: 2}}
    variables: {{leader: {r3_leader}}}
    modes:
      Transport:
        protocol: role_assignment
        roles:
          lead: {{inputs: {{v: 0.3, omega: 0}}, period: 0.05}}
          follow: {{law: {{use: formation.follow, period: 0.05, with: {{ahead: -1.0}}}}}}
  operator:
    operator: role_assignment
scenario:
{scenario}
simulation: {{duration: {duration}, sample_period: 0.05}}
"""


def team(
    make,
    *,
    d=0.03,
    jitter=0.0,
    loss=0.0,
    rate=20,
    scenario=(),
    duration=6.0,
    extra_network="",
    r3_leader="id_r2",
):
    lines = "\n".join(f"  - {{at: {t}, agent: {a}, raise: {e}}}" for t, a, e in scenario)
    return make(
        TEAM.format(
            d=d,
            jitter=jitter,
            loss=loss,
            rate=rate,
            duration=duration,
            ack=ack_timeout(d, jitter),
            scenario=lines or "  []",
            extra_network=extra_network,
            r3_leader=r3_leader,
        )
    )


def ack_timeout(d, jitter):
    """Longer than a round trip, as the protocol's documentation asks."""
    return max(0.1, 2 * (d + jitter) + 0.02)


def moves(run, agent):
    tr = run.transitions.where(agent=agent)
    return [
        (float(t), s, g, c)
        for t, s, g, c in zip(tr["t"], tr["source"], tr["target"], tr["cause"], strict=True)
        if s
    ]


# ---------------------------------------------------------------------------- handover
@pytest.mark.parametrize("d", [0.0, 0.03, 0.25])
def test_requested_handover_takes_one_latency_per_leg(team_from_yaml, d):
    """Fig. 10: request at t_a, grant sent at t_b = t_a + d, leadership at t_c = t_b + d."""
    run = ht.simulate(
        team(team_from_yaml, d=d, scenario=[(1.0, "r2", "want_lead")], r3_leader="id_r1")
    )
    assert run.outcome == "ok", run.message
    ((t_a, *_),) = [m for m in moves(run, "r2") if m[2] == "Transport.Requesting"]
    ((t_b, *_),) = [m for m in moves(run, "r1") if m[1] == "Transport.Lead"]
    ((t_c, *_),) = [m for m in moves(run, "r2") if m[2] == "Transport.Lead"]
    assert t_a == 1.0
    assert t_b - t_a == pytest.approx(d, abs=1e-12)
    assert t_c - t_b == pytest.approx(d, abs=1e-12)
    # the third robot followed r1 and re-attaches to the new leader when it is announced
    leader_of_r3 = [m for m in moves(run, "r3")]
    assert leader_of_r3 == [
        (pytest.approx(t_c + d), "Transport.Follow", "Transport.Follow", "message:announce")
    ]


def test_denial_within_min_hold_keeps_the_leader_leading(team_from_yaml):
    """Anti-chattering: r1 asks back 0.5 s after handing over (min_hold 1 s) and is denied;
    the new leader's Lead interval is not interrupted (an internal transition); asked again
    after min_hold, it grants."""
    run = ht.simulate(
        team(
            team_from_yaml,
            scenario=[
                (1.0, "r2", "want_lead"),
                (1.56, "r1", "want_lead"),
                (2.5, "r1", "want_lead"),
            ],
        )
    )
    r2 = moves(run, "r2")
    assert [m[1:] for m in r2] == [
        ("Transport.Follow", "Transport.Requesting", "event:want_lead"),
        ("Transport.Requesting", "Transport.Lead", "message:grant"),
        ("Transport.Lead", "Transport.Lead", "message:request"),  # the denial, internal
        ("Transport.Lead", "Transport.Follow", "message:request"),
    ]
    assert r2[2][0] == pytest.approx(1.59) and r2[3][0] == pytest.approx(2.53)
    leads = run.intervals.where(agent="r2", mode="Transport.Lead")
    assert list(zip(leads["start"], leads["end"], strict=True)) == [
        (pytest.approx(1.06), pytest.approx(2.53))
    ]
    assert [m[2] for m in moves(run, "r1")] == [
        "Transport.Follow",
        "Transport.Requesting",
        "Transport.Follow",
        "Transport.Requesting",
        "Transport.Lead",
    ]


def test_simultaneous_requests_are_ordered_by_priority(team_from_yaml):
    """r2 (priority 1) and r3 (priority 2), both following r1, ask at the same instant:
    r3's request is handled first and granted; r2's is denied by r1, a follower by then.
    Swapping the priorities swaps the outcome (so the order is not the agents' order)."""
    for prio3, winner, loser in ((2, "r3", "r2"), (0, "r2", "r3")):
        model = team(
            team_from_yaml,
            scenario=[(1.0, "r2", "want_lead"), (1.0, "r3", "want_lead")],
            r3_leader="id_r1",
        )
        run = ht.simulate(model, overrides={"r3.priority": prio3})
        assert [m[2] for m in moves(run, winner)][:2] == ["Transport.Requesting", "Transport.Lead"]
        assert [m[2] for m in moves(run, loser)][:2] == ["Transport.Requesting", "Transport.Follow"]
        ((t_b, *_),) = [m for m in moves(run, "r1") if m[1] == "Transport.Lead"]
        assert t_b == pytest.approx(1.03)


def test_resignation_to_everyone_goes_to_the_first_acceptor(team_from_yaml):
    run = ht.simulate(
        team(
            team_from_yaml,
            d=0.03,
            scenario=[(1.0, "r1", "resign")],
            extra_network="    r1 -> r3: {latency: 0.05}\n    r3 -> r1: {latency: 0.05}",
        )
    )
    assert [m[2:] for m in moves(run, "r1")] == [
        ("Transport.Offering", "event:resign"),
        ("Transport.Follow", "message:accept"),
        ("Transport.Follow", "message:accept"),
    ]  # the late acceptor is rejected (internal)
    assert [m[2] for m in moves(run, "r2")][:2] == ["Transport.Accepting", "Transport.Lead"]
    # r3 heard the offer later, accepted later, and was rejected
    assert [m[2] for m in moves(run, "r3")][:2] == ["Transport.Accepting", "Transport.Follow"]
    t_c = moves(run, "r2")[1][0]
    assert t_c == pytest.approx(1.0 + 3 * 0.03)  # offer, accept, confirm


PLAN = """
team: plan
parameters: {d: 0.03}
network: {latency: d}
agents:
  r1:
    plant: {kind: unicycle, state: {x: 1.0, y: 0.0, theta: 0.0}}
    variables: {successor: id_r2}
    modes:
      Transport:
        protocol: role_assignment
        initial: Lead
        roles:
          lead:
            initial: Go
            modes:
              Go:
                inputs: {v: 0.3, omega: 0}
                transitions: [{to: Slow, after: 1.0}]
              Slow:
                initial: Creep
                modes:
                  Start: {inputs: {v: 0.2, omega: 0}}
                  Creep:
                    inputs: {v: 0.1, omega: 0}
                    transitions: [{to: Start, after: 0.5}]
          follow: {inputs: {v: 0, omega: 0}}
  r2:
    plant: {kind: unicycle, state: {x: 0.0, y: 0.0, theta: 0.0}}
    variables: {leader: id_r1}
    modes:
      Transport:
        protocol: role_assignment
        roles:
          lead: {inputs: {v: 0.3, omega: 0}}
          follow: {inputs: {v: 0, omega: 0}}
scenario: [{at: 2.0, agent: r1, raise: resign}]
simulation: {duration: 3.0, sample_period: 0.01}
"""


def test_a_resigning_leader_keeps_doing_what_its_plan_was_doing(team_from_yaml):
    """Lead -> Offering switches protocol state, not role: the plan goes on where it was
    (Slow.Creep at 0.1 m/s, then Start at 0.2 m/s when its 0.5 s are up), it does not
    restart (Go, 0.3 m/s) and its delay does not start again."""
    text = PLAN.replace("d: 0.03", "d: 0.2").replace("at: 2.0", "at: 1.2")
    run = ht.simulate(team_from_yaml(text))
    assert run.outcome == "ok", run.message
    iv = run.intervals.where(agent="r1")
    spans = {
        m: (s, e)
        for m, s, e in zip(iv["mode"], iv["start"], iv["end"], strict=True)
        if m.startswith("Transport.Offering")
    }
    # offered at 1.2; offer and accept take a latency each, then r1 follows; Creep was
    # entered at 1.0 and ends at 1.5, inside the offer
    assert spans == {
        "Transport.Offering": pytest.approx((1.2, 1.6)),
        "Transport.Offering.Slow": pytest.approx((1.2, 1.6)),
        "Transport.Offering.Slow.Creep": pytest.approx((1.2, 1.5)),
        "Transport.Offering.Slow.Start": pytest.approx((1.5, 1.6)),
    }
    t, px = run.sample_times, run.samples["r1"][:, 0, 0]  # (time, instance, state)
    for lo, hi, v in [(1.2, 1.5, 0.1), (1.5, 1.6, 0.2)]:
        inside = (t >= lo - 1e-9) & (t <= hi + 1e-9)
        assert np.diff(px[inside]) / np.diff(t[inside]) == pytest.approx(v)


# ---------------------------------------------------------------------------- deadlock
def test_dead_link_is_a_deadlock_and_the_operator_takes_command(team_from_yaml):
    run = ht.simulate(
        team(
            team_from_yaml,
            scenario=[(1.0, "r2", "want_lead")],
            extra_network="    r1 -> r2: {loss: 1.0}\n    r2 -> r1: {loss: 1.0}",
        )
    )
    r2 = moves(run, "r2")
    assert [m[2] for m in r2][:2] == ["Transport.Requesting", "Transport.Operated"]
    detected = r2[1][0]
    # the request is undeliverable after 1 + 3 retries of 0.1 s, before the 1 s answer timeout
    assert detected == pytest.approx(1.0 + 4 * 0.1)
    assert r2[1][3] == "event:request_undeliverable"
    op = moves(run, "operator")
    assert op[0][2] == "Command" and op[0][0] == pytest.approx(detected + 0.03)
    # the operator halts everyone; r1 stops leading
    assert [m[2] for m in moves(run, "r1")] == ["Transport.Operated"]


# ---------------------------------------------------------------------------- properties
def command_gaps(run, t_end):
    """Intervals with no robot leading and the operator not in command."""
    holders = run.intervals.filter(np.isin(run.intervals["mode"], (*LEADING, "Command")))
    spans = sorted(zip(holders["start"].tolist(), holders["end"].tolist(), strict=True))
    gaps, covered = [], 0.0
    for s, e in spans:
        if s > covered + 1e-12:
            gaps.append((covered, s))
        covered = max(covered, e)
    if covered < t_end - 1e-12:
        gaps.append((covered, t_end))
    return gaps


def overlap_of_leaders(run):
    iv = run.intervals.filter(np.isin(run.intervals["mode"], LEADING))
    total = 0.0
    for a in set(iv["agent"]):
        for b in set(iv["agent"]):
            if a >= b:
                continue
            for s1, e1 in zip(*(iv.where(agent=a)[k] for k in ("start", "end")), strict=True):
                for s2, e2 in zip(*(iv.where(agent=b)[k] for k in ("start", "end")), strict=True):
                    total += max(0.0, min(e1, e2) - max(s1, s2))
    return total


@settings(
    max_examples=30,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)
@given(
    seed=st.integers(0, 10_000),
    loss=st.floats(0.0, 0.5),
    d=st.floats(0.0, 0.25),
    jitter=st.floats(0.0, 0.05),
    events=st.lists(
        st.tuples(
            st.floats(0.2, 4.0),
            st.sampled_from(["r1", "r2", "r3"]),
            st.sampled_from(["want_lead", "resign"]),
        ),
        max_size=4,
    ),
)
def test_role_assignment_properties(team_from_yaml, seed, loss, d, jitter, events):
    events = sorted((round(t, 3), a, e) for t, a, e in events)
    run = ht.simulate(
        team(team_from_yaml, d=d, jitter=jitter, loss=loss, rate=5, scenario=events, duration=6.0),
        seed=seed,
    )
    assert run.outcome == "ok", run.message
    # never two robots leading at once (the old leader steps down before the new one leads)
    assert overlap_of_leaders(run) == 0.0
    # someone holds command except inside a handover window, which is bounded: it opens
    # when the old leader steps down and closes when the new leader gets the grant or, at
    # the latest, when the operator gets the takeover after a timeout
    bound = max(1.0, 4 * ack_timeout(d, jitter)) + 2 * (d + jitter) + 1e-9
    for start, end in command_gaps(run, 6.0):
        assert end - start <= bound, (start, end)
    # every handover completes or ends in a detected deadlock: no robot stays in
    # Requesting, Offering or Accepting longer than the answer timeout
    waiting = run.intervals.filter(
        np.isin(
            run.intervals["mode"],
            ["Transport.Requesting", "Transport.Offering", "Transport.Accepting"],
        )
    )
    assert np.all(waiting["end"] - waiting["start"] <= 1.0 + 1e-9)
    # no control message acted on twice: one dispatched copy per (sender, id, receiver)
    m = run.messages
    acted = m.filter(
        (m["msg_id"] >= 0) & (m["status"] == "delivered") & (m["reason"] != "duplicate")
    )
    keys = list(zip(acted["sender"], acted["receiver"], acted["msg_id"], strict=True))
    assert len(keys) == len(set(keys))
    # and every grant-triggered move matches one distinct delivered grant
    grants = run.transitions.filter(run.transitions["cause"] == "message:grant")
    delivered = acted.filter(acted["type"] == "grant")
    assert len(grants) <= len(delivered)


def test_lossy_runs_exercise_retransmission_and_duplicates(team_from_yaml):
    """The property test's machinery is not idle: at 40 % loss, copies are resent and
    duplicates (a resend after a lost ack) are withheld."""
    reasons = []
    for seed in range(6):
        run = ht.simulate(
            team(
                team_from_yaml,
                loss=0.4,
                rate=5,
                scenario=[(1.0, "r2", "want_lead"), (3.0, "r1", "want_lead")],
            ),
            seed=seed,
        )
        reasons += run.messages["reason"].tolist()
    assert "retransmission" in reasons and "duplicate" in reasons


# ---------------------------------------------------------------------------- streams
def test_eight_hz_receiver_drops_excess_and_still_tracks(team_from_yaml):
    run = ht.simulate(
        team(team_from_yaml, duration=8.0, extra_network="  rate_limits: {r2: {data: 8}}")
    )
    m = run.messages.where(receiver="r2", type="state", sender="r1")
    dropped = m.filter(m["reason"] == "rate limit")
    kept = m.filter(m["status"] == "delivered")
    assert len(dropped) > 0 and len(kept) > 0
    assert len(kept) / (len(kept) + len(dropped)) == pytest.approx(1 / 3, abs=0.02)
    # r2 keeps its place one metre behind r1 (it starts exactly there)
    x1 = run.samples["r1"][:, 0, :2]
    x2 = run.samples["r2"][:, 0, :2]
    gap = np.hypot(*(x1 - x2).T)
    assert np.nanmax(np.abs(gap - 1.0)) < 0.02


def test_dead_reckoning_is_the_unicycle_arc():
    rng = np.random.default_rng(1)
    x0 = rng.normal(size=(50, 3))
    u = rng.normal(size=(50, 2))
    age = rng.uniform(0, 0.5, 50)
    exact = make_plant("unicycle").propagate(x0, u, age)
    est = _dead_reckon(
        {"x": x0[:, 0], "y": x0[:, 1], "theta": x0[:, 2], "v": u[:, 0], "omega": u[:, 1]}, age
    )
    assert np.allclose(np.stack([est["x"], est["y"], est["theta"]], 1), exact, atol=1e-12)


# ---------------------------------------------------------------------------- ensembles
def test_ensemble_over_loss_rates_equals_single_runs(team_from_yaml):
    losses = [0.0, 0.1, 0.2, 0.3, 0.4, 0.5]
    model = team(
        team_from_yaml, rate=5, scenario=[(1.0, "r2", "want_lead"), (2.5, "r3", "want_lead")]
    )
    ens = ht.simulate(model, n=6, overrides={"p_loss": losses}, seed=3)
    for i, p in enumerate(losses):
        one = ht.simulate(model, overrides={"p_loss": p}, seed=3)
        a, b = ens.instance(i), one
        assert a.outcome == b.outcome
        for table in ("transitions", "messages"):
            ta, tb = getattr(a, table), getattr(b, table)
            assert len(ta) == len(tb)
            for col in ta.names:
                if col != "instance":
                    assert ta[col].tolist() == tb[col].tolist() or np.array_equal(
                        ta[col], tb[col], equal_nan=True
                    ), (table, col)
        assert np.array_equal(a.samples["r2"], b.samples["r2"], equal_nan=True)


# ---------------------------------------------------------------------------- bad input
def test_unknown_protocol_is_located_with_a_suggestion(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    text = TEAM.format(
        d=0.03,
        jitter=0,
        loss=0,
        rate=20,
        duration=1,
        scenario="  []",
        extra_network="",
        r3_leader="id_r2",
        ack=0.1,
    )
    bad.write_text(
        text.replace(
            "protocol: role_assignment\n        initial: Lead",
            "protocol: role_asignment\n        initial: Lead",
        )
    )
    assert main(["validate", str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert "unknown protocol 'role_asignment'" in err and "did you mean 'role_assignment'" in err
    line = TEAM.splitlines().index("        protocol: role_assignment") + 1
    assert err.startswith(f"{bad}:{line}:")


FOLLOW = "          follow: {law: {use: formation.follow, period: 0.05, with: {ahead: 1.0}}}"
LEAD = "          lead: {inputs: {v: speed, omega: 0}, period: 0.05}"


@pytest.mark.parametrize(
    "line, wrong, where, message",
    [
        (
            FOLLOW,
            "with: {ahead: 1.0}}}",
            "with: {ahead: 1.0, gain: 2}}}",
            "follow.law.with.gain: law 'formation.follow' has no parameter 'gain'",
        ),
        (
            FOLLOW,
            "use: formation.follow, period: 0.05, with: {ahead: 1.0}",
            "use: transport.follow_holonomic, period: 0.05, with: {D: 1.0}",
            (
                "follow.law.use: law 'transport.follow_holonomic' drives holonomic plants, "
                "not unicycle"
            ),
        ),
        (
            LEAD,
            "omega: 0}",
            "omga: 0}",
            "lead.inputs.omga: a unicycle plant has no input 'omga'; did you mean 'omega'?",
        ),
    ],
)
def test_an_error_in_a_role_body_is_reported_once(tmp_path, capsys, line, wrong, where, message):
    """Follow, Requesting and a third state all play ``follow`` (Lead and Offering play
    ``lead``): the body is one place in the team file, compiled once per state, and its
    mistake is one error, located in the body, not at the protocol's states."""
    from tests.conftest import EXAMPLES

    text = (EXAMPLES / "protocols" / "handover.yaml").read_text()
    assert text.count(line) == 1 and wrong in line
    bad = tmp_path / "bad.yaml"
    bad.write_text(text.replace(line, line.replace(wrong, where)))
    assert main(["validate", str(bad)]) == 2
    err = capsys.readouterr().err.splitlines()
    row = text.splitlines().index(line) + 1
    assert len(err) == 1, err
    assert err[0].startswith(f"{bad}:{row}:")
    assert err[0].endswith(f"agents.xr4000.modes.Transport.roles.{message}")


def test_handover_example_runs_and_writes_its_views(tmp_path):
    from tests.conftest import EXAMPLES

    out = tmp_path / "out"
    assert (
        main(["run", str(EXAMPLES / "protocols" / "handover.yaml"), "-o", str(out), "--quiet"]) == 0
    )
    assert (out / "timeline.svg").exists() and (out / "sequence.mmd").exists()
    seq = (out / "sequence.mmd").read_text()
    assert "request @ 3.000 s" in seq and "grant @ 3.030 s" in seq
