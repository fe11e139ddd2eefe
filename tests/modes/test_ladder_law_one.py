"""The ladder's one-row float twins give the array versions' bits.

A single run evaluates the law (:mod:`...law_one`) and the corridor's instant
(:mod:`...world_one`) on Python floats; ensembles of more than a few use the numpy
versions. Both must give the same numbers, bit for bit, or a run would depend on how many
instances ran with it. Checked here on random rows against :func:`law.step`, and on whole
engine runs (successes, a stuck pair, broken links, the rotation vector, every reading of
the correction) against the same runs with the twins switched off.
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest
from hybridteam.modes.ladder import carry, law, law_one, world
from hybridteam.modes.ladder.frame import CornerFrame
from hybridteam.modes.ladder.world_one import in_corner
from hypothesis import given, settings
from hypothesis import strategies as st

from hybridteam.api import load, simulate
from hybridteam.library import FLOAT_PATHS
from hybridteam.world import corridor_with_turn

CORRIDOR = corridor_with_turn()
FRAME = CornerFrame.of(CORRIDOR)
SAMPLE = Path(__file__).resolve().parents[2] / "examples" / "ladder" / "sample.yaml"


def bits(*values: float) -> bytes:
    return struct.pack(f"{len(values)}d", *values)


def random_rows(rng: np.random.Generator, n: int, count: int, window: int):
    """Positions around the corner (some exactly on the frame's axes, where the wall rules'
    ties are), partners a ladder's length away, random paths and parameters."""
    own = rng.uniform(-250.0, 650.0, (n, 2)) @ FRAME.axes + FRAME.origin
    on_axis = rng.random(n) < 0.3
    own[on_axis] = FRAME.to_world(
        np.c_[np.zeros(on_axis.sum()), rng.uniform(-250, 650, on_axis.sum())]
    )
    angle = rng.uniform(0, 2 * np.pi, n)
    reach = rng.uniform(380.0, 520.0, n)
    partner = own + reach[:, None] * np.c_[np.cos(angle), np.sin(angle)]
    path = own[:, None, :] + np.cumsum(rng.normal(0.0, 8.0, (n, count, 2)), axis=1)
    params = {
        "length": rng.choice([450.0, 485.0], n),
        "v_max": rng.uniform(0.5, 2.0, n),
        "lookahead": rng.integers(0, 21, n).astype(float),
        "olim": rng.uniform(5, 15, n),
        "orsp": rng.uniform(0.0, 20.0, n),
        "kc": rng.uniform(0.0, 2.0, n),
        "kr": np.where(rng.random(n) < 0.5, 0.0, rng.uniform(0.1, 2.0, n)),
        "sc": rng.uniform(0.5, 1.5, n),
        "sc_partner": rng.uniform(0.5, 1.5, n),
        "radius": rng.uniform(10.0, 40.0, n),
        "ladder_margin": rng.uniform(0.0, 30.0, n),
    }
    heading = rng.normal(size=(n, 2))
    params["goal_heading"] = heading / np.hypot(*heading.T)[:, None]
    idx = rng.integers(0, count, n)
    return own, partner, path, idx, params


@settings(max_examples=200, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(1, 4),
    window=st.integers(1, 16),
    correction=st.sampled_from(["scaled", "distance", "capped"]),
)
def test_step_one_gives_the_array_laws_bits(seed, n, window, correction):
    rng = np.random.default_rng(seed)
    own, partner, path, idx, params = random_rows(rng, n, 40, window)
    guide = law.Guide(path, FRAME, window)
    with np.errstate(all="ignore"):
        move, nearest = law.step(
            own,
            partner,
            path,
            idx,
            params,
            CORRIDOR,
            window=window,
            frame=FRAME,
            guide=guide,
            correction=correction,
        )
    for i in range(n):
        p = {k: float(v[i]) for k, v in params.items() if k != "goal_heading"}
        p["hx"], p["hy"] = params["goal_heading"][i].tolist()
        try:
            dx, dy, k = law_one.step_one(
                tuple(own[i]),
                tuple(partner[i]),
                guide,
                i,
                int(idx[i]),
                p,
                FRAME,
                window,
                correction,
            )
        except law_one.Diverged:
            # numpy divided by zero: a robot centre inside the turn's inside (in the wall)
            x, y = FRAME.to_frame(own[i])
            assert x >= 0.0 and y >= 0.0
            continue
        assert bits(dx, dy) == bits(*move[i]), (i, (dx, dy), move[i])
        assert k == nearest[i]


def test_ties_follow_numpy():
    """np.maximum gives its second argument on ties of signed zeros and NaN from either
    side; the twins' hand-written helper must, where Python's max does not."""
    for a, b in [(0.0, -0.0), (-0.0, 0.0), (np.nan, 1.0), (1.0, np.nan), (2.0, 1.0)]:
        assert bits(law_one._max(a, b)) == bits(float(np.maximum(a, b)))
    assert bits(max(0.0, -0.0)) != bits(float(np.maximum(0.0, -0.0)))


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(-300, 300).map(lambda v: round(v, 1)), min_size=4, max_size=4))
def test_in_corner_twin(c):
    from hybridteam.modes.ladder.kernel import in_corner as array_in_corner

    expected = array_in_corner(*(np.array([v]) for v in c), FRAME.width_in, FRAME.width_out)
    assert in_corner(*c, FRAME.width_in, FRAME.width_out) == bool(expected[0])


def _variant(tmp_path, name: str, *, kr: float = 0.0, correction: str = "scaled"):
    """The sample team without its clearance series and requirements (the single-run
    sample path), with both robots' k_r and the correction reading given."""
    text = SAMPLE.read_text().split("requirements:")[0]
    text = text.replace("clearance: true", f"clearance: false\n      correction: {correction}")
    text = text.replace("kr: 0,", f"kr: {kr},")
    path = tmp_path / f"{name}.yaml"
    path.write_text(text)
    return load(path)


@pytest.mark.parametrize("case", ["sample", "rotation", "ensemble"])
def test_engine_runs_are_the_same_without_the_twins(tmp_path, case):
    """Whole runs with the float twins (a run of up to 4 instances) and with them switched
    off (the numpy versions for every size): the same trace, byte for byte."""
    if case == "sample":  # the Section 4 run to its success, with its clearance series
        team, n, over, duration = load(SAMPLE), 1, None, None
    elif case == "rotation":  # k_r > 0: the rotation vector and the goal heading
        team = _variant(tmp_path, "rotation", kr=0.5, correction="capped")
        n, over, duration = 1, None, 300
    else:  # still going, stuck (too slow to make progress), a broken link
        team, n = _variant(tmp_path, "ensemble", correction="distance"), 3
        over = {
            "R1.v_max": [2.0, 0.004, 2.0],
            "R2.v_max": [2.0, 0.004, 2.0],
            "R1.olim": [10.0, 10.0, 0.5],
        }
        duration = 300
    assert n <= min(carry.FEW, world.FEW) and FLOAT_PATHS.on  # (the twins' size)
    runs = [simulate(team, n=n, seed=3, overrides=over, duration=duration)]
    with FLOAT_PATHS.off():  # the numpy versions for every size
        runs.append(simulate(team, n=n, seed=3, overrides=over, duration=duration))
    assert runs[0].to_json() == runs[1].to_json()
    outcomes = list(runs[0].outcomes)
    if case == "ensemble":
        assert outcomes == ["ok", "stuck", "link_broken"]
    elif case == "sample":
        assert outcomes == ["success"]


def test_the_corridor_twin_declines_coinciding_robots_and_changes_nothing():
    """Two robots at one point make the springs' equilibrium divide by zero: numpy gives
    inf and NaN, floats would raise. The twin then returns False before writing anything,
    and the array version runs (a run cannot start that way: see the next test)."""
    from hybridteam.modes.ladder.world_one import update_few

    from hybridteam.engine.compile.compiler import compile_team
    from hybridteam.engine.run.simulator import Simulator

    sim = Simulator(compile_team(load(SAMPLE)), duration=1.0)
    sim._initialize()
    corridor = sim.ensemble.world.components[0]
    before = {k: getattr(corridor, k).copy() for k in ("tips", "prev", "steps", "path")}

    class Together:
        def pose(self, a, idx):
            return np.array([[100.0, 70.0, 0.0]])

    assert update_few(corridor, Together(), np.array([0])) is False
    for k, v in before.items():
        assert getattr(corridor, k).tobytes() == v.tobytes(), k


def test_robots_starting_at_one_point_are_refused_at_the_corridor(tmp_path, capsys):
    from hybridteam.cli import main

    path = tmp_path / "together.yaml"
    path.write_text(SAMPLE.read_text().replace("y: start_gap + length", "y: start_gap"))
    assert main(["run", str(path), "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "together.yaml:14:" in err and "world[0]" in err
    assert "start at the same point (100, 70)" in err
    assert not (tmp_path / "out").exists()
