"""Statechart semantics against hand-derived transition lists."""

from __future__ import annotations

import hybridteam as ht


def steps(run: ht.Run, agent: str | None = None) -> list[tuple[float, int, str, str]]:
    tr = run.transitions
    rows = [
        (round(r.t, 9), r.step, r.source, r.target)
        for r in tr
        if r.cause != "init" and (agent is None or r.agent == agent)
    ]
    return rows


CLOCK = "plant: {kind: flow, state: {c: 0}}"


def test_outer_transition_preempts_inner(team_from_yaml):
    team = team_from_yaml(f"""
        team: priority
        agents:
          a:
            {CLOCK}
            initial: Outer
            modes:
              Outer:
                initial: Inner1
                transitions: [{{to: Other, after: 1.0}}]
                modes:
                  Inner1: {{transitions: [{{to: Inner2, after: 1.0}}]}}
                  Inner2: {{}}
              Other: {{final: true}}
    """)
    run = ht.simulate(team)
    assert steps(run) == [(1.0, 0, "Outer", "Other")]
    assert run.outcome == "ok"


def test_priority_lets_an_inner_transition_win(team_from_yaml):
    team = team_from_yaml(f"""
        team: priority
        agents:
          a:
            {CLOCK}
            initial: Outer
            modes:
              Outer:
                initial: Inner1
                transitions: [{{to: Other, after: 1.0}}]
                modes:
                  Inner1: {{transitions: [{{to: Inner2, after: 1.0, priority: 1}}]}}
                  Inner2: {{}}
              Other: {{final: true}}
    """)
    run = ht.simulate(team)
    # the inner one fires first; Outer's timer (from t=0) still holds at the next micro-step
    assert steps(run) == [(1.0, 0, "Outer.Inner1", "Outer.Inner2"), (1.0, 1, "Outer", "Other")]


HISTORY = """
    team: history
    agents:
      a:
        plant: {{kind: flow, state: {{c: 0}}}}
        initial: Work
        modes:
          Work:
            history: {kind}
            initial: A
            transitions: [{{to: Break, on: pause}}]
            modes:
              A: {{transitions: [{{to: B, after: 1}}]}}
              B:
                initial: B1
                modes:
                  B1: {{transitions: [{{to: B2, after: 1}}]}}
                  B2: {{transitions: [{{to: B1, after: 10}}]}}
          Break: {{transitions: [{{to: Work, after: 1}}]}}
    scenario: [{{at: 2.5, agent: a, raise: pause}}]
    simulation: {{duration: 6}}
"""


def test_shallow_history_restores_the_child_not_the_grandchild(team_from_yaml):
    run = ht.simulate(team_from_yaml(HISTORY.format(kind="shallow")))
    assert steps(run) == [
        (1.0, 0, "Work.A", "Work.B"),
        (2.0, 0, "Work.B.B1", "Work.B.B2"),
        (2.5, 0, "Work", "Break"),
        (3.5, 0, "Break", "Work"),  # re-enters Work.B (history), then B's initial B1
        (4.5, 0, "Work.B.B1", "Work.B.B2"),
    ]
    leaves = [r.mode for r in run.intervals if r.start == 3.5 and r.depth == 3]
    assert leaves == ["Work.B.B1"]


def test_deep_history_restores_the_whole_configuration(team_from_yaml):
    run = ht.simulate(team_from_yaml(HISTORY.format(kind="deep")))
    assert steps(run) == [
        (1.0, 0, "Work.A", "Work.B"),
        (2.0, 0, "Work.B.B1", "Work.B.B2"),
        (2.5, 0, "Work", "Break"),
        (3.5, 0, "Break", "Work"),  # straight back into Work.B.B2
    ]
    leaves = [r.mode for r in run.intervals if r.start == 3.5 and r.depth == 3]
    assert leaves == ["Work.B.B2"]
    # B2's own timer restarts on re-entry: it would fire at 13.5, after the run ends


def test_no_history_enters_initial_children(team_from_yaml):
    run = ht.simulate(team_from_yaml(HISTORY.format(kind="none")))
    assert steps(run)[3:] == [
        (3.5, 0, "Break", "Work"),
        (4.5, 0, "Work.A", "Work.B"),
        (5.5, 0, "Work.B.B1", "Work.B.B2"),
    ]


def test_parallel_regions_step_together_and_outer_exit_leaves_both(team_from_yaml):
    team = team_from_yaml("""
        team: regions
        agents:
          a:
            plant: {kind: flow, state: {c: 0}}
            initial: Both
            modes:
              Both:
                parallel: true
                transitions: [{to: Stop, after: 3.2}]
                modes:
                  Left:
                    initial: L1
                    modes:
                      L1: {transitions: [{to: L2, after: 1}]}
                      L2: {transitions: [{to: L1, after: 1}]}
                  Right:
                    initial: R1
                    modes:
                      R1: {transitions: [{to: R2, after: 1}]}
                      R2: {transitions: [{to: R3, after: 0.5}]}
                      R3: {}
              Stop: {final: true}
        simulation: {duration: 10}
    """)
    run = ht.simulate(team)
    got = steps(run)
    # both regions fire in the same micro-step at t=1, in declaration (precedence) order
    assert got == [
        (1.0, 0, "Both.Left.L1", "Both.Left.L2"),
        (1.0, 0, "Both.Right.R1", "Both.Right.R2"),
        (1.5, 0, "Both.Right.R2", "Both.Right.R3"),
        (2.0, 0, "Both.Left.L2", "Both.Left.L1"),
        (3.0, 0, "Both.Left.L1", "Both.Left.L2"),
        (3.2, 0, "Both", "Stop"),
    ]
    assert run.outcome == "ok" and run.diagnostics[0]["t"] == 3.2
    closed = {(r.mode, r.start, r.end) for r in run.intervals}
    assert ("Both.Left.L2", 3.0, 3.2) in closed and ("Both.Right.R3", 1.5, 3.2) in closed


def test_after_uses_time_in_the_source_mode_and_expressions(team_from_yaml):
    team = team_from_yaml("""
        team: timers
        agents:
          a:
            plant: {kind: flow, state: {c: 0}}
            parameters: {d: 0.25}
            initial: A
            modes:
              A: {transitions: [{to: B, after: 4 * d}]}
              B: {transitions: [{to: C, after: d, guard: c >= 1.5}]}
              C: {final: true}
            # c stays 0 (no flow): B's guard is false when its timer expires
        simulation: {duration: 3}
    """)
    run = ht.simulate(team)
    assert steps(run) == [(1.0, 0, "A", "B")]
    assert run.outcome == "ok" and run.diagnostics[0]["t"] == 3.0


def test_after_with_guard_fires_when_the_guard_becomes_true(team_from_yaml):
    team = team_from_yaml("""
        team: timers
        agents:
          a:
            plant: {kind: flow, state: {c: 0}}
            initial: A
            modes:
              A:
                flow: {c: 1}
                transitions: [{to: B, after: 0.5, guard: c >= 1.25}]
              B: {final: true}
    """)
    run = ht.simulate(team)
    assert steps(run) == [(1.25, 0, "A", "B")]


def test_messages_and_local_events_in_superdense_time(team_from_yaml):
    team = team_from_yaml("""
        team: pingpong
        agents:
          a:
            plant: {kind: flow, state: {c: 0}}
            initial: Start
            modes:
              Start: {transitions: [{to: Wait, after: 1, do: [{send: ping}]}]}
              Wait: {transitions: [{to: Done, on: pong}]}
              Done: {final: true}
          b:
            plant: {kind: flow, state: {c: 0}}
            initial: Idle
            modes:
              Idle: {transitions: [{to: Got, on: ping, do: [{raise: reply}]}]}
              Got: {transitions: [{to: Done, on: reply, do: [{send: pong, to: a}]}]}
              Done: {final: true}
    """)
    run = ht.simulate(team)
    tr = [(r.t, r.step, r.agent, r.target, r.cause) for r in run.transitions if r.cause != "init"]
    assert tr == [
        (1.0, 0, "a", "Wait", "after"),
        (1.0, 1, "b", "Got", "message:ping"),
        (1.0, 2, "b", "Done", "event:reply"),
        (1.0, 3, "a", "Done", "message:pong"),
    ]
    assert run.outcome == "ok"
    msgs = [(m.sender, m.receiver, m.type, m.t_send, m.t_recv, m.status) for m in run.messages]
    assert msgs == [
        ("a", "b", "ping", 1.0, 1.0, "delivered"),
        ("b", "a", "pong", 1.0, 1.0, "delivered"),
    ]


#: a asks b (who waits only for go) at 0.5 s, then waits for a grant that never comes
STALLED = """\
        team: stalled
        agents:
          a:
            plant: {kind: flow, state: {c: 0}}
            initial: Ask
            modes:
              Ask: {transitions: [{to: Waiting, after: 0.5, do: [{send: request}]}]}
              Waiting: {transitions: [{to: Done, on: grant}]}
              Done: {final: true}
          b:
            plant: {kind: flow, state: {c: 0}}
            initial: Busy
            modes:
              Busy: {transitions: [{to: Done, on: go}]}
              Done: {final: true}
"""


def test_deadlock_when_everyone_waits_and_nothing_is_pending(team_from_yaml):
    team = team_from_yaml(STALLED)
    run = ht.simulate(team)
    assert run.outcome == "deadlock"
    assert run.diagnostics[0]["t"] == 0.5
    msg = run.message
    assert "agent 'a' in Waiting waits for grant" in msg
    assert "agent 'b' in Busy waits for go" in msg


def test_deadlock_found_where_only_a_dropped_message_arrives(team_from_yaml):
    """With 0.03 s of latency the request is in flight from 0.5 s: nothing stalls until it
    arrives at 0.53 s and is dropped (b waits for go). No mode changes at that instant, yet
    nothing is pending any more: the run deadlocks there, not later."""
    team = team_from_yaml(STALLED + "        network: {latency: 0.03}\n")
    run = ht.simulate(team)
    assert run.outcome == "deadlock"
    assert run.diagnostics[0]["t"] == 0.5 + 0.03
    assert [r.t for r in run.transitions if r.cause != "init"] == [0.5]


def test_scenario_event_nobody_waits_for_is_dropped(team_from_yaml):
    team = team_from_yaml("""
        team: drop
        agents:
          a:
            plant: {kind: flow, state: {c: 0}}
            initial: A
            modes:
              A: {transitions: [{to: B, on: go}]}
              B: {final: true}
        scenario:
          - {at: 0.5, agent: a, raise: noise}
          - {at: 1.0, agent: a, raise: go}
    """)
    run = ht.simulate(team)
    assert steps(run) == [(1.0, 0, "A", "B")]


def test_assignments_are_sequential_and_resets_change_state(team_from_yaml):
    team = team_from_yaml("""
        team: resets
        agents:
          a:
            plant: {kind: flow, state: {x: 0}}
            variables: {n: 1}
            initial: A
            modes:
              A:
                flow: {x: 1}
                transitions:
                  - {to: B, guard: x >= 2, do: ["n = n + 1", "n = n * 10", "x = -n"]}
              B: {flow: {x: 1}}
    """)
    run = ht.simulate(team, duration=3.0)
    assert steps(run) == [(2.0, 0, "A", "B")]
    # at t=3 x = -20 + 1 (reset to -n = -20 at t=2, then one second of flow); the crossing
    # at t=2 is located within event_tol (1e-12 s), so x is off by at most that much
    assert abs(run.samples["a"][-1, 0, 0] - (-19.0)) <= 2e-12
