"""SPIN as an independent second explorer (``--spin-rules``): the team's rules, not our
explored graph, go to Promela; SPIN explores them and the two explorations must reach the
same projected mode configurations, the same dead ends and the same deadlock verdict.
The comparisons skip where SPIN or a C compiler is missing; refusals and the missing-tool
message are tested everywhere."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from hybridteam import load
from hybridteam.cli import main
from hybridteam.verify import Options, promela, spin, verify
from tests.verify.test_verify import GO, REQUEST, mutate, roles_team
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
def test_the_role_protocol_and_a_mutant_agree(tmp_path):
    """Two robots and the operator, a request, no loss: the protocol (acknowledged, guards
    over discrete variables and a free min-hold guard, broadcasts) and the mutant whose
    requester leads when it asks (SPIN's unreduced search takes minutes on a loaded
    machine)."""
    opts = Options(losses=0)
    for protocol in (None, mutate(REQUEST, REQUEST.replace("to: Requesting", "to: Lead"))):
        kw = {} if protocol is None else {"protocol": protocol}
        report = verify(roles_team(tmp_path, "b", without_c=True, **kw), opts, replay=False)
        c = promela.compare(report, opts, tmp_path / "spin-rules")
        assert c.spin.configurations and c.differences() == []


@needs_spin
@pytest.mark.slow
def test_the_role_protocol_with_a_loss_agrees(tmp_path):
    """As above with one loss (SPIN's unreduced search: millions of states, minutes)."""
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


# an entry action (not translated): the follower counts its drives as it enters Drive
ENTRY = GO.replace(
    "        inputs: {v: 0.5, omega: 0}\n      Done:\n        final: true\nsimulation",
    "        inputs: {v: 0.5, omega: 0}\n        entry: [drives = drives + 1]\n"
    "      Done:\n        final: true\nsimulation",
).replace(
    "    plant: {kind: unicycle, state: {x: -1",
    "    variables: {drives: 0}\n    plant: {kind: unicycle, state: {x: -1",
)


def test_a_feature_not_translated_is_refused_with_one_line(tmp_path):
    report = verify(team(tmp_path, ENTRY, "entry"), Options(losses=0), replay=False)
    with pytest.raises(
        promela.Unsupported, match=r"^agent 'follower': mode Drive has entry or exit actions$"
    ):
        promela.prepare(report, Options(losses=0))


@needs_spin
def test_cli_spin_rules_prints_both_explorers(tmp_path, capsys):
    (tmp_path / "go.yaml").write_text(GO)
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
    out = capsys.readouterr().out
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
    (tmp_path / "entry.yaml").write_text(ENTRY)
    code = main(
        [
            "verify",
            str(tmp_path / "entry.yaml"),
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
    assert (
        "--spin-rules: not translated: agent 'follower': mode Drive has entry or exit actions"
        in err[0]
    )
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
