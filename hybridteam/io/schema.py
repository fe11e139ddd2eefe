"""pydantic schemas of the files users write: teams and mode libraries.

Every model forbids unknown keys, so a misspelt ``gaurd:`` is an error with a "did you
mean", never a silently ignored line. Names that expressions refer to (agents, modes,
parameters, variables) must be identifiers; that is checked here so the message can say
which key is wrong. ``hybridteam schema`` prints these models as JSON Schema for editors.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from typing import Annotated, Any, Literal, TypeVar

from pydantic import BaseModel, ConfigDict, Field, ValidationInfo, field_validator, model_validator

from hybridteam.engine.run.reliable import ACK
from hybridteam.errors import printable
from hybridteam.io.reqschema import RequirementEntry

NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*\Z")  # \Z: '$' would let "a\n" through
#: an event's name: names joined by dots (``error.io``), which wake transitions ``on`` each
#: prefix as SCXML's event descriptors do; no other character, as for names
EVENT = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*\Z")

ExprOrNumber = Annotated[float | str, Field(union_mode="left_to_right")]
AGENT_PARAMETERS = (
    "numbers, or expressions of the team's parameters and of this agent's "
    "parameters above (e.g. ack_timeout: 2 * latency + 0.05), re-evaluated "
    "per run"
)
PositiveFloat = Annotated[float, Field(gt=0)]
#: the coarsest ``simulation.event_tol``: crossings located more coarsely than a millisecond
#: would move a team's transitions by whole control periods
MAX_EVENT_TOL = 1e-3


#: a name's type as given: a name stays ``str``, an optional one ``str | None``
_Name = TypeVar("_Name", bound=str | None)


def check_names(names, what: str) -> None:
    for name in names:
        if not isinstance(name, str) or not NAME.match(name):
            raise ValueError(
                f"{what} name {name!r} is not valid: use letters, digits and _, "
                "not starting with a digit"
            )
        if name.startswith("__"):
            raise ValueError(f"{what} name {name!r} may not start with '__'")


def check_messages(names, what: str) -> None:
    """Message type names (the keys or items of ``names``), checked as names are, and never
    the acknowledged layer's own type: its acks travel as ``ack`` copies, so a team's own
    ``ack`` would be taken for one (and answered by no one)."""
    check_names(names, what)
    for name in names:
        if name == ACK:
            raise ValueError(
                f"{what} name {ACK!r} is the acknowledged layer's own message type "
                "(its acknowledgements); name yours differently, e.g. 'reply'"
            )


def check_message(name: _Name, what: str) -> _Name:
    """One message type name (None: not given), as :func:`check_messages` checks them."""
    if name is not None:
        check_messages([name], what)
    return name


def check_event(name: _Name, what: str) -> _Name:
    """An event's name (None: not given): names joined by dots, checked as names are."""
    if name is not None and (not isinstance(name, str) or not EVENT.match(name)):
        raise ValueError(
            f"{what} name {name!r} is not valid: use letters, digits and _, "
            "not starting with a digit (names may be joined by dots: error.io)"
        )
    if isinstance(name, str) and name.startswith("__"):
        raise ValueError(f"{what} name {name!r} may not start with '__'")
    return name


def check_title(text: str, what: str) -> str:
    """A free-text name (a team's, a protocol's) without control characters: it titles
    diagrams and plots and the terminal's summary, where an escape sequence would act."""
    if printable(text) != text:
        raise ValueError(
            f"{what} name {text!r} has control characters or lone "
            "surrogates; write it as plain text"
        )
    return text


def check_name(name: _Name, what: str) -> _Name:
    """One name (None: not given) checked as :func:`check_names` does. Message types,
    events, sockets and agents named in actions reach the diagrams, the sequence chart and
    the terminal as they are written, so they are names, never markup or control text."""
    if name is not None:
        check_names([name], what)
    return name


def named(
    *fields: str,
    what: str,
    rule: Callable[[Any, str], object] = check_name,
    empty: str | None = None,
) -> Any:
    """The validator of the name fields ``fields`` of a schema (assigned in its class body:
    ``_agent_name = named("to", what="agent")``): each value, unless not given (None),
    checked by ``rule`` as a ``what`` name — one name (:func:`check_name`, the default), an
    event's (:func:`check_event`), a title (:func:`check_title`), or the keys or items of a
    mapping or list (:func:`check_names`). ``empty``: the message refusing an empty one.

    One definition for every field that names something, so each says what it names the
    same way and a new rule is written once."""

    def validate(cls: type[BaseModel], v: Any) -> Any:
        if v is None:
            return v
        if empty is not None and not v:
            raise ValueError(empty)
        rule(v, what)
        return v

    return field_validator(*fields)(classmethod(validate))


class Strict(BaseModel):
    """Unknown keys are errors, and so are NaN and infinite numbers: no setting of a file
    means anything with them (leave a limit out to have none)."""

    model_config = ConfigDict(extra="forbid", populate_by_name=True, allow_inf_nan=False)


class SendSchema(Strict):
    """Broadcast a message (``send: Grant``), optionally to one agent only."""

    send: str = Field(description="message type")
    to: str | None = Field(None, description="receiving agent (default: every other agent)")
    socket: str = Field("control", description="socket name, e.g. control or data")
    fields: dict[str, ExprOrNumber] = Field(default_factory=dict)

    _message_name = named("send", what="message", rule=check_message)
    _agent_name = named("to", what="agent")
    _socket_name = named("socket", what="socket")


class RaiseSchema(Strict):
    """Raise a local event in the same agent (handled later in the same instant)."""

    raise_: str = Field(alias="raise", description="event name")

    _event_name = named("raise_", what="event", rule=check_event)


ActionSchema = Annotated[str | SendSchema | RaiseSchema, Field(union_mode="left_to_right")]


class TransitionSchema(Strict):
    """A guarded switch from the enclosing mode to ``to``."""

    to: str | Annotated[list[str], Field(min_length=1)] | None = Field(
        None,
        description="target mode: a unique name or a dotted path, or a list of "
        "targets in different parallel regions (none: an internal transition, actions only)",
    )
    on: str | None = Field(None, description="message type or local event that triggers it")
    after: ExprOrNumber | None = Field(None, description="seconds in the source mode")
    guard: str | None = Field(None, description="condition, e.g. 'x >= 22'")
    do: list[ActionSchema] = Field(
        default_factory=list, description="'var = expr' assignments/resets, send, raise"
    )
    priority: int = 0
    local: bool = Field(
        False,
        description="a transition from a composite to modes inside "
        "it that does not leave it (UML's local, SCXML's type='internal')",
    )
    description: str | None = None

    _trigger_name = named("on", what="message or event", rule=check_event)

    @field_validator("after")
    @classmethod
    def _after_not_negative(cls, v: float | str | None) -> float | str | None:
        if isinstance(v, float) and v < 0:
            raise ValueError(f"after must be >= 0 seconds, got {v}")
        return v


class LawSchema(Strict):
    """A control law: registry name or ``module:function``; sampled if ``period`` is set."""

    use: str
    period: PositiveFloat | None = None
    with_: dict[str, ExprOrNumber] = Field(default_factory=dict, alias="with")


class HistorySchema(Strict):
    """History with a default: where an entry goes while nothing is remembered yet."""

    kind: Literal["shallow", "deep"]
    default: str = Field(
        description="a descendant (name or dotted path below the mode) "
        "entered while nothing is remembered (instead of 'initial')"
    )


class ModeSchema(Strict):
    """A mode: a leaf, an OR-composite (``modes`` + ``initial``) or parallel regions."""

    description: str | None = None
    initial: str | None = Field(
        None,
        description="the child (or a deeper descendant, by "
        "name or dotted path below this mode) entered by default",
    )
    history: Literal["none", "shallow", "deep"] | HistorySchema = "none"
    parallel: bool = False
    modes: dict[str, ModeSchema] | None = None
    law: str | LawSchema | None = None
    inputs: dict[str, ExprOrNumber] | None = None
    period: PositiveFloat | None = Field(None, description="sampling period of 'inputs'")
    flow: dict[str, ExprOrNumber] | None = None
    invariant: str | None = None
    final: bool = False
    outcome: str | None = Field(
        None, description="a final mode's run outcome, e.g. 'success' (default: 'ok')"
    )
    transitions: list[TransitionSchema] = Field(default_factory=list)
    entry: list[ActionSchema] = Field(
        default_factory=list, description="actions each time the mode is entered (as 'do')"
    )
    exit: list[ActionSchema] = Field(
        default_factory=list, description="actions each time the mode is exited (as 'do')"
    )
    protocol: str | None = Field(
        None, description="a protocol (name or file) whose role region this mode becomes"
    )
    roles: dict[str, ModeSchema] | None = Field(
        None, description="with 'protocol': what each role (e.g. lead, follow) does"
    )

    _role_names = named("roles", what="role", rule=check_names)
    _mode_names = named(
        "modes",
        what="mode",
        rule=check_names,
        empty="'modes' is empty; remove it or declare a mode",
    )

    @model_validator(mode="after")
    def _period_needs_inputs(self) -> ModeSchema:
        if self.period is not None and self.inputs is None:
            raise ValueError(
                "'period' samples 'inputs'; this mode has no 'inputs' "
                "(a law takes its period in 'law: {use: ..., period: ...}')"
            )
        if self.outcome is not None and not self.final:
            raise ValueError("'outcome' names how a run ends in this mode; it needs 'final: true'")
        if self.outcome is not None and not self.outcome.isidentifier():
            raise ValueError(f"'outcome' must be a name such as 'success', got {self.outcome!r}")
        if self.roles is not None and self.protocol is None:
            raise ValueError("'roles' binds the roles of a protocol; add 'protocol: <name>'")
        if self.protocol is not None and self.modes is not None:
            raise ValueError(
                "a mode with 'protocol' gets its modes from the protocol's "
                "region; bind them with 'roles', not 'modes'"
            )
        return self


class PlantSchema(Strict):
    """Kinematics: unicycle (x, y, theta; v, omega), holonomic (x, y, theta; vx, vy, omega)
    or flow (any state; each mode gives its derivative). With a robot ``model`` the kind
    and limits come from the model, and ``limits`` here override it input by input."""

    kind: Literal["unicycle", "holonomic", "flow", "none"] | None = Field(
        None, description="required unless the agent names a robot 'model'"
    )
    state: dict[str, ExprOrNumber] = Field(default_factory=dict)
    limits: dict[str, tuple[float, float]] = Field(default_factory=dict)

    _state_names = named("state", what="state", rule=check_names)


class AgentSchema(Strict):
    """One robot or automaton: a plant, a mode tree, parameters and variables."""

    description: str | None = None
    model: str | None = Field(
        None,
        description="a robot model (labmate, xr4000, scout, omni): its plant kind, "
        "limits, footprint, sensors and manipulator, overridden by the keys below",
    )
    plant: PlantSchema | None = None
    # partial overrides of the model's sections, checked against it when it is resolved
    sensors: dict[str, Any] | None = Field(
        None, description="with 'model': per-sensor overrides, e.g. {ir: {max_range: 0.6}}"
    )
    manipulator: dict[str, Any] | None = Field(
        None, description="with 'model': overrides of its manipulator (null removes it)"
    )
    footprint: dict[str, Any] | None = Field(
        None, description="with 'model': overrides of its footprint, e.g. {radius: 0.4}"
    )
    parameters: dict[str, ExprOrNumber] = Field(default_factory=dict, description=AGENT_PARAMETERS)
    variables: dict[str, ExprOrNumber] = Field(default_factory=dict)
    initial: str | None = None
    history: Literal["none", "shallow", "deep"] = "none"
    modes: dict[str, ModeSchema] | None = None
    operator: str | None = Field(
        None, description="a protocol whose operator automaton this agent runs (no plant)"
    )

    @field_validator("plant")
    @classmethod
    def _kind_or_model(cls, v: PlantSchema | None, info: ValidationInfo) -> PlantSchema | None:
        # 'model' is declared first, so it is in info.data unless it failed on its own
        if v is not None and v.kind is None and info.data.get("model", "") is None:
            raise ValueError("missing required key 'kind' (or give the agent a robot 'model')")
        return v

    @field_validator("sensors", "manipulator", "footprint")
    @classmethod
    def _needs_model(cls, v: Any, info: ValidationInfo) -> Any:
        if info.data.get("model", "") is None:
            raise ValueError(
                f"'{info.field_name}' overrides a robot model's; add 'model: <name>' (e.g. xr4000)"
            )
        return v

    _names = named("parameters", "variables", what="parameter/variable", rule=check_names)
    _mode_names = named(
        "modes", what="mode", rule=check_names, empty="an agent needs at least one mode"
    )

    @model_validator(mode="after")
    def _modes_or_operator(self) -> AgentSchema:
        missing = [k for k in ("plant", "modes") if getattr(self, k) is None]
        if self.operator is None and missing:
            raise ValueError(
                f"missing required key '{missing[0]}' (an agent without a "
                "plant and modes is declared with 'operator: <protocol>')"
            )
        if self.operator is not None and self.modes is not None:
            raise ValueError("an operator agent gets its modes from its protocol; remove 'modes'")
        if self.operator is not None and self.model is not None:
            raise ValueError("an operator agent has no body; remove 'model'")
        return self


class ZenoSchema(Strict):
    max_steps_per_instant: Annotated[int, Field(ge=1)] = 1000
    max_transitions: Annotated[int, Field(ge=1)] = 100
    window: Annotated[float, Field(ge=0)] = 1e-6


class SimulationSchema(Strict):
    """Duration, output sampling, integrator accuracy and Zeno caps."""

    duration: Annotated[float, Field(ge=0)] = 10.0
    seed: Annotated[int, Field(ge=0)] = 0
    sample_period: PositiveFloat | None = Field(
        None, description="trace sampling period (default: duration/500)"
    )
    rtol: PositiveFloat = 1e-10
    atol: PositiveFloat = 1e-12
    max_step: PositiveFloat | None = None
    min_step: PositiveFloat | None = Field(
        None,
        description="smallest integrator step before a run ends 'stiff' (default: duration * 1e-6)",
    )
    event_tol: Annotated[float, Field(gt=0, le=MAX_EVENT_TOL)] = Field(
        1e-12, description="seconds within which a guard's crossing is located (at most 1e-3)"
    )
    crossing_checks: Annotated[int, Field(ge=0, le=32)] = 2
    zeno: ZenoSchema = Field(default_factory=ZenoSchema)


class ScenarioSchema(Strict):
    """A scripted event: ``{at: 5.0, agent: xr4000, raise: obstacle}``."""

    at: Annotated[float, Field(ge=0)]
    agent: str
    raise_: str = Field(alias="raise")

    _agent_name = named("agent", what="agent")
    _event_name = named("raise_", what="event", rule=check_event)


class LinkSchema(Strict):
    """Delay and loss on a link; numbers, or expressions of team parameters."""

    latency: ExprOrNumber = Field(0.0, description="seconds from send to receipt")
    jitter: ExprOrNumber = Field(0.0, description="extra delay, uniform in [0, jitter] s")
    loss: ExprOrNumber = Field(0.0, description="probability that a message is lost")

    @field_validator("latency", "jitter", "loss")
    @classmethod
    def _not_negative(cls, v: float | str) -> float | str:
        if isinstance(v, float) and v < 0:
            raise ValueError(f"must be >= 0, got {v}")
        return v

    @field_validator("loss")
    @classmethod
    def _probability(cls, v: float | str) -> float | str:
        if isinstance(v, float) and v > 1:
            raise ValueError(f"a loss probability is at most 1, got {v}")
        return v


class NetworkSchema(LinkSchema):
    """The broadcast medium: default link settings, per-link overrides, receive limits."""

    links: dict[str, LinkSchema] = Field(
        default_factory=dict, description="overrides per link, keyed 'sender->receiver'"
    )
    rate_limits: dict[str, dict[str, PositiveFloat]] = Field(
        default_factory=dict,
        description="messages per second a receiver processes, per socket ('*' for all)",
    )

    @field_validator("links")
    @classmethod
    def _link_keys(cls, v: dict[str, Any]) -> dict[str, Any]:
        for key in v:
            sender, arrow, receiver = key.partition("->")
            if not arrow or not sender.strip() or not receiver.strip():
                raise ValueError(f"link {key!r} must be written 'sender->receiver'")
        return v


class WorldSchema(Strict):
    """A world component: ``{use: ladder.corridor, with: {length: 450}}``."""

    use: str = Field(description="registered name of the component")
    with_: dict[str, bool | float | str | list[Any]] = Field(
        default_factory=dict,
        alias="with",
        description="settings: numbers or expressions of team parameters, or literals",
    )


class AckSchema(Strict):
    """Acknowledged delivery: wait ``timeout`` s for an ack, resend at most ``retries``."""

    timeout: ExprOrNumber = 0.1
    retries: ExprOrNumber = 3
    dedupe: bool = Field(
        True,
        description="act on a message once (false: on every copy, "
        "a resend after a lost ack included)",
    )


class MessageDeclSchema(Strict):
    """A message type of a protocol or of a team: its fields, socket, acknowledgement."""

    description: str | None = None
    socket: str = "control"
    fields: list[str] = Field(default_factory=list)
    ack: AckSchema | None = None
    priority: ExprOrNumber = Field(0.0, description="higher first among same-instant arrivals")

    _socket_name = named("socket", what="socket")
    _field_names = named("fields", what="field", rule=check_names)


class EndSchema(Strict):
    """When a run ends before its duration: ``{agents: [labmate, xr4000], when: all}``."""

    agents: list[str] | None = Field(
        None,
        min_length=1,
        description="agents whose final modes end the run (default: all but operators)",
    )
    when: Literal["all", "any"] = Field(
        "all", description="all: when every one of them is final; any: when the first is"
    )

    _agent_names = named("agents", what="agent", rule=check_names)


class SemanticsSchema(Strict):
    """Choices of the discrete semantics that statechart tools make differently."""

    priority: Literal["outer_first", "inner_first"] = Field(
        "outer_first",
        description="which of two enabled nested transitions fires: "
        "outer_first (Stateflow's: the outer one) or inner_first (SCXML's: the inner one; "
        "between regions, document order)",
    )


class TeamFile(Strict):
    """A team: agents that run in parallel, shared parameters, a simulation setup."""

    kind: Literal["team"] = "team"
    team: str = Field(description="name of the team")
    description: str | None = None
    parameters: dict[str, float] = Field(default_factory=dict)
    agents: dict[str, AgentSchema]
    simulation: SimulationSchema = Field(default_factory=SimulationSchema)
    scenario: list[ScenarioSchema] = Field(default_factory=list)
    network: NetworkSchema = Field(default_factory=NetworkSchema)
    world: list[WorldSchema] = Field(
        default_factory=list, description="world components: payloads, corridors, sensors"
    )
    end: EndSchema | None = Field(None, description="when a run ends before its duration")
    semantics: SemanticsSchema = Field(default_factory=SemanticsSchema)
    messages: dict[str, MessageDeclSchema] = Field(
        default_factory=dict,
        description="the team's own message types (fields, ack:, "
        "priority); a protocol's are declared in the protocol",
    )
    requirements_from: list[str] = Field(
        default_factory=list,
        description="requirement files (kind: requirements) whose "
        "formulas this team checks too, relative to this file",
    )
    requirements: dict[str, RequirementEntry] = Field(
        default_factory=dict,
        description="named temporal-logic formulas checked on every "
        "run: 'always(x <= 22.1)' or {formula: ..., description: ...}",
    )
    deploy: dict[str, Any] = Field(
        default_factory=dict,
        description="where the team runs live: per agent, its "
        "process's UDP address and its robot over ROS 2 (hybridteam live --plant ros2): "
        "{listen: HOST:PORT, cmd_vel: /r1/cmd_vel, odom: /r1/odom, scan, frame, timeout}; "
        "and udp: {peers: [HOST:PORT, ...]} or {multicast: GROUP:PORT, interface} or "
        "{broadcast: ADDR:PORT}; simulation ignores it",
    )

    _team_name = named("team", what="team", rule=check_title)
    _agent_names = named(
        "agents", what="agent", rule=check_names, empty="a team needs at least one agent"
    )
    _param_names = named("parameters", what="parameter", rule=check_names)
    _requirement_names = named("requirements", what="requirement", rule=check_names)
    _message_names = named("messages", what="message", rule=check_messages)


class StreamDeclSchema(Strict):
    """A periodic data message, e.g. a leader's pose at 20 Hz while in Lead."""

    message: str
    rate: ExprOrNumber = Field(description="messages per second")
    while_: list[str] | None = Field(
        None, alias="while", description="modes it is sent in (default: always)"
    )
    socket: str = "data"
    fields: dict[str, ExprOrNumber] = Field(default_factory=dict)

    _message_name = named("message", what="message", rule=check_message)
    _mode_names = named("while_", what="mode", rule=check_names)
    _socket_name = named("socket", what="socket")


class RegionModeSchema(ModeSchema):
    """A mode of a protocol's role region; ``role`` names the slot whose behaviour (law,
    submodes, transitions) the agent supplies."""

    role: str | None = None

    _role_name = named("role", what="role")


class RegionSchema(Strict):
    roles: list[str] = Field(default_factory=list)
    initial: str | None = None
    modes: dict[str, RegionModeSchema]

    _role_names = named("roles", what="role", rule=check_names)
    _mode_names = named("modes", what="mode", rule=check_names)


class OperatorSchema(Strict):
    """The automaton of an agent with no plant (a human operator)."""

    description: str | None = None
    parameters: dict[str, ExprOrNumber] = Field(default_factory=dict, description=AGENT_PARAMETERS)
    variables: dict[str, ExprOrNumber] = Field(default_factory=dict)
    initial: str | None = None
    modes: dict[str, ModeSchema]

    _names = named("parameters", "variables", what="parameter/variable", rule=check_names)
    _mode_names = named("modes", what="mode", rule=check_names)


class ProtocolFile(Strict):
    """A protocol: message types, data streams, and a role region to compose onto agents."""

    kind: Literal["protocol"] = "protocol"
    protocol: str
    description: str | None = None
    parameters: dict[str, float] = Field(default_factory=dict)
    variables: dict[str, ExprOrNumber] = Field(default_factory=dict)
    messages: dict[str, MessageDeclSchema] = Field(default_factory=dict)
    streams: list[StreamDeclSchema] = Field(default_factory=list)
    region: RegionSchema | None = None
    operator: OperatorSchema | None = None

    _protocol_name = named("protocol", what="protocol", rule=check_title)
    _message_names = named("messages", what="message", rule=check_messages)
