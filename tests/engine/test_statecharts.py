"""Statechart semantics beyond plain hierarchy (issue 49): history on parallel modes,
transitions without a target, regions as sources, against hand-derived traces.

A counter ``n`` is a flow plant's state with no flow (``dn/dt = 0``), so an assignment to
it is a reset the final sample shows exactly.
"""

from __future__ import annotations

import numpy as np
import pytest

import hybridteam as ht


def steps(run: ht.Run) -> list[tuple[float, int, str, str]]:
    return [
        (round(r.t, 9), r.step, r.source, r.target) for r in run.transitions if r.cause != "init"
    ]


def leaves_from(run: ht.Run, t: float) -> list[str]:
    """The leaf modes whose interval starts at ``t`` (entered then), in document order."""
    inner = {r.mode for r in run.intervals if r.start == t}
    return sorted(m for m in inner if not any(o.startswith(m + ".") for o in inner))


def counter(run: ht.Run) -> float:
    """The counter's last sampled value (a run that ends waiting samples NaN after)."""
    values = run.samples["a"][:, 0, 0]
    return float(values[~np.isnan(values)][-1])


PARALLEL_HISTORY = """
    team: parallel_history
    agents:
      a:
        plant: {{kind: flow, state: {{n: 0}}}}
        initial: P
        modes:
          P:
            parallel: true
            history: {kind}
            transitions: [{{to: Out, on: pause}}]
            modes:
              R1:
                initial: a
                modes:
                  a: {{transitions: [{{to: b, after: 1}}]}}
                  b:
                    initial: b1
                    modes:
                      b1: {{transitions: [{{to: b2, after: 0.25}}]}}
                      b2: {{}}
              R2:
                initial: c
                modes:
                  c: {{transitions: [{{to: d, after: 1}}]}}
                  d: {{}}
          Out: {{transitions: [{{to: P, after: 1}}]}}
    scenario: [{{at: 1.5, agent: a, raise: pause}}]
    simulation: {{duration: 3}}
"""


@pytest.mark.parametrize(
    ("kind", "back"),
    [
        ("none", ["P.R1.a", "P.R2.c"]),
        ("shallow", ["P.R1.b.b1", "P.R2.d"]),  # each region's child, b's initial below it
        ("deep", ["P.R1.b.b2", "P.R2.d"]),  # the whole configuration
    ],
)
def test_history_on_a_parallel_mode_restores_its_regions(team_from_yaml, kind, back):
    run = ht.simulate(team_from_yaml(PARALLEL_HISTORY.format(kind=kind)))
    assert steps(run)[:4] == [
        (1.0, 0, "P.R1.a", "P.R1.b"),
        (1.0, 0, "P.R2.c", "P.R2.d"),
        (1.25, 0, "P.R1.b.b1", "P.R1.b.b2"),
        (1.5, 0, "P", "Out"),
    ]
    assert steps(run)[4] == (2.5, 0, "Out", "P")
    assert leaves_from(run, 2.5) == back


def test_a_transition_without_target_on_a_region_runs_in_place(team_from_yaml):
    team = team_from_yaml("""
        team: region_internal
        agents:
          a:
            plant: {kind: flow, state: {n: 0}}
            initial: P
            modes:
              P:
                parallel: true
                modes:
                  R1:
                    initial: a
                    transitions: [{on: ping, do: ["n = n + 1"]}]
                    modes:
                      a: {transitions: [{to: b, after: 1}]}
                      b: {}
                  R2:
                    initial: c
                    modes:
                      c: {transitions: [{to: d, guard: n >= 2}]}
                      d: {}
        scenario: [{at: 0.5, agent: a, raise: ping}, {at: 2, agent: a, raise: ping}]
        simulation: {duration: 3}
    """)
    run = ht.simulate(team)
    assert steps(run) == [
        (0.5, 0, "P.R1", "P.R1"),
        (1.0, 0, "P.R1.a", "P.R1.b"),
        (2.0, 0, "P.R1", "P.R1"),
        (2.0, 1, "P.R2.c", "P.R2.d"),
    ]
    # (R2 moved at 2: n reached 2.) R1's child b was not left by the second ping: one
    # interval of it, from 1 to the end of the run
    assert [(r.start, r.end) for r in run.intervals if r.mode == "P.R1.b"] == [(1.0, 2.0)]


OUTER_INTERNAL = """
    team: outer_internal
    agents:
      a:
        plant: {{kind: flow, state: {{n: 0}}}}
        initial: S
        modes:
          S:
            initial: a
            transitions: [{{on: go, do: ["n = n + 1"]{outer}}}]
            modes:
              a: {{transitions: [{{to: b, on: go, do: ["n = n * 10"]}}]}}
              b: {{}}
          T: {{}}
    scenario: [{{at: 1, agent: a, raise: go}}]
    simulation: {{duration: 2}}
"""


def test_a_transition_without_target_exits_nothing_so_inner_ones_still_fire(team_from_yaml):
    """The outer transition exits nothing: it neither blocks nor is blocked by the inner
    one on the same event. Outer first: n = (0 + 1) * 10."""
    run = ht.simulate(team_from_yaml(OUTER_INTERNAL.format(outer="")))
    assert steps(run) == [(1.0, 0, "S", "S"), (1.0, 0, "S.a", "S.b")]
    assert counter(run) == 10.0


def test_an_outer_transition_that_leaves_still_preempts_the_inner_one(team_from_yaml):
    run = ht.simulate(team_from_yaml(OUTER_INTERNAL.format(outer=", to: T")))
    assert steps(run) == [(1.0, 0, "S", "T")]
    assert counter(run) == 1.0


REGION_SELF = """
    team: region_self
    agents:
      a:
        plant: {{kind: flow, state: {{n: 0}}}}
        initial: P
        modes:
          P:
            parallel: true
            modes:
              R1:
                initial: a
                transitions: [{{on: reset, to: {target}}}]
                modes:
                  a: {{transitions: [{{to: b, after: 1}}]}}
                  b: {{}}
              R2:
                initial: c
                modes:
                  c: {{transitions: [{{to: d, after: 1}}]}}
                  d: {{}}
    scenario: [{{at: 1.5, agent: a, raise: reset}}]
    simulation: {{duration: 2}}
"""


@pytest.mark.parametrize(
    ("target", "back"),
    [("R1", ["P.R1.a", "P.R2.c"]), ("R1.b", ["P.R1.b", "P.R2.c"]), ("R2.d", ["P.R1.a", "P.R2.d"])],
)
def test_a_region_to_itself_leaves_and_reenters_every_region(team_from_yaml, target, back):
    """The transition's domain is the parallel mode P: both regions are left and entered
    again (R2 by default), P itself stays active (one interval of it, to the end)."""
    run = ht.simulate(team_from_yaml(REGION_SELF.format(target=target)))
    assert steps(run)[2] == (1.5, 0, "P.R1", f"P.{target}")
    assert leaves_from(run, 1.5) == back
    closed = {(r.mode, r.start, r.end) for r in run.intervals}
    assert ("P.R2.d", 1.0, 1.5) in closed and ("P.R2", 0.0, 1.5) in closed
    assert [(r.start, r.end) for r in run.intervals if r.mode == "P"] == [(0.0, 2.0)]


def test_a_parallel_domain_runs_its_regions_exit_and_entry_actions_not_its_own(team_from_yaml):
    """SCION's more-parallel/test10b: x counts P's and a's entries and exits; a -> a
    leaves and re-enters a, not P: x = 2 (entering P, a), then 4."""
    team = team_from_yaml("""
        team: domain_actions
        agents:
          a:
            plant: {kind: flow, state: {x: 0}}
            initial: P
            modes:
              P:
                parallel: true
                entry: ["x = x + 1"]
                exit: ["x = x + 1"]
                modes:
                  a:
                    entry: ["x = x + 1"]
                    exit: ["x = x + 1"]
                    transitions: [{to: a, on: t1, guard: x == 2}]
                  b: {}
        scenario: [{at: 1, agent: a, raise: t1}]
        simulation: {duration: 2, sample_period: 0.5}
    """)
    run = ht.simulate(team)
    assert steps(run) == [(1.0, 0, "P.a", "P.a")]
    assert counter(run) == 4.0


def test_entry_and_exit_actions_run_in_statechart_order(team_from_yaml):
    """Each action appends a digit to n. Entering: outermost first, regions in document
    order (P 1, R1 2, a 3, R2 4, c 5). Leaving P for Q: innermost first, regions in
    reverse order (c 8, R2 9, a 6, R1 7, P 0), the transition's own action (1), then Q's
    entry (2)."""
    team = team_from_yaml("""
        team: order
        agents:
          a:
            plant: {kind: flow, state: {n: 0}}
            initial: P
            modes:
              P:
                parallel: true
                entry: ["n = n * 10 + 1"]
                exit: ["n = n * 10"]
                transitions: [{to: Q, on: go, do: ["n = n * 10 + 1"]}]
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
              Q: {entry: ["n = n * 10 + 2"], transitions: [{to: P, on: never}]}
        scenario: [{at: 1, agent: a, raise: go}]
        simulation: {duration: 2, sample_period: 0.5}
    """)
    run = ht.simulate(team)
    values = run.samples["a"][:, 0, 0]
    assert values[0] == 12345.0
    assert counter(run) == 123458967012.0


def test_entry_actions_run_before_the_modes_delays_are_armed(team_from_yaml):
    """B's entry sets its own delay: 'after: d' reads the d just assigned (2, not 0)."""
    team = team_from_yaml("""
        team: entry_delay
        agents:
          a:
            plant: {kind: flow, state: {n: 0}}
            variables: {d: 0}
            initial: A
            modes:
              A: {transitions: [{to: B, after: 1}]}
              B:
                entry: ["d = 2", {raise: hello}]
                transitions: [{to: C, after: d}, {to: B, on: hello, guard: d > 5}]
              C: {final: true}
    """)
    assert steps(ht.simulate(team)) == [(1.0, 0, "A", "B"), (3.0, 0, "B", "C")]


def test_an_internal_transition_runs_no_entry_or_exit_actions(team_from_yaml):
    team = team_from_yaml("""
        team: internal_actions
        agents:
          a:
            plant: {kind: flow, state: {n: 0}}
            initial: S
            modes:
              S:
                entry: ["n = n + 1"]
                exit: ["n = n + 100"]
                transitions: [{on: tick, do: ["n = n + 10"]}, {to: S, on: again}]
        scenario: [{at: 1, agent: a, raise: tick}, {at: 2, agent: a, raise: again}]
        simulation: {duration: 3, sample_period: 0.5}
    """)
    # 1 on entry; +10 at t=1 (internal); at 2 the self-transition exits (+100), enters (+1)
    assert counter(ht.simulate(team)) == 112.0


IN_MODE = """
    team: in_mode
    agents:
      a:
        plant: {{kind: flow, state: {{n: 0}}}}
        initial: P
        modes:
          P:
            parallel: true
            modes:
              R1:
                initial: a
                modes:
                  a: {{transitions: [{{to: b, after: 1}}]}}
                  b: {{}}
              R2:
                initial: c
                modes:
                  c: {{transitions: [{{to: d, on: go, guard: "{guard}"}}]}}
                  d: {{}}
    scenario: [{{at: 0.5, agent: a, raise: go}}, {{at: 1.5, agent: a, raise: go}}]
    simulation: {{duration: 2}}
"""


@pytest.mark.parametrize(
    ("guard", "when"),
    [
        ("in_mode(R1.b)", 1.5),
        ("in_mode(b)", 1.5),
        ("not in_mode(P.R1.b)", 0.5),
        ("in_mode(R1) and n == 0", 0.5),
    ],
)
def test_in_mode_reads_the_agents_own_configuration(team_from_yaml, guard, when):
    run = ht.simulate(team_from_yaml(IN_MODE.format(guard=guard)))
    assert (when, 0, "P.R2.c", "P.R2.d") in steps(run)
    assert len([s for s in steps(run) if s[2] == "P.R2.c"]) == 1


@pytest.mark.parametrize(
    ("guard", "message"),
    [
        ("in_mode(R1.x)", "agent 'a' has no mode 'R1.x'"),
        ("in_mode(other.b)", "agent 'a' has no mode 'other.b'"),
        ("in_mode(b, c)", r"in_mode\(\) takes one mode name"),
        ("in_mode(1)", r"in_mode\(\) takes one mode name"),
        ("in_mode(b) + 1 > 0", "'\\+' needs a number, but this is a condition"),
    ],
)
def test_in_mode_with_a_wrong_argument_is_a_located_error(team_from_yaml, guard, message):
    from hybridteam.io.filekind import InputErrors

    with pytest.raises(InputErrors, match=r"team\.yaml:19:\d+: .*guard: " + message):
        team_from_yaml(IN_MODE.format(guard=guard))


def test_in_mode_stays_out_of_flows(team_from_yaml):
    from hybridteam.io.filekind import InputErrors

    with pytest.raises(InputErrors, match="belongs to requirement formulas"):
        team_from_yaml(
            IN_MODE.format(guard="n == 0").replace("b: {}", "b: {flow: {n: in_mode(a)}}")
        )


DOOR = """
    team: door
    agents:
      door:
        plant: {kind: flow, state: {n: 0}}
        variables: {opened: 0}
        initial: Closed
        modes:
          Closed:
            entry: [{raise: locked}]
            transitions: [{to: Open, on: push}]
          Open:
            initial: Moving
            entry: ["opened = opened + 1"]
            exit: [{send: closed}]
            transitions: [{to: Closed, on: pull}]
            modes:
              Moving:
                exit: ["n = 0"]
                transitions: [{to: Still, after: 1}]
              Still: {}
"""


def test_diagrams_show_entry_and_exit_actions(team_from_yaml):
    from hybridteam.export.diagram import diagram_graph
    from hybridteam.export.render import render

    graph = diagram_graph(team_from_yaml(DOOR))
    node = graph.nodes
    assert node["door/Closed"]["behaviour"] == ["entry / raise locked"]
    assert node["door/Open"]["behaviour"] == ["entry / opened = opened + 1", "exit / send closed"]
    assert node["door/Open.Still"]["behaviour"] == []
    dot = render(graph, "dot")
    assert 'label="Closed\\nentry / raise locked"' in dot
    assert 'label="Open\\nentry / opened = opened + 1\\nexit / send closed"' in dot
    mermaid = render(graph, "mermaid").splitlines()
    assert "        door__Open : exit / send closed" in mermaid
    assert "            door__Open__Moving : exit / n = 0" in mermaid


def test_the_built_in_image_draws_actions_inside_their_boxes(team_from_yaml):
    """A leaf's actions are lines of its box; a composite's follow its title in the title
    bar, which is measured to hold them."""
    from hybridteam.export.diagram import diagram_graph
    from hybridteam.export.image import diagram_figure
    from hybridteam.export.layout import Layout

    graph = diagram_graph(team_from_yaml(DOOR))
    fig = diagram_figure(graph, dpi=72.0)
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    texts = {t.get_text(): t.get_window_extent(renderer) for t in fig.axes[0].texts}
    layout = Layout(graph)
    closed, moving = layout.boxes["door/Closed"], layout.boxes["door/Open.Moving"]
    assert "entry / raise locked" in closed.lines and "exit / n = 0" in moving.lines
    caption = "entry / opened = opened + 1   exit / send closed"
    title, actions = texts["Open"], texts[caption]
    assert actions.x0 > title.x1  # after the title, on its line
    assert abs(actions.y1 - title.y1) < title.height
    # the title bar is measured for both, so the caption ends inside the composite's box
    # (data units are the layout's points)
    box = layout.boxes["door/Open"]
    right = fig.axes[0].transData.inverted().transform((actions.x1, actions.y1))[0]
    assert box.x + _title_width(layout, "Open") < right < box.x + box.title_w <= box.x + box.w


def _title_width(layout, name: str) -> float:
    from hybridteam.export.layout import NAME_PT, _text_width

    return _text_width([name], NAME_PT)


DEEP_INITIAL = """
    team: deep_initial
    agents:
      a:
        plant: {{kind: flow, state: {{n: 0}}}}
        initial: {top}
        modes:
          S:
            initial: {initial}
            {history}
            transitions: [{{to: Out, on: leave}}]
            modes:
              A:
                initial: a1
                modes:
                  a1: {{transitions: [{{to: a2, after: 1}}]}}
                  a2: {{}}
              P:
                parallel: true
                modes:
                  R1: {{initial: x1, modes: {{x1: {{}}, x2: {{}}}}}}
                  R2: {{initial: y1, modes: {{y1: {{}}, y2: {{}}}}}}
          Out: {{transitions: [{{to: S, on: back}}]}}
    scenario: [{{at: 2, agent: a, raise: leave}}, {{at: 3, agent: a, raise: back}}]
    simulation: {{duration: 4}}
"""


@pytest.mark.parametrize(
    ("initial", "start"),
    [
        ("A", ["S.A.a1"]),
        ("a2", ["S.A.a2"]),
        ("A.a2", ["S.A.a2"]),
        ("x2", ["S.P.R1.x2", "S.P.R2.y1"]),
        ("P.R2.y2", ["S.P.R1.x1", "S.P.R2.y2"]),
    ],
)
def test_initial_may_name_a_deeper_descendant(team_from_yaml, initial, start):
    """The way down is entered, a parallel mode on it enters its other regions by default;
    re-entering S by a transition takes the same way."""
    run = ht.simulate(team_from_yaml(DEEP_INITIAL.format(top="S", initial=initial, history="")))
    assert leaves_from(run, 0.0) == start
    assert leaves_from(run, 3.0) == start


@pytest.mark.parametrize(
    ("history", "back"),
    [
        # nothing remembered yet at t=0 (S was never left): the history default; at t=3 S's
        # remembered child A is restored, and below it A's initial a1 (shallow history)
        ("history: {kind: shallow, default: a2}", ["S.A.a1"]),
        ("history: {kind: deep, default: a2}", ["S.A.a2"]),
        ("history: shallow", ["S.A.a1"]),
    ],
)
def test_a_history_default_is_entered_while_nothing_is_remembered(team_from_yaml, history, back):
    team = team_from_yaml(
        DEEP_INITIAL.format(top="Out", initial="P", history=history).replace(
            "{at: 2, agent: a, raise: leave}",
            "{at: 0.5, agent: a, raise: back}, {at: 2, agent: a, raise: leave}",
        )
    )
    run = ht.simulate(team)
    first = ["S.P.R1.x1", "S.P.R2.y1"] if history == "history: shallow" else ["S.A.a2"]
    assert leaves_from(run, 0.5) == first
    if history != "history: shallow":
        assert leaves_from(run, 3.0) == back


def test_several_targets_enter_one_mode_in_each_region(team_from_yaml):
    team = team_from_yaml("""
        team: fork
        agents:
          a:
            plant: {kind: flow, state: {n: 0}}
            initial: Idle
            modes:
              Idle: {transitions: [{to: [R2.y2, R1.x2], on: go, do: ["n = n * 10 + 3"]}]}
              P:
                parallel: true
                modes:
                  R1:
                    initial: x1
                    modes:
                      x1: {}
                      x2: {entry: ["n = n * 10 + 1"]}
                  R2:
                    initial: y1
                    modes:
                      y1: {}
                      y2: {entry: ["n = n * 10 + 2"]}
                  R3: {initial: z1, modes: {z1: {}, z2: {}}}
        scenario: [{at: 1, agent: a, raise: go}]
        simulation: {duration: 2, sample_period: 0.5}
    """)
    run = ht.simulate(team)
    assert steps(run) == [(1.0, 0, "Idle", "P.R2.y2")]  # (the record names the first)
    assert leaves_from(run, 1.0) == ["P.R1.x2", "P.R2.y2", "P.R3.z1"]
    assert counter(run) == 312.0  # the transition's action, then entries in document order


@pytest.mark.parametrize(
    ("to", "message"),
    [
        ("[R1.x2, R1.x1]", "targets 'P.R1.x2' and 'P.R1.x1' are not in different regions"),
        ("[P, R1.x1]", "targets 'P' and 'P.R1.x1' are not in different regions"),
        ("[R1.x2, nowhere]", "unknown mode 'nowhere'"),
        ("[]", "at least 1 item"),
    ],
)
def test_several_targets_in_one_region_are_refused(team_from_yaml, to, message):
    from hybridteam.io.filekind import InputErrors

    with pytest.raises(InputErrors, match=message):
        team_from_yaml(f"""
            team: bad_fork
            agents:
              a:
                plant: {{kind: flow, state: {{n: 0}}}}
                initial: Idle
                modes:
                  Idle: {{transitions: [{{to: {to}, on: go}}]}}
                  P:
                    parallel: true
                    modes:
                      R1: {{initial: x1, modes: {{x1: {{}}, x2: {{}}}}}}
                      R2: {{initial: y1, modes: {{y1: {{}}, y2: {{}}}}}}
        """)


@pytest.mark.parametrize(
    ("key", "value", "message"),
    [
        ("initial", "Out", "unknown initial mode 'Out'"),
        ("initial", "zz", "unknown initial mode 'zz'"),
        ("history", "{kind: deep, default: y9}", "unknown history default 'y9'"),
    ],
)
def test_an_initial_or_history_default_outside_the_mode_is_refused(
    team_from_yaml, key, value, message
):
    from hybridteam.io.filekind import InputErrors

    text = DEEP_INITIAL.format(top="S", initial="A", history="")
    text = text.replace(
        "initial: A\n",
        f"{key}: {value}\n" + ("            initial: A\n" if key == "history" else ""),
    )
    with pytest.raises(InputErrors, match=message):
        team_from_yaml(text)


def test_a_history_default_on_a_parallel_mode_is_refused(team_from_yaml):
    from hybridteam.io.filekind import InputErrors

    text = PARALLEL_HISTORY.format(kind="{kind: shallow, default: R1.b}")
    with pytest.raises(
        InputErrors,
        match=r"team\.yaml:10:43: .*history\.default: a history "
        "default .*give it to a region",
    ):
        team_from_yaml(text)


def test_a_transition_with_several_targets_is_drawn_to_each(team_from_yaml):
    from hybridteam.export.diagram import diagram_graph, edges_of

    team = team_from_yaml("""
        team: fork
        agents:
          a:
            plant: {kind: flow, state: {n: 0}}
            initial: Idle
            modes:
              Idle: {transitions: [{to: [R1.x2, R2.y2], on: go}]}
              P:
                parallel: true
                modes:
                  R1: {initial: x1, modes: {x1: {}, x2: {}}}
                  R2: {initial: y1, modes: {y1: {}, y2: {}}}
    """)
    assert [(u, v, d["label"]) for u, v, d in edges_of(diagram_graph(team), "transition")] == [
        ("a/Idle", "a/P.R1.x2", "go"),
        ("a/Idle", "a/P.R2.y2", "go"),
    ]


NESTED_EVENT = """
    team: nested_event
    {semantics}
    agents:
      a:
        plant: {{kind: flow, state: {{n: 0}}}}
        initial: S
        modes:
          S:
            initial: a
            transitions: [{{on: go, {outer}do: ["n = n * 10 + 1"]}}]
            modes:
              a: {{transitions: [{{to: b, on: go, do: ["n = n * 10 + 2"]}}]}}
              b: {{}}
          T: {{}}
    scenario: [{{at: 1, agent: a, raise: go}}]
    simulation: {{duration: 2}}
"""


@pytest.mark.parametrize(
    ("semantics", "outer", "fired", "n"),
    [
        ("", "to: T, ", [(1.0, 0, "S", "T")], 1.0),
        ("semantics: {priority: outer_first}", "to: T, ", [(1.0, 0, "S", "T")], 1.0),
        ("semantics: {priority: inner_first}", "to: T, ", [(1.0, 0, "S.a", "S.b")], 2.0),
        # without a target the outer one exits nothing: outer first, both fire (outer's action
        # first); inner first, the inner one is chosen for the active leaf, as in SCXML
        ("", "", [(1.0, 0, "S", "S"), (1.0, 0, "S.a", "S.b")], 12.0),
        ("semantics: {priority: inner_first}", "", [(1.0, 0, "S.a", "S.b")], 2.0),
    ],
)
def test_the_priority_rule_picks_outer_or_inner_transitions(
    team_from_yaml, semantics, outer, fired, n
):
    run = ht.simulate(team_from_yaml(NESTED_EVENT.format(semantics=semantics, outer=outer)))
    assert steps(run) == fired
    assert counter(run) == n


def test_inner_first_lets_the_inner_urgent_transition_go_before_the_outer(team_from_yaml):
    team = team_from_yaml("""
        team: urgent
        semantics: {priority: inner_first}
        agents:
          a:
            plant: {kind: flow, state: {c: 0}}
            initial: Outer
            modes:
              Outer:
                initial: Inner1
                transitions: [{to: Other, after: 1.0}]
                modes:
                  Inner1: {transitions: [{to: Inner2, after: 1.0}]}
                  Inner2: {}
              Other: {final: true}
    """)
    # the inner one at (1, 0); Outer's delay, counted from 0, still holds at (1, 1)
    assert steps(ht.simulate(team)) == [
        (1.0, 0, "Outer.Inner1", "Outer.Inner2"),
        (1.0, 1, "Outer", "Other"),
    ]


REGIONS_RACE = """
    team: race
    {semantics}
    agents:
      a:
        plant: {{kind: flow, state: {{n: 0}}}}
        initial: P
        modes:
          P:
            parallel: true
            modes:
              R1:
                initial: a
                modes:
                  a: {r1}
              R2:
                initial: c
                modes:
                  c: {r2}
          X: {{}}
          Y: {{}}
    scenario: [{{at: 1, agent: a, raise: go}}]
    simulation: {{duration: 2}}
"""
LEAF_X = "{transitions: [{to: X, on: go}]}"
LEAF_Y = "{transitions: [{to: Y, on: go}]}"
DEEP_X = "{initial: a1, modes: {a1: {transitions: [{to: X, on: go}]}}}"
DEEP_Y = "{initial: c1, modes: {c1: {transitions: [{to: Y, on: go}]}}}"


@pytest.mark.parametrize(
    ("rule", "r1", "r2", "winner"),
    [
        # both leave P: one fires. Outer first: the shallower source; at equal depth the
        # region written first. Inner first: the region written first (SCXML's document order:
        # neither source is inside the other), whatever the depths.
        ("outer_first", LEAF_X, LEAF_Y, "X"),
        ("outer_first", DEEP_X, LEAF_Y, "Y"),
        ("outer_first", LEAF_X, DEEP_Y, "X"),
        ("inner_first", LEAF_X, LEAF_Y, "X"),
        ("inner_first", DEEP_X, LEAF_Y, "X"),
        ("inner_first", LEAF_X, DEEP_Y, "X"),
    ],
)
def test_between_regions_the_rules_differ_only_in_depth(team_from_yaml, rule, r1, r2, winner):
    run = ht.simulate(
        team_from_yaml(
            REGIONS_RACE.format(semantics=f"semantics: {{priority: {rule}}}", r1=r1, r2=r2)
        )
    )
    assert [s[3] for s in steps(run)] == [winner]


def test_an_unknown_priority_rule_is_a_located_error(team_from_yaml):
    from hybridteam.io.filekind import InputErrors

    with pytest.raises(
        InputErrors,
        match=r"team\.yaml:3:\d+: semantics\.priority: .*"
        "expected one of 'outer_first', 'inner_first', got 'scxml'",
    ):
        team_from_yaml(NESTED_EVENT.format(semantics="semantics: {priority: scxml}", outer=""))


def test_a_transition_on_an_event_name_is_woken_by_its_dotted_descendants(team_from_yaml):
    """As SCXML's event descriptors: 'on: foo' takes foo and foo.bar.bat, not foobar."""
    team = team_from_yaml("""
        team: prefixes
        agents:
          a:
            plant: {kind: flow, state: {n: 0}}
            initial: A
            modes:
              A: {transitions: [{to: B, on: foo}]}
              B: {transitions: [{to: C, on: foo.bar}]}
              C: {transitions: [{to: D, on: foo}]}
              D: {}
        scenario:
          - {at: 1, agent: a, raise: foo.bar.bat}
          - {at: 2, agent: a, raise: foo}
          - {at: 3, agent: a, raise: foo.bar}
          - {at: 4, agent: a, raise: foobar}
          - {at: 5, agent: a, raise: foo.barn}
        simulation: {duration: 6}
    """)
    # at 2 'foo' is not foo.bar; at 4 'foobar' is not foo.*; at 5 'foo.barn' is
    assert steps(ht.simulate(team)) == [(1.0, 0, "A", "B"), (3.0, 0, "B", "C"), (5.0, 0, "C", "D")]


LOCAL = """
    team: local
    agents:
      a:
        plant: {{kind: flow, state: {{n: 0}}}}
        initial: S
        modes:
          S:
            initial: a1
            entry: ["n = n * 10 + 1"]
            exit: ["n = n * 10 + 2"]
            transitions: [{{to: a2, on: go{local}}}]
            modes:
              a1: {{exit: ["n = n * 10 + 3"]}}
              a2: {{entry: ["n = n * 10 + 4"]}}
    scenario: [{{at: 1, agent: a, raise: go}}]
    simulation: {{duration: 2, sample_period: 0.5}}
"""


@pytest.mark.parametrize(
    ("local", "n", "s_intervals"),
    [
        # external: a1 (3), S (2) exit; S (1), a2 (4) enter
        # (the run ends at 1: nothing is left to wait for)
        ("", 13214.0, [(0.0, 1.0), (1.0, 1.0)]),
        # local: S is neither left nor entered: a1 exits (3), a2 enters (4)
        (", local: true", 134.0, [(0.0, 1.0)]),
    ],
)
def test_a_local_transition_stays_in_its_source(team_from_yaml, local, n, s_intervals):
    run = ht.simulate(team_from_yaml(LOCAL.format(local=local)))
    assert steps(run) == [(1.0, 0, "S", "S.a2")]
    assert counter(run) == n
    assert [(r.start, r.end) for r in run.intervals if r.mode == "S"] == s_intervals


def test_a_local_transition_must_target_inside_its_source(team_from_yaml):
    from hybridteam.io.filekind import InputErrors

    text = LOCAL.format(local=", local: true").replace("to: a2", "to: S")
    with pytest.raises(
        InputErrors,
        match=r"team\.yaml:12:\d+: .*local: a local transition "
        "stays inside its source: its targets must be modes inside 'S'",
    ):
        team_from_yaml(text)


def test_modes_entered_by_several_targets_or_a_deep_initial_are_reachable(team_from_yaml):
    from hybridteam.io.check import check_team

    team = team_from_yaml("""
        team: reach
        agents:
          a:
            plant: {kind: flow, state: {n: 0}}
            initial: Idle
            modes:
              Idle: {transitions: [{to: [R1.x2, R2.y2], on: go}]}
              P:
                parallel: true
                transitions: [{to: Q, on: back}]
                modes:
                  R1: {initial: x1, modes: {x1: {}, x2: {}}}
                  R2: {initial: y1, modes: {y1: {}, y2: {}}}
              Q:
                initial: q2
                modes:
                  Q1: {initial: q1, modes: {q1: {}, q2: {}}}
    """)
    assert [w.message for w in check_team(team) if "unreachable" in w.message] == []
