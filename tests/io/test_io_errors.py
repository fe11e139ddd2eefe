"""Tests for hybridteam.io.errors: pydantic errors become located, plain-words messages.

The models below are defined here (not imported from the real schema) so the expected
messages depend only on this file; line/column numbers are counted by hand.
"""

from __future__ import annotations

import textwrap
from enum import StrEnum
from typing import Annotated, Any, Literal

import pytest
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from hybridteam.io.errors import did_you_mean, located_errors
from hybridteam.io.yamlpos import load_yaml


class Strict(BaseModel):
    model_config = ConfigDict(extra="forbid")


class Transition(Strict):
    to: str
    guard: str | None = None
    reset: dict[str, str] = {}


class Mode(Strict):
    flow: dict[str, str] = {}
    on: list[Transition] = []


class Unicycle(Strict):
    kind: Literal["unicycle"]
    speed: Annotated[float, Field(gt=0)]
    modes: dict[str, Mode] = {}


class Drone(Strict):
    kind: Literal["drone"]
    altitude: float
    rotors: int = 4


class Circle(Strict):
    centre: tuple[float, float]
    radius: float


class Square(Strict):
    centre: tuple[float, float]
    side: float


class Network(Strict):
    loss: float = 0.0
    mode: Literal["broadcast", "unicast"] = "broadcast"

    @field_validator("loss")
    @classmethod
    def _loss_is_a_probability(cls, value: float) -> float:
        if not 0 <= value <= 1:
            raise ValueError("loss must be between 0 and 1")
        return value


class Team(Strict):
    name: str
    agents: dict[str, Annotated[Unicycle | Drone, Field(discriminator="kind")]]
    network: Network | None = None
    enabled: bool = True
    seeds: list[int] = []
    obstacles: list[Circle | Square] = []


def errors_for(text: str, model: type[BaseModel] = Team) -> list[str]:
    data, positions = load_yaml(textwrap.dedent(text).lstrip("\n"), filename="team.yaml")
    with pytest.raises(ValidationError) as info:
        Team.model_validate(data)
    return [str(e) for e in located_errors(info.value, model, data, positions, "team.yaml")]


def test_did_you_mean() -> None:
    assert did_you_mean("gaurd", ["to", "guard", "reset"]) == "did you mean 'guard'?"
    assert did_you_mean("Guard", ["to", "guard"]) == "did you mean 'guard'?"
    assert did_you_mean("xyz", ["to", "guard"]) is None
    assert did_you_mean("guard", ["guard"]) is None  # not a misspelling
    assert did_you_mean("guard", []) is None


def test_typical_mistakes_are_located_and_explained() -> None:
    text = """
        name: demo
        agents:
          ball:
            kind: unicycle
            speed: -1
            modes:
              fall:
                flow: {x: v}
                on:
                  - to: bounce
                    gaurd: "h <= 0"
          drone1:
            kind: drone
            altitude: high
            rotor: 6
        network:
          loss: 2
          mode: unicst
        enabled: maybe
    """
    assert errors_for(text) == [
        "team.yaml:5:12: agents.ball.speed: must be > 0, got -1",
        "team.yaml:11:13: agents.ball.modes.fall.on[0].gaurd: unknown key 'gaurd'; "
        "did you mean 'guard'?",
        "team.yaml:14:15: agents.drone1.altitude: expected a number, got 'high'",
        "team.yaml:15:5: agents.drone1.rotor: unknown key 'rotor'; did you mean 'rotors'?",
        "team.yaml:17:9: network.loss: loss must be between 0 and 1",
        "team.yaml:18:9: network.mode: expected one of 'broadcast', 'unicast', got 'unicst'; "
        "did you mean 'unicast'?",
        "team.yaml:19:10: enabled: expected true or false, got 'maybe'",
    ]


def test_missing_keys_tags_and_wrong_kinds_of_value() -> None:
    text = """
        # no name
        agents:
          ball:
            kind: unicylce
          cart:
            knd: drone
          box: [1, 2]
        seeds: [1, x]
        network: 5
    """
    assert errors_for(text) == [
        "team.yaml:1:1: missing required key 'name'",
        "team.yaml:4:11: agents.ball.kind: unknown kind 'unicylce'; expected one of "
        "'unicycle', 'drone'; did you mean 'unicycle'?",
        "team.yaml:6:5: agents.cart: missing required key 'kind'; is 'knd' a misspelling of it?",
        "team.yaml:7:8: agents.box: expected a mapping, got [1, 2]",
        "team.yaml:8:12: seeds[1]: expected an integer, got 'x'",
        "team.yaml:9:10: network: expected a mapping, got 5",
    ]


def test_missing_key_inside_a_union_member_points_at_its_mapping() -> None:
    text = """
        name: demo
        agents:
          d:
            kind: drone
            rotors: 2
    """
    assert errors_for(text) == ["team.yaml:4:5: agents.d: missing required key 'altitude'"]


def test_plain_union_keeps_only_the_member_the_user_meant() -> None:
    text = """
        name: demo
        agents: {}
        obstacles:
          - radius: 1
            centre: [0, 0]
          - side: 2
            centre: [1, nope]
          - centre: [3, 3]
            radus: 1
          - centre: [4, 4]
            radius: 1
            sid: 3
    """
    assert errors_for(text) == [
        "team.yaml:7:17: obstacles[1].centre[1]: expected a number, got 'nope'",
        # the typo explains the missing 'radius'; no noise from the Square member
        "team.yaml:9:5: obstacles[2].radus: unknown key 'radus'; did you mean 'radius'?",
        # best match is Circle (has 'radius'), so 'sid' gets no Square hint
        "team.yaml:12:5: obstacles[3].sid: unknown key 'sid'",
    ]


def test_union_of_scalar_types_merges_expectations() -> None:
    class Pick(Strict):
        value: int | str

    data, positions = load_yaml("value: [1, 2]\n", filename="p.yaml")
    with pytest.raises(ValidationError) as info:
        Pick.model_validate(data)
    found = located_errors(info.value, Pick, data, positions, "p.yaml")
    assert [str(e) for e in found] == [
        "p.yaml:1:8: value: expected an integer or a string, got [1, 2]"
    ]


def test_error_attributes_and_long_inputs_are_truncated() -> None:
    long_text = "x" * 100
    data, positions = load_yaml(f"name: demo\nagents: {{}}\nenabled: {long_text}\n")
    with pytest.raises(ValidationError) as info:
        Team.model_validate(data)
    (error,) = located_errors(info.value, Team, data, positions, "t.yaml")
    assert (error.file, error.line, error.column, error.path) == ("t.yaml", 3, 10, ("enabled",))
    shown = repr(long_text)[:37] + "..."
    assert error.message == f"expected true or false, got {shown}"
    assert len(shown) == 40


def test_unresolvable_model_still_reports_unknown_key_without_hint() -> None:
    text = """
        name: demo
        agents:
          ball:
            kind: drone
            altitud: 3
    """
    # model given as plain BaseModel: the governing model cannot be found, so no hint
    assert errors_for(text, model=BaseModel) == [
        "team.yaml:4:5: agents.ball: missing required key 'altitude'",
        "team.yaml:5:5: agents.ball.altitud: unknown key 'altitud'",
    ]
    # with the real model the typo is recognised and the missing key is not repeated
    assert errors_for(text) == [
        "team.yaml:5:5: agents.ball.altitud: unknown key 'altitud'; did you mean 'altitude'?",
    ]


def test_model_level_validator_and_dict_key_errors() -> None:
    class Ranges(Strict):
        limits: dict[Annotated[str, Field(pattern=r"^[a-z]+$")], float]
        low: float = 0
        high: float = 1

        @field_validator("high")
        @classmethod
        def _ordered(cls, value: float, info: Any) -> float:
            if value < info.data.get("low", 0):
                raise ValueError("high must not be below low")
            return value

    text = "limits:\n  ok: 1\n  Bad1: 2\nlow: 5\nhigh: 3\n"
    data, positions = load_yaml(text, filename="r.yaml")
    with pytest.raises(ValidationError) as info:
        Ranges.model_validate(data)
    assert [str(e) for e in located_errors(info.value, Ranges, data, positions, "r.yaml")] == [
        "r.yaml:3:3: limits.Bad1: must match the pattern '^[a-z]+$', got 'Bad1'",
        "r.yaml:5:7: high: high must not be below low",
    ]


def test_errors_are_sorted_and_deduplicated() -> None:
    text = """
        name: demo
        agents:
          zed: {kind: drone, altitude: x}
          abe: {kind: drone, altitude: y}
        obstacles:
          - {centre: [0, 0], colour: red}
    """
    # the obstacle fits Circle and Square equally: both members report 'colour', shown once
    assert errors_for(text) == [
        "team.yaml:3:32: agents.zed.altitude: expected a number, got 'x'",
        "team.yaml:4:32: agents.abe.altitude: expected a number, got 'y'",
        "team.yaml:6:5: obstacles[0]: missing required key 'radius'",
        "team.yaml:6:5: obstacles[0]: missing required key 'side'",
        "team.yaml:6:22: obstacles[0].colour: unknown key 'colour'",
    ]


def test_enum_and_single_literal() -> None:
    class Colour(StrEnum):
        RED = "red"
        BLUE = "blue"

    class Paint(Strict):
        colour: Colour
        finish: Literal["matt"] = "matt"

    data, positions = load_yaml("colour: rd\nfinish: gloss\n", filename="p.yaml")
    with pytest.raises(ValidationError) as info:
        Paint.model_validate(data)
    assert [str(e) for e in located_errors(info.value, Paint, data, positions, "p.yaml")] == [
        "p.yaml:1:9: colour: expected one of 'red', 'blue', got 'rd'; did you mean 'red'?",
        "p.yaml:2:9: finish: expected 'matt', got 'gloss'",
    ]
