"""The engine skips work at an instant where nothing it depends on changed (issue 19): an
event consumed without a transition leaves modes, variables and state as they were, so
urgent guards, drivers, timers and streams are not looked at again. A guard that reads a
stream estimate is the exception: the copy that arrives changes what it reads."""

TEAM = """
team: est_guard
network:
  latency: {latency}
agents:
  a:
    plant: {{kind: unicycle, state: {{x: 1.0, y: 0.0, theta: 0.0}}}}
    modes:
      Transport:
        protocol: role_assignment
        initial: Lead
        roles:
          lead: {{inputs: {{v: 0.0, omega: 0.0}}, period: 0.05}}
          follow: {{inputs: {{v: 0.0, omega: 0.0}}, period: 0.05}}
  b:
    plant: {{kind: unicycle, state: {{x: 0.0, y: 0.0, theta: 0.0}}}}
    initial: Wait
    modes:
      Wait:
        inputs: {{v: 0.0, omega: 0.0}}
        period: 0.05
        transitions: [{{to: Go, guard: {guard}}}]
      Go:
        inputs: {{v: 0.1, omega: 0.0}}
        period: 0.05
  operator:
    operator: role_assignment
simulation: {{duration: 0.2, sample_period: 0.05}}
"""


def _go(team_from_yaml, latency: float, guard: str) -> tuple[float, int]:
    import hybridteam as ht

    run = ht.simulate(team_from_yaml(TEAM.format(latency=latency, guard=guard)))
    tr = run.transitions
    rows = [(float(t), int(k)) for t, k, who, to in
            zip(tr["t"], tr["step"], tr["agent"], tr["target"], strict=True)
            if who == "b" and to == "Go"]
    assert len(rows) == 1
    return rows[0]


def test_an_urgent_guard_on_a_stream_estimate_fires_when_the_first_copy_arrives(
        team_from_yaml):
    """`a` streams its pose (x = 1) from t = 0; the copy takes the link's latency, so `b`'s
    guard `est_state_x > 0.5` holds from t = latency: it fires then, in the micro-step
    after the one that consumed the copy — not at b's next law tick (0.05 s)."""
    for latency in (0.03, 0.01):
        assert _go(team_from_yaml, latency, "est_state_x > 0.5") == (latency, 1)


def test_an_urgent_guard_on_the_estimate_age_too(team_from_yaml):
    """`est_state_age` (t minus the latest copy's send time) is infinite until a copy
    arrives, and the latency then: `est_state_age < 1` turns true on the arrival."""
    assert _go(team_from_yaml, 0.03, "est_state_age < 1") == (0.03, 1)
