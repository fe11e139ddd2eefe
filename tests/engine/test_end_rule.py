"""When a run ends: the end rule (issue 16, item 1).

A protocol's operator stands by forever, so a team with one used to run to its duration
even after every robot had arrived. By default a run now ends when every agent but the
operators is final; ``end: {agents: [...], when: all|any}`` says which agents matter.
"""

from __future__ import annotations

import pytest

import hybridteam as ht

TEAM = """
team: arrive
parameters: {speed: 0.3}
network: {latency: 0.03}
agents:
  xr4000:
    plant: {kind: unicycle, state: {x: 1.0, y: 0.0, theta: 0.0}}
    initial: Transport
    modes:
      Transport:
        protocol: role_assignment
        initial: Lead
        roles:
          lead: {inputs: {v: speed, omega: 0}, period: 0.05}
          follow: {law: {use: formation.follow, period: 0.05, with: {ahead: 1.0}}}
        transitions:
          - {to: Arrived, guard: x >= 2.5}
      Arrived: {final: true, outcome: success}
  labmate:
    plant: {kind: unicycle, state: {x: 0.0, y: 0.0, theta: 0.0}}
    variables: {leader: id_xr4000}
    initial: Transport
    modes:
      Transport:
        protocol: role_assignment
        initial: Follow
        roles:
          lead: {inputs: {v: speed, omega: 0}, period: 0.05}
          follow: {law: {use: formation.follow, period: 0.05, with: {ahead: -1.0}}}
        transitions:
          - {to: Parked, guard: x >= 1.5}
      Parked: {final: true}
  operator:
    operator: role_assignment
simulation: {duration: 20.0}
"""


def arrivals(run) -> dict[str, float]:
    tr = run.transitions
    return {row.agent: row.t for row in tr if row.target in ("Arrived", "Parked")}


def test_a_team_with_an_operator_ends_when_its_robots_arrive(team_from_yaml):
    """The XR4000 leads at 0.3 m/s from x = 1: it arrives (x = 2.5) at t = 5 s exactly; the
    run ends when the Labmate, following, parks too — not at the 20 s duration."""
    run = ht.simulate(team_from_yaml(TEAM))
    times = arrivals(run)
    assert times["xr4000"] == pytest.approx(5.0, abs=1e-9)
    assert run.outcome == "success"
    assert run.diagnostics[0]["t"] == max(times.values()) < 20.0
    assert run.message == (
        "every agent reached a final mode (operators are not waited for: 'operator')"
    )


def test_the_end_rule_names_the_agents_that_matter(team_from_yaml):
    """``when: any`` over the leader: the run ends the instant the XR4000 arrives."""
    run = ht.simulate(team_from_yaml(TEAM + "end: {agents: [xr4000], when: any}\n"))
    assert run.outcome == "success"
    assert run.diagnostics[0]["t"] == pytest.approx(5.0, abs=1e-9)
    assert "labmate" not in arrivals(run)
    assert run.message == "'xr4000' reached a final mode"


def test_an_end_rule_naming_no_agent_is_a_located_error(team_from_yaml):
    from hybridteam.io.filekind import InputErrors

    with pytest.raises(
        InputErrors,
        match=r"team.yaml:36:16: end.agents\[0\]: unknown agent "
        r"'xr400'; did you mean 'xr4000'\?",
    ):
        team_from_yaml(TEAM + "end: {agents: [xr400]}\n")


def test_a_robot_outside_the_protocol_validates(team_from_yaml):
    """A team robot that is no member of the role-assignment protocol used to fail with 21
    errors inside the shipped protocol file; now it simply takes no part."""
    scout = (
        "  scout:\n    plant: {kind: unicycle, state: {x: -2.0, y: 0.0, theta: 0.0}}\n"
        "    modes: {Idle: {}}\n  operator:\n"
    )
    team = team_from_yaml(TEAM.replace("  operator:\n", scout))
    run = ht.simulate(team)
    assert run.outcome == "ok"  # the scout has no final mode: the run goes to its end


def test_a_non_member_that_sends_a_protocol_message_is_told_what_it_lacks(team_from_yaml):
    from hybridteam.io.filekind import InputErrors

    scout = (
        "  scout:\n    plant: {kind: unicycle, state: {x: -2.0, y: 0.0, theta: 0.0}}\n"
        "    modes:\n      Idle:\n        transitions: [{to: Idle, on: go, do: [{send: "
        "request, to: xr4000}]}]\n  operator:\n"
    )
    with pytest.raises(InputErrors) as exc:
        team_from_yaml(TEAM.replace("  operator:\n", scout))
    messages = [str(e) for e in exc.value.errors]
    assert len(messages) == 3
    assert all(":34:5: agents.scout: agent 'scout' sends 'request', whose " in m for m in messages)
    assert (
        "priority cannot be evaluated for it: unknown name 'priority'; give the agent "
        "that parameter (parameters:), or make it a member of the protocol that declares "
        "'request' (role_assignment)" in messages[0]
    )
