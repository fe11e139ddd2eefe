"""The roles view of a state diagram: protocol states summarised by role (Fig. 4 level).

Expected graphs are read off the role_assignment protocol file by hand: a follower becomes
a leader when a grant answers its request (``want_lead`` raised it) or a confirm answers its
acceptance of an offer; a leader becomes a follower on a request, or, offering (after
``resign``), on an accept or a request.
"""

from __future__ import annotations

import itertools

import pytest

import hybridteam as ht
from hybridteam.cli import main
from hybridteam.export.diagram import diagram_graph, edges_of
from hybridteam.export.render import render
from hybridteam.export.roles import roles_view
from tests.conftest import EXAMPLES, FIXTURES

EXPERIMENT2 = EXAMPLES / "transport" / "experiment2.yaml"


@pytest.fixture(scope="module")
def views():
    full = diagram_graph(ht.load(EXPERIMENT2))
    return full, roles_view(full)


def test_one_state_per_role_with_its_body(views):
    full, roles = views
    transport = sorted(n for n in roles if n.startswith("xr4000/Transport"))
    assert transport == [
        "xr4000/Transport",
        "xr4000/Transport.Follow",
        "xr4000/Transport.Lead",
        "xr4000/Transport.Lead.Hold",
        "xr4000/Transport.Lead.Pass",
        "xr4000/Transport.Lead.Sidestep",
        "xr4000/Transport.Operated",
    ]
    assert "labmate/Transport.Lead.Curve" in roles
    assert not any("Offering" in n or "Requesting" in n or "Accepting" in n for n in roles)
    assert "operator" not in roles and "operator/Standby" not in roles  # protocol-only agent
    # the Dock modes are the team's own: untouched
    assert {n for n in full if "Dock" in n} <= set(roles)


def test_role_changes_are_one_edge_per_pair_labelled_by_handshakes(views):
    _, roles = views
    edges = {
        (u, v): d["label"]
        for u, v, d in edges_of(roles, "transition")
        if d["protocol"] and u.startswith("labmate/")
    }
    t = "labmate/Transport."
    assert edges == {
        (t + "Follow", t + "Lead"): "want_lead … grant, offer … confirm",
        (t + "Lead", t + "Follow"): "request, resign … accept, resign … request",
        (t + "Lead", t + "Operated"): "halt, after(answer_timeout), undeliverable",
        (t + "Follow", t + "Operated"): "undeliverable, halt, after(answer_timeout)",
    }


def test_own_transitions_stay_and_body_copies_go(views):
    full, roles = views
    own = [(u, v, d["label"]) for u, v, d in edges_of(roles, "transition") if not d["protocol"]]
    # the XR4000's follow body asks to lead when it sees the obstacle: drawn once, on Follow
    # (the full diagram has it on Follow, Requesting and Accepting, the body's three copies)
    loops = [e for e in own if "obstacle_detected" in e[2]]
    assert [(u, v) for u, v, _ in loops] == [("xr4000/Transport.Follow",) * 2]
    assert sum("obstacle_detected" in d["label"] for _, _, d in edges_of(full, "transition")) == 3
    assert ("xr4000/Transport.Lead.Sidestep", "xr4000/Transport.Lead.Pass", "after(4)") in own


def test_protocol_messages_become_one_link_per_pair_of_robots(views):
    full, roles = views
    messages = [(u, v, d["label"]) for u, v, d in edges_of(roles, "message")]
    assert messages == [
        ("xr4000/Dock.Lift", "labmate/Dock.Idle", "docked"),
        ("labmate/Dock.Align", "xr4000/Dock.Wait", "ready"),
        ("xr4000/Transport", "labmate/Transport", "role_assignment ⇄"),
    ]
    assert len(edges_of(full, "message")) > 20
    assert [
        d["order"] for *_, d in sorted(roles.edges(data=True), key=lambda e: e[2]["order"])
    ] == list(range(roles.number_of_edges()))


def test_a_team_without_protocols_is_drawn_as_it_is():
    full = diagram_graph(ht.load(EXAMPLES / "automata" / "relay.yaml"))
    roles = roles_view(full)
    assert render(roles, "dot") == render(full, "dot")


def test_cli_detail_and_run_views(tmp_path):
    out = tmp_path / "d.dot"
    assert main(["diagram", str(EXPERIMENT2), "-o", str(out)]) == 0
    assert "Requesting" not in out.read_text() and "Lead" in out.read_text()
    assert main(["diagram", str(EXPERIMENT2), "--detail", "full", "-o", str(out)]) == 0
    assert "Requesting" in out.read_text()
    run_out = tmp_path / "run"
    assert (
        main(
            [
                "run",
                str(EXAMPLES / "protocols" / "handover.yaml"),
                "-o",
                str(run_out),
                "--quiet",
                "--duration",
                "1",
            ]
        )
        == 0
    )
    assert "Requesting" in (run_out / "modes-full.svg").read_text()
    assert "Requesting" not in (run_out / "modes.svg").read_text()


def test_protocol_copies_are_tints_of_their_role_and_24_modes_get_24_colours():
    from hybridteam.export.style import PALETTE, team_mode_colors

    colors = team_mode_colors(
        [
            [
                ("T", False, ""),
                ("T.Lead", False, "lead"),
                ("T.Lead.A", False, ""),
                ("T.Offering", False, "lead"),
                ("T.Offering.A", False, ""),
                ("T.Follow", False, "follow"),
                ("T.Requesting", False, "follow"),
                ("T.Accepting", False, "follow"),
            ]
        ]
    )
    assert [colors[p] for p in ("T", "T.Lead", "T.Lead.A", "T.Follow")] == list(PALETTE[:4])
    # 45 % white on #009E73 (0, 158, 115) -> (115, 202, 178); 70 % on #CC79A7 -> (240, 215, 229)
    assert colors["T.Offering.A"] == "#73CAB2"
    assert colors["T.Accepting"] == "#F0D7E5"
    assert colors["T.Requesting"] != colors["T.Accepting"]
    many = team_mode_colors([[(f"M{k}", False) for k in range(24)]])
    assert len(set(many.values())) == 24


def test_three_robots_stack_in_rows_and_a_repeated_footnote_is_said_once():
    """The corridor team's roles view: three robots of 486, 416 and 408 pt side by side
    (with 80 pt between) made a diagram 1,486 pt wide; past ROW_WIDTH they wrap, here one
    robot a row, each row below the last. The three robots' Lead/Follow edges do not fit
    their label and carry the same footnote: one note, marked (1) on each edge."""
    from hybridteam.export.image import diagram_figure
    from hybridteam.export.layout import PANEL_GAP, ROW_WIDTH, Layout

    graph = roles_view(diagram_graph(ht.load(FIXTURES / "acceptance" / "corridor_carry.yaml")))
    layout = Layout(graph)
    widths = [p.w + p.loop for p in layout.panels]
    assert widths[0] + PANEL_GAP + widths[1] > ROW_WIDTH
    xs = [p.x for p in layout.panels]
    assert xs == [xs[0]] * 3
    for upper, lower in itertools.pairwise(layout.panels):
        assert lower.y == upper.y + upper.h + PANEL_GAP
    assert layout.width <= max(widths) + 2 * 8.0 + PANEL_GAP / 2 < ROW_WIDTH
    texts = diagram_figure(graph, dpi=72.0).axes[0].texts
    (notes,) = [t.get_text() for t in texts if t.get_gid() == "footnotes"]
    assert notes == "(1) want_lead … grant, offer … confirm"
    assert [t.get_text() for t in texts if t.get_gid() == "edge-label"].count("(1)") == 3


def test_two_robots_that_fit_a_page_stay_side_by_side():
    """The hand-over's two robots (396 and 404 pt, 80 pt apart: 880 pt) fit one row."""
    from hybridteam.export.layout import PANEL_GAP, Layout

    layout = Layout(roles_view(diagram_graph(ht.load(EXAMPLES / "protocols" / "handover.yaml"))))
    first, second = layout.panels
    assert first.y == second.y and second.x == first.x + first.w + first.loop + PANEL_GAP
