"""An agent's behaviour as an SCXML chart: its mode tree, transitions, actions, variables.

The inverse of :mod:`hybridteam.io.scxml`: what statechart tools share is written in SCXML
(states, parallel regions, finals, history with its default, transitions with event, cond
and targets, entry and exit actions, a numeric datamodel); what only hybridteam has — a
mode's flow, inputs, law, invariant and outcome, a transition's ``after`` and
``priority``, sends — in the ``urn:hybridteam:scxml`` namespace, which other tools ignore.
The plant, parameters and robot model stay in the team file: ``hybridteam convert`` puts
a chart back into a team, and the agent then behaves as before (the traces are the same
byte for byte; ``tests/io/test_scxml.py`` checks every example agent).

Not every agent can be written: one whose modes come from a protocol (their messages'
acknowledgements and streams belong to the protocol), a protocol's operator, or one whose
mode names repeat (SCXML ids are unique). :class:`NotExpressible` says why.
"""

from __future__ import annotations

import re
from xml.sax.saxutils import quoteattr

from hybridteam.io.protocols import InFile
from hybridteam.io.scxml import HT_NS, SCXML_NS
from hybridteam.model import Agent, Assign, Mode, Raise, Send, Transition

_AUG = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*(\*\*|[-+*/%])=(.*)$", re.DOTALL)
_SET = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*=(?!=)(.*)$", re.DOTALL)
_IN_MODE = re.compile(r"\bin_mode\(\s*([A-Za-z_][A-Za-z0-9_.]*)\s*\)")


class NotExpressible(ValueError):
    """An agent that an SCXML chart cannot carry, with the reason."""


def agent_chart(agent: Agent, priority_rule: str = "inner_first") -> str:
    """The SCXML text of ``agent``'s behaviour (raises :class:`NotExpressible`);
    ``priority_rule``: its team's, written as ``ht:priority`` unless it is SCXML's own
    (``inner_first``), so the chart alone runs as the agent did."""
    _expressible(agent)
    root = agent.root
    rule = "" if priority_rule == "inner_first" else f" ht:priority={quoteattr(priority_rule)}"
    out = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        f'<scxml xmlns="{SCXML_NS}" xmlns:ht="{HT_NS}" version="1.0" '
        f"name={quoteattr(agent.name)}{_initial_attr(root)}{rule}>",
    ]
    if agent.variables:
        out.append("  <datamodel>")
        out += [
            f"    <data id={quoteattr(n)} expr={quoteattr(_text(v))}/>"
            for n, v in agent.variables.items()
        ]
        out.append("  </datamodel>")
    histories = {m.name for _p, m in root.walk() if m.history != "none"}
    for child in root.children:
        _mode(child, out, "  ", histories)
    out.append("</scxml>")
    return "\n".join(out) + "\n"


def _expressible(agent: Agent) -> None:
    if agent.operator:
        raise NotExpressible(
            f"agent '{agent.name}' is a protocol's operator: its automaton "
            "belongs to the protocol file"
        )
    if agent.root.history != "none":
        raise NotExpressible(
            f"agent '{agent.name}' has history on its root: an SCXML chart's top level has none"
        )
    seen: set[str] = set()
    for path, mode in agent.root.walk():
        if mode is agent.root:
            continue
        if mode.role is not None or (mode.where and isinstance(mode.where[0], InFile)):
            raise NotExpressible(
                f"agent '{agent.name}': mode '{path}' comes from a protocol "
                "(its acknowledgements and streams belong to the protocol)"
            )
        if mode.name in seen:
            raise NotExpressible(
                f"agent '{agent.name}': two modes are named '{mode.name}' (SCXML ids are unique)"
            )
        seen.add(mode.name)
        if mode.inputs is None and mode.input_period is not None:
            raise NotExpressible(f"agent '{agent.name}': mode '{path}' has a period without inputs")


def _text(value: object) -> str:
    return repr(float(value)) if isinstance(value, int | float) else str(value)


def _last(name: str) -> str:
    """A mode named by a dotted path: its id (names are unique in a written chart)."""
    return name.rsplit(".", 1)[-1]


def _initial_attr(mode: Mode) -> str:
    if mode.initial is None or mode.parallel:
        return ""
    return f" initial={quoteattr(_last(mode.initial))}"


def _mode(mode: Mode, out: list[str], pad: str, histories: set[str]) -> None:
    tag = "final" if mode.final else "parallel" if mode.parallel else "state"
    attrs = f"id={quoteattr(mode.name)}"
    if tag == "state":
        attrs += _initial_attr(mode)
    if mode.invariant is not None:
        attrs += f" ht:invariant={quoteattr(mode.invariant)}"
    if mode.outcome is not None:
        attrs += f" ht:outcome={quoteattr(mode.outcome)}"
    body: list[str] = []
    inner = pad + "  "
    for var, expr in (mode.flow or {}).items():
        body.append(f"{inner}<ht:flow var={quoteattr(var)} expr={quoteattr(_text(expr))}/>")
    if mode.inputs is not None:
        period = (
            ""
            if mode.input_period is None
            else f" period={quoteattr(repr(float(mode.input_period)))}"
        )
        body.append(f"{inner}<ht:inputs{period}>")
        body += [
            f"{inner}  <ht:input var={quoteattr(k)} expr={quoteattr(_text(v))}/>"
            for k, v in mode.inputs.items()
        ]
        body.append(f"{inner}</ht:inputs>")
    if mode.law is not None:
        period = (
            "" if mode.law.period is None else f" period={quoteattr(repr(float(mode.law.period)))}"
        )
        body.append(f"{inner}<ht:law use={quoteattr(mode.law.name)}{period}>")
        body += [
            f"{inner}  <ht:with name={quoteattr(k)} expr={quoteattr(_text(v))}/>"
            for k, v in mode.law.params.items()
        ]
        body.append(f"{inner}</ht:law>")
    if mode.history != "none":
        hid = f"{mode.name}_history"
        if mode.history_default is None:
            body.append(f"{inner}<history id={quoteattr(hid)} type={quoteattr(mode.history)}/>")
        else:
            body += [
                f"{inner}<history id={quoteattr(hid)} type={quoteattr(mode.history)}>",
                f"{inner}  <transition target={quoteattr(_last(mode.history_default))}/>",
                f"{inner}</history>",
            ]
    for key, actions in (("onentry", mode.on_entry), ("onexit", mode.on_exit)):
        if actions:
            body.append(f"{inner}<{key}>")
            body += [_action(a, inner + "  ") for a in actions]
            body.append(f"{inner}</{key}>")
    for tr in mode.transitions:
        body += _transition(tr, inner, histories)
    for child in mode.children:
        _mode(child, body, inner, histories)
    if body:
        out += [f"{pad}<{tag} {attrs}>", *body, f"{pad}</{tag}>"]
    else:
        out.append(f"{pad}<{tag} {attrs}/>")


def _transition(tr: Transition, pad: str, histories: set[str]) -> list[str]:
    attrs = ""
    if tr.on is not None:
        attrs += f" event={quoteattr(tr.on)}"
    if tr.guard is not None:
        attrs += f" cond={quoteattr(_IN_MODE.sub(_in, tr.guard))}"
    if tr.targets:
        # a mode with history restores on every entry: SCXML says so by the history's id
        ids = [_last(t) + ("_history" if _last(t) in histories else "") for t in tr.targets]
        attrs += f" target={quoteattr(' '.join(ids))}"
    if tr.local:
        attrs += ' type="internal"'
    if tr.after is not None:
        attrs += f" ht:after={quoteattr(_text(tr.after))}"
    if tr.priority:
        attrs += f" ht:priority={quoteattr(str(tr.priority))}"
    if not tr.actions:
        return [f"{pad}<transition{attrs}/>"]
    return [
        f"{pad}<transition{attrs}>",
        *(_action(a, pad + "  ") for a in tr.actions),
        f"{pad}</transition>",
    ]


def _in(match: re.Match) -> str:
    return f"In('{_last(match[1])}')"


def _action(action: Assign | Send | Raise, pad: str) -> str:
    if isinstance(action, Raise):
        return f"{pad}<raise event={quoteattr(action.event)}/>"
    if isinstance(action, Send):
        attrs = f"message={quoteattr(action.message)}"
        if action.to is not None:
            attrs += f" to={quoteattr(action.to)}"
        if action.socket != "control":
            attrs += f" socket={quoteattr(action.socket)}"
        if not action.fields:
            return f"{pad}<ht:send {attrs}/>"
        fields = "".join(
            f"<ht:field name={quoteattr(k)} expr={quoteattr(_text(v))}/>"
            for k, v in action.fields.items()
        )
        return f"{pad}<ht:send {attrs}>{fields}</ht:send>"
    aug, plain = _AUG.match(action.text), _SET.match(action.text)
    if aug:
        location, expr = aug[1], f"{aug[1]} {aug[2]} ({aug[3].strip()})"
    elif plain:
        location, expr = plain[1], plain[2].strip()
    else:  # the compiler accepted it, so this cannot happen; say so rather than guess
        raise NotExpressible(f"assignment '{action.text}' is not 'name = expression'")
    return f"{pad}<assign location={quoteattr(location)} expr={quoteattr(expr)}/>"
