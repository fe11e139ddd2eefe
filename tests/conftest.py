"""Shared helpers: build teams from YAML text, find examples."""

from __future__ import annotations

import textwrap
from pathlib import Path

import matplotlib
import pytest

matplotlib.use("Agg")

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
FIXTURES = Path(__file__).resolve().parent / "fixtures"

#: The hysteresis thermostat, with an open requirements: section to append to. It
#: heats as x' = K (30 - x) from 19 and cools as x' = -K x, switching at 22 and 18,
#: so its first switch is at ln(11/8)/K and the room stays in [18, 22].
THERMOSTAT = """
team: thermostat
agents:
  thermostat:
    plant: {kind: flow, state: {x: 19.0}}
    parameters: {K: 0.1, low: 18.0, high: 22.0}
    initial: Heat
    modes:
      Heat:
        flow: {x: K * (30 - x)}
        transitions: [{to: Cool, guard: x >= high}]
      Cool:
        flow: {x: -K * x}
        transitions: [{to: Heat, guard: x <= low}]
simulation: {duration: 30, sample_period: 0.1}
requirements:
"""


@pytest.fixture
def team_from_yaml(tmp_path):
    """Write YAML text to a file and load it as a team (dedented)."""
    from hybridteam import load

    def make(text: str, name: str = "team.yaml"):
        path = tmp_path / name
        path.write_text(textwrap.dedent(text))
        return load(path)

    return make


NO_RCLPY = (
    "rclpy cannot be imported (pip install 'hybridteam[ros]'; wheels for CPython 3.11 "
    "on Linux x86_64)"
)


@pytest.fixture
def ros(monkeypatch):
    """rclpy, with discovery kept on this machine and Fast DDS; skips, saying why, where
    rclpy cannot be imported (the ros extra's wheels are for CPython 3.11 on Linux x86_64)."""
    rclpy = pytest.importorskip("rclpy", reason=NO_RCLPY, exc_type=ImportError)
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    monkeypatch.setenv("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")
    return rclpy
