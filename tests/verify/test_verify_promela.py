"""SPIN as an independent second explorer (``--spin-rules``): the team's rules, not our
explored graph, go to Promela; SPIN explores them and the two explorations must reach the
same projected mode configurations, the same dead ends and the same deadlock verdict.
The comparisons skip where SPIN or a C compiler is missing; refusals and the missing-tool
message are tested everywhere."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from hybridteam import load
from hybridteam.cli import main
from hybridteam.verify import Options, promela, spin, verify
from tests.verify.test_verify import (
    FAR,
    GO,
    GRANT,
    NO_OPERATOR,
    PROTOCOL,
    REQUEST,
    ROOT,
    docking,
    mutate,
    roles_team,
)
from tests.verify.test_verify_bounds import BOUNDED

needs_spin = pytest.mark.skipif(
    spin.missing() is not None, reason=f"SPIN cannot run here: {spin.missing()}"
)

# Two agents (their plants stand still): plain messages with a field that carries a discrete value,
# a reply to the sender, a hierarchical mode (entered at its initial child, left as a
# whole by an after: timeout), a guard over a variable and a message field, a guard that
# reads time (free: both ways) pre-empting a later transition on the same message, and a
# scenario event.
PINGPONG = """team: pingpong
agents:
  a:
    plant: {kind: unicycle, state: {x: 0, y: 0, theta: 0}}
    variables: {n: 0}
    initial: Idle
    modes:
      Idle:
        transitions:
          - {to: Busy, on: start, do: [{send: ping, to: b, fields: {k: n}}]}
      Busy:
        initial: Wait
        transitions:
          - {to: Idle, after: 1.0}
        modes:
          Wait:
            transitions:
              - {to: Got, on: pong, guard: msg_k == n, do: [n = n + 1]}
          Got: {}
  b:
    plant: {kind: unicycle, state: {x: 1, y: 0, theta: 0}}
    variables: {last: -1}
    initial: Ready
    modes:
      Ready:
        transitions:
          - {to: Late, on: ping, guard: t > 5}
          - to: Answered
            on: ping
            do: [last = msg_k, {send: pong, to: sender, fields: {k: msg_k}}]
      Answered:
        transitions:
          - {to: Ready, on: ping, guard: last == msg_k}
      Late:
        final: true
scenario:
  - {at: 1.0, agent: a, raise: start}
simulation: {duration: 10}
"""


def team(tmp_path, text: str, name: str):
    path = tmp_path / f"{name}.yaml"
    path.write_text(text)
    return load(path)


def compared(tmp_path, text: str, opts: Options, drop=None) -> promela.Comparison:
    report = verify(team(tmp_path, text, "team"), opts, replay=False)
    return promela.compare(report, opts, tmp_path / "spin-rules", drop=drop)


@needs_spin
def test_the_go_model_agrees_with_the_configurations_by_hand(tmp_path):
    """GO with one loss: the leader goes Wait -> Drive (sending go) -> Done; the follower
    leaves Wait only when go arrives, so it never drives while the leader waits. Bits per
    agent: root, Wait, Drive, Done."""
    c = compared(tmp_path, GO, Options(losses=1))
    by_hand = {"1100|1100", "1010|1100", "1001|1100", "1010|1010", "1001|1010"}
    assert c.ours.configurations == by_hand
    assert c.spin.configurations == by_hand
    # dead ends: the leader done, the follower driving, or waiting for the lost go
    assert c.spin.dead_ends == c.ours.dead_ends == {"1001|1010", "1001|1100"}
    assert c.spin.deadlock is False and c.ours.deadlock is False  # the lost go
    assert c.differences() == []


@needs_spin
def test_the_go_model_without_losses_has_no_deadlock_in_either(tmp_path):
    c = compared(tmp_path, GO, Options(losses=0))
    assert (
        c.ours.configurations
        == c.spin.configurations
        == {"1100|1100", "1010|1100", "1001|1100", "1010|1010", "1001|1010"}
    )
    assert c.spin.deadlock is True and c.ours.deadlock is True
    assert c.spin.dead_ends == c.ours.dead_ends == {"1001|1010"}


# by hand (bits: a's root, Idle, Busy, Busy.Wait, Busy.Got | b's root, Ready, Answered,
# Late): start sends ping (a in Busy.Wait); b takes it late (Late) or answers (Answered);
# a's pong arrives in Wait (Got), or its timeout takes it back to Idle at any moment
PINGPONG_BY_HAND = {
    "11000|1100",
    "10110|1100",
    "10110|1001",
    "10110|1010",
    "11000|1001",
    "11000|1010",
    "10101|1010",
}
# a duplicated ping reaches b in Answered with the same k: b is Ready again, a in Got
DUPLICATED = {"10101|1100"}


@needs_spin
@pytest.mark.parametrize("losses,duplicates", [(0, 0), (1, 0), (0, 1), (1, 1)])
def test_pingpong_agrees_with_losses_and_duplicates(tmp_path, losses, duplicates):
    c = compared(tmp_path, PINGPONG, Options(losses=losses, duplicates=duplicates))
    by_hand = PINGPONG_BY_HAND | (DUPLICATED if duplicates else set())
    assert c.ours.configurations == c.spin.configurations == by_hand
    assert c.differences() == []
    # b answered and waits for a ping that never comes: a deadlock in both
    assert c.spin.deadlock is c.ours.deadlock is False


# a timeout in place that sets a flag: after the first expiry it changes nothing (our
# explorer keeps no self-loop, so that state is a dead end; SPIN must find it too)
ONCE = BOUNDED.replace("guard: n < 5, do: [n = n + 1]", "do: [n = 1]")


@needs_spin
@pytest.mark.parametrize("text", [BOUNDED, ONCE], ids=["bounded", "once"])
def test_timeouts_in_place_agree_on_the_dead_end(tmp_path, text):
    c = compared(tmp_path, text, Options(losses=0))
    assert c.ours.configurations == c.spin.configurations == {"11"}  # root and A
    assert c.ours.dead_ends == c.spin.dead_ends == {"11"}  # n = 5, or n = 1
    assert c.ours.deadlock is c.spin.deadlock is True  # a timeout is no message awaited


PARALLEL = """team: par
agents:
  s:
    plant: {kind: unicycle, state: {x: 0, y: 0, theta: 0}}
    initial: Wait
    modes:
      Wait:
        transitions:
          - {to: Sent, after: 1.0, do: [{send: go, to: r}]}
      Sent: {}
  r:
    plant: {kind: unicycle, state: {x: 1, y: 0, theta: 0}}
    initial: Both
    modes:
      Both:
        parallel: true
        modes:
          Left:
            initial: L0
            modes:
              L0:
                transitions: [{to: L1, on: go}]
              L1: {}
          Right:
            initial: R0
            modes:
              R0:
                transitions: [{to: R1, on: go}]
              R1: {}
simulation: {duration: 5}
"""


@needs_spin
def test_one_message_steps_both_regions_of_a_parallel_mode(tmp_path):
    """go wakes a transition in each region of r's parallel mode; both fire (no conflict).
    By hand (s: root, Wait, Sent | r: root, Both, Left, L0, L1, Right, R0, R1): waiting
    with L0 and R0; sent with go in flight (or lost); arrived: L1 and R1 together."""
    c = compared(tmp_path, PARALLEL, Options(losses=1, duplicates=1))
    assert (
        c.ours.configurations
        == c.spin.configurations
        == {"110|11110110", "101|11110110", "101|11101101"}
    )
    assert c.differences() == []


def acked_go(retries: int) -> str:
    return GO.replace(
        "agents:\n", f"messages:\n  go: {{ack: {{timeout: 0.1, retries: {retries}}}}}\nagents:\n", 1
    )


@needs_spin
@pytest.mark.parametrize(
    "retries,losses,deadlock",
    [
        (0, 1, False),  # the one copy lost: go_undeliverable, the follower waits for ever
        (1, 1, True),  # a lost go, or a lost ack (the copy resent is filtered), is resent
        (1, 2, False),  # both copies lost
    ],
)
def test_the_acknowledged_layer_agrees(tmp_path, retries, losses, deadlock):
    """The acknowledged go: resends, duplicate filter, acks lost too, undeliverable. The
    configurations are GO's five (the follower drives once a copy arrives); the lost go's
    dead end (leader Done, follower Wait) is there exactly when every copy may be lost."""
    c = compared(tmp_path, acked_go(retries), Options(losses=losses, duplicates=1))
    assert (
        c.ours.configurations
        == c.spin.configurations
        == {"1100|1100", "1010|1100", "1001|1100", "1010|1010", "1001|1010"}
    )
    assert c.ours.deadlock is c.spin.deadlock is deadlock
    assert (
        c.spin.dead_ends
        == c.ours.dead_ends
        == ({"1001|1010"} if deadlock else {"1001|1010", "1001|1100"})
    )
    assert c.differences() == []


@needs_spin
@pytest.mark.slow
def test_the_role_protocol_with_a_loss_agrees(tmp_path):
    """As above with one loss (SPIN's unreduced search met 5.7 million states before the
    canonical form and the invisible-copy rule; now about as many as ours, 858)."""
    opts = Options(losses=1)
    report = verify(roles_team(tmp_path, "b", without_c=True), opts, replay=False)
    c = promela.compare(report, opts, tmp_path / "spin-rules")
    assert c.differences() == []


EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "automata"


@needs_spin
@pytest.mark.parametrize(
    "name", ["relay", "thermostat", "thermostat_chatter", "unicycle_square", "water_tanks"]
)
def test_the_examples_it_translates_agree(tmp_path, name):
    opts = Options(losses=1, duplicates=1)
    report = verify(load(EXAMPLES / f"{name}.yaml"), opts, replay=False)
    c = promela.compare(report, opts, tmp_path / "spin-rules")
    assert c.ours.configurations and c.differences() == []


@needs_spin
def test_a_dropped_transition_is_caught(tmp_path):
    """The comparison can fail: the follower's transition on go left out of the export
    (agent 1, transition 0), SPIN never sees the follower drive."""
    c = compared(tmp_path, GO, Options(losses=1), drop=(1, 0))
    diff = c.differences()
    assert "2 configurations only ours reaches, e.g. 1001|1010" in diff
    assert c.spin.deadlock is False
    # in the rich model, b's reply to ping dropped: a never gets its pong
    c = compared(tmp_path, PINGPONG, Options(losses=0), drop=(1, 1))
    assert any("only ours reaches" in d for d in c.differences())


@needs_spin
def test_the_export_is_promela_spin_compiles(tmp_path):
    report = verify(team(tmp_path, PINGPONG, "team"), Options(losses=1), replay=False)
    text = promela.prepare(report, Options(losses=1))
    assert "proctype agent_0()" in text and "proctype agent_1()" in text
    assert "proctype network()" in text and "proctype scenario()" in text
    c = promela.compare(report, Options(losses=1), tmp_path / "x", promela=text)
    assert (tmp_path / "x" / "pan").is_file() and "errors: 0" in (
        tmp_path / "x" / "pan.out"
    ).read_text()
    assert c.differences() == []


# a raised event that wakes a guard over the plant (not translated): the follower, once
# go arrives, checks where it is
RAISED_FREE = GO.replace(
    "          - {to: Drive, on: go}\n      Drive:\n        inputs: {v: 0.5, omega: 0}\n",
    "          - {to: Drive, on: go, do: [{raise: check}]}\n      Drive:\n"
    "        inputs: {v: 0.5, omega: 0}\n"
    "        transitions: [{to: Done, on: check, guard: x > 0}]\n",
)
NOT_TRANSLATED = "agent 'follower': the raised event 'check' wakes a guard that reads time or state"


def test_a_feature_not_translated_is_refused_with_one_line(tmp_path):
    report = verify(team(tmp_path, RAISED_FREE, "raised"), Options(losses=0), replay=False)
    with pytest.raises(promela.Unsupported, match=rf"^{re.escape(NOT_TRANSLATED)}$"):
        promela.prepare(report, Options(losses=0))


def spin_rules_cli(tmp_path, capsys, text: str) -> tuple[int, str]:
    """``verify --losses 1 --spin-rules --no-replay`` of the team ``text`` (written to
    ``go.yaml``, the results in ``o/``): its exit code and what it printed."""
    (tmp_path / "go.yaml").write_text(text)
    code = main(
        [
            "verify",
            str(tmp_path / "go.yaml"),
            "--losses",
            "1",
            "--spin-rules",
            "--no-replay",
            "-o",
            str(tmp_path / "o"),
            "--progress",
            "none",
        ]
    )
    return code, capsys.readouterr().out


@needs_spin
def test_cli_spin_rules_prints_both_explorers(tmp_path, capsys):
    code, out = spin_rules_cli(tmp_path, capsys, GO)
    assert code == 1  # the deadlock (not replayed)
    assert "spin-rules: ours: 5 mode configurations, 2 at dead ends, deadlock violated" in out
    assert "spin-rules: SPIN: 5 mode configurations, 2 at dead ends, deadlock violated" in out
    assert "spin-rules: the explorers agree" in out
    data = json.loads((tmp_path / "o" / "verify.json").read_text())
    assert data["spin_rules"]["differences"] == []
    assert (tmp_path / "o" / "spin-rules" / "rules.pml").is_file()


def test_cli_spin_rules_without_spin_is_one_line_exit_2(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(spin, "TOOLS", ("no-such-model-checker",))
    (tmp_path / "go.yaml").write_text(GO)
    code = main(
        [
            "verify",
            str(tmp_path / "go.yaml"),
            "--spin-rules",
            "-o",
            str(tmp_path / "o"),
            "--progress",
            "none",
        ]
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and "--spin-rules: 'no-such-model-checker' not found on PATH" in err[0]
    assert not (tmp_path / "o").exists()


def test_cli_spin_rules_refuses_a_model_not_translated_before_writing(tmp_path, capsys):
    (tmp_path / "raised.yaml").write_text(RAISED_FREE)
    code = main(
        [
            "verify",
            str(tmp_path / "raised.yaml"),
            "--losses",
            "0",
            "--spin-rules",
            "-o",
            str(tmp_path / "o"),
            "--progress",
            "none",
        ]
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1
    assert f"--spin-rules: not translated: {NOT_TRANSLATED}" in err[0]
    assert not (tmp_path / "o").exists()


@needs_spin
def test_a_model_that_outgrows_the_slots_is_reported_not_compared(tmp_path):
    """One slot for copies in flight: the go and its duplicate need two, so the model
    cannot hold every behaviour; SPIN's run says so instead of comparing."""
    opts = Options(losses=0, duplicates=2)
    report = verify(team(tmp_path, acked_go(1), "team"), opts, replay=False)
    text = promela.export(report.skeleton, 0, 2, slots=1)
    with pytest.raises(RuntimeError, match="slots overflowed"):
        promela.run_spin(text, tmp_path / "x")


# -- every verify test model and mutant (tests/verify/test_verify.py) ------------------

STAYS = mutate(GRANT, GRANT.replace("        - to: Follow\n          on:", "        - on:"))
LEADS = mutate(REQUEST, REQUEST.replace("to: Requesting", "to: Lead"))
_DENY = "        - on: request\n          do: [{send: deny, to: sender}]\n        - to: Offering"
NO_DENY = mutate(_DENY, "        - to: Offering")
NO_DEDUPE = mutate(
    "  accept: {ack: {timeout: ack_timeout, retries: ack_retries}}",
    "  accept: {ack: {timeout: ack_timeout, retries: ack_retries, dedupe: false}}",
)
OFFER = mutate(
    "        - {on: accept, do: [{send: reject, to: sender}]}",
    "        - {on: accept, do: [{send: confirm, to: sender}]}",
)
RESTORED = (
    "  leadership_restored: always(implies(count_in_role(lead) == 0, eventually("
    "count_in_role(lead) == 1 or in_mode(operator, Command))))\n"
)


def modes_of(report, config: str) -> list[set[str]]:
    """Per agent, the paths of the active modes a configuration line names (its bits in
    mode order, agents separated by '|')."""
    agents = report.skeleton.original.agents
    return [
        {ca.modes[m].path for m, b in enumerate(bits) if b == "1" and ca.modes[m].path}
        for ca, bits in zip(agents, config.split("|"), strict=True)
    ]


def leaders(report, config: str) -> int:
    """How many robots are in the lead role (Transport.Lead or Transport.Offering): the
    one_leader invariant read off a configuration, independently of our verdict."""
    return sum(
        bool(ms & {"Transport.Lead", "Transport.Offering"}) for ms in modes_of(report, config)
    )


def commanded(report, config: str) -> bool:
    """Whether the operator has taken command: no_operator read off a configuration."""
    return any("Command" in ms for ms in modes_of(report, config))


def verdict(report, name: str) -> bool | None:
    return next(v.holds for v in report.verdicts if v.prop.name == name)


def agreed(tmp_path, team, opts: Options):
    report = verify(team, opts, replay=False)
    c = promela.compare(report, opts, tmp_path / "spin-rules")
    assert c.ours.configurations and c.differences() == []
    return report, c


@needs_spin
@pytest.mark.slow
def test_the_one_leader_mutants_are_violated_in_both(tmp_path):
    """The leader-stays-Lead and requester-leads mutants (two robots and the operator, a
    request): both explorers reach the same configurations, among them one with two
    leaders; the correct protocol reaches none. (The offer-confirmed mutant, three robots
    and a resignation: test_the_offer_confirmed_mutant_agrees.)"""
    for protocol, holds in ((PROTOCOL, True), (STAYS, False), (LEADS, False)):
        team = roles_team(tmp_path, "b", protocol, without_c=True)
        report, c = agreed(tmp_path, team, Options(losses=0))
        assert verdict(report, "one_leader") is holds
        assert all(leaders(report, k) <= 1 for k in c.spin.configurations) is holds


@needs_spin
@pytest.mark.slow
def test_fifo_order_agrees_and_finds_the_mutant(tmp_path):
    """Per-link order (the slots sorted stably by link, only each link's oldest copy may
    arrive, be lost or duplicated): the leader-stays-Lead mutant with a loss in fifo
    order, two leaders in both."""
    team = roles_team(tmp_path, "b", STAYS, without_c=True)
    report, c = agreed(tmp_path, team, Options(losses=1, order="fifo"))
    assert verdict(report, "one_leader") is False
    assert max(leaders(report, k) for k in c.spin.configurations) == 2


@needs_spin
@pytest.mark.parametrize("timeouts,called", [("any", True), ("own", True), ("long", False)])
def test_timing_assumptions_agree(tmp_path, timeouts, called):
    """b asks a for the lead, no loss. Its answer timeout may expire before the grant
    arrives with --timeouts any, and with own (the grant is a's message, not b's): then
    b calls the operator. With long only once the network is quiet, when the grant has
    arrived: the operator is never called, in either explorer."""
    team = roles_team(tmp_path, "b", extra=NO_OPERATOR, without_c=True)
    report, c = agreed(tmp_path, team, Options(losses=0, timeouts=timeouts))
    assert verdict(report, "no_operator") is not called
    assert any(commanded(report, k) for k in c.spin.configurations) is called


@needs_spin
@pytest.mark.slow
def test_the_min_hold_mutant_calls_the_operator_in_both(tmp_path):
    """The min-hold deny removed, two requests, --timeouts long: the ignored request's
    answer timeout calls the operator though nothing was lost, in both explorers."""
    team = roles_team(tmp_path, "bc", NO_DENY, extra=NO_OPERATOR)
    report, c = agreed(tmp_path, team, Options(losses=0, timeouts="long"))
    assert verdict(report, "no_operator") is False
    assert any(commanded(report, k) for k in c.spin.configurations)


@needs_spin
@pytest.mark.slow
def test_the_duplicate_suppression_mutant_agrees(tmp_path):
    """dedupe off, a resignation, one loss: the resent accept the filter no longer
    withholds reaches the same configurations in both, and SPIN finds on the rules the
    response property it violates (leadership lost for good without the operator: the
    copy's reject decides), which the protocol with the filter keeps."""
    for protocol, restored in ((NO_DEDUPE, False), (PROTOCOL, True)):
        team = roles_team(tmp_path, "a", protocol, extra=RESTORED, without_c=True)
        _, c = agreed(tmp_path, team, Options(losses=1))
        assert c.spin.verdicts["leadership_restored"] is restored


@needs_spin
def test_a_guard_over_the_plant_agrees(tmp_path):
    """FAR: a guard over the plant (free in both explorers) leads to a final mode. (The
    other test models: BOUNDED in test_timeouts_in_place_agree_on_the_dead_end, the
    role teams of test_verify_bounds are the two-robot team of the tests above.)"""
    agreed(tmp_path, team(tmp_path, FAR, "far"), Options(losses=0))


# s raises two events in one action list: the queue is first in, first out, so arm
# (Armed -> Fired, sending go) comes before done (Fired -> Done); the other order would
# leave s in Idle (Armed -> Idle on done, then arm unheard)
RAISING = """team: raising
agents:
  s:
    plant: {kind: unicycle, state: {x: 0, y: 0, theta: 0}}
    initial: Idle
    modes:
      Idle:
        transitions:
          - {to: Armed, on: start, do: [{raise: arm}, {raise: done}]}
      Armed:
        transitions:
          - {to: Fired, on: arm, do: [{send: go, to: r}]}
          - {to: Idle, on: done}
      Fired:
        transitions: [{to: Done, on: done}]
      Done: {final: true}
  r:
    plant: {kind: unicycle, state: {x: 1, y: 0, theta: 0}}
    initial: Wait
    modes:
      Wait:
        transitions: [{to: Got, on: go}]
      Got: {}
scenario:
  - {at: 1.0, agent: s, raise: start}
simulation: {duration: 5}
"""


@needs_spin
@pytest.mark.parametrize("losses", [0, 1])
def test_raised_events_are_dispatched_in_order_within_the_step(tmp_path, losses):
    """By hand (s: root, Idle, Armed, Fired, Done | r: root, Wait, Got): the scenario's
    start takes s to Done in one step (Armed and Fired are passed within it), go flies;
    it arrives (r Got) or, with a loss, r waits for ever (a deadlock)."""
    c = compared(tmp_path, RAISING, Options(losses=losses))
    assert c.ours.configurations == c.spin.configurations == {"11000|110", "10001|110", "10001|101"}
    lost = {"10001|110"} if losses else set()
    assert c.ours.dead_ends == c.spin.dead_ends == {"10001|101"} | lost
    assert c.ours.deadlock is c.spin.deadlock is (not losses)


# a world event (an IR beam's obstacle_detected) may come at any moment in Drive; the
# transition it wakes raises stopped, which R's Stop region takes at once, telling O
SENSING = """team: sensing
world:
  - use: obstacles
    with:
      walls: [[2, -1, 2, 1]]
      radius: [[R, 0.3]]
      detect:
        - agent: R
          sensor: ir
          beams: [0]
          below: 0.255
          raise: obstacle_detected
          ring: {count: 4, max_range: 2.0, mount_radius: 0.3}
agents:
  R:
    plant: {kind: holonomic, state: {x: 0, y: 0, theta: 0}}
    initial: Drive
    modes:
      Drive:
        inputs: {vx: 0.1, vy: 0, omega: 0}
        period: 0.1
        transitions:
          - {to: Stop, on: obstacle_detected, do: [{raise: stopped}]}
      Stop:
        initial: Brake
        modes:
          Brake:
            transitions: [{to: Still, on: stopped, do: [{send: halt, to: O}]}]
          Still: {}
  O:
    plant: {kind: unicycle, state: {x: -1, y: 0, theta: 0}}
    initial: Run
    modes:
      Run:
        transitions: [{to: Halted, on: halt}]
      Halted: {}
simulation: {duration: 20, sample_period: 0.1}
"""


@needs_spin
def test_a_world_event_and_what_it_raises_agree(tmp_path):
    """By hand (R: root, Drive, Stop, Stop.Brake, Stop.Still | O: root, Run, Halted): the
    beam fires in Drive; R passes Brake within the step and ends in Still with halt in
    flight; halt arrives, or is lost (O waits for ever). In Stop the beam wakes nothing
    (no step, so the dead ends are the same in both)."""
    c = compared(tmp_path, SENSING, Options(losses=1))
    assert c.ours.configurations == c.spin.configurations == {"11000|110", "10101|110", "10101|101"}
    assert c.ours.dead_ends == c.spin.dead_ends == {"10101|110", "10101|101"}
    assert c.ours.deadlock is c.spin.deadlock is False


# Work remembers its child (shallow history): after next (A -> B), pause and resume, h is
# back in Work.B; without history it would restart in Work.A
HISTORY = """team: history
agents:
  h:
    plant: {kind: unicycle, state: {x: 0, y: 0, theta: 0}}
    initial: Work
    modes:
      Work:
        initial: A
        history: HISTORY
        transitions: [{to: Pause, on: pause}]
        modes:
          A:
            transitions: [{to: B, on: next}]
          B: {}
      Pause:
        transitions: [{to: Work, on: resume}]
scenario:
  - {at: 1.0, agent: h, raise: next}
  - {at: 2.0, agent: h, raise: pause}
  - {at: 3.0, agent: h, raise: resume}
simulation: {duration: 5}
"""


@needs_spin
@pytest.mark.parametrize("history,end", [("shallow", "11010"), ("none", "11100")])
def test_history_restores_the_child_left(tmp_path, history, end):
    """By hand (root, Work, Work.A, Work.B, Pause): A, then B, then Pause; resumed, Work
    restores B with history and starts again in A without: the run ends there, its one
    dead end (the scenario is spent)."""
    c = compared(tmp_path, HISTORY.replace("HISTORY", history), Options(losses=0))
    assert c.ours.configurations == c.spin.configurations == {"11100", "11010", "10001"}
    assert c.ours.dead_ends == c.spin.dead_ends == {end}


@needs_spin
@pytest.mark.slow
def test_the_docking_handshake_agrees(tmp_path):
    """Experiment 2's docking handshake (plain datagrams, no loss): world events (the IR
    ring's at_box and obstacle_detected), raise actions (want_lead, resign), history and
    the role body carried over from Lead to Offering (542,742 SPIN states without the
    invisible-copy rule, 1,605 with it, ours 1,547; with a loss:
    test_the_plain_docking_handshake_with_a_loss_deadlocks_in_both). By hand: the XR4000
    resigns as its Pass phase ends (Pass -> Hold raises resign), so it offers the lead
    holding still — the body carried over, in Offering.Hold, never restarted in
    Offering.Sidestep."""
    report, c = agreed(tmp_path, docking(tmp_path, acknowledged=False), Options(losses=0))
    xr = [modes_of(report, k)[0] for k in c.spin.configurations]
    assert any("Transport.Offering.Hold" in ms for ms in xr)
    assert not any("Transport.Offering.Sidestep" in ms for ms in xr)


# -- the reduction, and the properties decided on the rules ----------------------------


@needs_spin
def test_the_invisible_copy_first_rule_keeps_what_is_compared(tmp_path):
    """The acknowledged go with a resend, a loss and a duplicate: acks and withheld copies
    fly beside everything else. SPIN with the rule (an invisible copy's fates first)
    reaches the same configurations, dead ends and verdicts as SPIN without it, in fewer
    states; and the model with the rule computes ``inv`` in settle and guards the other
    steps with it."""
    opts = Options(losses=1, duplicates=1)
    report = verify(team(tmp_path, acked_go(1), "team"), opts, replay=False)
    props = [v.prop for v in report.verdicts]
    kw = dict(slots=8, outbox=8, seen=16, props=props)
    reduced = promela.export(report.skeleton, 1, 1, **kw)
    full = promela.export(report.skeleton, 1, 1, reduce=False, **kw)
    assert "now.inv = first_invisible();" in reduced and "inv == 0" in reduced
    assert "first_invisible" not in full and "inv == 0" not in full
    a = promela.run_spin(reduced, tmp_path / "reduced", props=props)
    b = promela.run_spin(full, tmp_path / "full", props=props)
    assert a.configurations == b.configurations == promela.ours(report).configurations
    assert a.dead_ends == b.dead_ends and a.deadlock is b.deadlock is True
    assert a.states < b.states
    # with --ack-timing any a timer may expire while its ack flies: no reduction
    loose = promela.export(report.skeleton, 1, 1, ack_timing="any", **kw)
    assert "first_invisible" not in loose


# GO with properties: the follower drives once the leader does (a response), both drive
# at once (an invariant, violated: the go arrives before the leader's x > 3), the leader
# stays near (reads the plant: decided by neither explorer)
GO_PROPS = GO.replace(
    "simulation: {duration: 20}\n",
    "simulation: {duration: 20}\nrequirements:\n"
    "  follows: always(implies(in_mode(leader, Drive), eventually(in_mode(follower, Drive))))\n"
    "  one_driving: always(count_in_mode(Drive) <= 1)\n"
    "  near: always(leader.x < 10)\n",
)
# PINGPONG with invariants over a's counter n: one pong at most ever arrives in Wait
PINGPONG_PROPS = PINGPONG.replace(
    "simulation: {duration: 10}\n",
    "simulation: {duration: 10}\nrequirements:\n"
    "  never_counted: always(a.n <= 0)\n"
    "  counted_once: always(a.n <= 1)\n"
    "  in_range: always(abs(a.n - 3) >= 2 and max(a.n, 0) == min(a.n, 5) and -a.n <= 0)\n"
    "  halved: always(a.n / 2 < 1)\n",
)


@needs_spin
@pytest.mark.parametrize("losses,follows", [(0, True), (1, False)])
def test_invariants_and_responses_are_decided_on_the_rules(tmp_path, losses, follows):
    """By hand: without loss the go always arrives (no dead end holds a copy in flight),
    so a driving leader is followed; with a loss the leader drives on to Done and the
    follower waits for ever (a dead end where psi never comes, which SPIN's LTL semantics
    extends by stuttering). Both drive at once in either case. ``near`` reads the plant:
    neither explorer decides it, and SPIN says why."""
    c = compared(tmp_path, GO_PROPS, Options(losses=losses))
    assert c.spin.verdicts == c.ours.verdicts == {"follows": follows, "one_driving": False}
    assert c.spin.undecided == {"near": "it reads leader's plant state"}
    assert "near" in c.ours.undecided
    assert c.differences() == []


@needs_spin
def test_an_invariant_over_a_discrete_variable_is_decided(tmp_path):
    """By hand: a's n becomes 1 when b's pong (k = 0) arrives in Wait; no second pong can
    arrive in Wait (a is in Got, or back in Idle for good), even with a duplicate. So n is
    0 or 1 (in_range: |n - 3| >= 2, max and min agree on n, -n <= 0); a division is not an int's
    and SPIN leaves it undecided (ours decides it on its floats)."""
    c = compared(tmp_path, PINGPONG_PROPS, Options(losses=1, duplicates=1))
    assert c.spin.verdicts == {"never_counted": False, "counted_once": True, "in_range": True}
    assert c.ours.verdicts == {**c.spin.verdicts, "halved": True}
    assert c.spin.undecided == {"halved": "it applies divide, which is not translated"}
    assert c.differences() == []


@needs_spin
def test_a_wrong_verdict_is_caught(tmp_path):
    """The comparison reads SPIN's verdicts: ours said otherwise, it differs."""
    opts = Options(losses=1)
    report = verify(team(tmp_path, GO_PROPS, "team"), opts, replay=False)
    c = promela.compare(report, opts, tmp_path / "spin-rules")
    c.ours.verdicts["follows"] = True
    assert c.differences() == ["follows: ours holds, SPIN violated"]


@needs_spin
@pytest.mark.slow
def test_the_offer_confirmed_mutant_agrees(tmp_path):
    """Three robots and the operator, a resigns: the offer confirmed to every acceptor
    makes b and c lead together, in both explorers (SPIN's configurations read
    independently of our verdict); b's and c's requests need none (they hold)."""
    report, c = agreed(tmp_path, roles_team(tmp_path, "a", OFFER), Options(losses=0))
    assert c.spin.verdicts == {"one_leader": False, "b_answered": True, "c_answered": True}
    two = [modes_of(report, k) for k in c.spin.configurations if leaders(report, k) == 2]
    assert any({"Transport.Lead"} <= b and {"Transport.Lead"} <= c for _, b, c, _ in two)


@needs_spin
@pytest.mark.slow
@pytest.mark.parametrize("losses", [0, 1])
def test_the_acknowledged_docking_handshake_agrees(tmp_path, losses):
    """Experiment 2's handshake acknowledged: with or without a lost copy, the XR4000
    waiting in Dock.Wait is always carried off (carried holds) and nothing deadlocks."""
    _, c = agreed(tmp_path, docking(tmp_path, acknowledged=True), Options(losses=losses))
    assert c.spin.verdicts == {"carried": True} and c.spin.deadlock is True


@needs_spin
@pytest.mark.slow
def test_the_plain_docking_handshake_with_a_loss_deadlocks_in_both(tmp_path):
    """Plain datagrams, one loss: SPIN reaches the sweep's failure on its own — a dead
    end with the XR4000 in Dock.Wait while the Labmate leads off (Transport.Lead.Stop),
    a deadlock — and finds carried violated."""
    report, c = agreed(tmp_path, docking(tmp_path, acknowledged=False), Options(losses=1))
    assert c.spin.deadlock is False and c.spin.verdicts == {"carried": False}
    stuck = [modes_of(report, k) for k in c.spin.dead_ends]
    assert any("Dock.Wait" in xr and "Transport.Lead.Stop" in lab for xr, lab, _ in stuck)


@needs_spin
@pytest.mark.slow
def test_three_requests_and_a_resignation_agree(tmp_path):
    """The whole example (three robots, three requests, a resignation, no loss): the same
    configurations, and every property holds in both."""
    team = load(ROOT / "examples" / "protocols" / "roles_verify.yaml")
    _, c = agreed(tmp_path, team, Options(losses=0))
    assert c.spin.verdicts == {"one_leader": True, "b_answered": True, "c_answered": True}


@needs_spin
def test_cli_spin_rules_prints_spins_verdicts(tmp_path, capsys):
    code, out = spin_rules_cli(tmp_path, capsys, GO_PROPS)
    assert code == 1  # violations, agreed on
    assert "spin-rules: follows: SPIN violated on the rules" in out
    assert "spin-rules: one_driving: SPIN violated on the rules" in out
    assert "spin-rules: near: not decided by SPIN: it reads leader's plant state" in out
    assert "spin-rules: the explorers agree" in out
    data = json.loads((tmp_path / "o" / "verify.json").read_text())["spin_rules"]
    assert data["verdicts"]["follows"] == {"ours": False, "spin": False}
    assert data["states"]["spin"] > 0


# Entry and exit actions: the leader's exit from Wait sends go and counts it (sent = 1),
# then the transition's own action multiplies (sent = 10: exit actions run before the
# transition's, 1 the other way round); the follower's Wait is entered at the start
# (drives = 100: the initial configuration's entry actions run), go's action sets
# drives = 5, then Drive's entry adds one (6) and raises started, which takes it to Done
# in the same step (its guard drives == 6 needs the transition's action before the entry:
# else drives would be 5 and the follower would stay in Drive).
ENTRY_EXIT = """team: entryexit
agents:
  leader:
    plant: {kind: unicycle, state: {x: 0, y: 0, theta: 0}}
    variables: {sent: 0}
    initial: Wait
    modes:
      Wait:
        inputs: {v: 0, omega: 0}
        exit: [{send: go, to: follower}, sent = sent + 1]
        transitions:
          - {to: Drive, after: 2.0, do: [sent = sent * 10]}
      Drive:
        inputs: {v: 0.5, omega: 0}
        transitions:
          - {to: Done, guard: x > 3}
      Done:
        final: true
  follower:
    plant: {kind: unicycle, state: {x: -1, y: 0, theta: 0}}
    variables: {drives: 0}
    initial: Wait
    modes:
      Wait:
        entry: [drives = 100]
        transitions:
          - {to: Drive, on: go, do: [drives = 5]}
      Drive:
        entry: [drives = drives + 1, {raise: started}]
        transitions:
          - {to: Done, on: started, guard: drives == 6}
      Done:
        final: true
simulation: {duration: 20}
requirements:
  never_sent: always(leader.sent == 0)
  exit_then_do: always(leader.sent == 0 or leader.sent == 10)
  do_then_entry: always(follower.drives == 100 or follower.drives == 6)
"""


@needs_spin
@pytest.mark.parametrize("losses", [0, 1])
def test_entry_and_exit_actions_agree_with_the_order_by_hand(tmp_path, losses):
    """By hand (bits per agent: root, Wait, Drive, Done): the leader waits, drives (go in
    flight), is done; the follower waits, or is done once go arrives — never seen in
    Drive, which started leaves within the step. A lost go leaves the follower waiting
    for a message that never comes: the deadlock (go is a message, though only an exit
    action sends it). The verdicts read the order of the actions."""
    c = compared(tmp_path, ENTRY_EXIT, Options(losses=losses))
    assert (
        c.ours.configurations
        == c.spin.configurations
        == {"1100|1100", "1010|1100", "1010|1001", "1001|1100", "1001|1001"}
    )
    lost = {"1001|1100"} if losses else set()
    assert c.ours.dead_ends == c.spin.dead_ends == {"1001|1001"} | lost
    assert c.ours.deadlock is c.spin.deadlock is (not losses)
    assert (
        c.ours.verdicts
        == c.spin.verdicts
        == {"never_sent": False, "exit_then_do": True, "do_then_entry": True}
    )
    assert c.differences() == []


def test_verify_hears_a_message_only_an_exit_action_sends(tmp_path):
    """Ours alone (no SPIN needed): go, sent only by the leader's exit action, is a message
    to verify's skeleton, and started, raised only by the follower's entry action, is its
    own event — neither is an input from outside — so a lost go is a deadlock (the
    follower waits for a message that never comes), as by hand."""
    report = verify(team(tmp_path, ENTRY_EXIT, "team"), Options(losses=1), replay=False)
    assert report.skeleton.inputs == [set(), set()]
    assert verdict(report, "deadlock") is False


# A rally that never ends: a serves when started, then a and b return the ball for ever
# (each a leaf back into itself, sending it back). a never rests again: a response
# violated by a cycle alone (the ball always flies, so no dead end) without loss, and
# with a lost ball by a dead end as well.
RALLY = """team: rally
agents:
  a:
    plant: {kind: unicycle, state: {x: 0, y: 0, theta: 0}}
    initial: Rest
    modes:
      Rest:
        transitions:
          - {to: Rally, on: start, do: [{send: ball, to: b}]}
      Rally:
        transitions:
          - {to: Rally, on: ball, do: [{send: ball, to: b}]}
  b:
    plant: {kind: unicycle, state: {x: 1, y: 0, theta: 0}}
    initial: Rally
    modes:
      Rally:
        transitions:
          - {to: Rally, on: ball, do: [{send: ball, to: a}]}
scenario:
  - {at: 1.0, agent: a, raise: start}
simulation: {duration: 10}
requirements:
  rests_again: always(implies(in_mode(a, Rally), eventually(in_mode(a, Rest))))
  keeps_playing: always(implies(in_mode(a, Rally), eventually(in_mode(b, Rally))))
"""


@needs_spin
@pytest.mark.parametrize("losses", [0, 1])
def test_a_response_violated_by_a_cycle_is_found_by_both(tmp_path, losses):
    """By hand (a: root, Rest, Rally | b: root, Rally): two configurations; without loss
    no dead end, so rests_again fails only through the rally's cycle (SPIN: an acceptance
    cycle); keeps_playing holds (b is always in Rally)."""
    c = compared(tmp_path, RALLY, Options(losses=losses))
    assert c.ours.configurations == c.spin.configurations == {"110|11", "101|11"}
    assert c.ours.dead_ends == c.spin.dead_ends == ({"101|11"} if losses else set())
    assert c.ours.verdicts == c.spin.verdicts == {"rests_again": False, "keeps_playing": True}
    assert c.differences() == []


# Statechart order (tests/engine/test_statecharts.py's digits, a discrete counter here):
# entering P appends P 1, R1 2, a 3, R2 4, c 5 (outermost first, regions in document
# order); leaving it appends c 8, R2 9, a 6, R1 7, P 0 (innermost first, regions in
# reverse): n = 12345, then 1234589670 (within Promela's 32-bit int)
ORDER = """team: order
agents:
  a:
    plant: {kind: unicycle, state: {x: 0, y: 0, theta: 0}}
    variables: {n: 0}
    initial: Q
    modes:
      P:
        parallel: true
        entry: ["n = n * 10 + 1"]
        exit: ["n = n * 10"]
        transitions: [{to: Q, on: back}]
        modes:
          R1:
            initial: a
            entry: ["n = n * 10 + 2"]
            exit: ["n = n * 10 + 7"]
            modes:
              a: {entry: ["n = n * 10 + 3"], exit: ["n = n * 10 + 6"]}
          R2:
            initial: c
            entry: ["n = n * 10 + 4"]
            exit: ["n = n * 10 + 9"]
            modes:
              c: {entry: ["n = n * 10 + 5"], exit: ["n = n * 10 + 8"]}
      Q: {transitions: [{to: P, on: go}]}
scenario: [{at: 1, agent: a, raise: go}, {at: 2, agent: a, raise: back}]
simulation: {duration: 3}
requirements:
  in_order: always(a.n == 0 or a.n == 12345 or a.n == 1234589670)
  entered: always(implies(in_mode(a, P), a.n == 12345))
"""


@needs_spin
def test_entry_and_exit_order_through_parallel_regions_agrees(tmp_path):
    """By hand (bits: root, P, R1, a, R2, c, Q): Q, then P with both regions, then Q
    again; the counter's values read the order of every entry and exit action."""
    c = compared(tmp_path, ORDER, Options(losses=0))
    assert c.ours.configurations == c.spin.configurations == {"1000001", "1111110"}
    assert c.ours.verdicts == c.spin.verdicts == {"in_order": True, "entered": True}
    assert c.differences() == []


# Urgent transitions (no trigger, an exact guard), as the engine's discrete phase takes
# them: before any pending event, every agent its enabled ones. Boot is left at the first
# instant (n = 0: to Idle, n = 1); start takes Idle to A (n = 2) and raises ping; A's
# urgent transitions go before the queued ping: to B (n = 3), the second (to X) blocked by
# the first, which precedes it on the same mode; ping then finds s in B: C. Dispatching
# ping first would reach X, skipping the first instant would leave s in Boot.
URGENT = """team: urgent
agents:
  s:
    plant: {kind: unicycle, state: {x: 0, y: 0, theta: 0}}
    variables: {n: 0}
    initial: Boot
    modes:
      Boot:
        transitions:
          - {to: Idle, guard: n == 0, do: [n = 1]}
      Idle:
        transitions:
          - {to: A, on: start, do: [n = 2, {raise: ping}]}
      A:
        transitions:
          - {to: B, guard: n == 2, do: [n = 3]}
          - {to: X, guard: n >= 2}
          - {to: X, on: ping}
      B:
        transitions:
          - {to: C, on: ping, guard: n == 3}
      C: {final: true}
      X: {final: true}
scenario:
  - {at: 1.0, agent: s, raise: start}
simulation: {duration: 3}
requirements:
  never_x: always(not in_mode(s, X))
  settled: always(s.n == 1 or s.n == 3)
"""


@needs_spin
def test_urgent_transitions_fire_before_pending_events_in_both(tmp_path):
    """By hand (bits: root, Boot, Idle, A, B, C, X): Idle, then C, its one dead end; X
    never; n is 1 or 3 in every state (2 only within the step)."""
    c = compared(tmp_path, URGENT, Options(losses=0))
    assert c.ours.configurations == c.spin.configurations == {"1010000", "1000010"}
    assert c.ours.dead_ends == c.spin.dead_ends == {"1000010"}
    assert c.ours.verdicts == c.spin.verdicts == {"never_x": True, "settled": True}
    assert c.differences() == []


@needs_spin
def test_a_zeno_cycle_of_urgent_transitions_is_reported_not_compared(tmp_path):
    """Two urgent transitions that take each other's mode for ever: the step never ends,
    which the model reports (as an overflow) instead of comparing."""
    zeno = URGENT.replace("          - {to: C, on: ping, guard: n == 3}", "          - {to: A}")
    zeno = zeno.replace("          - {to: B, guard: n == 2, do: [n = 3]}", "          - {to: B}")
    report = verify(team(tmp_path, zeno, "team"), Options(losses=0), replay=False)
    with pytest.raises(RuntimeError, match="urgent micro-steps"):
        promela.compare(report, Options(losses=0), tmp_path / "x")
