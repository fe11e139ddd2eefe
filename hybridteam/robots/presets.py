"""Robot presets: named robot models (Labmate, XR4000, Scout, omni) declared as data.

A team says ``model: xr4000`` and overrides only what differs for its robot, so the models
live in ``presets.yaml`` rather than in code, and a preset is *resolved* by deep-merging the
team's overrides onto it before strict validation: an override that names a field the
preset does not have is an error with a "did you mean", not a silently ignored line.
Errors name the path inside the preset (``sensors.ir.max_rang``); the caller prefixes the
path of the ``model:`` entry in its own file.
"""

from __future__ import annotations

import copy
import math
import os
from collections.abc import Mapping
from functools import cache
from importlib import resources
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    ValidationInfo,
    create_model,
    field_validator,
    model_validator,
)

from hybridteam.dynamics.plants import KINEMATICS
from hybridteam.errors import ModelError, ModelErrors, did_you_mean
from hybridteam.io.errors import located_errors
from hybridteam.io.yamlpos import SourceError, load_yaml
from hybridteam.world.sensors import RangeRing

Positive = Annotated[float, Field(gt=0)]
NonNegative = Annotated[float, Field(ge=0)]


class Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


class KinematicsSpec(Strict):
    """Kinematics and actuator saturation; an input without a limit is free."""

    kind: Literal["unicycle", "holonomic"]
    limits: dict[str, tuple[float, float]] = Field(default_factory=dict)

    @field_validator("limits")
    @classmethod
    def _limits_name_inputs(
        cls, v: dict[str, tuple[float, float]], info: ValidationInfo
    ) -> dict[str, tuple[float, float]]:
        kind = info.data.get("kind")
        inputs = KINEMATICS[kind]().input_names if kind in KINEMATICS else ()
        for name, (lo, hi) in v.items():
            if inputs and name not in inputs:
                hint = did_you_mean(name, inputs) or f"its inputs are {', '.join(inputs)}"
                raise ValueError(f"a {kind} has no input {name!r}; {hint}")
            if not lo <= hi:
                raise ValueError(f"{name}: need [lo, hi] with lo <= hi, got [{lo}, {hi}]")
        return v


class FootprintSpec(Strict):
    """The disk that encloses the base."""

    radius: Positive


class RangeRingSpec(Strict):
    """A ring of range sensors; built into a :class:`RangeRing` by :meth:`RobotPreset.ring`."""

    kind: Literal["range_ring"]
    count: Annotated[int, Field(ge=1)]
    max_range: Positive
    min_range: NonNegative = 0.0
    mount_radius: NonNegative | None = Field(None, description="default: on the hull")
    offset_deg: float = Field(0.0, description="first beam, from the heading, CCW")
    cone_deg: Annotated[float, Field(ge=0, lt=180)] = Field(
        0.0, description="full beam width; 0: a single line"
    )
    rays_per_beam: Annotated[int, Field(ge=2)] = Field(
        5, description="rays sampling a cone (unused when cone_deg is 0)"
    )

    @model_validator(mode="after")
    def _ranges(self) -> RangeRingSpec:
        if self.min_range >= self.max_range:
            raise ValueError(
                f"min_range ({self.min_range}) must be below max_range ({self.max_range})"
            )
        return self


class EncodersSpec(Strict):
    """Joint encoders (wheels, arm, lift): odometry and joint state."""

    kind: Literal["encoders"]
    joints: Annotated[list[str], Field(min_length=1)]


class ContactSpec(Strict):
    """A bumper ring around the footprint, split into ``segments`` equal contact arcs."""

    kind: Literal["contact"]
    segments: Annotated[int, Field(ge=1)]
    offset_deg: float = 0.0


class ArmSensorSpec(Strict):
    """The manipulator's sensed state (the Labmate's x_a), named as laws will see it."""

    kind: Literal["arm"]
    state: Annotated[list[str], Field(min_length=1)]


Sensor = Annotated[
    RangeRingSpec | EncodersSpec | ContactSpec | ArmSensorSpec, Field(discriminator="kind")
]


class Grasp(Strict):
    """What every manipulator shares: the compliant grasp of the ``payload`` component, with
    its names (``mount``, ``spring``, ``limit``), so a grasp can default to them."""

    mount: tuple[float, float] = Field((0.0, 0.0), description="[x, y] in the robot frame")
    spring: Positive = Field(description="planar spring constant of the grasp")
    limit: Positive = Field(description="the grasp breaks past this offset")


class CompliantArmSpec(Grasp):
    """A planar arm held compliant by control: offsets (x_a, y_a) and a rotation theta_a."""

    kind: Literal["compliant_arm"]
    angle_spring: Positive = Field(description="spring constant of theta_a")
    angle_limit: Positive = Field(description="largest |theta_a|")


class LiftSpec(Strict):
    """One vertical prismatic joint."""

    travel: tuple[float, float]
    speed: Positive

    @field_validator("travel")
    @classmethod
    def _ordered(cls, v: tuple[float, float]) -> tuple[float, float]:
        if not v[0] < v[1]:
            raise ValueError(f"travel must be [low, high] with low < high, got {list(v)}")
        return v


class ForkliftSpec(Grasp):
    """Forks on a vertical prismatic joint; the load rests on them."""

    kind: Literal["forklift"]
    lift: LiftSpec


class SpringLinkSpec(Grasp):
    """A force sensor at the robot's centre, modelled as an ideal spring (ladder paper)."""

    kind: Literal["spring_link"]


Manipulator = Annotated[
    CompliantArmSpec | ForkliftSpec | SpringLinkSpec, Field(discriminator="kind")
]


class RobotPreset(Strict):
    """One robot model: plant, footprint, sensors and manipulator (see ``presets.yaml``)."""

    description: str = ""
    length_unit: str = "m"
    plant: KinematicsSpec
    footprint: FootprintSpec
    sensors: dict[str, Sensor] = Field(default_factory=dict)
    manipulator: Manipulator | None = None

    @field_validator("sensors")
    @classmethod
    def _sensor_names(cls, v: dict[str, Any]) -> dict[str, Any]:
        bad = [name for name in v if not name.isidentifier() or name.startswith("__")]
        if bad:
            raise ValueError(f"sensor name {bad[0]!r} is not valid: use letters, digits and _")
        return v

    @property
    def inputs(self) -> tuple[str, ...]:
        """The plant's input names, in the order the engine stacks them."""
        return KINEMATICS[self.plant.kind]().input_names

    def bounds(self) -> tuple[list[float], list[float]]:
        """Lower and upper input limits in :attr:`inputs` order (+-inf where free)."""
        free = (-math.inf, math.inf)
        pairs = [self.plant.limits.get(name, free) for name in self.inputs]
        return [lo for lo, _ in pairs], [hi for _, hi in pairs]

    def ring(self, name: str) -> RangeRing:
        """The range ring called ``name``, ready to :meth:`~RangeRing.read`."""
        spec = self.sensors.get(name)
        if not isinstance(spec, RangeRingSpec):
            rings = [n for n, s in self.sensors.items() if isinstance(s, RangeRingSpec)]
            what = "is not a range ring" if spec is not None else "is not a sensor"
            hint = did_you_mean(name, rings) or (
                f"its range rings: {', '.join(rings)}" if rings else "it has no range rings"
            )
            raise ModelError(("sensors", name), f"{name!r} {what} of this robot", hint=hint)
        cone = spec.cone_deg > 0.0
        return RangeRing(
            count=spec.count,
            max_range=spec.max_range,
            min_range=spec.min_range,
            mount_radius=(
                self.footprint.radius if spec.mount_radius is None else spec.mount_radius
            ),
            offset=math.radians(spec.offset_deg),
            half_angle=math.radians(spec.cone_deg / 2.0) if cone else 0.0,
            rays_per_beam=spec.rays_per_beam if cone else 1,
            name=name,
        )

    def rings(self) -> dict[str, RangeRing]:
        """Every range ring of the robot, by sensor name."""
        return {n: self.ring(n) for n, s in self.sensors.items() if isinstance(s, RangeRingSpec)}


class PresetErrors(Exception):
    """All problems of a presets file, each located (``file:line:column: path: message``)."""

    def __init__(self, errors: list[SourceError]) -> None:
        self.errors = errors
        super().__init__("\n".join(map(str, errors)))


def _shipped() -> str:
    return str(resources.files("hybridteam.robots") / "presets.yaml")


@cache
def _documents(path: str, version: tuple[int, int]) -> dict[str, dict]:
    """The validated raw mapping of each preset in a file (cached per mtime and size).

    The file is validated as one model with a field per preset, so every error is located
    in the file by the same translator the team files use.
    """
    data, positions = load_yaml(Path(path), filename=path)
    bad = [
        name
        for name in data
        if not isinstance(name, str) or not name.isidentifier() or name.startswith("_")
    ]
    if bad:
        raise PresetErrors(
            [
                positions.error(
                    (name,),
                    f"robot model name {name!r} is not valid: use letters, digits and _",
                    at_key=True,
                )
                for name in bad
            ]
        )
    fields: dict[str, Any] = {name: (RobotPreset, ...) for name in data}
    model = create_model("PresetsFile", __base__=Strict, **fields)
    try:
        model.model_validate(data)
    except ValidationError as exc:
        raise PresetErrors(located_errors(exc, model, data, positions, path)) from None
    return data


def _raw(source: str | os.PathLike | None) -> dict[str, dict]:
    path = _shipped() if source is None else os.fspath(source)
    try:
        stat = os.stat(path)
        return _documents(path, (stat.st_mtime_ns, stat.st_size))
    except OSError as exc:
        raise PresetErrors([SourceError(path, message=f"cannot read: {exc.strerror}")]) from None
    except SourceError as exc:
        raise PresetErrors([exc]) from None


def load_presets(source: str | os.PathLike | None = None) -> dict[str, RobotPreset]:
    """Every preset of a presets file (default: the shipped ``presets.yaml``), by name."""
    return {name: RobotPreset.model_validate(body) for name, body in _raw(source).items()}


def deep_merge(base: Mapping[str, Any], overrides: Mapping[str, Any]) -> dict[str, Any]:
    """``base`` with ``overrides`` merged in: mappings merge key by key, anything else
    (numbers, lists such as ``[lo, hi]``) replaces, and ``None`` removes the key.

    A mapping whose ``kind`` differs from the one it overrides replaces it whole: fields of
    a forklift mean nothing to a compliant arm.
    """
    out = copy.deepcopy(dict(base))
    for key, value in overrides.items():
        old = out.get(key)
        if value is None:
            out.pop(key, None)
        elif (
            isinstance(value, Mapping)
            and isinstance(old, Mapping)
            and value.get("kind", old.get("kind")) == old.get("kind")
        ):
            out[key] = deep_merge(out[key], value)
        else:
            out[key] = copy.deepcopy(value)
    return out


def resolve(
    name: str, overrides: Mapping[str, Any] | None = None, source: str | os.PathLike | None = None
) -> RobotPreset:
    """The preset ``name`` with a team's ``overrides`` deep-merged onto it, validated.

    Raises :class:`~hybridteam.errors.ModelError` (one problem) or
    :class:`~hybridteam.errors.ModelErrors` with paths relative to the override mapping:
    an unknown model, an unknown sensor or a manipulator the model lacks (a new one needs
    its ``kind``), an unknown field.
    """
    presets = _raw(source)
    if name not in presets:
        raise ModelError(
            (),
            f"unknown robot model {name!r}",
            hint=did_you_mean(name, presets) or f"known: {', '.join(presets)}",
        )
    overrides = {} if overrides is None else overrides
    if not isinstance(overrides, Mapping):
        raise ModelError((), f"overrides of {name!r} must be a mapping, got {overrides!r}")
    base = presets[name]
    sensors = overrides.get("sensors")
    if isinstance(sensors, Mapping):
        known = base.get("sensors") or {}
        for sensor, spec in sensors.items():
            if sensor not in known and not (isinstance(spec, Mapping) and "kind" in spec):
                hint = did_you_mean(str(sensor), known) or "a new sensor needs its 'kind'"
                raise ModelError(
                    ("sensors", sensor), f"{name} has no sensor {sensor!r}", hint=hint, at_key=True
                )
    arm = overrides.get("manipulator")
    if isinstance(arm, Mapping) and not base.get("manipulator") and "kind" not in arm:
        raise ModelError(
            ("manipulator",),
            f"{name} has no manipulator",
            hint="a new one needs its 'kind' (compliant_arm, forklift or "
            "spring_link), spring and limit",
            at_key=True,
        )
    merged = deep_merge(base, overrides)
    try:
        return RobotPreset.model_validate(merged)
    except ValidationError as exc:
        _, nowhere = load_yaml("{}", filename=f"<robot model {name}>")
        found = located_errors(exc, RobotPreset, merged, nowhere, nowhere.filename)
        errors = [
            ModelError(e.path, e.message, at_key=e.message.startswith("unknown key")) for e in found
        ]
        raise (errors[0] if len(errors) == 1 else ModelErrors(errors)) from None
