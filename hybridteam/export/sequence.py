"""Message sequence charts of a run: who told whom what, when, and what got lost.

A team's behaviour is mostly in its messages (a baton handed over, an acknowledgement that
never came), and a sequence chart shows their order at a glance where the messages table
needs reading. One arrow per recorded message of one instance, in send order; the label
carries the type, the send time and the latency, and a lost message ends in a cross with
the network's reason. Output is Mermaid ``sequenceDiagram`` or PlantUML text.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from hybridteam.errors import did_you_mean
from hybridteam.export.render import mermaid_text, plantuml_text
from hybridteam.trace import Trace

FORMATS = ("mermaid", "plantuml")


@dataclass(frozen=True)
class SequenceArrow:
    """One message as drawn: endpoints, label and whether it was lost."""

    sender: str
    receiver: str
    label: str
    lost: bool


def seconds(t: float) -> str:
    """Times in seconds to the millisecond: ``5.000``."""
    return f"{t:.3f}"


def latency(t_send: float, t_recv: float) -> str:
    """``+30 ms`` / ``+1.25 s`` for a delivery that took time, else empty."""
    if not (math.isfinite(t_send) and math.isfinite(t_recv)) or t_recv <= t_send:
        return ""
    dt = t_recv - t_send
    if dt >= 1.0:
        return f"+{dt:.3g} s"
    ms = dt * 1e3
    return f"+{ms:.0f} ms" if ms >= 1.0 else f"+{ms:.3g} ms"


def arrows(
    trace: Trace, instance: int = 0, sockets: Iterable[str] | None = ("control",)
) -> list[SequenceArrow]:
    """The messages of one instance on the chosen sockets (None: all), in send order."""
    table = trace.messages
    if len(table) == 0:
        return []
    mask = table["instance"] == instance
    if sockets is not None:
        mask &= np.isin(table["socket"].astype(str), list(sockets))
    rows = sorted(table.filter(mask), key=lambda r: (r.t_send, r.seq))
    out = []
    for r in rows:
        label = f"{r.type} @ {seconds(r.t_send)} s"
        late = latency(r.t_send, r.t_recv)
        if late:
            label += f" ({late})"
        lost = r.status == "lost"
        notes = copy_notes(str(r.reason or ""), lost)
        if notes:
            label += f" ({notes})"
        out.append(SequenceArrow(str(r.sender), str(r.receiver), label, lost))
    return out


def copy_notes(reason: str, lost: bool) -> str:
    """What a label says of a copy besides its type, time and latency, once each:
    ``retransmission, lost: loss`` for a resent copy the network lost.

    The network records a lost copy's reason as its cause with the copy's own note in
    brackets (``loss (retransmission)``), a delivered one's as the note alone; a label
    that printed both the reason and the note said "retransmission" twice.
    """
    cause, _, note = reason.partition(" (") if lost else ("", "", reason)
    parts = ["retransmission"] if "retransmi" in note else []
    if lost:
        parts.append(f"lost: {cause}" if cause else "lost")
    return ", ".join(parts)


def _participants(trace: Trace, found: list[SequenceArrow]) -> list[str]:
    """Agents in the team's order, then anyone else a message names (e.g. a broadcast)."""
    names = list(trace.agents)
    for a in found:
        for n in (a.sender, a.receiver):
            if n not in names:
                names.append(n)
    return names


def _span(names: list[str]) -> list[str]:
    """The first and last participant: a note over them covers the whole chart."""
    return [_ident(n) for n in (names if len(names) < 2 else [names[0], names[-1]])]


# words the sequence-diagram grammars read as keywords where a participant is expected
KEYWORDS = frozenset(
    {
        "alt",
        "and",
        "as",
        "activate",
        "actor",
        "autonumber",
        "box",
        "break",
        "create",
        "critical",
        "deactivate",
        "destroy",
        "else",
        "end",
        "left",
        "loop",
        "note",
        "of",
        "opt",
        "over",
        "par",
        "participant",
        "rect",
        "right",
        "title",
    }
)


def _ident(name: str) -> str:
    ident = re.sub(r"\W", "_", name) or "_"
    return ident + "_" if ident.lower() in KEYWORDS else ident


def _mermaid_text(text: str) -> str:
    """Names and labels as Mermaid text: what a trace names (a message type, an agent, a
    loss reason) is read from a file and may carry a directive or a tag; the text is made
    inert (:func:`~hybridteam.export.render.mermaid_text`). A ``;`` would end the message,
    so it becomes a comma."""
    return mermaid_text(text.replace(";", ","))


def _mermaid(names: list[str], found: list[SequenceArrow]) -> str:
    lines = ["sequenceDiagram"]
    for n in names:
        ident = _ident(n)
        lines.append(f"    participant {ident}" + (f" as {_mermaid_text(n)}" if ident != n else ""))
    for a in found:
        arrow = "-x" if a.lost else "->>"
        lines.append(f"    {_ident(a.sender)}{arrow}{_ident(a.receiver)}: {_mermaid_text(a.label)}")
    if not found:
        lines.append(f"    Note over {','.join(_span(names))}: no messages")
    return "\n".join(lines) + "\n"


def _plantuml(names: list[str], found: list[SequenceArrow]) -> str:
    lines = ["@startuml", "hide footbox"]
    for n in names:
        ident = _ident(n)
        shown = plantuml_text(n).replace('"', "'")
        lines.append(f'participant "{shown}" as {ident}' if ident != n else f"participant {n}")
    for a in found:
        arrow = "->x" if a.lost else "->"
        label = plantuml_text(a.label)
        lines.append(f"{_ident(a.sender)} {arrow} {_ident(a.receiver)} : {label}")
    if not found:
        lines.append(f"note over {', '.join(_span(names))} : no messages")
    lines.append("@enduml")
    return "\n".join(lines) + "\n"


def sequence_chart(
    trace: Trace,
    fmt: str = "mermaid",
    instance: int = 0,
    sockets: Iterable[str] | None = ("control",),
) -> str:
    """The sequence chart of one instance's messages as Mermaid or PlantUML text.

    ``sockets`` picks the network sockets shown (``None`` shows all): control messages
    explain a team's decisions, while periodic data traffic would drown them.
    """
    if fmt not in FORMATS:
        hint = did_you_mean(fmt, FORMATS)
        raise ValueError(
            f"unknown sequence chart format {fmt!r} (known: {', '.join(FORMATS)})"
            + (f"; {hint}" if hint else "")
        )
    if not 0 <= instance < max(trace.n, 1):
        raise ValueError(f"instance {instance} is out of range: the run has {trace.n}")
    found = arrows(trace, instance, sockets)
    names = _participants(trace, found) or ["team"]
    return _mermaid(names, found) if fmt == "mermaid" else _plantuml(names, found)
