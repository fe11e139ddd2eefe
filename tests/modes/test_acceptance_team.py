"""Issue 16's acceptance: a team a newcomer writes from the README alone.

Three heterogeneous robots (a Labmate leading, an XR4000 holding the box's far end, a Scout
trailing as a remote sensor), a box, a corridor with a post, role assignment with an
operator (``tests/fixtures/acceptance/corridor_carry.yaml``). The Labmate's plan is
open-loop, v = −0.1 m/s along x from x = 0, so every time below is hand-computed:

- it reaches its goal x = −2 at t = 20 s, and the run ends ``success`` there by the end
  rule (``end: {agents: [labmate]}``), though the operator never finishes;
- with a wall across the corridor at x = −1.5 the Labmate's 0.35 m footprint touches it
  when x = −1.15, at t = 11.5 s: the run ends ``collision`` at the first check at or after
  that instant (checks are on the 0.05 s ticks, and 11.5 is one).
"""

from __future__ import annotations

import pytest

import hybridteam as ht
from hybridteam.cli import main
from tests.conftest import FIXTURES

TEAM = FIXTURES / "acceptance" / "corridor_carry.yaml"


def test_it_validates_without_warnings(capsys):
    assert main(["validate", str(TEAM)]) == 0
    assert "warning" not in capsys.readouterr().err


def test_it_ends_in_success_when_the_leader_arrives():
    run = ht.simulate(ht.load(TEAM))
    row = run.summary()["instances"][0]
    assert (row["outcome"], row["message"]) == (
        "success",
        "'labmate' reached a final mode (the end rule)",
    )
    assert row["t_end"] == pytest.approx(20.0, abs=1e-9)
    # clearances, by hand: the Labmate passes the post (r 0.1 at y = 0.9) at y = 0, its
    # radius 0.35: 0.45; the XR4000 ends at x = -0.3, 1.14 m from the post: 0.71; the
    # Scout, radius 0.2, holds its place at y = -0.7 along the wall at -1.3: 0.4; the box
    # (half-depth 0.25) ends under the post: 0.9 - 0.25 - 0.1 = 0.55
    lab, xr, scout = row["min_clearance"]
    assert lab == pytest.approx(0.45, abs=1e-9)
    assert xr == pytest.approx((0.7**2 + 0.9**2) ** 0.5 - 0.1 - 0.33, abs=1e-6)
    assert scout == pytest.approx(0.4, abs=1e-6)
    assert row["payload_clearance"] == pytest.approx(0.55, abs=1e-9)
    assert max(row["max_grasp_offset"]) < 0.01  # held: the limits are 0.10 and 0.05


def test_it_ends_in_collision_when_a_wall_is_moved_into_its_path(team_from_yaml):
    text = TEAM.read_text().replace(
        "walls: [[-4.0, -1.3, 4.0, -1.3], [-4.0, 1.3, 4.0, 1.3]]",
        "walls: [[-4.0, -1.3, 4.0, -1.3], [-4.0, 1.3, 4.0, 1.3], [-1.5, -1.3, -1.5, 1.3]]",
    )
    run = ht.simulate(team_from_yaml(text))
    row = run.summary()["instances"][0]
    assert row["outcome"] == "collision"
    assert row["message"].startswith("robot 'labmate' hit walls[2]")
    assert 11.5 - 1e-9 <= row["t_end"] <= 11.55 + 1e-9
