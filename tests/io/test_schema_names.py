"""Every field of the file schemas that names something refuses a bad name, saying what it
names (``hybridteam/io/schema.py``: one validator definition, ``named``, for all of them)."""

from __future__ import annotations

from typing import Any

import pytest
from pydantic import BaseModel, ValidationError

from hybridteam.io import schema as S

BAD = "1x"  # starts with a digit
INVALID = "is not valid: use letters, digits and _, not starting with a digit"
AGENT = {"plant": {"kind": "flow"}, "modes": {"M": {}}}
RESERVED = "message name 'ack' is the acknowledged layer's own message type"

#: (schema, document, the field's location, what the message says), one per named field
CASES: list[tuple[type[BaseModel], dict[str, Any], tuple[str, ...], str]] = [
    (S.SendSchema, {"send": BAD}, ("send",), f"message name '{BAD}' {INVALID}"),
    (S.SendSchema, {"send": "a", "to": BAD}, ("to",), f"agent name '{BAD}' {INVALID}"),
    (S.SendSchema, {"send": "a", "socket": "__s"}, ("socket",), "socket name '__s' may not"),
    (S.RaiseSchema, {"raise": "a..b"}, ("raise",), "event name 'a..b' is not valid"),
    (S.TransitionSchema, {"on": BAD}, ("on",), f"message or event name '{BAD}' is not valid"),
    (S.ModeSchema, {"protocol": "p", "roles": {BAD: {}}}, ("roles",), f"role name '{BAD}'"),
    (S.ModeSchema, {"modes": {}}, ("modes",), "'modes' is empty; remove it or declare a mode"),
    (S.ModeSchema, {"modes": {BAD: {}}}, ("modes",), f"mode name '{BAD}' {INVALID}"),
    (S.PlantSchema, {"kind": "flow", "state": {BAD: 0}}, ("state",), f"state name '{BAD}'"),
    (S.AgentSchema, {**AGENT, "parameters": {BAD: 1}}, ("parameters",), "parameter/variable"),
    (S.AgentSchema, {**AGENT, "variables": {BAD: 1}}, ("variables",), "parameter/variable"),
    (S.AgentSchema, {**AGENT, "modes": {}}, ("modes",), "an agent needs at least one mode"),
    (S.AgentSchema, {**AGENT, "modes": {BAD: {}}}, ("modes",), f"mode name '{BAD}'"),
    (S.ScenarioSchema, {"at": 0, "agent": BAD, "raise": "e"}, ("agent",), "agent name"),
    (S.ScenarioSchema, {"at": 0, "agent": "a", "raise": BAD}, ("raise",), "event name"),
    (S.MessageDeclSchema, {"socket": BAD}, ("socket",), f"socket name '{BAD}'"),
    (S.MessageDeclSchema, {"fields": [BAD]}, ("fields",), f"field name '{BAD}'"),
    (S.EndSchema, {"agents": [BAD]}, ("agents",), f"agent name '{BAD}'"),
    (S.TeamFile, {"team": "t\x1b[2J", "agents": {"a": AGENT}}, ("team",), "control characters"),
    (S.TeamFile, {"team": "t", "agents": {}}, ("agents",), "a team needs at least one agent"),
    (S.TeamFile, {"team": "t", "agents": {BAD: AGENT}}, ("agents",), f"agent name '{BAD}'"),
    (
        S.TeamFile,
        {"team": "t", "agents": {"a": AGENT}, "parameters": {BAD: 1}},
        ("parameters",),
        f"parameter name '{BAD}'",
    ),
    (
        S.TeamFile,
        {"team": "t", "agents": {"a": AGENT}, "requirements": {BAD: "always(true)"}},
        ("requirements",),
        f"requirement name '{BAD}'",
    ),
    (
        S.TeamFile,
        {"team": "t", "agents": {"a": AGENT}, "messages": {BAD: {}}},
        ("messages",),
        f"message name '{BAD}'",
    ),
    (S.StreamDeclSchema, {"message": BAD, "rate": 1}, ("message",), "message name"),
    (S.StreamDeclSchema, {"message": "m", "rate": 1, "while": [BAD]}, ("while",), "mode name"),
    (S.StreamDeclSchema, {"message": "m", "rate": 1, "socket": BAD}, ("socket",), "socket"),
    (S.RegionModeSchema, {"role": BAD}, ("role",), f"role name '{BAD}'"),
    (S.RegionModeSchema, {"modes": {BAD: {}}}, ("modes",), f"mode name '{BAD}'"),  # (a mode's)
    (S.RegionModeSchema, {"protocol": "p", "roles": {BAD: {}}}, ("roles",), "role name"),
    (S.RegionSchema, {"roles": [BAD], "modes": {}}, ("roles",), f"role name '{BAD}'"),
    (S.RegionSchema, {"modes": {BAD: {}}}, ("modes",), f"mode name '{BAD}'"),
    (S.OperatorSchema, {"modes": {BAD: {}}}, ("modes",), f"mode name '{BAD}'"),
    (S.OperatorSchema, {"modes": {}, "variables": {BAD: 0}}, ("variables",), "variable name"),
    (S.OperatorSchema, {"modes": {}, "parameters": {BAD: 0}}, ("parameters",), "parameter/"),
    (S.ProtocolFile, {"protocol": "p\x07"}, ("protocol",), "protocol name 'p\\x07' has control"),
    (S.ProtocolFile, {"protocol": "p", "messages": {BAD: {}}}, ("messages",), "message name"),
    # the acknowledged layer's own type: a team's "ack" would be taken for an acknowledgement
    (S.SendSchema, {"send": "ack"}, ("send",), RESERVED),
    (S.StreamDeclSchema, {"message": "ack", "rate": 1}, ("message",), RESERVED),
    (S.ProtocolFile, {"protocol": "p", "messages": {"ack": {}}}, ("messages",), RESERVED),
    (
        S.TeamFile,
        {"team": "t", "agents": {"a": AGENT}, "messages": {"ack": {}}},
        ("messages",),
        RESERVED,
    ),
]


@pytest.mark.parametrize(("schema", "doc", "loc", "says"), CASES)
def test_a_bad_name_is_refused_saying_what_it_names(schema, doc, loc, says):
    with pytest.raises(ValidationError) as exc:
        schema.model_validate(doc)
    found = [e["msg"] for e in exc.value.errors() if e["loc"][: len(loc)] == loc]
    assert any(says in msg for msg in found), (found, exc.value.errors())


def test_good_names_and_absent_ones_pass():
    """The validators refuse only bad names: dotted events, empty optional lists and
    fields not given are fine."""
    S.SendSchema.model_validate({"send": "Grant", "to": "b"})
    S.RaiseSchema.model_validate({"raise": "error.io"})
    S.TransitionSchema.model_validate({"on": None})
    S.EndSchema.model_validate({})
    S.ModeSchema.model_validate({"modes": {"A": {}}})
    S.TeamFile.model_validate({"team": "team one", "agents": {"a": AGENT}})


def test_every_name_field_is_checked_here():
    """Each named field of the schemas has its case above (a new one is added to CASES)."""
    validated = {
        (cls.__name__, field)
        for cls in vars(S).values()
        if isinstance(cls, type) and issubclass(cls, BaseModel) and cls.__module__ == S.__name__
        for dec in cls.__pydantic_decorators__.field_validators.values()
        if dec.func.__qualname__.startswith("named.")
        for field in dec.info.fields
    }
    by_alias = {"raise": "raise_", "while": "while_"}
    cased = {(schema.__name__, by_alias.get(loc[0], loc[0])) for schema, _, loc, _ in CASES}
    assert validated and validated <= cased, validated - cased


PING = """\
team: ping
agents:
  asker:
    plant: {kind: unicycle, state: {x: 0, y: 0, theta: 0}}
    initial: Idle
    modes:
      Idle:
        transitions:
          - {to: Done, after: 1.0, do: [{send: req, to: answerer}]}
      Done: {final: true}
  answerer:
    plant: {kind: unicycle, state: {x: 1, y: 0, theta: 0}}
    modes:
      Wait:
        transitions:
          - {to: Wait, on: req, do: [{send: ack, to: sender}]}
simulation: {duration: 2.0}
"""


def test_a_team_answering_with_its_own_ack_is_refused_where_it_sends_it(tmp_path, capsys):
    """A newcomer's reply named ``ack`` crashed the run (the reliable layer read it as an
    acknowledgement without an id): now ``run`` and ``verify`` refuse the file, naming the
    line and column of the send, exit 2, and write nothing."""
    from hybridteam.cli import main

    team = tmp_path / "ping.yaml"
    team.write_text(PING)
    for argv in (
        ["run", str(team), "-o", str(tmp_path / "r")],
        ["verify", str(team), "-o", str(tmp_path / "v")],
    ):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert f"{team}:16:45:" in err and RESERVED in err and "Traceback" not in err
        assert not (tmp_path / argv[3].rsplit("/", 1)[-1]).exists()
    ok = tmp_path / "reply.yaml"
    ok.write_text(PING.replace("send: ack", "send: reply"))
    assert main(["run", str(ok), "-o", str(tmp_path / "ok")]) == 0
