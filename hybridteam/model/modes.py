"""Mode trees and transitions, as plain declarations.

These classes say *what* a behaviour is; they hold expression text, not compiled code, so a
model can be built in Python, loaded from YAML, printed back or drawn without running anything.
:mod:`hybridteam.engine.compile.compiled` turns them into vectorized callables.

A mode is a leaf, an OR-composite (``children`` with an ``initial`` child or deeper
descendant, optionally with ``history``) or an AND-composite (``parallel=True``: every child
is a region that runs at the same time). Transitions are declared on their source mode.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Literal

from hybridteam.errors import DocPath

History = Literal["none", "shallow", "deep"]


@dataclass(frozen=True)
class LawBinding:
    """A control law attached to a mode: registry name or ``module:function``.

    ``period`` makes the law sampled (evaluated at mode entry and every ``period`` seconds on
    the global clock, output held in between); ``None`` makes it continuous. ``params`` are
    expression texts evaluated on the agent's parameters and variables.
    """

    name: str
    period: float | None = None
    params: dict[str, str | float] = field(default_factory=dict)
    where: DocPath = ()


@dataclass(frozen=True)
class Assign:
    """``target = expression``: a variable update, or a reset when the target is plant state."""

    text: str
    where: DocPath = ()


@dataclass(frozen=True)
class Send:
    """Broadcast a message (to every other agent, or to ``to`` only) on a socket."""

    message: str
    to: str | None = None
    socket: str = "control"
    fields: dict[str, str | float] = field(default_factory=dict)
    where: DocPath = ()


@dataclass(frozen=True)
class Raise:
    """Raise a local event in the same agent, handled later in the same instant."""

    event: str
    where: DocPath = ()


Action = Assign | Send | Raise


@dataclass(frozen=True)
class Transition:
    """A guarded, possibly triggered switch from the mode it is declared on to ``target``.

    ``on`` names a message type or local event; ``after`` is a delay (seconds in the source
    mode; a number or an expression of parameters). Without ``on`` a transition is *urgent*:
    taken at the first instant its guard and delay allow. Higher ``priority`` wins; at equal
    priority an outer (ancestor) mode's transition beats an inner one. Without a ``target``
    the transition is *internal*: its actions run but the mode is neither left nor
    re-entered (a leader denying a request keeps its plan and its time in mode).
    """

    target: str | None
    on: str | None = None
    after: str | float | None = None
    guard: str | None = None
    actions: tuple[Action, ...] = ()
    priority: int = 0
    where: DocPath = ()
    #: further targets (``to: [A.x, B.y]``), one in each of other parallel regions: the
    #: transition enters all of them at once (its ``target`` is the first)
    more_targets: tuple[str, ...] = ()
    #: a transition from a composite to modes inside it that stays in it: its source is
    #: neither exited nor entered again (UML's local transition, SCXML's type="internal")
    local: bool = False

    @property
    def targets(self) -> tuple[str, ...]:
        """Every target, in the order written (none for a transition without ``to``)."""
        return () if self.target is None else (self.target, *self.more_targets)


@dataclass(frozen=True)
class Mode:
    """A node of a mode tree."""

    name: str
    children: tuple[Mode, ...] = ()
    initial: str | None = None
    parallel: bool = False
    history: History = "none"
    #: the descendant a history entry goes to while nothing is remembered (default: the
    #: ``initial`` one), as an SCXML ``<history>``'s own transition
    history_default: str | None = None
    law: LawBinding | None = None
    inputs: dict[str, str | float] | None = None
    input_period: float | None = None
    flow: dict[str, str | float] | None = None
    invariant: str | None = None
    final: bool = False
    outcome: str | None = None  # a final mode may name the run's outcome (e.g. "success")
    role: str | None = None  # a protocol region's mode: the role it plays (lead, follow, ...)
    transitions: tuple[Transition, ...] = ()
    where: DocPath = ()
    #: a protocol region's mode that plays a role: where the agent's body for the role is
    #: (its law, inputs or flow and its submodes come from there, so their errors are
    #: located there, not at the protocol's mode); () when the mode is its own body
    body: DocPath = ()
    #: actions (as a transition's ``do:``) run each time the mode is entered / exited: a
    #: transition exits innermost first, runs its own actions, enters outermost first
    on_entry: tuple[Action, ...] = ()
    on_exit: tuple[Action, ...] = ()

    @property
    def is_leaf(self) -> bool:
        return not self.children

    def walk(self, prefix: str = "") -> Iterator[tuple[str, Mode]]:
        """Pre-order walk yielding ``(dotted path, mode)``; the root's path is its name."""
        path = f"{prefix}.{self.name}" if prefix else self.name
        yield path, self
        for child in self.children:
            yield from child.walk(path)
