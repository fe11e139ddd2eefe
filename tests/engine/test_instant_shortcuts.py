"""The engine skips work at an instant where nothing it depends on changed (issue 19): an
event consumed without a transition leaves modes, variables and state as they were, so
urgent guards, drivers, timers and streams are not looked at again. A guard that reads a
stream estimate is the exception: the copy that arrives changes what it reads. Sampled
inputs of parameters alone are not evaluated again at a tick that enters no mode."""

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
    rows = [
        (float(t), int(k))
        for t, k, who, to in zip(tr["t"], tr["step"], tr["agent"], tr["target"], strict=True)
        if who == "b" and to == "Go"
    ]
    assert len(rows) == 1
    return rows[0]


def test_an_urgent_guard_on_a_stream_estimate_fires_when_the_first_copy_arrives(team_from_yaml):
    """`a` streams its pose (x = 1) from t = 0; the copy takes the link's latency, so `b`'s
    guard `est_state_x > 0.5` holds from t = latency: it fires then, in the micro-step
    after the one that consumed the copy — not at b's next law tick (0.05 s)."""
    for latency in (0.03, 0.01):
        assert _go(team_from_yaml, latency, "est_state_x > 0.5") == (latency, 1)


def test_an_urgent_guard_on_the_estimate_age_too(team_from_yaml):
    """`est_state_age` (t minus the latest copy's send time) is infinite until a copy
    arrives, and the latency then: `est_state_age < 1` turns true on the arrival."""
    assert _go(team_from_yaml, 0.03, "est_state_age < 1") == (0.03, 1)


HELD = """
team: held
parameters: {turn: 0.3}
agents:
  r:
    plant: {kind: unicycle, state: {x: 0.0, y: 0.0, theta: 0.0}}
    variables: {k: 0}
    initial: Ramp
    modes:
      Ramp:
        inputs: {v: 0.0, omega: 0.1 * t + 0.2 * k}
        period: 0.5
        transitions: [{to: Ramp, after: 2.0, do: ["k = k + 1"]}]
      Held:
        inputs: {v: 0.0, omega: turn}
        period: 0.5
        transitions: [{to: Held, after: 2.0}]
simulation: {duration: 5.0, sample_period: 0.5}
"""


def test_held_inputs_keep_their_values_and_inputs_of_time_or_variables_are_resampled(
    team_from_yaml,
):
    """Only inputs of parameters alone are held between ticks. Ramp's omega (time and a
    variable) is sampled at every tick t_j = 0.5 j: the heading after 5 s is the sum of
    0.5 (0.1 t_j + 0.2 k_j), k_j the re-entries at or before t_j (2 s and 4 s): 1.125 + 0.8.
    Held turns at 0.3 throughout, its mode re-entered at 2 s and 4 s: 1.5."""
    import hybridteam as ht
    from hybridteam.engine.compile.compiler import compile_team

    team = team_from_yaml(HELD)
    drivers = {d.owner: d for d in compile_team(team).agents[0].drivers if d.owner >= 0}
    assert [drivers[m].held for m in sorted(drivers)] == [False, True]
    ramp = ht.simulate(team)
    k = [j // 4 for j in range(10)]  # ticks at 0, 0.5, ..., 4.5; re-entries at 2 and 4 s
    expected = sum(0.5 * (0.1 * 0.5 * j + 0.2 * k[j]) for j in range(10))
    assert abs(expected - 1.925) < 1e-12
    assert abs(ramp.samples["r"][-1, 0, 2] - expected) < 1e-12
    held = ht.simulate(team_from_yaml(HELD.replace("initial: Ramp", "initial: Held")))
    assert abs(held.samples["r"][-1, 0, 2] - 1.5) < 1e-12
