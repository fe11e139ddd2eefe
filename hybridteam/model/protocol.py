"""Protocol declarations: message types with their delivery policy, and data streams.

A protocol (``kind: protocol`` file) adds to a team what the bare network lacks: which
messages need an acknowledgement (and how long to wait, how often to retry), which messages
are periodic data streams, and the transitions of a role region. These are plain
declarations; the engine's :mod:`~hybridteam.engine.run.reliable` and
:mod:`~hybridteam.engine.run.streams` give them behaviour.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from hybridteam.errors import DocPath


@dataclass(frozen=True)
class AckPolicy:
    """Reliable delivery: resend after ``timeout`` seconds without an acknowledgement, at
    most ``retries`` times; then the sender gets the local event ``<type>_undeliverable``.
    Both are numbers or expressions of the sender's parameters. ``dedupe``: a receiver acts
    on a message once (False: on every copy, retransmissions included)."""

    timeout: str | float = 0.1
    retries: str | float = 3
    where: DocPath = ()
    dedupe: bool = True


@dataclass(frozen=True)
class MessageSpec:
    """A declared message type. ``priority`` (an expression of the sender's parameters)
    orders copies that arrive at the same instant: higher first."""

    name: str
    socket: str = "control"
    fields: tuple[str, ...] = ()
    ack: AckPolicy | None = None
    priority: str | float = 0.0
    protocol: str = ""
    where: DocPath = ()


@dataclass(frozen=True)
class StreamSpec:
    """A periodic data message: sent ``rate`` times a second while the agent is in one of
    the ``while_`` modes (always, when empty), carrying ``fields`` (expressions at the
    sender, e.g. ``{x: x, v: u_v}``). Receivers keep the latest copy per sender."""

    message: str
    rate: str | float
    fields: dict[str, str | float] = field(default_factory=dict)
    while_: tuple[str, ...] = ()
    socket: str = "data"
    where: DocPath = ()
