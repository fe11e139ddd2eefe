"""Compiled form of a team: flat, indexed structures the engine runs vectorized.

Every mode of an agent has an index (pre-order, the root is 0); every transition has its
guard and actions as numpy callables, its exit root and entry path resolved, and its
conflicts with higher-precedence transitions precomputed.
:mod:`~hybridteam.engine.compile.compiler` builds these from the declarations; nothing here
refers to YAML.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from hybridteam.dynamics.plants import Plant
from hybridteam.errors import DocPath
from hybridteam.expr import Atom, Expression
from hybridteam.laws import LawContext, LawSpec, LawWorld, StreamInbox
from hybridteam.model import Team

REPLY = -1  # ``to: sender``: answer whoever sent the message that triggered the transition
RESERVED = frozenset({"t", "t_in_mode", "pi", "inf", "true", "false"})
CONTINUOUS_NAMES = frozenset({"t", "t_in_mode"})


class Ctx:
    """Evaluation context of expressions and laws for a subset of instances.

    ``x`` state (m, d), ``v`` variables (m, V), ``p`` parameters (m, P), ``t`` time (m,),
    ``t_in`` time since the owning mode was entered (m,), ``m`` the fields of the message
    that triggered the transition being evaluated (name -> (m,)), if any; ``e`` the agent's
    stream estimates for these instances (an
    :class:`~hybridteam.engine.run.streams.InboxView`), ``u`` the held inputs (m, k) where a
    stream's fields may read them; ``w`` the agent's view of the world components and its
    law memory (an :class:`~hybridteam.engine.run.world.AgentView`), where laws run.

    The one-letter slots are what compiled expressions read at every evaluation (kept
    short and plain: they are the hottest attribute reads of the engine). A law reads the
    same context through :class:`~hybridteam.laws.LawRows`, the typed contract with domain
    names (``state``, ``parameters``, ``variables``, ``time``, ``time_in_mode``,
    ``streams``, ``world``) that the properties below implement.
    """

    __slots__ = ("_since", "_t_in", "e", "m", "p", "q", "t", "u", "v", "w", "x")

    def __init__(
        self,
        x: np.ndarray,
        v: np.ndarray,
        p: np.ndarray,
        t: np.ndarray,
        t_in: np.ndarray | None = None,
        m: dict[str, np.ndarray] | None = None,
        e=None,
        w=None,
        since: tuple[np.ndarray, np.ndarray | slice] | None = None,
        q: tuple[np.ndarray, np.ndarray | slice] | None = None,
    ) -> None:
        """``since``: instead of ``t_in``, the entry times it is computed from when first
        read, ``(column, rows)``: ``t - column[rows]``. A law or an ``inputs:``
        expression rarely reads the time in its mode, and computing it costs two numpy
        calls at every tick; its caller consumes the context before any entry time
        changes."""
        self.x, self.v, self.p, self.t = x, v, p, t
        self._t_in = t if t_in is None and since is None else t_in
        self._since = since
        self.m = m
        self.e = e
        self.w = w
        self.u: np.ndarray | None = None
        #: the agent's configuration and these instances' rows in it, ``(active, rows)``,
        #: where a guard may read it (``in_mode``): read through :meth:`in_mode` only
        self.q = q

    def in_mode(self, m: int) -> np.ndarray:
        """Whether mode ``m`` is active in each of these instances."""
        active, rows = self.q  # type: ignore[misc]  # (a guard's context has its q)
        return active[:, m][rows]

    @property
    def t_in(self) -> np.ndarray:
        if self._t_in is None:
            column, rows = self._since  # type: ignore[misc]  # (given where t_in is not)
            self._t_in = self.t - column[rows]
        return self._t_in

    # ------------------------------------------------------------------ LawRows
    @property
    def state(self) -> np.ndarray:
        return self.x

    @property
    def parameters(self) -> np.ndarray:
        return self.p

    @property
    def variables(self) -> np.ndarray:
        return self.v

    @property
    def time(self) -> np.ndarray:
        return self.t

    @property
    def time_in_mode(self) -> np.ndarray:
        return self.t_in

    @property
    def streams(self) -> StreamInbox | None:
        return self.e

    @property
    def world(self) -> LawWorld:
        return self.w


class Row:
    """One instance's context on Python floats, for :attr:`hybridteam.expr.Atom.row`:
    ``x`` its state, ``v`` its variables, ``p`` its parameters (lists), ``t`` the time
    and ``t_in`` the time in the owning mode. What a single run's crossing search reads
    at each of its trial points, without a numpy call."""

    __slots__ = ("p", "t", "t_in", "v", "x")

    def __init__(
        self, x: list[float], v: list[float], p: list[float], t: float, t_in: float
    ) -> None:
        self.x, self.v, self.p, self.t, self.t_in = x, v, p, t, t_in


@dataclass
class Driver:
    """What moves the plant in a mode: a sampled or continuous law, a flow, or nothing."""

    kind: str  # "sampled" | "continuous" | "flow" | "zero"
    owner: int  # mode index that declares it (-1 for the agent-wide "zero" driver)
    period: float = 0.0
    law: LawSpec | None = None
    params: dict[str, Expression] = field(default_factory=dict)
    inputs: list[Expression] | None = None  # expression inputs (``inputs:`` in a mode)
    #: sampled expression inputs of parameters alone: every tick gives the values its mode
    #: was entered with, so a tick that enters nothing need not evaluate them again
    held: bool = False
    flow: list[Expression | None] | None = None  # one per state component (None: 0)
    where: DocPath = ()  # the law binding (a law that fails is reported there)
    #: the law's parameter columns by the names it reads at once (LawContext.table)
    tables: dict = field(default_factory=dict, repr=False, compare=False)

    @property
    def needs_rk(self) -> bool:
        return self.kind in ("continuous", "flow")

    @functools.cached_property
    def reads_t_in(self) -> bool:
        """Whether evaluating this driver may read ``t_in_mode``: a law may (it is Python);
        expressions do only if they name it. The integrator asks a dozen times a step, and
        need not compute the time in mode for a flow such as ``K * (30 - x)``."""
        exprs = self.flow if self.kind == "flow" else self.inputs
        if self.law is not None or exprs is None:
            return self.kind != "zero"
        return any(e is not None and "t_in_mode" in e.names for e in exprs)


@dataclass
class CAction:
    kind: str  # "assign" | "send" | "raise"
    target: tuple[str, int] | None = None  # ("x", j) or ("v", j)
    expr: Expression | None = None
    name: str = ""
    to: int | None = None  # an agent, None for broadcast, REPLY for the triggering sender
    socket: str = "control"
    fields: dict[str, Expression] = field(default_factory=dict)
    to_expr: Expression | None = None  # ``to: <expression>``: an agent index per instance


@dataclass
class CPolicy:
    """How an agent sends one message type: its priority and, if acknowledged, the ack
    timeout and retry limit (expressions of the sender's parameters)."""

    priority: Expression | None = None
    timeout: Expression | None = None
    retries: Expression | None = None
    where: DocPath = ()  # the ``ack:`` declaration (its values are checked when sent)
    dedupe: bool = True  # receivers act on a message once

    @property
    def acknowledged(self) -> bool:
        return self.timeout is not None


@dataclass(frozen=True)
class Entry:
    """How a transition (or a default entry) enters modes: ``first`` is activated, then
    each mode in ``marks`` on the way down (a parallel mode's other regions by default)
    until each of ``targets``, which completes its own entry (initial child or history)."""

    first: int
    marks: frozenset[int]
    targets: frozenset[int]
    #: ``first`` is a domain that stays active (a parallel mode, or a local transition's
    #: source): only what is below it is entered
    active_first: bool = False


@dataclass
class CTransition:
    index: int  # position in precedence order
    source: int
    target: int
    exit_root: int
    entry_path: list[int]
    on: str | None
    after: Expression | None
    guard: Expression | None
    actions: list[CAction]
    priority: int
    depth: int
    text: str  # "Source -> Target" for messages
    guard_text: str
    conflicts: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.intp))
    after_slot: int = -1
    internal: bool = False  # no target: actions only, nothing exited or entered
    origin: tuple = ()  # document path of the declaration (copies of one body share it)
    # between two protocol states of one role (Lead -> Offering): the role body's
    # configuration carries over. ``carry`` pairs each OR mode of the source's body with its
    # copy in the target's; ``carry_map[m]`` is the copy of mode m (-1 elsewhere, and at
    # index -1, so an unset history maps to unset); ``carry_timers`` holds (mode of the
    # copy, after-slot in the source, after-slot in the copy), so running delays go on.
    carry: list[tuple[int, int]] = field(default_factory=list)
    carry_map: np.ndarray | None = None
    carry_timers: list[tuple[int, int, int]] = field(default_factory=list)
    declared: int = -1  # position among the agent's transitions as declared (pre-order)
    entry: Entry | None = None  # how it enters (None: internal)
    targets: list[int] = field(default_factory=list)  # every target (``target``: the first)
    #: the exit root is a domain that stays active (a parallel mode, or a local
    #: transition's source): what is below it is exited, not the mode itself
    exit_inside: bool = False


@dataclass
class CMode:
    index: int
    name: str
    path: str
    parent: int
    depth: int
    kind: str  # "leaf" | "or" | "and"
    children: list[int]
    initial: int
    history: str
    final: bool
    driver: int
    invariant: Expression | None
    invariant_text: str
    subtree: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.intp))
    outgoing: list[int] = field(default_factory=list)
    role: str | None = None  # the protocol role this mode plays (views number role changes)
    #: an OR mode's default entry (its ``initial``, possibly a deeper descendant) and, with
    #: a history default, where a history entry goes while nothing is remembered
    default: Entry | None = None
    history_default: Entry | None = None
    on_entry: list[CAction] = field(default_factory=list)  # run each time it is entered
    on_exit: list[CAction] = field(default_factory=list)  # run each time it is exited


@dataclass
class Watch:
    """An atom (comparison) whose sign changes must be located during flow."""

    atom: Atom
    mode: int  # the mode that owns the guard or invariant (``t_in_mode`` is measured from it)
    owner: Expression | None  # the guard or invariant the atom belongs to
    invariant: bool
    #: a requirement's comparison: its crossings are located (and the run stops there, so
    #: the state at the crossing is recorded) though no guard depends on it
    observer: bool = False
    #: the atom is a conjunct of its guard: where it is false, so is the guard, and a flip
    #: of it to false cannot enable the transition
    conjunct: bool = False


@dataclass
class CStream:
    """A compiled stream of one sending agent."""

    message: str
    socket: str
    period: Expression  # 1 / rate, an expression of the sender's parameters
    fields: dict[str, Expression]
    modes: list[int]  # indices of the modes it is sent in; empty: always
    where: DocPath = ()  # the declaration (its ``rate`` is checked where it is evaluated)
    rate_text: str = ""
    fixed_rate: bool = False  # the rate reads only parameters: one period per instance


@dataclass
class CAgent:
    index: int
    name: str
    plant: Plant
    modes: list[CMode]
    transitions: list[CTransition]
    drivers: list[Driver]
    state_index: dict[str, int]
    var_index: dict[str, int]
    param_index: dict[str, int]
    param_defaults: np.ndarray
    init_state: list[Expression]
    init_vars: list[Expression]
    lower: np.ndarray
    upper: np.ndarray
    watches: list[Watch]
    eventless: list[int]
    triggered: dict[str, list[int]]
    after: list[int]
    driver_modes: list[int]  # modes that own a driver, deepest first
    has_eventless: np.ndarray
    has_triggered: np.ndarray
    final: np.ndarray
    leaves: np.ndarray
    outcome: list[str | None] = field(default_factory=list)  # per mode: a final's outcome
    policies: dict[str, CPolicy] = field(default_factory=dict)
    streams: list[CStream] = field(default_factory=list)
    # parameters written as expressions of the others: (column, expression), in order
    derived_params: tuple = ()
    # the source mode of every transition, by index (a gather finds which can fire)
    transition_sources: np.ndarray = field(default_factory=lambda: np.zeros(0, np.intp))
    #: every name the agent's expressions read (state, variables, parameters, ``t``, the
    #: team's names): analyses that recompile part of a guard (``hybridteam verify``) use it
    symbols: Mapping = field(default_factory=dict)
    #: whether some mode has entry or exit actions (without, entering and exiting look
    #: for none)
    mode_actions: bool = False
    #: the transitions a dotted event wakes (see :meth:`waiting`), found once per name
    prefixed: dict[str, list[int]] = field(default_factory=dict, repr=False)

    def waiting(self, event: str) -> list[int]:
        """The transitions an event triggers, in precedence order: those ``on`` its name
        and, for a dotted name, ``on`` each of its prefixes (``on: error`` is woken by
        ``error.io``, not by ``errors``), as SCXML's event descriptors match."""
        if "." not in event:
            return self.triggered.get(event, [])
        found = self.prefixed.get(event)
        if found is None:
            parts = event.split(".")
            found = sorted(
                {
                    j
                    for k in range(1, len(parts) + 1)
                    for j in self.triggered.get(".".join(parts[:k]), [])
                }
            )
            self.prefixed[event] = found
        return found

    @functools.cached_property
    def lone_watches(self) -> list[bool]:
        """Per watched atom: whether it is the only atom its guard or invariant watches.
        Its flip then decides alone, and the truths at the end of a sub-interval it flips
        in tell whether the flip matters (``search._relevant``); an atom with siblings
        may flip together with one, and only the state at the crossing can tell."""
        return [sum(o.owner is w.owner for o in self.watches) == 1 for w in self.watches]

    @functools.cached_property
    def fixed_names(self) -> frozenset[str]:
        """The names that stay constant over an integration step (variables and
        parameters): a flow expression of these alone is evaluated once per step."""
        return frozenset(self.var_index) | frozenset(self.param_index)

    @functools.cached_property
    def row_watches(self) -> bool:
        """Whether every watched atom has a float form (:attr:`~hybridteam.expr.Atom.row`),
        so a single run's checkpoints can be judged on floats."""
        return bool(self.watches) and all(w.atom.row is not None for w in self.watches)

    @functools.cached_property
    def row_owners(self) -> bool:
        """Whether every watched guard and invariant has a float form
        (:attr:`~hybridteam.expr.Expression.row`), so a single run's flips can be judged
        relevant on floats (a requirement's atoms have no owner and always matter)."""
        return all(w.owner is None or w.owner.row is not None for w in self.watches)

    @property
    def limited(self) -> bool:
        """Whether any input has a finite actuator limit."""
        return self.bounds is not None

    @functools.cached_property
    def bounds(self) -> tuple[np.ndarray, np.ndarray] | None:
        """The actuator limits as rows ``(1, inputs)``, or None when no input has a finite
        one. Asked at every law tick: kept, and shaped like the inputs' rows, because numpy
        broadcasts arrays of equal rank about twice as fast as a row against a matrix."""
        if not (np.isfinite(self.lower).any() or np.isfinite(self.upper).any()):
            return None
        return self.lower.reshape(1, -1), self.upper.reshape(1, -1)

    @functools.cached_property
    def invariant_modes(self) -> list[CMode]:
        """The modes that declare an invariant (checked at every instant: a team's
        protocols give its agents dozens of modes, a few of them with one)."""
        return [m for m in self.modes if m.invariant is not None]

    @functools.cached_property
    def final_leaves(self) -> np.ndarray:
        """Which leaf modes are final, in the order of ``leaves``."""
        return self.final[self.leaves]

    def initial_values(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Initial plant state ``(n, d)`` and variables ``(n, V)`` for parameters ``p``
        ``(n, P)``: their expressions read parameters only (the engine starts a run with
        these, a batch fast path is given them)."""
        n = p.shape[0]
        x = np.zeros((n, len(self.plant.state_names)))
        v = np.zeros((n, len(self.var_index)))
        ctx = Ctx(x, v, p, np.zeros(n))
        for j, e in enumerate(self.init_state):
            x[:, j] = np.broadcast_to(e(ctx), (n,))
        for j, e in enumerate(self.init_vars):
            v[:, j] = np.broadcast_to(e(ctx), (n,))
        return x, v

    def law_context(self, ctx: Ctx, driver: Driver) -> LawContext:
        return LawContext(
            ctx,
            driver.params,
            self.name,
            self.state_index,
            self.var_index,
            self.param_index,
            self.plant.input_names,
            driver.tables,
        )


@dataclass
class CTeam:
    team: Team
    agents: list[CAgent]
    scenario: list[tuple[float, int, str]]
    ending: list[int] = field(default_factory=list)  # agents whose final modes end a run
    end_any: bool = False  # the first of them to be final ends it (else: all of them)
