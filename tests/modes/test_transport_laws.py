"""The transport library's laws, run in small role-assignment teams against analytic answers.

Each test builds a team the way a user would (YAML, the role_assignment protocol, the
leader's ``state`` stream over the network) and checks the follower against the paper's
equation integrated exactly: laws are sampled every T = 0.05 s and held, kinematic plants
are integrated in closed form, and a constant-velocity leader's dead-reckoned estimate is
exact, so most answers hold to rounding. Two test-only world components stand in for
sensors: a constant arm reading, and an IR ring that sees one wall (cast with the
framework's range sensors), which pins the approach law apart from the ``obstacles``
component (tested too when it is installed).
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
import pytest
import yaml

import hybridteam as ht
from hybridteam.dynamics.plants import make_plant
from hybridteam.world.component import WorldComponent, world_component
from hybridteam.world.sensors import RangeRing
from tests.conftest import FIXTURES

T = 0.05  # every law's period, and the sample period


# ----------------------------------------------------------------------------- team helpers
def robot(
    kind: str,
    pose: tuple[float, float, float],
    lead: dict,
    follow: dict,
    initial: str = "Follow",
    leader: str | None = None,
) -> dict:
    spec: dict[str, Any] = {
        "plant": {
            "kind": kind,
            "state": dict(zip(("x", "y", "theta"), map(float, pose), strict=True)),
        },
        "modes": {
            "Transport": {
                "protocol": "role_assignment",
                "initial": initial,
                "roles": {"lead": lead, "follow": follow},
            }
        },
    }
    if leader is not None:
        spec["variables"] = {"leader": f"id_{leader}"}
    return spec


def held(**inputs: float) -> dict:
    return {"inputs": inputs, "period": T}


def uses(name: str, **params: float) -> dict:
    return {"law": {"use": name, "period": T, "with": {k: float(v) for k, v in params.items()}}}


def team_text(
    agents: dict,
    *,
    latency: float = 0.0,
    duration: float = 2.0,
    world: list | None = None,
    scenario: list | None = None,
) -> str:
    roles = any("Transport" in a["modes"] for a in agents.values())
    operator = {"operator": {"operator": "role_assignment"}} if roles else {}
    doc: dict[str, Any] = {
        "team": "transport-test",
        "network": {"latency": latency},
        "agents": {**agents, **operator},
        "simulation": {"duration": duration, "sample_period": T},
    }
    if world:
        doc["world"] = world
    if scenario:
        doc["scenario"] = scenario
    return yaml.safe_dump(doc, sort_keys=False)


def run_team(make, agents: dict, **kw):
    run = ht.simulate(make(team_text(agents, **kw)))
    assert run.outcome == "ok", run.message
    return run


def poses(run, agent: str) -> np.ndarray:
    return run.samples[agent][:, 0, :3]


UNICYCLE = make_plant("unicycle")


def unicycle_path(pose0, law, steps: int) -> np.ndarray:
    """The reference: ``law(pose) -> (v, omega)`` held for T, integrated exactly."""
    out = [np.asarray(pose0, float)]
    for _ in range(steps):
        u = np.asarray(law(out[-1]), float)
        out.append(UNICYCLE.propagate(out[-1][None], u[None], T)[0])
    return np.array(out)


# ----------------------------------------------------------------------------- components
@world_component("tests.transport_arm")
class ConstantArm(WorldComponent):
    """Every robot's arm reads the same constant x_a (a stand-in for a held payload)."""

    params: ClassVar[dict[str, Any]] = {"x_a": 0.0, "y_a": 0.0, "theta_a": 0.0}

    def senses(self) -> tuple[str, ...]:
        return ("arm",)

    def sense(self, agent: int, idx: np.ndarray, name: str) -> np.ndarray:
        v = self.values
        return np.stack([np.asarray(v[k], float)[idx] for k in ("x_a", "y_a", "theta_a")], 1)


@world_component("tests.transport_wall")
class WallRing(WorldComponent):
    """One wall segment, seen by every robot's XR4000-like IR ring (24 beams, 0.5 m, on a
    0.33 m hull), cast with the framework's range sensors; the segment is instance 0's."""

    params: ClassVar[dict[str, Any]] = {"x0": 1.0, "y0": -5.0, "x1": 1.0, "y1": 5.0}
    RING = RangeRing(count=24, max_range=0.5, mount_radius=0.33, name="ir")

    def start(self, world) -> None:
        self.ir = np.full((self.n, len(self.team.agents), 24), np.nan)
        self.update(world, np.arange(self.n))

    def update(self, world, idx: np.ndarray) -> None:
        seg = [[float(np.asarray(self.values[k], float)[0]) for k in ("x0", "y0", "x1", "y1")]]
        for a in range(len(world.agents)):
            if world.has_pose(a):
                self.ir[idx, a] = self.RING.read(world.pose(a, idx), seg)

    def senses(self) -> tuple[str, ...]:
        return ("ir",)

    def sense(self, agent: int, idx: np.ndarray, name: str) -> np.ndarray:
        return self.ir[idx, agent]


def test_the_library_is_registered_through_its_entry_point():
    from importlib import metadata

    from hybridteam.laws import registered

    eps = {ep.name: ep.value for ep in metadata.entry_points(group="hybridteam.libraries")}
    assert eps.get("transport") == "hybridteam.modes.transport"
    assert {
        "transport.follow",
        "transport.follow_holonomic",
        "transport.match",
        "transport.dock_arm",
        "transport.approach",
    } <= set(registered())


# ----------------------------------------------------------------------------- (1) follow
def test_follow_behind_a_straight_leader_copies_its_heading_and_speed(team_from_yaml):
    """No arm, same heading: u1 = v̂_l cos 0 = v, u2 = 0 — the follower drives like the
    leader from the first copy (sent and, with no latency, used at t = 0)."""
    run = run_team(
        team_from_yaml,
        {
            "xr4000": robot(
                "unicycle", (1, 0, 0), held(v=0.3, omega=0), held(v=0, omega=0), initial="Lead"
            ),
            "labmate": robot(
                "unicycle",
                (0, 0, 0),
                held(v=0, omega=0),
                uses("transport.follow", D=1.0),
                leader="xr4000",
            ),
        },
    )
    t, lab, xr = run.sample_times, poses(run, "labmate"), poses(run, "xr4000")
    np.testing.assert_allclose(lab[:, 0], 0.3 * t, atol=1e-12)
    np.testing.assert_allclose(lab[:, 1:], 0.0, atol=1e-12)
    np.testing.assert_allclose(xr[:, 0] - lab[:, 0], 1.0, atol=1e-12)


@pytest.mark.parametrize(
    ("D", "v"),
    [(1.0, 0.3), (-1.0, -0.3)],
    ids=["leader-ahead-driving-forward", "leader-behind-backing"],
)
def test_follow_heading_term_turns_toward_the_leaders_heading(team_from_yaml, D, v):
    """Heading error 0.2 rad: u2 = (v̂_l/D) sin(θ̂_l − θ) < 0 turns the follower back when
    the leader pulls (v/D > 0), whether it is ahead (D > 0) or behind (D < 0)."""
    run = run_team(
        team_from_yaml,
        {
            "xr4000": robot(
                "unicycle", (D, 0, 0), held(v=v, omega=0), held(v=0, omega=0), initial="Lead"
            ),
            "labmate": robot(
                "unicycle",
                (0, 0, 0.2),
                held(v=0, omega=0),
                uses("transport.follow", D=D),
                leader="xr4000",
            ),
        },
    )
    lab = poses(run, "labmate")
    ref = unicycle_path(
        (0, 0, 0.2), lambda p: (v * np.cos(-p[2]), v / D * np.sin(-p[2])), len(lab) - 1
    )
    np.testing.assert_allclose(lab, ref, atol=1e-9)
    assert np.all(np.diff(lab[:, 2]) < 0) and 0 < lab[-1, 2] < 0.2


# ----------------------------------------------------------------------------- (2) holonomic
def test_holonomic_follow_error_decays_exponentially_despite_latency(team_from_yaml):
    """Leader (Labmate) straight at 0.3 m/s along 0.3 rad; the XR4000 starts off its set
    point x^d = x̂_l + D (cos, sin) θ̂_l. Copies take 30 ms, so the first is used at the
    t = 0.05 tick (standing still until then); dead reckoning makes x̂_l exact and the
    feed-forward cancels the leader's motion, so each axis's error obeys e' = −k e held
    over T: e_n = e_0 (1 − k T)^n, i.e. exp(−k' t) with k' = −ln(1 − kT)/T → k."""
    th_l, v, D, k = 0.3, 0.3, 1.0, np.array([1.0, 2.0, 1.5])
    xd0 = np.array([D * np.cos(th_l), D * np.sin(th_l), th_l])
    start = xd0 - np.array([0.4, -0.3, 0.5])
    run = run_team(
        team_from_yaml,
        {
            "labmate": robot(
                "unicycle", (0, 0, th_l), held(v=v, omega=0), held(v=0, omega=0), initial="Lead"
            ),
            "xr4000": robot(
                "holonomic",
                tuple(start),
                held(vx=0, vy=0, omega=0),
                uses("transport.follow_holonomic", D=D, k1=k[0], k2=k[1], k3=k[2]),
                leader="labmate",
            ),
        },
        latency=0.03,
        duration=3.0,
    )
    t, xr = run.sample_times, poses(run, "xr4000")
    np.testing.assert_allclose(xr[t <= 0.05 + 1e-9], [start, start], atol=1e-15)
    xd = xd0 + np.outer(t, [v * np.cos(th_l), v * np.sin(th_l), 0.0])
    err = xd - xr
    n = np.rint((t - 0.05) / T)
    after = n >= 0
    expected = err[after][0] * (1 - k * T) ** n[after][:, None]
    np.testing.assert_allclose(err[after], expected, atol=1e-9)
    rate = -np.log(1 - k * T) / T
    np.testing.assert_allclose(rate, k, rtol=0.08)
    assert np.all(np.abs(err[-1]) < np.abs(err[after][0]) * np.exp(-0.9 * k * 2.9))


@pytest.mark.parametrize(("k_ff", "bound"), [(1.0, 0.01), (0.0, None)])
def test_holonomic_feed_forward_tracks_a_turning_leader(team_from_yaml, k_ff, bound):
    """A leader on an arc (v 0.3, ω 0.3): the set point swings round it, so it moves at
    v_l + ω × D(cos, sin) ≈ 0.42 m/s. Fed forward, the XR4000 stays within a centimetre
    (only the hold over each period lags); the paper's pure P law (k_ff = 0) lags by about
    |ẋ^d| / k."""
    v, w, D = 0.3, 0.3, 1.0
    run = run_team(
        team_from_yaml,
        {
            "labmate": robot(
                "unicycle", (0, 0, 0), held(v=v, omega=w), held(v=0, omega=0), initial="Lead"
            ),
            "xr4000": robot(
                "holonomic",
                (D, 0, 0),
                held(vx=0, vy=0, omega=0),
                uses("transport.follow_holonomic", D=D, k_ff=k_ff),
                leader="labmate",
            ),
        },
        duration=4.0,
    )
    lab, xr = poses(run, "labmate"), poses(run, "xr4000")
    xd = lab[:, :2] + D * np.c_[np.cos(lab[:, 2]), np.sin(lab[:, 2])]
    lag = np.hypot(*(xd - xr[:, :2]).T)
    if bound is not None:
        assert lag.max() < bound
        np.testing.assert_allclose(xr[:, 2], lab[:, 2], atol=1e-12)  # θ^d = θ̂_l, fed ω
    else:
        speed = np.hypot(v, w * D)
        assert lag[-1] == pytest.approx(speed / 1.0, rel=0.15)


# ----------------------------------------------------------------------------- (3) match
@pytest.mark.parametrize("latency", [0.0, 0.03])
def test_match_reproduces_the_leaders_speed_and_turn_rate(team_from_yaml, latency):
    """u = (v̂_l, ω̂_l): from the tick that sees the first copy (t0), the Scout runs the
    leader's inputs, so its path from its start is the leader's from its own, t0 later."""
    run = run_team(
        team_from_yaml,
        {
            "labmate": robot(
                "unicycle", (1, 0, 0), held(v=0.3, omega=0.2), held(v=0, omega=0), initial="Lead"
            ),
            "scout": robot(
                "unicycle",
                (0, 0.5, 0),
                held(v=0, omega=0),
                uses("transport.match", k_form=0),
                leader="labmate",
            ),
        },
        latency=latency,
    )
    lab, scout = poses(run, "labmate"), poses(run, "scout")
    lag = int(np.ceil(latency / T - 1e-9))
    np.testing.assert_allclose(scout[: lag + 1], scout[:1].repeat(lag + 1, 0), atol=1e-15)
    moved = scout[lag:] - scout[0]
    np.testing.assert_allclose(moved, lab[: len(lab) - lag] - lab[0], atol=1e-12)


def test_match_formation_term_is_on_by_default_and_off_at_k_form_0(team_from_yaml):
    """The Scout starts 0.3 m off its station (one metre behind the leader; capture off):
    with k_form 0 (the paper's copy) the offset stays; by default it shrinks."""

    def gap(**params: float) -> np.ndarray:
        run = run_team(
            team_from_yaml,
            {
                "labmate": robot(
                    "unicycle", (1, 0, 0), held(v=0.3, omega=0), held(v=0, omega=0), initial="Lead"
                ),
                "scout": robot(
                    "unicycle",
                    (-0.3, 0, 0),
                    held(v=0, omega=0),
                    uses("transport.match", capture=0, ahead=-1.0, **params),
                    leader="labmate",
                ),
            },
            duration=3.0,
        )
        return poses(run, "labmate")[:, 0] - 1.0 - poses(run, "scout")[:, 0]

    np.testing.assert_allclose(gap(k_form=0.0), 0.3, atol=1e-12)
    pulled = gap()
    assert pulled[-1] < 0.3 * 0.1 and np.all(np.diff(pulled) < 0)


def _switching_team(follow: dict) -> dict:
    """Two leaders side by side, 2 m apart, driving +x at 0.3 m/s; the follower hears A
    until t = 2 s, when its ``leader`` becomes B (as a role change would make it)."""
    follower = robot("unicycle", (0, 0.5, 0), held(v=0, omega=0), follow, leader="a")
    follower["modes"]["Transport"]["roles"]["follow"]["transitions"] = [
        {"on": "switch", "do": ["leader = id_b"]}
    ]
    return {
        "a": robot("unicycle", (1, 0, 0), held(v=0.3, omega=0), held(v=0, omega=0), initial="Lead"),
        "b": robot("unicycle", (1, 2, 0), held(v=0.3, omega=0), held(v=0, omega=0), initial="Lead"),
        "scout": follower,
    }


@pytest.mark.parametrize("name", ["transport.match", "formation.follow"])
def test_a_capturing_follower_keeps_its_place_in_the_team_when_the_leader_changes(
    team_from_yaml, name
):
    """With ``capture`` the follower holds the place it had when a leader's first copy
    arrived — 1 m behind A and 0.5 m to its left, 1.5 m to B's right — so the change of
    leader at t = 2 s changes nothing: it drives on at y = 0.5, 1 m behind the leaders.
    Without it, it heads for its fixed station 1 m behind B, at y = 2."""
    kw = {"duration": 6.0, "scenario": [{"at": 2.0, "agent": "scout", "raise": "switch"}]}
    run = run_team(team_from_yaml, _switching_team(uses(name, capture=1)), **kw)
    scout, a = poses(run, "scout"), poses(run, "a")
    started = run.samples_frame(wide=True)["t"].to_numpy() >= T  # the first copy is at t = 0
    np.testing.assert_allclose(scout[started, 1], 0.5, atol=1e-9)
    np.testing.assert_allclose((a[:, 0] - scout[:, 0])[started], 1.0, atol=1e-9)
    fixed = run_team(team_from_yaml, _switching_team(uses(name, capture=0, left=0.0)), **kw)
    assert poses(fixed, "scout")[-1, 1] > 1.0  # on its way to y = 2, behind B


def test_a_follower_captures_again_when_it_follows_the_same_leader_anew(team_from_yaml):
    """The Scout holds 1 m behind A, pauses from t = 2 s to 3 s (another mode: it stands
    while A drives on 0.3 m) and follows A again: it holds the new place, 1.3 m behind,
    rather than closing up to where it was before."""
    scout = robot(
        "unicycle", (0, 0, 0), held(v=0, omega=0), uses("transport.match", capture=1), leader="a"
    )
    scout["initial"] = "Transport"
    scout["modes"]["Transport"]["transitions"] = [{"to": "Pause", "on": "pause"}]
    scout["modes"]["Pause"] = {
        **held(v=0, omega=0),
        "transitions": [{"to": "Transport", "after": 1.0}],
    }
    run = run_team(
        team_from_yaml,
        {
            "a": robot(
                "unicycle", (1, 0, 0), held(v=0.3, omega=0), held(v=0, omega=0), initial="Lead"
            ),
            "scout": scout,
        },
        duration=6.0,
        scenario=[{"at": 2.0, "agent": "scout", "raise": "pause"}],
    )
    t = run.sample_times
    gap = poses(run, "a")[:, 0] - poses(run, "scout")[:, 0]
    np.testing.assert_allclose(gap[(t > 0) & (t <= 2.0)], 1.0, atol=1e-9)
    np.testing.assert_allclose(gap[t >= 3.0], 1.3, atol=1e-9)


def test_follow_with_capture_uses_the_link_it_has_to_its_leader(team_from_yaml):
    """``capture`` replaces D by the leader's distance along the robot's heading when the
    first copy arrives: a Labmate 3 m behind a turning leader, told D = 1, then moves
    exactly as with D = 3 (the rigid link it actually has)."""

    def labmate(**params: float) -> np.ndarray:
        run = run_team(
            team_from_yaml,
            {
                "lead": robot(
                    "unicycle",
                    (3, 0, 0),
                    held(v=0.3, omega=0.2),
                    held(v=0, omega=0),
                    initial="Lead",
                ),
                "labmate": robot(
                    "unicycle",
                    (0, 0, 0),
                    held(v=0, omega=0),
                    uses("transport.follow", **params),
                    leader="lead",
                ),
            },
            duration=4.0,
        )
        return poses(run, "labmate")

    captured, told = labmate(D=1.0, capture=1), labmate(D=3.0)
    np.testing.assert_allclose(captured, told, atol=1e-12)
    assert not np.allclose(labmate(D=1.0), told, atol=1e-3)  # D matters: the test can fail


# ----------------------------------------------------------------------------- (4) dock_arm
def test_dock_arm_commands_the_restoring_input_for_a_constant_offset(team_from_yaml):
    """x_a = 0.05 (mount ahead of the grasp), y_a = 0.02 (left of it), θ_a = 0.01: with the
    default gains u1 = −x_a (back up), u2 = −y_a + θ_a = −0.01 (turn right)."""
    run = run_team(
        team_from_yaml,
        {
            "labmate": {
                "plant": {"kind": "unicycle", "state": {"x": 0, "y": 0, "theta": 0}},
                "modes": {"Dock": uses("transport.dock_arm")},
            }
        },
        world=[{"use": "tests.transport_arm", "with": {"x_a": 0.05, "y_a": 0.02, "theta_a": 0.01}}],
    )
    lab = poses(run, "labmate")
    ref = unicycle_path((0, 0, 0), lambda p: (-0.05, -0.01), len(lab) - 1)
    np.testing.assert_allclose(lab, ref, atol=1e-12)
    assert lab[-1, 0] < 0 and lab[-1, 2] < 0


def test_dock_arm_closes_a_real_grasp_offset_at_the_spring_shared_rate(team_from_yaml):
    """A bar held by the XR4000 (still, spring 3) and the Labmate (facing it, spring 1),
    stretched by s0 = 0.08. The Labmate's grasp takes w = 3/4 of the stretch, so its arm
    reads x_a = −w s (robot frame, facing −x) and u1 = −x_a = w s closes it: s_n = s0 (1 − wT)^n."""
    s0, w = 0.08, 0.75
    run = run_team(
        team_from_yaml,
        {
            "xr4000": {
                "plant": {"kind": "holonomic", "state": {"x": 0, "y": 0, "theta": 0}},
                "modes": {"Hold": held(vx=0, vy=0, omega=0)},
            },
            "labmate": {
                "plant": {
                    "kind": "unicycle",
                    "state": {"x": 1 + s0, "y": 0, "theta": float(np.pi)},
                },
                "modes": {"Dock": uses("transport.dock_arm")},
            },
        },
        world=[
            {
                "use": "payload",
                "with": {
                    "name": "bar",
                    "shape": "bar",
                    "length": 1.0,
                    "grasps": [
                        {"agent": "xr4000", "point": [-0.5, 0], "spring": 3},
                        {"agent": "labmate", "point": [0.5, 0], "spring": 1},
                    ],
                },
            }
        ],
        duration=3.0,
    )
    s = poses(run, "labmate")[:, 0] - 1.0
    n = np.arange(len(s))
    np.testing.assert_allclose(s, s0 * (1 - w * T) ** n, atol=1e-9)


# ----------------------------------------------------------------------------- (5) approach
def xr_approach(model: bool = False, **params: float) -> dict:
    plant = {"kind": "holonomic", "state": {"x": 0, "y": 0, "theta": 0}}
    spec = {"plant": plant, "modes": {"Approach": uses("transport.approach", **params)}}
    if model:  # the preset's IR ring (24 beams, 0.5 m, on its 0.33 m hull)
        del plant["kind"]
        spec = {"model": "xr4000", **spec}
    return spec


def _has_obstacles() -> bool:
    from hybridteam.world.component import registered

    return "obstacles" in registered()


WALL_AHEAD = {
    "stand-in": ({"use": "tests.transport_wall"}, False),
    "obstacles": ({"use": "obstacles", "with": {"walls": [[1, -5, 1, 5]]}}, True),
}


@pytest.mark.parametrize(
    "world",
    [
        "stand-in",
        pytest.param(
            "obstacles",
            marks=pytest.mark.skipif(
                not _has_obstacles(), reason="the obstacles component is not installed"
            ),
        ),
    ],
)
def test_approach_stops_at_stand_off_from_a_wall(team_from_yaml, world):
    """A wall 1 m ahead is 0.67 m from the hull, beyond the IR's 0.5 m: the XR4000 comes on
    at `speed` (0.1) until the gap is 0.2, then at k (gap − 0.1) held over T, and stops
    within `tol` of the stand-off, for good. The same with the test's stand-in ring and
    with the framework's obstacles component and the XR4000 preset's ring."""
    component, model = WALL_AHEAD[world]
    run = run_team(team_from_yaml, {"xr4000": xr_approach(model)}, duration=8.0, world=[component])
    xr = poses(run, "xr4000")
    gap, ref, stop = 0.67, [0.0], None
    for n in range(len(xr) - 1):
        r = min(gap, 0.5)
        u = 0.0 if abs(r - 0.1) <= 0.005 else float(np.clip(r - 0.1, -0.1, 0.1))
        stop = n if stop is None and u == 0.0 else stop
        gap -= u * T
        ref.append(1.0 - 0.33 - gap)
    np.testing.assert_allclose(xr[:, 0], ref, atol=1e-9)
    np.testing.assert_allclose(xr[:, 1:], 0.0, atol=1e-12)
    final_gap = 0.67 - xr[-1, 0]
    assert abs(final_gap - 0.1) <= 0.005
    # saturated for 0.47 m (4.7 s), then ln(0.1 / 0.005) / -ln(1 - k T) periods
    assert stop is not None
    assert stop * T == pytest.approx(4.7 + T * np.ceil(np.log(20) / -np.log(1 - T)), abs=T)
    assert np.all(xr[stop:, 0] == xr[stop, 0])


def test_approach_slides_toward_an_edge_seen_on_the_left(team_from_yaml):
    """Only the left half of the front sector sees the box (its edge at y = 0.02): the front
    and right beams read 0.5, the +15° beam less, so the XR4000 slides left (and ahead)."""
    run = run_team(
        team_from_yaml,
        {"xr4000": xr_approach()},
        duration=0.1,
        world=[
            {"use": "tests.transport_wall", "with": {"x0": 0.6, "y0": 0.02, "x1": 0.6, "y1": 2.0}}
        ],
    )
    xr = poses(run, "xr4000")
    a = np.radians(15)
    left = (0.6 - 0.33 * np.cos(a)) / np.cos(a)
    lateral = min(0.5 * (0.5 - left), 0.1)
    forward = min(left - 0.1, 0.1)
    np.testing.assert_allclose(xr[1], [forward * T, lateral * T, 0.0], atol=1e-12)


# ----------------------------------------------------------------------------- lead plans
PLAN = {
    "initial": "Back",
    "modes": {
        "Back": {**held(v=-0.1, omega=0), "transitions": [{"to": "Turn", "after": 4}]},
        "Turn": {**held(v=-0.1, omega=0.2), "transitions": [{"to": "Stop", "after": 2}]},
        "Stop": held(v=0, omega=0),
    },
}


def test_a_lead_role_can_be_a_composite_plan_entered_on_a_handover(team_from_yaml):
    """The Labmate follows the XR4000, asks to lead at t = 1, is granted at 1.06 (30 ms a
    leg) and runs its open-loop plan: Back for 4 s, Turn for 2 s, Stop; the XR4000, now
    following, keeps its place D ahead on the Labmate's heading, and the Scout copies the
    Labmate's motion (the paper's law, k_form = 0), ending with its heading."""
    D = 1.0
    run = run_team(
        team_from_yaml,
        {
            "xr4000": robot(
                "holonomic",
                (D, 0, 0),
                held(vx=0.1, vy=0, omega=0),
                uses("transport.follow_holonomic", D=D),
                initial="Lead",
            ),
            "labmate": robot(
                "unicycle", (0, 0, 0), PLAN, uses("transport.follow", D=D), leader="xr4000"
            ),
            "scout": robot(
                "unicycle",
                (0, -1, 0),
                held(v=0, omega=0),
                uses("transport.match", k_form=0),
                leader="labmate",
            ),
        },
        latency=0.03,
        duration=11.0,
        scenario=[{"at": 1.0, "agent": "labmate", "raise": "want_lead"}],
    )
    tr = run.transitions.where(agent="labmate")
    moves = [
        (round(float(t), 9), s, g)
        for t, s, g in zip(tr["t"], tr["source"], tr["target"], strict=True)
        if s
    ]
    assert moves == [
        (1.0, "Transport.Follow", "Transport.Requesting"),
        (1.06, "Transport.Requesting", "Transport.Lead"),
        (5.06, "Transport.Lead.Back", "Transport.Lead.Turn"),
        (7.06, "Transport.Lead.Turn", "Transport.Lead.Stop"),
    ]
    iv = run.intervals.where(agent="labmate")
    leaves = [
        (str(m), round(float(a), 9))
        for m, a in zip(iv["mode"], iv["start"], strict=True)
        if "Lead." in m
    ]
    assert leaves == [
        ("Transport.Lead.Back", 1.06),
        ("Transport.Lead.Turn", 5.06),
        ("Transport.Lead.Stop", 7.06),
    ]
    t, lab, xr = run.sample_times, poses(run, "labmate"), poses(run, "xr4000")
    i, j = (int(np.argmin(abs(t - s))) for s in (1.1, 5.0))
    # Back: straight on its heading at 0.1 m/s backwards
    step = lab[j, :2] - lab[i, :2]
    heading = np.array([np.cos(lab[i, 2]), np.sin(lab[i, 2])])
    np.testing.assert_allclose(step, -0.1 * (t[j] - t[i]) * heading, atol=1e-12)
    # Turn: 0.4 rad in all, then the Labmate stands; the Scout ends on the same heading
    assert lab[-1, 2] - lab[j, 2] == pytest.approx(0.4, abs=1e-12)
    assert poses(run, "scout")[-1, 2] == pytest.approx(lab[-1, 2], abs=1e-9)
    end = lab[-1, :2] + D * np.array([np.cos(lab[-1, 2]), np.sin(lab[-1, 2])])
    # the last copy still turning (sent before the stop, 30 ms old) leaves a transient
    # error of a few mm that has decayed like exp(-t) by the end
    np.testing.assert_allclose(xr[-1], [*end, lab[-1, 2]], atol=1e-3)


CARRY = FIXTURES / "transport" / "carry.yaml"


def test_paper_team_carries_the_box_without_dropping_it():
    """Fixture: the Labmate leads backwards on a curve, the XR4000 follows D ahead facing
    it (phi = π) with arm feedback, the Scout copies the Labmate; a box on two grasps."""
    run = ht.simulate(ht.load(CARRY))
    assert run.outcome == "ok", run.message
    (stats,) = [o["stats"] for o in run._outcomes]
    assert max(stats["max_grasp_offset"]) < 0.02
    assert poses(run, "scout")[-1, 2] == pytest.approx(poses(run, "labmate")[-1, 2])


def test_labmate_follows_an_xr4000_that_faces_it(team_from_yaml):
    """The fixture without the Scout, and the XR4000 asks to lead at t = 8: it backs away
    from the Labmate at 0.1 m/s (pulling the box), and the Labmate, following a leader whose
    heading is opposite its own (θ̂_l − θ = π, so u1 = −v̂_l), comes along with the box."""
    doc = yaml.safe_load(CARRY.read_text())
    del doc["agents"]["scout"]
    doc["simulation"]["duration"] = 16.0
    doc["scenario"] = [{"at": 8.0, "agent": "xr4000", "raise": "want_lead"}]
    run = ht.simulate(team_from_yaml(yaml.safe_dump(doc, sort_keys=False)))
    assert run.outcome == "ok", run.message
    (stats,) = [o["stats"] for o in run._outcomes]
    assert max(stats["max_grasp_offset"]) < 0.02
    t, lab = run.sample_times, poses(run, "labmate")
    i = int(np.argmin(abs(t - 9.0)))
    np.testing.assert_allclose(
        np.hypot(*(lab[-1, :2] - lab[i, :2])), 0.1 * (t[-1] - t[i]), rtol=0.01
    )
    # a pulling leader keeps the heading term at rest: the Labmate turns only by the few
    # mrad its arm's θ_a feedback settles the box by
    np.testing.assert_allclose(lab[i:, 2], lab[i, 2], atol=5e-3)
