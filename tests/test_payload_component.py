"""The framework's ``payload`` world component: equilibrium pose, arm readings, breaks."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from hybridteam.api import load, simulate
from hybridteam.laws import LawContext, law

FIXTURE = Path(__file__).parent / "fixtures" / "world" / "bar_pull.yaml"


def test_stretched_bar_settles_by_the_spring_ratio_and_breaks_on_time():
    run = simulate(load(FIXTURE))
    (out,) = run.outcomes
    assert out == "link_broken"
    o = run._outcomes[0]
    # limit 0.31 on A's side, which takes 3/4 of the stretch 0.1 t: t* = 4.1333, next tick 4.2
    assert abs(o["t"] - 4.2) < 1e-9
    assert "bar dropped: the grasp of 'A' is offset 0.315 > limit 0.31" in o["message"]
    t = run.sample_times
    bar = run.samples["bar"][:, 0]
    ok = ~np.isnan(bar[:, 0])
    # weighted centroids coincide: x = (1 (2 + 0.1 t) + 3 * 0) / 4 + 0.5 = 1 + 0.025 t
    np.testing.assert_allclose(bar[ok, 0], 1 + 0.025 * t[ok], atol=1e-12)
    np.testing.assert_allclose(bar[ok, 1:], 0.0, atol=1e-12)
    np.testing.assert_allclose(o["stats"]["max_grasp_offset"], [0.315, 0.105], atol=1e-12)
    assert run.meta["payloads"] == ["bar"]


@law("tests.arm_probe", plants=("holonomic",))
def arm_probe(ctx: LawContext) -> np.ndarray:
    """Drive at the arm's reading: vx = x_a, vy = y_a, omega = theta_a (a probe)."""
    return np.asarray(ctx.sense("arm"), dtype=float).copy()


def test_arm_reads_the_offset_in_the_robot_frame(tmp_path):
    """A robot turned by 90 degrees reads a world-x stretch as its own -y."""
    text = FIXTURE.read_text().replace(
        "state: {x: 0, y: 0, theta: 0}", "state: {x: 0, y: 0, theta: 1.5707963267948966}"
    ).replace("Hold: {inputs: {vx: 0, vy: 0, omega: 0}, period: 0.1}",
              "Hold: {law: {use: tests.arm_probe, period: 0.5}}").replace(
        "duration: 10", "duration: 1")
    path = tmp_path / "probe.yaml"
    path.write_text(text)
    run = simulate(load(path))
    # at t = 0.5 the bar (x = 1 + 0.025 t) puts B's grasp point at world x = 0.0125, so B's
    # offset is (-0.0125, 0) in the world and (0, 0.0125) in its own frame (turned 90 deg);
    # the probe drives at that for 0.5 s (holonomic inputs are world-frame velocities)
    b = run.samples["B"][:, 0]
    k = int(np.argmin(abs(run.sample_times - 1.0)))
    np.testing.assert_allclose(b[k], [0.0, 0.5 * 0.0125, np.pi / 2], atol=1e-12)
