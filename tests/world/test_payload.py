"""Payloads held by compliant grasps: the quasi-static equilibrium pose and offsets."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import minimize

from hybridteam.world.payload import (
    bar,
    equilibrium,
    spring_energy,
    two_grasp_slack,
    world_points,
)


@pytest.mark.parametrize(
    ("length", "dist", "sc1", "sc2"),
    [
        (450.0, 460.0, 0.8, 1.0),
        (450.0, 440.0, 0.8, 1.0),
        (100.0, 130.0, 1.0, 1.0),
        (300.0, 295.0, 2.5, 0.5),
    ],
)
def test_bar_offsets_follow_the_paper(length, dist, sc1, sc2):
    """|o1| = sc2 / (sc1 + sc2) * |D - l|, along the robots' line (ladder paper, Sec. 2)."""
    rng = np.random.default_rng(0)
    angle = rng.uniform(-math.pi, math.pi, 5)
    rear = rng.uniform(-100, 100, (5, 2))
    front = rear + dist * np.stack([np.cos(angle), np.sin(angle)], axis=-1)
    robots = np.stack([front, rear], axis=1)
    eq = equilibrium(robots, bar(length), np.array([[sc1, sc2]] * 5))
    o1 = np.hypot(*eq.offsets[:, 0].T)
    o2 = np.hypot(*eq.offsets[:, 1].T)
    np.testing.assert_allclose(o1, sc2 / (sc1 + sc2) * abs(dist - length), rtol=1e-9)
    np.testing.assert_allclose(o2, sc1 / (sc1 + sc2) * abs(dist - length), rtol=1e-9)
    # The bar lies on the line through the robots, front end toward the front robot.
    np.testing.assert_allclose(np.cos(eq.theta - angle), 1.0, atol=1e-12)
    unit = (front - rear) / dist
    sign = np.sign(dist - length)
    np.testing.assert_allclose(eq.offsets[:, 0], sign * o1[:, None] * unit, atol=1e-9)
    # Forces balance: sc1 * o1 + sc2 * o2 = 0.
    np.testing.assert_allclose(sc1 * eq.offsets[:, 0] + sc2 * eq.offsets[:, 1], 0.0, atol=1e-9)


@pytest.mark.parametrize("k", [3, 4])
def test_equilibrium_is_the_numeric_minimum(k):
    rng = np.random.default_rng(10 + k)
    n = 6
    body = rng.uniform(-50, 50, (n, k, 2))
    springs = rng.uniform(0.2, 3.0, (n, k))
    theta0 = rng.uniform(-math.pi, math.pi, n)
    shift = rng.uniform(-100, 100, (n, 2))
    robots = world_points(shift[:, 0], shift[:, 1], theta0, body) + rng.normal(0, 5, (n, k, 2))
    eq = equilibrium(robots, body, springs)
    energy = spring_energy(robots, body, springs, eq.x, eq.y, eq.theta)
    for i in range(n):

        def f(v, i=i):
            return spring_energy(
                robots[i : i + 1], body[i : i + 1], springs[i : i + 1], v[0:1], v[1:2], v[2:3]
            )[0]

        best = min(
            (
                minimize(f, [shift[i, 0], shift[i, 1], t0], method="BFGS", options={"gtol": 1e-10})
                for t0 in (theta0[i], theta0[i] + 3)
            ),
            key=lambda r: r.fun,
        )
        assert energy[i] == pytest.approx(best.fun, rel=1e-7, abs=1e-9)
        assert (eq.x[i], eq.y[i]) == pytest.approx((best.x[0], best.x[1]), abs=1e-4)
        assert math.cos(eq.theta[i] - best.x[2]) == pytest.approx(1.0, abs=1e-9)
    # Offsets are robot minus world grasp point.
    grasps = world_points(eq.x, eq.y, eq.theta, body)
    np.testing.assert_allclose(eq.offsets, robots - grasps, atol=1e-9)


def test_equilibrium_is_batch_independent_and_broadcasts():
    rng = np.random.default_rng(5)
    robots = rng.uniform(-300, 300, (37, 3, 2))
    body = np.array([[0.0, 0.0], [100.0, 0.0], [0.0, 50.0]])
    springs = rng.uniform(0.5, 2.0, (37, 3))
    eq = equilibrium(robots, body, springs)
    for i in range(0, 37, 4):
        one = equilibrium(robots[i : i + 1], body, springs[i : i + 1])
        for a, b in zip(eq, one, strict=True):
            assert np.array_equal(a[i], b[0])
    per_instance = equilibrium(robots, np.broadcast_to(body, (37, 3, 2)), springs)
    for a, b in zip(eq, per_instance, strict=True):
        np.testing.assert_array_equal(a, b)
    same = equilibrium(robots, body, np.ones(3))
    assert same.offsets.shape == (37, 3, 2)
    # without offsets (the payload component places the grasps itself): the same pose,
    # bit for bit, and offsets that placing the grasps gives
    bare = equilibrium(robots, body, springs, offsets=False)
    for a, b in zip(eq[:3], bare[:3], strict=True):
        np.testing.assert_array_equal(a, b)
    assert bare.offsets.shape == (37, 0, 2)
    np.testing.assert_array_equal(
        robots - world_points(bare.x, bare.y, bare.theta, body), eq.offsets
    )


def test_equilibrium_rejects_bad_input():
    with pytest.raises(ValueError):
        equilibrium(np.zeros((2, 2)), bar(1.0), np.ones(2))
    with pytest.raises(ValueError):
        equilibrium(np.zeros((1, 2, 2)), bar(1.0), np.array([1.0, 0.0]))


def test_two_grasp_slack():
    # Equal springs share the mismatch: each may take olim, together 2 * olim.
    assert two_grasp_slack(10, 10, 1, 1) == 20
    # The softer spring (sc 0.8) takes 1 / 1.8 of it and reaches its limit first.
    assert two_grasp_slack(10, 10, 0.8, 1.0) == pytest.approx(18.0)
    assert two_grasp_slack(10, 5, 1, 1) == 10
