"""Early warnings (issue 16, item 4): settings that cannot work are said before running.

With 0.25 s of latency each way an acknowledged message needs more than 0.5 s for its ack
to come back; the protocol's default ack timeout of 0.1 s would resend every one of them
and, after the retries, report it undeliverable — the run said ``ok`` all the same.
"""

from __future__ import annotations

from hybridteam.cli import main
from tests.engine.test_end_rule import TEAM


def test_an_ack_timeout_shorter_than_a_round_trip_is_a_warning(tmp_path, capsys):
    slow = tmp_path / "slow.yaml"
    slow.write_text(TEAM.replace("network: {latency: 0.03}", "network: {latency: 0.25}"))
    assert main(["validate", str(slow)]) == 0
    err = capsys.readouterr().err
    assert (
        ":6:3: agents.xr4000: agent 'xr4000' resends request, grant, deny, offer, accept, "
        "confirm, reject, announce, takeover after 0.1 s without an acknowledgement, but a "
        "round trip to 'labmate' takes up to 0.5 s" in err
    )
    assert "make the ack timeout longer than 0.5 s (e.g. ack_timeout: 1.05) (warning)" in err
    assert main(["validate", "--strict", str(slow)]) == 2
    capsys.readouterr()
    assert (
        main(["run", str(slow), "-o", str(tmp_path / "out"), "--no-views", "--duration", "1"]) == 0
    )
    assert "round trip to 'labmate' takes up to 0.5 s" in capsys.readouterr().err  # run warns
    fixed = tmp_path / "fixed.yaml"
    fixed.write_text(
        slow.read_text().replace(
            "parameters: {speed: 0.3}",
            "parameters: {speed: 0.3, ack_timeout: 1.05, answer_timeout: 5}",
        )
    )
    assert main(["validate", str(fixed)]) == 0
    assert "warning" not in capsys.readouterr().err


# ------------------------------------------------- agent parameters written as expressions
DERIVED = """
team: derived
parameters: {latency: 0.25}
agents:
  a:
    plant: {kind: flow, state: {x: 0}}
    parameters: {k: 3, ack_timeout: 2 * latency + 0.05, rate: ack_timeout * 2 + k}
    modes:
      Run: {flow: {x: rate}}
simulation: {duration: 1}
"""


def _x_at_end(run) -> list[float]:
    rows = run.samples_frame(wide=True)
    return rows[rows.t == 1.0]["a.x"].round(9).tolist()


def test_agent_parameters_may_be_expressions_of_team_parameters(team_from_yaml):
    """x' = rate, so x(1) = rate = 2 (2·latency + 0.05) + 3: 4.1 at the team's latency, and
    re-evaluated per instance when a study overrides latency (0 -> 3.1, 1 -> 7.1); an
    override of the derived parameter itself wins over its formula (ack_timeout = 1 -> 5)."""
    import hybridteam as ht

    team = team_from_yaml(DERIVED)
    assert _x_at_end(ht.simulate(team)) == [4.1]
    assert _x_at_end(ht.simulate(team, n=2, overrides={"latency": [0.0, 1.0]})) == [3.1, 7.1]
    assert _x_at_end(
        ht.simulate(team, n=2, overrides={"latency": [0.0, 1.0], "a.ack_timeout": 1.0})
    ) == [5.0, 5.0]


def test_a_parameter_that_reads_one_declared_below_it_is_a_located_error(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text(
        DERIVED.replace(
            "{k: 3, ack_timeout: 2 * latency + 0.05, rate: ack_timeout * 2 + k}",
            "{rate: ack_timeout * 2 + k, k: 3, ack_timeout: 1}",
        )
    )
    assert main(["validate", str(bad)]) == 2
    assert (
        "bad.yaml:7:24: agents.a.parameters.rate: parameter 'rate' reads 'ack_timeout', "
        "which is not declared above it" in capsys.readouterr().err
    )


# ------------------------------------------------- answer timeouts and rate limits
def test_an_answer_timeout_shorter_than_the_retries_is_a_warning(tmp_path, capsys):
    """ack_timeout 0.55 s with the protocol's 3 retries resends a request until 0.55 × 4 =
    2.2 s, but the protocol gives up on an answer after answer_timeout = 1 s."""
    team = TEAM.replace("network: {latency: 0.03}", "network: {latency: 0.25}").replace(
        "parameters: {speed: 0.3}", "parameters: {speed: 0.3, ack_timeout: 0.55}"
    )
    path = tmp_path / "t.yaml"
    path.write_text(team)
    assert main(["validate", str(path)]) == 0
    err = capsys.readouterr().err
    assert "round trip" not in err
    assert (
        "agent 'labmate' waits 1 s (after: answer_timeout) for an answer to offer in "
        "'Transport.Offering', request in 'Transport.Requesting', accept in "
        "'Transport.Accepting', but it resends them until 2.2 s" in err
    )
    assert "make the wait longer than 2.2 s, or resend sooner (warning)" in err
    path.write_text(team.replace("ack_timeout: 0.55}", "ack_timeout: 0.55, answer_timeout: 2.5}"))
    assert main(["validate", str(path)]) == 0
    assert "warning" not in capsys.readouterr().err


def test_a_rate_limit_below_the_streams_is_a_warning(tmp_path, capsys):
    """Two robots stream their pose at 20 Hz to a third that takes 8 data messages a second:
    8 of 40 get through (80 % dropped); with no jitter the order is the same every period."""
    team = TEAM.replace(
        "network: {latency: 0.03}", "network: {latency: 0.03, rate_limits: {operator: {data: 8}}}"
    ).replace(
        "  operator:\n    operator: role_assignment\n",
        "  operator:\n    operator: role_assignment\n  scout:\n"
        "    plant: {kind: unicycle, state: {x: 0, y: 1, theta: 0}}\n"
        "    modes:\n      Wait: {inputs: {v: 0, omega: 0}, period: 0.1}\n",
    )
    team = team.replace("{operator: {data: 8}}", "{scout: {data: 8}}")
    path = tmp_path / "t.yaml"
    path.write_text(team)
    assert main(["validate", str(path)]) == 0
    err = capsys.readouterr().err
    assert (
        "network.rate_limits.scout.data: 'scout' takes at most 8 data messages per second "
        "but streams send it 40 (xr4000 20, labmate 20): at least 80 % of the copies are "
        "dropped; with no jitter" in err
    )
    path.write_text(team.replace("{data: 8}", "{data: 40}"))
    assert main(["validate", str(path)]) == 0
    assert "rate_limits" not in capsys.readouterr().err
