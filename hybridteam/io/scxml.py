"""SCXML charts as hybridteam files: a chart becomes one agent's mode tree.

An ``.scxml`` file is read into the same :class:`~hybridteam.io.filekind.Document` a team
YAML file gives (the data of a team of one agent, and where each part came from), so the
schema, the compiler and every command take it unchanged and their errors point at the
chart's lines. The core subset is read:

- ``<state>``, ``<parallel>``, ``<final>``; ``initial`` (attribute or ``<initial>``), the
  first child by default; ``<history type>`` with its default transition (a transition to
  the history enters its parent, which then restores on every entry);
- ``<transition event cond target type>``: several events give one transition each,
  ``foo.*`` means ``foo``; several targets enter one mode per region; ``type="internal"``
  into the source's own children is a local transition (the source is not left);
- ``<onentry>``/``<onexit>`` and a transition's content: ``<assign location expr>``,
  ``<raise event>`` (``<log>`` is dropped: it changes nothing);
- a numeric datamodel, ``<data id expr>``, as the agent's variables; conditions and
  expressions in hybridteam's expression language, with ``In('id')``, ``&&``, ``||``,
  ``!`` and ``===`` read as ``in_mode(id)``, ``and``, ``or``, ``not`` and ``==``;
- hybridteam's own extensions in the ``urn:hybridteam:scxml`` namespace (written by
  ``hybridteam convert``): a mode's ``ht:invariant``, ``ht:outcome``, ``<ht:flow>``,
  ``<ht:inputs>``, ``<ht:law>``; a transition's ``ht:after``, ``ht:priority``;
  ``<ht:send>``; the chart's ``ht:priority`` (its team's priority rule, where that is not
  SCXML's ``inner_first``).

Everything else — ``<script>``, ``<invoke>``, ``<send>``, ``<if>``, ``<foreach>``,
``<cancel>``, ``<donedata>``, other namespaces — is refused with the element named at its
line. A DOCTYPE (and so any entity) is refused before anything is expanded: a chart needs
none, and entities are how XML files expand without bound or fetch other files.
"""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any, Never
from xml.parsers import expat

from hybridteam.io.filekind import Document, InputErrors
from hybridteam.io.yamlcompose import read_text
from hybridteam.io.yamlpos import MAX_DEPTH, Mark, Positions, SourceError

SCXML_NS = "http://www.w3.org/2005/07/scxml"
HT_NS = "urn:hybridteam:scxml"
_ID = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")
_STATES = ("state", "parallel", "final")
#: executable content outside the subset, with why
_REFUSED = {
    "script": "scripts are ECMAScript code, which hybridteam never runs",
    "invoke": "invoking other services is outside the subset",
    "send": "SCXML's IO processors are outside the subset (hybridteam's own sends are <ht:send>)",
    "if": "conditional content is outside the subset (write guarded transitions)",
    "elseif": "conditional content is outside the subset",
    "else": "conditional content is outside the subset",
    "foreach": "loops are outside the subset",
    "cancel": "delayed sends are outside the subset",
    "donedata": "done events are not generated",
    "content": "message content is outside the subset",
    "param": "message parameters are outside the subset",
}


class Element:
    """A parsed XML element: namespace, local name, attributes, children and where it
    starts (1-based line and column)."""

    def __init__(self, ns: str, tag: str, attrs: dict[str, str], mark: Mark) -> None:
        self.ns, self.tag, self.attrs, self.mark = ns, tag, attrs, mark
        self.children: list[Element] = []
        self.text = ""

    @property
    def name(self) -> str:
        return f"<ht:{self.tag}>" if self.ns == HT_NS else f"<{self.tag}>"


def parse(text: str, filename: str) -> Element:
    """The element tree of ``text``; :class:`SourceError` for XML that is not well formed,
    has a DOCTYPE or entities, or elements of a foreign namespace."""
    parser = expat.ParserCreate(namespace_separator=" ")
    parser.SetParamEntityParsing(expat.XML_PARAM_ENTITY_PARSING_NEVER)
    stack: list[Element] = []
    root: list[Element] = []

    def here() -> Mark:
        return Mark(parser.CurrentLineNumber, parser.CurrentColumnNumber + 1)

    def refuse(*_args: Any) -> Never:
        raise SourceError(
            filename,
            *_at(here()),
            (),
            "a DOCTYPE or entity declaration is "
            "refused: an SCXML chart needs none, and entities can expand "
            "without bound or read other files",
        )

    def start(name: str, attrs: dict[str, str]) -> None:
        ns, _, tag = name.rpartition(" ")
        if ns not in ("", SCXML_NS, HT_NS):
            raise SourceError(
                filename,
                *_at(here()),
                (),
                f"element <{tag}> of namespace '{ns}' is outside the subset",
            )
        plain = {}
        for key, value in attrs.items():
            a_ns, _, a_name = key.rpartition(" ")
            plain[f"ht:{a_name}" if a_ns == HT_NS else a_name] = value
        el = Element(ns or SCXML_NS, tag, plain, here())
        if len(stack) >= MAX_DEPTH:
            raise SourceError(
                filename,
                *_at(el.mark),
                (),
                f"elements are nested more than {MAX_DEPTH} deep: far beyond any chart, refused",
            )
        (stack[-1].children if stack else root).append(el)
        stack.append(el)

    def end(_name: str) -> None:
        stack.pop()

    def data(chars: str) -> None:
        if stack:
            stack[-1].text += chars

    parser.StartDoctypeDeclHandler = refuse
    parser.EntityDeclHandler = refuse
    parser.ExternalEntityRefHandler = refuse
    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.CharacterDataHandler = data
    try:
        parser.Parse(text, True)
    except expat.ExpatError as exc:
        raise SourceError(
            filename,
            exc.lineno,
            exc.offset + 1,
            (),
            f"not well-formed XML: {expat.ErrorString(exc.code)}",
        ) from None
    if not root or root[0].tag != "scxml":
        raise SourceError(filename, 1, 1, (), "an SCXML file's root element is <scxml>")
    return root[0]


def _at(mark: Mark) -> tuple[int, int]:
    return mark.line, mark.column


def read_chart(source: str | os.PathLike, agent: str | None = None) -> Document:
    """An ``.scxml`` file as a team document: a team of one agent (``agent``, else the
    chart's ``name``, else the file's stem) without a plant; :class:`InputErrors` where it
    cannot be."""
    filename = str(source)
    try:
        text = read_text(Path(source), filename)
        reader = ChartReader(filename)
        root = parse(text, filename)
        name = agent or root.attrs.get("name") or Path(filename).stem.replace("-", "_")
        if not _ID.match(name):
            name = "chart"
        body = reader.agent(root, ("agents", name))
    except SourceError as exc:
        raise InputErrors([exc]) from None
    # an SCXML chart means SCXML's priority rule (innermost first, document order),
    # unless it says it came from a team of another (ht:priority)
    data = {
        "team": name,
        "semantics": {"priority": root.attrs.get("ht:priority", "inner_first")},
        "agents": {name: {"plant": {"kind": "none"}, **body}},
    }
    reader.marks.setdefault((), Mark(1, 1))
    reader.marks[("semantics",)] = reader.marks[("semantics", "priority")] = root.mark
    for path in (("team",), ("agents",), ("agents", name), ("agents", name, "plant")):
        reader.marks.setdefault(path, root.mark)
    return Document(filename, data, Positions.of_marks(filename, text, reader.marks))


class ChartReader:
    """Turns a chart's elements into the data of an agent (``initial``, ``modes``,
    ``variables``), remembering where each part came from."""

    def __init__(self, filename: str) -> None:
        self.filename = filename
        self.marks: dict[tuple, Mark] = {}
        self.history_of: dict[str, str] = {}  # a <history>'s mode name -> its parent's
        self.with_history: set[str] = set()
        #: each state's id -> its mode name: the id itself, or with every character a
        #: name cannot have as '_' (SCXML ids such as 'b1.2' are common)
        self.names: dict[str, str] = {}
        self.ids: dict[str, str] = {}  # the other way

    def fail(self, el: Element, message: str) -> SourceError:
        return SourceError(self.filename, *_at(el.mark), (), message)

    def agent(self, root: Element, path: tuple) -> dict:
        """The chart's agent: its variables, initial mode and modes."""
        self.marks[path] = root.mark
        self._histories(root)
        out: dict[str, Any] = {}
        variables: dict[str, Any] = {}
        for el in root.children:
            if el.tag == "datamodel" and el.ns == SCXML_NS:
                for data in el.children:
                    self._check(data, ("data",))
                    variables[self._variable(data)] = self._number(data)
                    self.marks[(*path, "variables", self._variable(data))] = data.mark
            elif el.tag not in _STATES:
                self._check(el, (*_STATES, "datamodel"))
        if variables:
            out["variables"] = variables
        modes = self._modes(root, (*path, "modes"))
        initial = self._initial(root, modes)
        if initial:
            out["initial"] = initial
            self.marks[(*path, "initial")] = root.mark
        out["modes"] = modes
        return out

    # ------------------------------------------------------------------ states
    def _histories(self, el: Element) -> None:
        """Name every state and map every <history> to its parent first: transitions may
        target one before it is met in document order."""
        for child in el.children:
            if child.ns == SCXML_NS and child.tag in (*_STATES, "history"):
                self._name(child)
            if child.tag == "history" and child.ns == SCXML_NS:
                if el.tag not in ("state", "parallel"):
                    raise self.fail(child, "a <history> belongs in a <state> or <parallel>")
                self.history_of[self._id(child)] = self._id(el)
                self.with_history.add(self._id(el))
            self._histories(child)

    def _modes(self, el: Element, path: tuple) -> dict[str, dict]:
        out: dict[str, dict] = {}
        for child in el.children:
            if child.ns == SCXML_NS and child.tag in _STATES:
                name = self._id(child)
                if name in out:
                    raise self.fail(child, f"a second state '{name}' in one parent")
                out[name] = self._mode(child, (*path, name))
        if not out and el.tag == "scxml":
            raise self.fail(el, "an <scxml> chart needs a <state>, <parallel> or <final>")
        return out

    def _mode(self, el: Element, path: tuple) -> dict:
        self.marks[path] = el.mark
        mode: dict[str, Any] = {}
        if el.tag == "final":
            mode["final"] = True
        if el.tag == "parallel":
            mode["parallel"] = True
        allowed = {
            "state": (
                "state",
                "parallel",
                "final",
                "history",
                "initial",
                "onentry",
                "onexit",
                "transition",
                "datamodel",
            ),
            "parallel": ("state", "parallel", "history", "onentry", "onexit", "transition"),
            "final": ("onentry", "onexit"),
        }[el.tag]
        for child in el.children:
            if child.ns == HT_NS:
                self._extension(child, mode, path)
                continue
            self._check(child, allowed)
            if child.tag == "datamodel":
                raise self.fail(
                    child,
                    "a <datamodel> belongs to the <scxml> element (the "
                    "agent's variables are shared by all its modes)",
                )
            if child.tag in ("onentry", "onexit"):
                key = "entry" if child.tag == "onentry" else "exit"
                mode.setdefault(key, []).extend(
                    self._content(child, (*path, key), len(mode.get(key, [])))
                )
            elif child.tag == "history":
                if "history" in mode:
                    raise self.fail(
                        child,
                        "a second <history> in one state: hybridteam keeps one history per mode",
                    )
                mode["history"] = self._history(child, el, (*path, "history"))
        self._mode_attrs(el, mode, path)
        kids = self._modes(el, (*path, "modes"))
        if kids:
            mode["modes"] = kids
            initial = self._initial(el, kids)
            if initial and not mode.get("parallel"):
                mode["initial"] = initial
                self.marks[(*path, "initial")] = el.mark
        transitions = [
            t
            for child in el.children
            if child.ns == SCXML_NS and child.tag == "transition"
            for t in self._transitions(child, el, (*path, "transitions"))
        ]
        for k, (tr, mark) in enumerate(transitions):
            self.marks[(*path, "transitions", k)] = mark
            for key in tr:
                self.marks[(*path, "transitions", k, key)] = mark
        if transitions:
            mode["transitions"] = [tr for tr, _ in transitions]
        return mode

    def _mode_attrs(self, el: Element, mode: dict, path: tuple) -> None:
        for key, value in el.attrs.items():
            if key in ("id", "initial"):
                continue
            if key == "ht:invariant":
                mode["invariant"] = value
            elif key == "ht:outcome":
                mode["outcome"] = value
            else:
                raise self.fail(el, f"attribute '{key}' of {el.name} is outside the subset")
            self.marks[(*path, key.removeprefix("ht:"))] = el.mark

    def _initial(self, el: Element, kids: dict[str, dict]) -> str | None:
        """The initial child's name (or a deeper descendant's): the ``initial`` attribute,
        an ``<initial>`` element's transition, else the first child."""
        names = el.attrs.get("initial", "").split()
        for child in el.children:
            if child.tag == "initial" and child.ns == SCXML_NS:
                trs = [t for t in child.children if t.tag == "transition"]
                if len(trs) != 1 or set(trs[0].attrs) - {"target"} or trs[0].children:
                    raise self.fail(
                        child,
                        "an <initial> holds one <transition target> "
                        "(without content, in this subset)",
                    )
                names = trs[0].attrs.get("target", "").split()
        if len(names) > 1:
            raise self.fail(
                el,
                f"{el.name} names {len(names)} initial states; the subset "
                "takes one (a deeper one enters the regions on the way by default)",
            )
        if names:
            return self.ref(names[0])
        if len(kids) > 1 and el.tag != "parallel":
            return next(iter(kids))
        return None

    def _history(self, el: Element, parent: Element, path: tuple) -> Any:
        kind = el.attrs.get("type", "shallow")
        if kind not in ("shallow", "deep") or set(el.attrs) - {"id", "type"}:
            raise self.fail(el, "a <history> takes 'id' and 'type' (shallow or deep)")
        self.marks[path] = el.mark
        default = [t for t in el.children if t.tag == "transition"]
        if len(default) > 1 or any(t.tag != "transition" for t in el.children):
            raise self.fail(el, "a <history> holds at most one default <transition>")
        if not default:
            return kind
        targets = default[0].attrs.get("target", "").split()
        if len(targets) != 1 or default[0].children:
            raise self.fail(
                default[0],
                "a history's default transition names one target (without content, in this subset)",
            )
        self.marks[(*path, "kind")] = self.marks[(*path, "default")] = default[0].mark
        return {"kind": kind, "default": self.ref(targets[0])}

    # ------------------------------------------------------------------ transitions
    def _transitions(self, el: Element, source: Element, path: tuple) -> list[tuple]:
        """One transition per event of ``event`` (or one without a trigger)."""
        unknown = set(el.attrs) - {"event", "cond", "target", "type", "ht:after", "ht:priority"}
        if unknown:
            raise self.fail(
                el, f"attribute '{sorted(unknown)[0]}' of <transition> is outside the subset"
            )
        tr: dict[str, Any] = {}
        written = [self.ref(t) for t in el.attrs.get("target", "").split()]
        targets = [self.history_of.get(t, t) for t in written]
        for t, w in zip(targets, written, strict=True):
            if t == w and t in self.with_history:
                raise self.fail(
                    el,
                    f"target '{t}' has a <history>: in hybridteam every "
                    "entry of it restores, so target the history instead",
                )
        if targets:
            tr["to"] = targets[0] if len(targets) == 1 else targets
        if el.attrs.get("type", "external") not in ("external", "internal"):
            raise self.fail(el, "a transition's type is 'external' or 'internal'")
        if (
            el.attrs.get("type") == "internal"
            and targets
            and source.tag == "state"
            and all(self._inside(t, source) for t in targets)
        ):
            tr["local"] = True  # into its own children without leaving: a local one
        if "cond" in el.attrs:
            tr["guard"] = expression(el.attrs["cond"], self.ref)
        if "ht:after" in el.attrs:
            tr["after"] = _value(el.attrs["ht:after"])
        if "ht:priority" in el.attrs:
            try:
                tr["priority"] = int(el.attrs["ht:priority"])
            except ValueError:
                raise self.fail(el, "ht:priority is a whole number") from None
        actions = self._content(el, (*path, "do"), 0)
        if actions:
            tr["do"] = actions
        events = el.attrs.get("event", "").split()
        if "*" in events:
            raise self.fail(el, "the event '*' (any event) is outside the subset")
        if not events:
            return [(tr, el.mark)]
        return [({"on": e.removesuffix(".*"), **tr}, el.mark) for e in events]

    def _inside(self, name: str, el: Element) -> bool:
        return any(
            self._id(c) == name or self._inside(name, c)
            for c in el.children
            if c.ns == SCXML_NS and c.tag in _STATES
        )

    def _content(self, el: Element, path: tuple, start: int) -> list:
        """Executable content: assignments, raised events, hybridteam's sends."""
        out: list = []
        for child in el.children:
            if child.ns == HT_NS and child.tag == "send":
                out.append(self._send(child))
            elif child.ns == HT_NS:
                raise self.fail(child, f"{child.name} is not executable content")
            elif child.tag == "log":
                continue
            else:
                self._check(child, ("assign", "raise"))
                if child.tag == "assign":
                    if set(child.attrs) != {"location", "expr"}:
                        raise self.fail(
                            child, "an <assign> takes 'location' and 'expr' (in this subset)"
                        )
                    out.append(
                        f"{child.attrs['location']} = {expression(child.attrs['expr'], self.ref)}"
                    )
                else:
                    if set(child.attrs) != {"event"}:
                        raise self.fail(child, "a <raise> takes 'event'")
                    out.append({"raise": child.attrs["event"]})
            self.marks[(*path, start + len(out) - 1)] = child.mark
        return out

    def _send(self, el: Element) -> dict:
        send: dict[str, Any] = {"send": el.attrs.get("message", "")}
        for key in ("to", "socket"):
            if key in el.attrs:
                send[key] = el.attrs[key]
        fields = {f.attrs.get("name", ""): _value(f.attrs.get("expr", "")) for f in el.children}
        if fields:
            send["fields"] = fields
        return send

    # ------------------------------------------------------------------ extensions
    def _extension(self, el: Element, mode: dict, path: tuple) -> None:
        """A mode's hybridteam extension: its flow, inputs or law."""
        pairs = {
            c.attrs.get("var", c.attrs.get("name", "")): _value(c.attrs.get("expr", ""))
            for c in el.children
        }
        if el.tag == "flow":
            mode["flow"] = {
                **mode.get("flow", {}),
                el.attrs.get("var", ""): _value(el.attrs.get("expr", "")),
            }
            self.marks[(*path, "flow")] = el.mark
        elif el.tag == "inputs":
            mode["inputs"] = pairs
            if "period" in el.attrs:
                mode["period"] = _float(el.attrs["period"])
            self.marks[(*path, "inputs")] = el.mark
        elif el.tag == "law":
            law: dict[str, Any] = {"use": el.attrs.get("use", "")}
            if "period" in el.attrs:
                law["period"] = _float(el.attrs["period"])
            if pairs:
                law["with"] = pairs
            mode["law"] = law
            self.marks[(*path, "law")] = el.mark
        else:
            raise self.fail(el, f"{el.name} is not a mode's extension (ht:flow, ht:inputs, ht:law)")

    # ------------------------------------------------------------------ checks
    def _check(self, el: Element, allowed: tuple[str, ...]) -> None:
        if el.ns == SCXML_NS and el.tag in allowed:
            return
        reason = (
            _REFUSED.get(el.tag, "outside the subset") if el.ns == SCXML_NS else "not allowed here"
        )
        raise self.fail(el, f"{el.name} is not supported: {reason}")

    def _id(self, el: Element) -> str:
        """A state's mode name (see :attr:`names`)."""
        return self.names[el.attrs.get("id", f"{el.tag}_{el.mark.line}_{el.mark.column}")]

    def _name(self, el: Element) -> None:
        given = el.attrs.get("id", f"{el.tag}_{el.mark.line}_{el.mark.column}")
        name = re.sub(r"\W", "_", given, flags=re.ASCII)
        if not _ID.match(name):
            name = f"s{name}"
        if given in self.names or name.startswith("__") or name in self.ids:
            other = self.ids.get(name, given)
            raise self.fail(
                el,
                f"{el.name} id '{given}' "
                + (
                    "is used twice"
                    if other == given
                    else f"reads as mode name '{name}', as '{other}' does"
                ),
            )
        self.names[given], self.ids[name] = name, given

    def ref(self, given: str) -> str:
        """The mode name of a state's id where the chart refers to one."""
        return self.names.get(given, given)

    def _variable(self, el: Element) -> str:
        name = el.attrs.get("id", "")
        if not _ID.match(name) or name.startswith("__"):
            raise self.fail(
                el,
                f"<data> id '{name}' is not a variable name (letters, "
                "digits and _, not starting with a digit)",
            )
        return name

    def _number(self, el: Element) -> Any:
        unknown = set(el.attrs) - {"id", "expr"}
        if unknown or el.children:
            raise self.fail(el, "a <data> takes 'id' and 'expr' (in this subset)")
        return _value(el.attrs.get("expr", el.text.strip() or "0"))


def _value(text: str) -> float | str:
    """A number where the text is one (as YAML would give it), else the expression."""
    value = _float(text)
    return text if value is None else value


#: The keys of an agent that its chart gives (the rest — plant, robot model, parameters,
#: sensors — stays in the team file).
CHART_KEYS = ("initial", "history", "modes", "variables")


def merge_chart(team: dict, agent: str, chart: dict) -> dict:
    """Team data (a team file's, as loaded) with ``agent``'s behaviour replaced by a
    chart's agent data (:func:`read_chart`'s); KeyError if the team has no such agent."""
    old = team["agents"][agent]
    new = {k: v for k, v in old.items() if k not in CHART_KEYS}
    new.update({k: chart[k] for k in CHART_KEYS if k in chart})
    return {**team, "agents": {**team["agents"], agent: new}}


def _float(text: str) -> float | None:
    try:
        return float(text)
    except ValueError:
        return None


_IN = re.compile(r"""\bIn\(\s*(['"])([^'"]+)\1\s*\)""")


def expression(text: str, ref=lambda name: name) -> str:
    """An SCXML condition or value in hybridteam's language: ``In('s')`` is
    ``in_mode(s)``; ``&&``, ``||``, ``!``, ``===``/``!==`` are ``and``, ``or``, ``not``,
    ``==``/``!=``. What then does not compile is reported where it is used."""
    out = _IN.sub(lambda m: f"in_mode({ref(m[2])})", text)
    out = out.replace("===", "==").replace("!==", "!=").replace("&&", " and ")
    out = out.replace("||", " or ")
    out = re.sub(r"!(?!=)", " not ", out)
    return re.sub(r"\s+", " ", out).strip()
