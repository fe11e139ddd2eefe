"""Robot presets: the shipped models, deep-merged overrides, and the errors users see."""

from __future__ import annotations

import math
import textwrap

import numpy as np
import pytest

from hybridteam.errors import ModelError, ModelErrors
from hybridteam.robots import PresetErrors, RobotPreset, load_presets, resolve
from hybridteam.robots.presets import deep_merge
from hybridteam.world.geometry import rectangle
from hybridteam.world.sensors import RangeRing, detect, polygon_edges


def test_every_preset_loads_and_builds_its_rings():
    presets = load_presets()
    assert sorted(presets) == ["labmate", "omni", "scout", "xr4000"]
    for name, preset in presets.items():
        assert isinstance(preset, RobotPreset), name
        assert preset.footprint.radius > 0
        lower, upper = preset.bounds()
        assert len(lower) == len(upper) == len(preset.inputs)
        assert all(lo <= hi for lo, hi in zip(lower, upper, strict=True))
        for ring in preset.rings().values():
            assert isinstance(ring, RangeRing)
        assert resolve(name) == preset


def test_the_xr4000_has_24_ir_and_24_sonar_beams_and_three_inputs():
    xr = load_presets()["xr4000"]
    assert xr.plant.kind == "holonomic" and xr.inputs == ("vx", "vy", "omega")
    ir, sonar = xr.ring("ir"), xr.ring("sonar")
    assert (ir.count, sonar.count) == (24, 24)
    assert ir.rays_per_beam == 1 and ir.max_range == pytest.approx(0.5)
    assert sonar.rays_per_beam == 5 and sonar.half_angle == pytest.approx(math.radians(12.5))
    assert ir.mount_radius == sonar.mount_radius == xr.footprint.radius  # on the hull
    assert xr.manipulator.kind == "forklift"
    assert xr.manipulator.lift.travel[0] < xr.manipulator.lift.travel[1]
    # Its front IR sees a wall 0.3 m ahead of the hull; the one behind sees nothing.
    room = polygon_edges(rectangle(0.0, -2.0, 10.0, 2.0))
    poses = np.array([[10.0 - 0.33 - 0.3, 0.0, 0.0], [10.0 - 0.33 - 0.3, 0.0, math.pi]])
    readings = ir.read(poses, room)
    assert readings.shape == (2, 24)
    assert readings[0, 0] == pytest.approx(0.3)
    assert detect(readings, 0.4, ir.sector(0.0, math.radians(30))).tolist() == [True, False]


def test_the_labmate_is_a_unicycle_with_a_compliant_arm():
    lab = load_presets()["labmate"]
    assert lab.plant.kind == "unicycle" and lab.inputs == ("v", "omega")
    assert lab.bounds() == ([-0.5, -1.0], [0.5, 1.0])
    assert lab.manipulator.kind == "compliant_arm"
    assert lab.manipulator.spring > 0 and lab.manipulator.limit > 0
    assert lab.manipulator.angle_spring > 0 and lab.manipulator.angle_limit > 0
    assert lab.sensors["arm"].state == ["x_a", "y_a", "theta_a"]
    assert {s.kind for s in lab.sensors.values()} == {"encoders", "arm"}
    assert lab.rings() == {}
    with pytest.raises(ModelError, match="no range rings"):
        lab.ring("ir")


def test_the_scout_and_the_omni_robot():
    presets = load_presets()
    scout = presets["scout"]
    assert scout.plant.kind == "unicycle" and scout.manipulator is None
    assert scout.ring("sonar").count == 16 and scout.sensors["bumper"].kind == "contact"
    with pytest.raises(ModelError, match="'sonr' is not a sensor of this robot; did you"):
        scout.ring("sonr")
    with pytest.raises(ModelError, match="'bumper' is not a range ring"):
        scout.ring("bumper")
    omni = presets["omni"]
    assert omni.plant.kind == "holonomic" and omni.plant.limits == {}
    assert omni.bounds() == ([-math.inf] * 3, [math.inf] * 3)
    from hybridteam.modes.ladder.params import Robot  # the ladder library's defaults

    assert omni.footprint.radius == Robot().radius
    assert (omni.manipulator.spring, omni.manipulator.limit) == (Robot().sc, Robot().olim)


def test_an_override_changes_one_leaf_and_keeps_the_rest():
    base = load_presets()["xr4000"]
    tuned = resolve(
        "xr4000", {"sensors": {"ir": {"max_range": 0.6}}, "plant": {"limits": {"vx": [-0.3, 0.3]}}}
    )
    assert tuned.ring("ir").max_range == 0.6
    assert tuned.plant.limits == {**base.plant.limits, "vx": (-0.3, 0.3)}
    want = base.model_dump()
    want["sensors"]["ir"]["max_range"] = 0.6
    want["plant"]["limits"]["vx"] = (-0.3, 0.3)
    assert tuned.model_dump() == want
    assert load_presets()["xr4000"] == base  # the preset itself is untouched


def test_overrides_remove_replace_and_add():
    lab = resolve("labmate", {"manipulator": None})
    assert lab.manipulator is None
    scout = resolve(
        "scout",
        {"sensors": {"bumper": None, "ir": {"kind": "range_ring", "count": 8, "max_range": 0.4}}},
    )
    assert sorted(scout.sensors) == ["encoders", "ir", "sonar"]
    assert scout.ring("ir").mount_radius == scout.footprint.radius
    swapped = resolve(
        "labmate", {"manipulator": {"kind": "spring_link", "spring": 2.0, "limit": 0.2}}
    )
    assert swapped.manipulator.kind == "spring_link" and swapped.manipulator.mount == (0, 0)
    bigger = resolve("xr4000", {"footprint": {"radius": 0.4}})
    assert bigger.ring("sonar").mount_radius == 0.4  # rings sit on the hull
    assert deep_merge({"a": {"b": 1, "c": [1, 2]}, "d": 1}, {"a": {"c": [3]}, "d": None}) == {
        "a": {"b": 1, "c": [3]}
    }


def test_unknown_model_sensor_and_field_are_named():
    with pytest.raises(ModelError, match="unknown robot model 'xr400'; did you mean 'xr4000'"):
        resolve("xr400")
    with pytest.raises(ModelError, match="known: labmate, xr4000, scout, omni"):
        resolve("pr2")
    with pytest.raises(ModelError, match="xr4000 has no sensor 'irr'; did you mean 'ir'") as exc:
        resolve("xr4000", {"sensors": {"irr": {"max_range": 1.0}}})
    assert exc.value.path == ("sensors", "irr")
    with pytest.raises(ModelError, match="unknown key 'max_rang'; did you mean 'max_range'") as exc:
        resolve("xr4000", {"sensors": {"ir": {"max_rang": 0.6}}})
    assert exc.value.path == ("sensors", "ir", "max_rang")
    with pytest.raises(ModelError, match="holonomic has no input 'v'"):
        resolve("xr4000", {"plant": {"limits": {"v": [-1, 1]}}})
    with pytest.raises(ModelError, match="lo <= hi"):
        resolve("scout", {"plant": {"limits": {"v": [1, -1]}}})
    with pytest.raises(ModelErrors) as many:
        resolve("scout", {"footprint": {"radius": -1}, "plant": {"kind": "unicyle"}})
    assert {e.path for e in many.value.errors} == {("footprint", "radius"), ("plant", "kind")}
    with pytest.raises(ModelError, match="must be a mapping"):
        resolve("scout", ["v"])  # type: ignore[arg-type]


def test_a_broken_presets_file_is_reported_with_lines(tmp_path):
    path = tmp_path / "robots.yaml"
    path.write_text(
        textwrap.dedent("""\
        tiny:
          plant: {kind: unicycle}
          footprint: {radius: 0.1}
          sensors:
            sonar: {kind: range_ring, count: 8, max_range: 3, cone_deg: 25, rays_per_bem: 3}
        """)
    )
    with pytest.raises(PresetErrors) as exc:
        load_presets(path)
    assert str(exc.value) == (
        f"{path}:5:69: tiny.sensors.sonar.rays_per_bem: unknown key "
        "'rays_per_bem'; did you mean 'rays_per_beam'?"
    )
    path.write_text(path.read_text().replace("rays_per_bem", "rays_per_beam"))
    assert resolve("tiny", source=path).ring("sonar").rays_per_beam == 3
