"""An independent second explorer: the skeleton's *rules* as Promela, explored by SPIN.

:mod:`.spin` hands SPIN the graph our explorer built, so SPIN cannot notice a successor
the explorer missed. Here SPIN gets the rules instead and explores the protocol on its
own; the two explorations are then compared (:func:`compare`).

**What is shared and what is not.** The export reads the *compiled* team (modes, the
precedence order of transitions, their conflict sets, entry and exit sets, parameter
values and initial variables) and the skeleton's classification of what is exact and what
is abstracted (:mod:`.abstraction`). It does not use :class:`~.machine.Machine` or the
engine's discrete phase: the run-time semantics — which transitions an event wakes, which
of them fire (:func:`~hybridteam.engine.run.discrete.select_and_fire`), exit then actions
then entry, where a send goes, the explorer's choices — is written again in Promela.

**The acknowledged layer** (``ack:``) is written again after
:mod:`hybridteam.engine.run.reliable`: a send takes the sender's next id and leaves an
outbox entry waiting for each receiver's ack; an arriving copy with an id is answered with
an ack and, where the sender's policy filters duplicates, withheld when its (receiver,
sender, id) was seen; an ack clears its receiver from the entry; a retransmission timer
(only once no copy of the message nor an ack of it flies, as ``--ack-timing bounded``
has it) resends to the receivers still waiting or, out of retries, drops the entry and
raises ``<type>_undeliverable`` at the sender. Every step ends with ``settle()``, our
canonical form (:meth:`.Machine.canonical`) written again in C: acks nobody waits for and
filter entries no copy can match again dropped, ids renumbered per sender, the slots
sorted — stably by link in fifo order — so SPIN meets one state where we do. Like ours,
the model delivers a copy no mode sees (an ack, a withheld copy) before anything else, a
partial-order reduction written again from the model's own data (:func:`_first_invisible`);
without it the acks interleave with everything and SPIN met over a million states on
the docking handshake, where ours met 1,547 (now about 1,600 for SPIN as well).

**The model.** Each agent is a proctype; its active modes are bits ``m<a>_<k>``, its
discrete variables ints. Copies in flight are an array of slots (a bag: any copy may
arrive next, as ``--order any`` has it, or in fifo order the oldest of its link); an
agent's step picks one copy addressed to it and dispatches it by type as the engine does
(the transitions on its type, in precedence order, each enabled one firing unless an
earlier chosen one conflicts with it) — the pick and the free comparisons' values are
chosen inside the step's atomic sequence before its ``d_step`` (SPIN stores no state
inside an atomic sequence), so each dispatch is written once, not once per slot. A
``raise`` queues its event; the queue is dispatched in order within the step, as the
engine's micro-steps of one instant, an enabled urgent transition (no trigger, an exact
guard) taking its micro-step before the next event. Where an agent has history or a role carry-over,
each of its 'or' modes keeps its last child (``h<a>_<m>``, AgentState.last) and an entry
reads it at run time. A ``network`` proctype loses or duplicates a copy
within the budgets (``--losses``, ``--duplicates``), a ``scenario`` proctype raises the
scenario's events in order, a world event may come whenever it fires a transition, and a
time-driven transition (``after:``, or a guard that reads time or state) may fire
whenever its source is active (``--timeouts any``: no clock needed; ``own``: once the
agent's own messages are settled; ``long``: once the network is quiet). A free
comparison (one that reads time or state) is a nondeterministic truth value; a step
that may change nothing (a time-driven transition, a world event) is written once per
assignment of the free comparisons it reads, a ``d_step`` whose condition includes the
guard, so it is enabled only when it changes the state.

**How the configurations are collected (soundly).** Every step that fires a transition
(or overflows a slot) ends with a print of the projected configuration (per agent its
active modes as bits; each distinct line once, a C hash set outside SPIN's state); a
step that fires none (a loss, an ack, a withheld copy) leaves the configuration as it
was, so every reachable state's configuration is the initial one (printed by ``init``
before any agent starts) or that of a printed step's target. pan compiled with
``-DPRINTF -DNOREDUCE`` runs an exhaustive depth-first search (no bitstate, none of
SPIN's own partial-order reduction) in which every transition out of every reachable
state of the model is executed once, so every such step prints, and nothing unreachable
does: the printed set is exactly the model's reachable projected configurations, which
the invisible-copy rule keeps those of every interleaving (:func:`_first_invisible`
says why). ``spin -o2``: SPIN would otherwise
keep variables it judges write-only (mode bits read only by the prints) out of the state
vector, merging states that differ in them. A ``watcher`` proctype waits on ``timeout``
(true exactly when no other statement is executable: a dead end) and prints the dead
end's configuration and whether it is a deadlock by the definition of :mod:`.properties`
(written here as a predicate over the mode bits).

**Verdicts compared.** ``deadlock``: SPIN's dead ends classified, against ours. Each
invariant and response property whose formulas read only modes, discrete variables and
parameters becomes an LTL claim over the model's variables (the formula's own getters
read :class:`_Signals`, which answers with Promela expressions), decided by SPIN's nested
depth-first search on the rules (:func:`_decide`) and compared with our verdict; one
that reads time, plant states, series or message events is left undecided with the
reason, as ours leaves it unchecked.

**Scope.** A feature this module cannot translate exactly refuses the model with one
line naming it (:class:`Unsupported`) rather than exporting an approximation:
time-driven transitions back into their own mode (other than a leaf into itself without
entry or exit actions, or targetless), a raised event that wakes a guard reading time or
state, non-integer values. Urgent transitions (no trigger, an exact guard) are taken as
the engine's discrete phase takes them (:meth:`_Ctx.drain`). Entry and exit actions
are translated where the engine runs them (exit actions of the active modes left,
innermost first, before the transition's own; entry actions as each mode is activated,
outermost first; the initial configuration's at the start, :func:`_initial_entry`). A
model that outgrows the slots (copies in flight, outbox and filter entries, raised
events, ids) is reported, not compared; :func:`prepare` gives it twice the room our
exploration needed (an export sized by hand may not: the three-robot example needs 11
slots for copies in flight, and with the default 8 the model overflows).
"""

from __future__ import annotations

import ast
import itertools
import re
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar, TypedDict

import numpy as np

from hybridteam.engine.compile.compiled import CAgent
from hybridteam.engine.compile.compiler import message_fields
from hybridteam.expr.compiler import free_names
from hybridteam.requirements import nodes as N
from hybridteam.verify.abstraction import Skeleton, _discrete_names, _message_names
from hybridteam.verify.machine import State
from hybridteam.verify.spin import _run, missing
from hybridteam.verify.symmetry import permute

#: slots for copies in flight (a send beyond them is reported, never dropped silently)
SLOTS = 8
#: outbox entries (acknowledged messages awaiting acks) and duplicate-filter entries
OUTBOX = 8
SEEN = 16
#: message ids one agent may hand out (the acknowledged layer's per-sender counter)
MAX_IDS = 200
#: below this many states of ours, SPIN's search is short: its verifier compiled unoptimized
SMALL = 500
#: free comparisons one step may read (each doubles the step's options)
MAX_FREE = 6
#: events one step may raise (the queue of raised events, drained within the step)
RAISED = 8
#: urgent micro-steps one step may take (more: a Zeno cycle, reported as an overflow)
MICRO = 32


class Unsupported(Exception):
    """The model uses a feature the export does not translate exactly (one line)."""


@dataclass
class Exploration:
    """What one explorer found: projected configurations, dead ends, the deadlock verdict,
    and the invariant and response verdicts it decided (name: holds)."""

    configurations: set[str]
    dead_ends: set[str]
    deadlock: bool  # True: no deadlock (the property holds)
    verdicts: dict[str, bool] = field(default_factory=dict)
    #: states stored (SPIN's: a few more than ours, among them its state before ``init``
    #: starts the processes and one after the watcher's step at each dead end)
    states: int = 0
    #: properties not decided, with the reason (SPIN: a formula the export cannot translate)
    undecided: dict[str, str] = field(default_factory=dict)


@dataclass
class Comparison:
    ours: Exploration
    spin: Exploration

    def differences(self) -> list[str]:
        """Each way the explorations differ, in words (empty: they agree)."""
        out = []
        for what, a, b in (
            ("configurations", self.ours.configurations, self.spin.configurations),
            ("dead-end configurations", self.ours.dead_ends, self.spin.dead_ends),
        ):
            if a - b:
                out.append(f"{len(a - b)} {what} only ours reaches, e.g. {min(a - b)}")
            if b - a:
                out.append(f"{len(b - a)} {what} only SPIN reaches, e.g. {min(b - a)}")
        if self.ours.deadlock != self.spin.deadlock:
            out.append(
                f"deadlock: ours {_word(self.ours.deadlock)}, SPIN {_word(self.spin.deadlock)}"
            )
        for name, holds in self.spin.verdicts.items():
            if name in self.ours.verdicts and self.ours.verdicts[name] != holds:
                out.append(f"{name}: ours {_word(self.ours.verdicts[name])}, SPIN {_word(holds)}")
        return out


def _word(holds: bool) -> str:
    return "holds" if holds else "violated"


# ---------------------------------------------------------------------------- the export


class _Agent:
    """One agent's names in the model and its translation helpers."""

    def __init__(self, sk: Skeleton, a: int, params: np.ndarray, init: np.ndarray) -> None:
        self.sk, self.a = sk, a
        self.ca: CAgent = sk.original.agents[a]
        ca = self.ca
        self.name = ca.name
        self.vars = {n: j for n, j in ca.var_index.items() if j in sk.discrete_vars[a]}
        self.var_name = {j: f"v{a}_{j}" for j in self.vars.values()}
        self.consts: dict[str, int] = {}
        for n, j in ca.param_index.items():
            self.consts[n] = params[j]
        for n in ca.symbols:
            if n.startswith("id_"):
                self.consts[n] = next(
                    b for b, o in enumerate(sk.original.agents) if o.name == n[3:]
                )
        self.init = {j: init[j] for j in self.vars.values()}
        #: 'or' modes whose last active child is kept (``h<a>_<m>``, -1: none), as
        #: AgentState.last: every one of an agent that has history or a role carry-over
        restores = any(m.history != "none" for m in ca.modes) or any(
            tr.carry for tr in ca.transitions
        )
        self.hist = [m.index for m in ca.modes if m.kind == "or"] if restores else []
        self.known = _discrete_names(ca, set(sk.abstract_vars[a]))
        #: per mode with entry actions, their Promela (filled by the export's context)
        self.entry_code: dict[int, list[str]] = {}

    def bit(self, m: int) -> str:
        return f"m{self.a}_{m}"

    def last(self, m: int) -> str:
        return f"h{self.a}_{m}"

    def activate(self, m: int) -> list[str]:
        """Mode ``m`` becomes active, and its entry actions run at once, before anything
        below it is entered (AgentState.activate calls them there: outermost first)."""
        return [f"{self.bit(m)} = 1;", *self.entry_code.get(m, [])]


def export(
    sk: Skeleton,
    losses: int,
    duplicates: int,
    slots: int = SLOTS,
    outbox: int = OUTBOX,
    seen: int = SEEN,
    drop: tuple[int, int] | None = None,
    ack_timing: str = "bounded",
    order: str = "any",
    timeouts: str = "any",
    reduce: bool = True,
    props: list | None = None,
) -> str:
    """The Promela model of ``sk``'s rules (raises :class:`Unsupported`). ``drop``: leave
    out one (agent, transition) — only to show that the comparison catches a wrong model.
    ``reduce``: an invisible copy's fates first (:func:`_first_invisible`; with
    ``--ack-timing bounded`` only), else SPIN explores every interleaving. ``props``: the
    invariant and response properties (:class:`~.properties.Property`) written as LTL
    claims ``p<k>`` (:func:`claims`)."""
    team = sk.original
    fields = {k: sorted(v) for k, v in message_fields(team.team).items()}
    exact = {t: [f for f in fs if (t, f) not in sk.abstract_fields] for t, fs in fields.items()}
    types = sorted(fields)
    nf = max([len(v) for v in exact.values()] + [1])
    from hybridteam.engine.run.ensemble import Ensemble

    ens = Ensemble(team, 1, 0, 1.0, {})  # parameters and initial values, as a run has them
    agents = []
    for a, st in enumerate(ens.states):
        _, v = st.ca.initial_values(st.p[:1])
        agents.append(
            _Agent(sk, a, _ints(st.p[0], f"agent '{st.ca.name}': a parameter"), np.asarray(v[0]))
        )
    for ag in agents:
        _refuse(sk, ag)
        for j in ag.vars.values():
            ag.init[j] = _int(ag.init[j], f"agent '{ag.name}': an initial variable")
    ctx = _Ctx(
        sk,
        agents,
        fields,
        exact,
        types,
        slots,
        drop,
        ack_timing == "bounded",
        order == "fifo",
        timeouts,
        reduce and ack_timing == "bounded",
    )
    ctx.outbox = outbox
    for ag in agents:
        ag.entry_code = {
            m.index: ctx.actions(ag, m.on_entry, None) for m in ag.ca.modes if m.on_entry
        }
    lines = [
        f"/* hybridteam verify --spin-rules: the rules of team '{team.team.name}' */",
        f"#define SLOTS {slots}",
        f"#define OUTBOX {outbox}",
        f"#define SEEN {seen}",
        f"#define ACK_T {len(types)}",
        "typedef Copy { byte used; byte snd; byte rcv; byte typ; int mid; "
        + " ".join(f"int f{k};" for k in range(nf))
        + " }",
        "typedef Out { byte used; byte snd; int mid; byte typ; byte wait; byte left; "
        + " ".join(f"int f{k};" for k in range(nf))
        + " }",
        "typedef Seen { byte used; byte rcv; byte snd; int mid }",
        "Copy fl[SLOTS];",
        "Out ob[OUTBOX];",
        "Seen sn[SEEN];",
        f"byte nid[{len(agents)}];",
        "byte losses = 0;",
        "byte dups = 0;",
        "bit overflow = 0;",
        "bit moved = 0;",
        "bit started = 0;",
        "byte inv = 0;",
        "hidden byte sl;",
        "hidden byte so;",
        "hidden byte r_snd;",
        "hidden int r_mid;",
        "hidden byte held;",
        "hidden byte r_typ;",
        "hidden int s_mid;",
        *[f"hidden int r_f{k};" for k in range(nf)],
        "byte sk = 0;",
        *[f"bit fr{k} = 0;" for k in range(MAX_FREE)],
        f"hidden byte rq[{RAISED}];",
        "hidden byte nr;",
        "hidden byte ri;",
        "hidden byte mi;",
        *_first_invisible(agents, types, slots, seen, ctx.fifo, ctx.reduce),
        *_settle((slots, outbox, seen), nf, ctx.fifo, len(agents), len(types), ctx.reduce),
        *_note(agents),
    ]
    for ag in agents:
        on = _default_config(ag.ca)
        lines += [f"bit {ag.bit(m)} = {int(m in on)};" for m in range(len(ag.ca.modes))]
        lines += [f"int {ag.var_name[j]} = {ag.init[j]};" for j in ag.vars.values()]
        lines += [f"short {ag.last(m)} = -1;" for m in ag.hist]
        lines += [f"hidden byte c{ag.a}_{j};" for j in range(len(ag.ca.transitions))]
    lines += [f"/* message type {k}: {t} */" for k, t in enumerate(types)]
    lines += [f"/* raised event {k}: {e} */" for k, (_, e) in enumerate(ctx.events)]
    first = _config_print(agents)
    config = f"if :: moved || overflow -> {first} moved = 0 :: else -> skip fi"
    for ag in agents:
        lines += ctx.agent_proc(ag, config)
    lines += ctx.network_proc(losses, duplicates, config)
    scenario = ctx.scenario_proc(config)
    lines += scenario
    start_scenario = " run scenario();" if scenario else ""
    lines += [
        "proctype watcher() {",
        "  timeout -> d_step { " + _print("T", agents, " %d", _deadlock_expr(sk, agents)) + " }",
        "}",
    ]
    runs = " ".join(f"run agent_{ag.a}();" for ag in agents)
    lines += [
        "init {",
        "  atomic { "
        + _initial_entry(ctx, agents)
        + first
        + f" moved = 0; started = 1; {runs} run network();{start_scenario} run watcher(); }}",
        "}",
    ]
    lines += _claim_lines(agents, props or [])
    return "\n".join([*lines, ""])


def _initial_entry(ctx: _Ctx, agents: list[_Agent]) -> str:
    """The initial configuration's entry actions, as the simulator's start runs them:
    agent by agent, the root activated and its default entry completed (each mode's
    entry actions as it is activated, outermost first), then the events they raised
    dispatched and the containers settled — all before the first state. The mode bits
    are set to the initial configuration already; setting them again changes nothing."""
    code = []
    for ag in agents:
        if ag.entry_code:
            code += [*ag.entry_code.get(0, []), *_enter_default(ag, 0, False, False)]
    if code or any(ctx.urgent(ag) for ag in agents):  # (urgent ones may fire at once)
        return " ".join(code) + " " + ctx.tail() + " "
    return ""


def _ints(values, what: str) -> np.ndarray:
    """Parameter values: whole numbers as ints, others None (refused where read)."""
    return np.array(
        [int(v) if np.isfinite(v) and float(v).is_integer() else None for v in values], dtype=object
    )


def _int(v, what: str) -> int:
    v = float(v)
    if not v.is_integer():
        raise Unsupported(f"{what} is not a whole number ({v:g})")
    return int(v)


def _refuse(sk: Skeleton, ag: _Agent) -> None:
    """One line naming the first feature of ``ag`` the export does not translate."""
    ca, who = ag.ca, f"agent '{ag.name}'"
    for m in ca.modes:
        for act in [*m.on_entry, *m.on_exit]:
            if act.kind == "send" and act.socket != "control":
                raise Unsupported(f"{who}: mode {m.path}: a send on socket '{act.socket}'")
    timed = set(sk.time_driven[ag.a])
    for tr in ca.transitions:
        where = f"{who} {tr.text}"
        if (
            tr.index in timed
            and not _in_place(ca, tr)
            and (_above(ca, tr.target, tr.source) or _above(ca, tr.source, tr.target))
        ):
            raise Unsupported(f"{where}: a time-driven transition back into its own mode")
        if (
            tr.index in timed
            and not tr.internal
            and _in_place(ca, tr)
            and (ca.modes[tr.source].on_entry or ca.modes[tr.source].on_exit)
        ):
            raise Unsupported(
                f"{where}: a time-driven transition in place through a mode with entry or "
                "exit actions"
            )
        if tr.index in timed and _in_place(ca, tr) and not _sends(tr):
            assigned: set[int] = set()
            for act in tr.actions:
                if act.kind != "assign" or act.target is None or act.target[0] != "v":
                    continue
                assert act.expr is not None  # (an assignment has its expression)
                reads = {ag.vars[n] for n in act.expr.names if n in ag.vars}
                if reads & assigned:
                    raise Unsupported(
                        f"{where}: a time-driven transition in place whose "
                        "assignments read each other"
                    )
                assigned.add(act.target[1])
        for act in tr.actions:
            if act.kind == "send" and act.socket != "control":
                raise Unsupported(f"{where}: a send on socket '{act.socket}'")


def _in_place(ca: CAgent, tr) -> bool:
    """A transition that leaves the configuration as it is: targetless, or from a leaf
    back into it."""
    return tr.internal or (tr.source == tr.target and ca.modes[tr.source].kind == "leaf")


def _sends(tr) -> bool:
    return any(act.kind == "send" for act in tr.actions)


def _above(ca: CAgent, m: int, n: int) -> bool:
    """Whether mode ``m`` is ``n`` or one of its ancestors."""
    while n >= 0:
        if n == m:
            return True
        n = ca.modes[n].parent
    return False


def _entered(ca: CAgent, entry, out: set[int]) -> None:
    """The modes ``entry`` activates (no history: refused), as AgentState.enter has it."""
    if not entry.active_first:
        out.add(entry.first)
    _below(ca, entry.first, entry, out)


def _below(ca: CAgent, m: int, entry, out: set[int]) -> None:
    if m in entry.targets:
        _default(ca, m, out)
        return
    for c in ca.modes[m].children:
        if c in entry.marks:
            out.add(c)
            _below(ca, c, entry, out)
        elif ca.modes[m].kind == "and":
            out.add(c)
            _default(ca, c, out)


def _default(ca: CAgent, m: int, out: set[int]) -> None:
    mode = ca.modes[m]
    if mode.kind == "and":
        for r in mode.children:
            out.add(r)
            _default(ca, r, out)
    elif mode.kind == "or":
        _entered(ca, mode.default, out)


def _default_config(ca: CAgent) -> set[int]:
    out = {0}
    _default(ca, 0, out)
    return out


def _remember(ag: _Agent, m: int) -> str:
    """Exiting 'or' mode ``m``: its active child becomes its last (AgentState.exit)."""
    kids = " ".join(
        f":: {ag.bit(m)} && {ag.bit(c)} -> {ag.last(m)} = {c}" for c in ag.ca.modes[m].children
    )
    return f"if {kids} :: else -> skip fi;"


def _carried(ag: _Agent, a: int, b: int, mapping) -> str:
    """A role carry-over: mode ``b`` (in the target's copy of the body) remembers the copy
    of what ``a`` remembered (``last[b] = carry_map[last[a]]``, unset stays unset)."""
    kids = " ".join(
        f":: {ag.last(a)} == {c} -> {ag.last(b)} = {int(mapping[c])}"
        for c in ag.ca.modes[a].children
    )
    return f"if {kids} :: else -> {ag.last(b)} = -1 fi;"


def _enter(ag: _Agent, entry, deep: bool) -> list[str]:
    """Entering as ``entry`` says (AgentState.enter): its first mode, down through its
    marked modes to its targets, which complete their entry — by history, read at run
    time from the ``h`` variables, where a mode has one (or ``deep``, a carry-over)."""
    out = [] if entry.active_first else ag.activate(entry.first)
    return out + _enter_below(ag, entry.first, entry, deep)


def _enter_below(ag: _Agent, m: int, entry, deep: bool) -> list[str]:
    if m in entry.targets:
        return _enter_default(ag, m, deep, False)
    out = []
    for c in ag.ca.modes[m].children:
        if c in entry.marks:
            out += [*ag.activate(c), *_enter_below(ag, c, entry, deep)]
        elif ag.ca.modes[m].kind == "and":
            out += [*ag.activate(c), *_enter_default(ag, c, False, False)]
    return out


def _enter_default(ag: _Agent, m: int, deep: bool, restore: bool) -> list[str]:
    """AgentState.enter_default: initial children, or the remembered ones."""
    mode = ag.ca.modes[m]
    out: list[str] = []
    if mode.kind == "and":
        for r in mode.children:
            out += ag.activate(r)
            out += _enter_default(
                ag, r, deep or mode.history == "deep", restore or mode.history == "shallow"
            )
        return out
    if mode.kind != "or":
        return out
    deeper = deep or mode.history == "deep"
    if not (restore or deep or mode.history != "none"):
        return _enter(ag, mode.default, False)
    fresh = mode.history_default or mode.default
    assert fresh is not None  # (an 'or' mode has its default entry)
    if fresh.targets == {mode.initial}:  # nothing remembered: the initial child
        unset = [*ag.activate(mode.initial), *_enter_default(ag, mode.initial, deeper, False)]
    else:
        unset = _enter(ag, fresh, False)
    options = [
        f":: {ag.last(m)} == {c} -> "
        + " ".join([*ag.activate(c), *_enter_default(ag, c, deeper, False)])
        for c in mode.children
    ]
    return ["if " + " ".join(options) + " :: else -> " + (" ".join(unset) or "skip") + " fi;"]


def _exited(ca: CAgent, tr) -> list[int]:
    sub = ca.modes[tr.exit_root].subtree
    return [int(m) for m in (sub[1:] if tr.exit_inside else sub)]


def _config_print(agents: list[_Agent]) -> str:
    """The step's closing print: the projected configuration, and whether a send found
    no free slot (then the comparison is refused, not made on a truncated model); each
    distinct line once (``note``)."""
    return "c_code { note(now.overflow); };"


def _note(agents: list[_Agent]) -> list[str]:
    """``note``: print a configuration line unless it was printed before (a C hash set of
    the lines, outside SPIN's state), so the output holds one line per configuration
    rather than one per transition SPIN executes — the printed set is the same."""
    bits = [f"now.{ag.bit(m)}" for ag in agents for m in range(len(ag.ca.modes))]
    size = len(bits) + len(agents) + 8
    put, k = [], 2
    for ag in agents:
        if ag.a:
            put.append(f"b[{k}] = '|';")
            k += 1
        for m in range(len(ag.ca.modes)):
            put.append(f"b[{k}] = '0' + now.{ag.bit(m)};")
            k += 1
    return [
        "c_code {",
        "  static char **lines_seen; static unsigned long lines_n, lines_cap;",
        "  static void note(int overflow) {",
        f"    char b[{size}]; unsigned long h = 14695981039346656037UL, i; char *c;",
        "    b[0] = 'C'; b[1] = ' '; " + " ".join(put),
        f"    b[{k}] = ' '; b[{k + 1}] = '0' + (overflow != 0); b[{k + 2}] = 0;",
        "    if (2 * (lines_n + 1) > lines_cap) {  /* grow: rehash into twice the room */",
        "      unsigned long cap = lines_cap ? 2 * lines_cap : 1024, j;",
        "      char **t = (char **) calloc(cap, sizeof(char *));",
        "      for (j = 0; j < lines_cap; j++) if (lines_seen[j]) {",
        "        unsigned long g = 14695981039346656037UL; for (c = lines_seen[j]; *c; c++) "
        "g = (g ^ (unsigned char) *c) * 1099511628211UL;",
        "        for (i = g % cap; t[i]; i = (i + 1) % cap); t[i] = lines_seen[j];",
        "      }",
        "      free(lines_seen); lines_seen = t; lines_cap = cap;",
        "    }",
        "    for (c = b; *c; c++) h = (h ^ (unsigned char) *c) * 1099511628211UL;",
        "    for (i = h % lines_cap; lines_seen[i]; i = (i + 1) % lines_cap)",
        "      if (strcmp(lines_seen[i], b) == 0) return;",
        "    lines_seen[i] = strdup(b); lines_n++;",
        '    printf("%s\\n", b);',
        "  }",
        "}",
    ]


def _print(tag: str, agents: list[_Agent], fmt_more: str, args_more: str) -> str:
    fmt = "|".join("%d" * len(ag.ca.modes) for ag in agents)
    args = ", ".join(ag.bit(m) for ag in agents for m in range(len(ag.ca.modes)))
    return f'printf("{tag} {fmt}{fmt_more}\\n", {args}, {args_more});'


class _Ctx:
    """Translation of guards, actions and steps (one model's worth of names)."""

    def __init__(
        self, sk, agents, fields, exact, types, slots, drop, bounded, fifo, timeouts, reduce
    ) -> None:
        self.sk, self.agents, self.fields, self.exact = sk, agents, fields, exact
        self.types, self.slots, self.drop, self.bounded = types, slots, drop, bounded
        self.fifo, self.timeouts, self.reduce = fifo, timeouts, reduce
        self.outbox = OUTBOX  # (export sets the model's size)
        self.events = self.raised_events()

    # -- expressions
    def expr(
        self,
        ag: _Agent,
        source: str,
        on: str | None,
        free: list[str] | None = None,
        condition: bool = False,
    ) -> str:
        """``source`` in Promela; with ``free`` (a guard), comparisons that read abstracted
        names become free bits ``FREE<k>`` appended to ``free``."""
        known = ag.known | _message_names(on, self.fields, self.sk.abstract_fields)
        text = source.strip()
        node = ast.parse(text, mode="eval").body

        def cond(n) -> str:  # the guard's Boolean structure over its comparisons
            if isinstance(n, ast.BoolOp):
                op = " && " if isinstance(n.op, ast.And) else " || "
                return "(" + op.join(cond(v) for v in n.values) + ")"
            if isinstance(n, ast.UnaryOp) and isinstance(n.op, ast.Not):
                return f"(!{cond(n.operand)})"
            seg = ast.get_source_segment(text, n) or text
            if free is not None and not free_names(seg, condition=True) <= known:
                free.append(seg)
                return f"FREE{len(free) - 1}"
            return go(n)

        def go(n) -> str:
            if isinstance(n, (ast.BoolOp, ast.UnaryOp)) and not isinstance(n.op, ast.USub):
                return cond(n)
            if isinstance(n, ast.UnaryOp):
                return f"(-{go(n.operand)})"
            if isinstance(n, ast.Compare) and len(n.ops) == 1:
                compare: dict[type[ast.cmpop], str] = {
                    ast.Eq: "==",
                    ast.NotEq: "!=",
                    ast.Lt: "<",
                    ast.LtE: "<=",
                    ast.Gt: ">",
                    ast.GtE: ">=",
                }
                op = compare.get(type(n.ops[0]))
                if op:
                    return f"({go(n.left)} {op} {go(n.comparators[0])})"
            if isinstance(n, ast.BinOp):
                arith: dict[type[ast.operator], str] = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*"}
                op = arith.get(type(n.op))
                if op:
                    return f"({go(n.left)} {op} {go(n.right)})"
            if isinstance(n, ast.Constant) and isinstance(n.value, bool):
                return str(int(n.value))
            if isinstance(n, ast.Constant) and isinstance(n.value, (int, float)):
                return str(_int(n.value, f"agent '{ag.name}': '{text}'"))
            if isinstance(n, ast.Name):
                return self.name(ag, n.id, on, text)
            raise Unsupported(
                f"agent '{ag.name}': '{text}': "
                f"{ast.get_source_segment(text, n) or text} is not translated"
            )

        return cond(node) if free is not None else go(node)

    def name(self, ag: _Agent, name: str, on: str | None, text: str) -> str:
        if name in ag.vars:
            return ag.var_name[ag.vars[name]]
        if name == "msg_sender" and on is not None:
            return "r_snd"
        if name.startswith("msg_") and on in self.exact and name[4:] in self.exact[on]:
            return f"r_f{self.exact[on].index(name[4:])}"
        if name in ag.consts:
            c = ag.consts[name]
            if isinstance(c, int):
                return str(c)
        raise Unsupported(f"agent '{ag.name}': '{text}' reads '{name}', which is not translated")

    # -- one transition
    def guard(self, ag: _Agent, tr, free: list[str]) -> str:
        cond = ag.bit(tr.source)
        if tr.guard is not None:
            cond += " && " + self.expr(ag, tr.guard.source, tr.on, free, True)
        return cond

    def fire(self, ag: _Agent, tr) -> list[str]:
        """Exit (the exit set), actions, entry (the entry set), as engine.run.discrete.fire."""
        out = []
        if not tr.internal:
            exited = _exited(ag.ca, tr)
            for m in exited[::-1]:  # exit actions of the active ones, innermost first
                code = " ".join(self.actions(ag, ag.ca.modes[m].on_exit, None))
                if code:
                    out.append(f"if :: {ag.bit(m)} -> {code} :: else -> skip fi;")
            out += [_remember(ag, m) for m in exited if m in ag.hist]
            out += [f"{ag.bit(m)} = 0;" for m in exited]
        out += self.actions(ag, tr.actions, tr.on)
        if not tr.internal:
            for a, b in tr.carry:  # same role: the body resumes (compiler._role_carry)
                out.append(_carried(ag, a, b, tr.carry_map))
            out += [*_enter(ag, tr.entry, bool(tr.carry)), "moved = 1;"]
        return out

    def actions(self, ag: _Agent, actions, on: str | None) -> list[str]:
        """An action list in order (engine.run.actions.run_actions): assignments to the
        discrete variables (sequential), sends, raises (queued, dispatched after the
        step's firings). ``on``: the triggering message, None in entry and exit lists."""
        out = []
        for act in actions:
            if act.kind == "assign":
                kind, j = act.target
                if kind == "v" and j in ag.var_name:
                    out.append(f"{ag.var_name[j]} = {self.expr(ag, act.expr.source, on)};")
            elif act.kind == "send":
                out += self.send(ag, act, on)
            elif act.kind == "raise":
                k = self.events.index((ag.a, act.name))
                out.append(
                    f"if :: nr >= {RAISED} -> overflow = 1 :: else -> rq[nr] = {k}; nr++ fi;"
                )
        return out

    def send(self, ag: _Agent, act, on: str | None) -> list[str]:
        """A send: a datagram to each receiver (as engine.run.network.send picks them),
        through the acknowledged layer (engine.run.reliable.send: a fresh id, an outbox
        entry waiting for the receivers' acks) when the type's policy asks for acks."""
        typ = self.types.index(act.name)
        values = [
            self.expr(ag, act.fields[f].source, on) if f in act.fields else "0"
            for f in self.exact.get(act.name, [])
        ]
        n = len(self.agents)
        others = [r for r in range(n) if r != ag.a]
        everyone = sum(1 << r for r in others)
        to = None
        if act.to_expr is not None:
            to = self.expr(ag, act.to_expr.source, on)
        elif _reply(act) and on is not None:
            to = "r_snd"
        if to is not None:
            pairs = [(f"(({to}) == {r} || ({to}) < 0)", r) for r in others]
            wait = f"(({to}) < 0 -> {everyone} : (1 << ({to})))"
        elif act.to is None or _reply(act):
            pairs = [("1", r) for r in others]
            wait = str(everyone)
        else:
            pairs = [("1", int(act.to))]
            wait = str(1 << int(act.to))
        policy = ag.ca.policies.get(act.name)
        out = []
        mid = "-1"
        if policy is not None and policy.acknowledged:
            retries = self.expr(ag, policy.retries.source, None)  # type: ignore[union-attr]
            put = [
                f"ob[so].used = 1; ob[so].snd = {ag.a}; ob[so].mid = nid[{ag.a}]; "
                f"ob[so].typ = {typ}; ob[so].wait = {wait}; ob[so].left = {retries};"
            ] + [f"ob[so].f{k} = {v};" for k, v in enumerate(values)]
            out.append(
                f"if :: nid[{ag.a}] >= {MAX_IDS} -> overflow = 1 :: else -> skip fi; "
                "so = 0; do :: so < OUTBOX && ob[so].used -> so++ :: else -> break od; "
                "if :: so == OUTBOX -> overflow = 1 :: else -> "
                + " ".join(put)
                + f" fi; so = 0; s_mid = nid[{ag.a}]; nid[{ag.a}]++;"
            )
            mid = "s_mid"
        for cond, r in pairs:
            out.append(
                f"if :: {cond} -> {_put(str(ag.a), str(r), str(typ), mid, values)} "
                ":: else -> skip fi;"
            )
        if mid != "-1":
            out.append("s_mid = 0;")
        return out

    def dispatch(self, ag: _Agent, event: str, on: str | None, free: list[str]) -> list[str]:
        """select_and_fire for the transitions ``event`` wakes: enabled ones (in precedence
        order) fire unless an earlier chosen one conflicts; guards are read before any
        fires. ``free`` collects the free comparisons read (FREE<k> placeholders)."""
        cands = [j for j in ag.ca.waiting(event) if self.drop != (ag.a, j)]
        out = []
        for j in sorted(cands):
            tr = ag.ca.transitions[j]
            c = f"c{ag.a}_{j}"
            cond = self.guard(ag, tr, free)
            block = [f"c{ag.a}_{k}" for k in tr.conflicts.tolist() if k in cands and k < j]
            out.append(f"{c} = ({cond})" + "".join(f" && !{b}" for b in block) + ";")
        for j in sorted(cands):
            tr = ag.ca.transitions[j]
            out.append(
                f"if :: c{ag.a}_{j} -> " + " ".join(self.fire(ag, tr)) + " :: else -> skip fi;"
            )
        out += [f"c{ag.a}_{j} = 0;" for j in sorted(cands)]
        return out

    # -- processes
    def arrives(self, k: int) -> str:
        """Whether the copy in slot ``k`` may arrive (or be lost, or duplicated) next: any
        copy (``--order any``), or in fifo order the oldest on its link — the slots are
        kept sorted stably by link (``settle``), so that is the first of its link."""
        if not self.fifo or k == 0:
            return f"fl[{k}].used"
        return f"fl[{k}].used && (fl[{k - 1}].snd != fl[{k}].snd || fl[{k - 1}].rcv != fl[{k}].rcv)"

    def fate(self, k: int) -> str:
        """``arrives(k)``, and where an invisible copy flies only if it is that copy
        (:func:`_first_invisible`): what may happen to the copy in slot ``k`` next."""
        if not self.reduce:
            return self.arrives(k)
        return f"{self.arrives(k)} && (inv == 0 || inv == {k + 1})"

    def visible(self) -> str:
        """The condition of every step that is not a copy's fate: no invisible copy flies
        (``1`` without the reduction)."""
        return "inv == 0" if self.reduce else "1"

    def choose(self, free: list[str], who: str) -> str:
        """Nondeterministic values of the free comparisons a step reads (bits ``fr<k>``,
        set inside the step's atomic sequence before its ``d_step``)."""
        if len(free) > MAX_FREE:
            raise Unsupported(f"agent '{who}': more than {MAX_FREE} free comparisons in one step")
        return " ".join(f"if :: fr{k} = 1 :: skip fi;" for k in range(len(free)))

    def tail(self) -> str:
        """What closes every step: the events its transitions raised, dispatched in order
        (each a micro-step of the same instant, as the engine's queue has them), the
        choice bits cleared, and the containers brought to their canonical order."""
        return (
            self.drain()
            + " sk = 0; "
            + " ".join(f"fr{k} = 0;" for k in range(MAX_FREE))
            + " settle();"
        )

    def raised_events(self) -> list[tuple[int, str]]:
        """(agent, event) of every ``raise`` action: numbered in the raised-event queue."""
        out: list[tuple[int, str]] = []
        for ag in self.agents:
            lists = [tr.actions for tr in ag.ca.transitions]
            lists += [m.on_entry for m in ag.ca.modes] + [m.on_exit for m in ag.ca.modes]
            for actions in lists:
                for act in actions:
                    if act.kind == "raise" and (ag.a, act.name) not in out:
                        out.append((ag.a, act.name))
        return out

    def urgent(self, ag: _Agent) -> list[int]:
        """``ag``'s urgent transitions: no trigger, not time-driven (an exact guard, or
        none), in precedence order."""
        timed = set(self.sk.time_driven[ag.a])
        return [
            j
            for j, tr in enumerate(ag.ca.transitions)
            if tr.on is None and j not in timed and self.drop != (ag.a, j)
        ]

    def micro_step(self) -> tuple[str, str]:
        """(whether some urgent transition is enabled, the micro-step in which every
        agent takes its enabled ones): engine.run.discrete.discrete_phase takes such a
        micro-step before any pending event, select_and_fire over the agent's urgent
        transitions (guards read before any fires, an earlier chosen one blocking a
        conflicting later one)."""
        enabled, choose, fire = [], [], []
        for ag in self.agents:
            cands = self.urgent(ag)
            for j in cands:
                tr = ag.ca.transitions[j]
                free: list[str] = []
                cond = self.guard(ag, tr, free)
                assert not free  # (a guard that reads time or state makes it time-driven)
                enabled.append(f"({cond})")
                block = [f"c{ag.a}_{k}" for k in tr.conflicts.tolist() if k in cands and k < j]
                choose.append(f"c{ag.a}_{j} = ({cond})" + "".join(f" && !{b}" for b in block) + ";")
                fire.append(
                    f"if :: c{ag.a}_{j} -> " + " ".join(self.fire(ag, tr)) + " :: else -> skip fi;"
                )
                fire.append(f"c{ag.a}_{j} = 0;")
        return " || ".join(enabled), " ".join(choose + fire)

    def drain(self) -> str:
        """The rest of the instant, in micro-steps as the engine takes them: while some
        urgent transition is enabled, every agent takes its enabled ones; else the first
        raised event in the queue is dispatched (an event raised meanwhile joins the
        queue's end); until neither is left. A queue that outgrows ``RAISED``, or more
        than ``MICRO`` urgent micro-steps (a Zeno cycle), is an overflow."""
        enabled, micro = self.micro_step()
        if not self.events and not enabled:
            return ""
        options = []
        for k, (a, name) in enumerate(self.events):
            ag = self.agents[a]
            free: list[str] = []
            body = " ".join(self.dispatch(ag, name, None, free))
            if free:
                raise Unsupported(
                    f"agent '{ag.name}': the raised event '{name}' wakes a guard that "
                    "reads time or state"
                )
            options.append(f":: rq[ri] == {k} -> {body or 'skip'}")
        event = (
            "if :: ri < nr -> if "
            + " ".join(options)
            + " :: else -> skip fi; rq[ri] = 0; ri++ :: else -> break fi"
        )
        if not enabled:
            return f" ri = 0; do :: true -> {event} od; nr = 0; ri = 0;"
        return (
            f" ri = 0; mi = 0; do :: ({enabled}) -> if :: mi >= {MICRO} -> overflow = 1; "
            f"break :: else -> {micro} mi++ fi :: else -> {event} od; nr = 0; ri = 0; mi = 0;"
        )

    def agent_proc(self, ag: _Agent, config: str) -> list[str]:
        out = [f"proctype agent_{ag.a}() {{  /* {ag.name} */", "end:", "  do"]
        # a copy arrives: one option picks the slot (one of those addressed to this agent),
        # the next dispatches it by type; the dispatch is written once per type, not once
        # per slot, which keeps the model (and the C compiler's work) small
        pick = " ".join(
            f":: {self.fate(k)} && fl[{k}].rcv == {ag.a} -> sk = {k}" for k in range(self.slots)
        )
        branches = []
        for t, name in enumerate(self.types):
            free: list[str] = []
            body = _subst(" ".join(self.dispatch(ag, name, name, free)), None)
            read = (
                "r_snd = fl[sk].snd; r_mid = fl[sk].mid; "
                + " ".join(f"r_f{i} = fl[sk].f{i};" for i in range(len(self.exact[name])))
                + f" {_clear('sk', self.exact)}"
            )
            branches.append(
                f":: fl[sk].typ == {t} -> {self.choose(free, ag.name)} d_step {{ {read} "
                f"{self.screen(ag, name)} if :: !held -> {body or 'skip'} :: else -> skip fi; "
                f"{_reset(self.exact)} {self.tail()} }}"
            )
        # an ack arrives (engine.run.reliable.screen)
        branches.append(
            ":: fl[sk].typ == ACK_T -> d_step { r_snd = fl[sk].snd; r_mid = fl[sk].mid; "
            f"{_clear('sk', self.exact)} so = 0; do :: so < OUTBOX -> if :: "
            f"ob[so].used && ob[so].snd == {ag.a} && ob[so].mid == r_mid -> "
            "ob[so].wait = ob[so].wait & ~(1 << r_snd); if :: ob[so].wait == 0 -> "
            f"{_clear_out('so', self.exact)} :: else -> skip fi :: else -> skip fi; "
            f"so++ :: else -> break od; so = 0; {_reset(self.exact)} {self.tail()} }}"
        )
        out.append(f"  :: atomic {{ if {pick} fi; if {' '.join(branches)} fi; {config} }}")
        out += self.timers(ag, config)
        for j in self.sk.time_driven[ag.a]:
            if self.drop == (ag.a, j):
                continue
            tr = ag.ca.transitions[j]
            free = []
            cond = (
                f"{self.visible()} && "
                + self.guard(ag, tr, free)
                + self.changes(ag, tr)
                + self.waits(ag, tr)
            )
            for bits in _assignments(free, ag.name):
                out.append(
                    f"  :: atomic {{ d_step {{ {_subst(cond, bits)} -> "
                    + _subst(" ".join(self.fire(ag, tr)), bits)
                    + f" {self.tail()} }}; "
                    + config
                    + " }"
                )
        for b, event in self.sk.world_events:
            if b != ag.a:
                continue
            # a world event (a sensor's, a component's) may be raised at any moment; only
            # where it fires a transition (our explorer keeps no step that changes nothing)
            cands = [j for j in ag.ca.waiting(event) if self.drop != (ag.a, j)]
            free = []
            body = " ".join(self.dispatch(ag, event, None, free))
            check: list[str] = []
            enabled = " || ".join(
                self.guard(ag, ag.ca.transitions[j], check) for j in sorted(cands)
            )
            assert check == free  # (the same guards, read in the same order)
            for bits in _assignments(free, ag.name):
                out.append(
                    f"  :: atomic {{ d_step {{ {self.visible()} && "
                    f"({_subst(enabled or '0', bits)}) -> "
                    f"{_subst(body, bits)} {self.tail()} }}; {config} }}"
                )
        out += ["  od", "}"]
        return out

    def waits(self, ag: _Agent, tr) -> str:
        """The timing assumption on an ``after:`` timeout (``--timeouts``, as
        explore.choices has it): ``long``, only once nothing is in flight nor awaits an
        ack; ``own``, only once none of the agent's copies but acks flies and nothing of
        it awaits an ack."""
        if self.timeouts == "any" or tr.after is None:
            return ""
        if self.timeouts == "long":
            busy = [f"fl[{k}].used" for k in range(self.slots)]
            busy += [f"ob[{o}].used" for o in range(self.outbox)]
        else:
            busy = [
                f"(fl[{k}].used && fl[{k}].snd == {ag.a} && fl[{k}].typ != ACK_T)"
                for k in range(self.slots)
            ]
            busy += [f"(ob[{o}].used && ob[{o}].snd == {ag.a})" for o in range(self.outbox)]
        return " && !(" + " || ".join(busy) + ")"

    def screen(self, ag: _Agent, name: str) -> str:
        """The acknowledged layer's look at an arriving copy (engine.run.reliable.screen):
        an ack back for an acknowledged one, and, where its sender's policy filters
        duplicates, ``held`` when the (receiver, sender, id) was seen before."""
        dedupe = [
            b
            for b, o in enumerate(self.agents)
            if (p := o.ca.policies.get(name)) is not None and p.acknowledged and p.dedupe
        ]
        if not any(
            (p := o.ca.policies.get(name)) is not None and p.acknowledged for o in self.agents
        ):
            return "held = 0;"
        ack = _put(str(ag.a), "r_snd", "ACK_T", "r_mid", [])
        out = f"held = 0; if :: r_mid >= 0 -> {ack} :: else -> skip fi;"
        if dedupe:
            filt = " || ".join(f"r_snd == {b}" for b in dedupe)
            out += (
                f" if :: r_mid >= 0 && ({filt}) -> so = 0; do :: so < SEEN -> if :: "
                f"sn[so].used && sn[so].rcv == {ag.a} && sn[so].snd == r_snd && "
                "sn[so].mid == r_mid -> held = 1 :: else -> skip fi; so++ "
                ":: else -> break od; if :: !held -> so = 0; do :: so < SEEN && "
                "sn[so].used -> so++ :: else -> break od; if :: so == SEEN -> "
                f"overflow = 1 :: else -> sn[so].used = 1; sn[so].rcv = {ag.a}; "
                "sn[so].snd = r_snd; sn[so].mid = r_mid fi :: else -> skip fi; so = 0 "
                ":: else -> skip fi;"
            )
        return out

    def timers(self, ag: _Agent, config: str) -> list[str]:
        """Retransmission timers of ``ag``'s outbox entries (engine.run.reliable.on_timer):
        with ``--ack-timing bounded`` only once no copy of the message nor an ack of it
        flies; resend to each receiver still waiting, or, out of retries, drop the entry
        and raise ``<type>_undeliverable`` at the sender. One option picks the entry, the
        next what its timer does (written once, not once per entry)."""
        if not any(p.acknowledged for p in ag.ca.policies.values()):
            return []
        acked = [
            t
            for t, name in enumerate(self.types)
            if (p := ag.ca.policies.get(name)) is not None and p.acknowledged
        ]
        picks = []
        for o in range(self.outbox):
            e = f"ob[{o}]"
            cond = f"{self.visible()} && {e}.used && {e}.snd == {ag.a}"
            if self.bounded:
                cond += (
                    " && !("
                    + " || ".join(
                        f"(fl[{k}].used && fl[{k}].mid == {e}.mid && ((fl[{k}].typ != ACK_T && "
                        f"fl[{k}].snd == {ag.a}) || (fl[{k}].typ == ACK_T && fl[{k}].rcv == "
                        f"{ag.a})))"
                        for k in range(self.slots)
                    )
                    + ")"
                )
            picks.append(f":: {cond} -> sk = {o}")
        e = "ob[sk]"
        values = [f"{e}.f{i}" for i in range(_nf(self.exact))]
        resend = " ".join(
            f"if :: {e}.wait & {1 << r} -> "
            f"{_put(str(ag.a), str(r), f'{e}.typ', f'{e}.mid', values)} :: else -> skip fi;"
            for r in range(len(self.agents))
            if r != ag.a
        )
        branches = [f":: {e}.left > 0 -> d_step {{ {e}.left--; {resend} {self.tail()} }}"]
        for t in acked:
            free: list[str] = []
            body = _subst(
                " ".join(self.dispatch(ag, f"{self.types[t]}_undeliverable", None, free)), None
            )
            branches.append(
                f":: {e}.left == 0 && {e}.typ == {t} -> {self.choose(free, ag.name)} "
                f"d_step {{ {_clear_out('sk', self.exact)} {body} {self.tail()} }}"
            )
        return [f"  :: atomic {{ if {' '.join(picks)} fi; if {' '.join(branches)} fi; {config} }}"]

    def changes(self, ag: _Agent, tr) -> str:
        """For a time-driven transition in place without sends: the condition that it
        changes a variable (our explorer keeps no self-loop, so a step that changes
        nothing must not be enabled either, or SPIN's ``timeout`` would miss a dead end).
        Its assignments read none of each other's targets (else refused), so each new
        value is the expression on the state before the step."""
        if not _in_place(ag.ca, tr) or _sends(tr):
            return ""
        parts = [
            f"({self.expr(ag, act.expr.source, tr.on)}) != {ag.var_name[act.target[1]]}"
            for act in tr.actions
            if act.kind == "assign" and act.target[0] == "v" and act.target[1] in ag.var_name
        ]
        return " && (" + (" || ".join(parts) or "0") + ")"

    def network_proc(self, losses: int, duplicates: int, config: str) -> list[str]:
        out = ["proctype network() {", "end:", "  do"]
        for k in range(self.slots):
            if losses:
                out.append(
                    f"  :: atomic {{ d_step {{ {self.fate(k)} && losses < {losses} -> "
                    f"{_clear(k, self.exact)} losses++; settle() }}; " + config + " }"
                )
            if duplicates:
                copy = " ".join(
                    f"fl[sl].{f} = fl[{k}].{f};"
                    for f in ["used", "snd", "rcv", "typ", "mid"]
                    + [f"f{i}" for i in range(_nf(self.exact))]
                )
                out.append(
                    f"  :: atomic {{ d_step {{ {self.fate(k)} && dups < {duplicates} -> "
                    "sl = 0; "
                    "do :: sl < SLOTS && fl[sl].used -> sl++ :: else -> break od; "
                    f"if :: sl == SLOTS -> overflow = 1 :: else -> {copy} fi; sl = 0; "
                    "dups++; settle() }; " + config + " }"
                )
        if not losses and not duplicates:
            out.append("  :: false")
        out += ["  od", "}"]
        return out

    def scenario_proc(self, config: str) -> list[str]:
        out = ["proctype scenario() {"]
        for _, a, name in self.sk.original.scenario:
            ag = self.agents[a]
            free: list[str] = []
            body = " ".join(self.dispatch(ag, name, None, free))
            options = [
                f"  :: atomic {{ d_step {{ {self.visible()} -> {_subst(body, bits)} "
                f"{self.tail()} }}; "
                f"{config} }}"
                for bits in _assignments(free, ag.name)
            ]
            out += ["  if", *options, "  fi;"]
        if len(out) == 1:
            return []  # no scenario: no process (its one step would double every state)
        # the last event's step ends the process: a statement after it would be one more
        # state (its program counter) after every state the rest of the run reaches
        out[-1] = "  fi"
        return [*out, "}"]


def _reply(act) -> bool:
    """``to: sender``: the compiled team marks it with a negative agent index (no agent
    has one)."""
    return act.to is not None and act.to < 0


def _put(snd: str, rcv: str, typ: str, mid: str, values: list[str]) -> str:
    """A copy into the first free slot (overflow flagged when there is none)."""
    put = [
        f"fl[sl].used = 1; fl[sl].snd = {snd}; fl[sl].rcv = {rcv}; fl[sl].typ = {typ}; "
        f"fl[sl].mid = {mid};"
    ] + [f"fl[sl].f{k} = {v};" for k, v in enumerate(values)]
    return (
        "sl = 0; do :: sl < SLOTS && fl[sl].used -> sl++ :: else -> break od; "
        "if :: sl == SLOTS -> overflow = 1 :: else -> " + " ".join(put) + " fi; sl = 0;"
    )


def _nf(exact: dict) -> int:
    return max([len(v) for v in exact.values()] + [1])


def _clear(k: int | str, exact: dict) -> str:
    return (
        f"fl[{k}].used = 0; fl[{k}].snd = 0; fl[{k}].rcv = 0; fl[{k}].typ = 0; "
        f"fl[{k}].mid = 0; " + " ".join(f"fl[{k}].f{i} = 0;" for i in range(_nf(exact)))
    )


def _clear_out(o: str, exact: dict) -> str:
    return (
        f"ob[{o}].used = 0; ob[{o}].snd = 0; ob[{o}].mid = 0; ob[{o}].typ = 0; "
        f"ob[{o}].wait = 0; ob[{o}].left = 0; "
        + " ".join(f"ob[{o}].f{i} = 0;" for i in range(_nf(exact)))
    )


def _reset(exact: dict) -> str:
    return "r_snd = 0; r_mid = 0; held = 0; " + " ".join(f"r_f{i} = 0;" for i in range(_nf(exact)))


def _assignments(free: list[str], who: str) -> list[dict[int, int]]:
    if len(free) > MAX_FREE:
        raise Unsupported(f"agent '{who}': more than {MAX_FREE} free comparisons in one step")
    return [dict(enumerate(bits)) for bits in itertools.product((0, 1), repeat=len(free))]


def _subst(code: str, bits: dict[int, int] | None) -> str:
    """The free comparisons' placeholders as the values ``bits`` (a step written once per
    assignment), or as the bits ``fr<k>`` chosen before the step (``None``)."""
    if bits is None:
        return re.sub(r"FREE(\d+)", r"fr\1", code)
    return re.sub(r"FREE(\d+)", lambda m: str(bits[int(m.group(1))]), code)


def _settle(
    sizes: tuple[int, int, int], nf: int, fifo: bool, agents: int, ack: int, reduce: bool
) -> list[str]:
    """``settle()``, which ends every step: our canonical form (:meth:`.Machine.canonical`)
    written again in C, so that states that differ only in bookkeeping are one state for
    SPIN as they are for us — the projected configurations are the same either way, SPIN
    just meets fewer states. An ack that no outbox entry waits for and a filter entry
    that no copy can match again are dropped (each could only be consumed without effect
    later); each sender's live message ids are renumbered 0.. in order and its next id is
    their count; the copies in flight, the outbox and the filter are sorted (used entries
    first). Bubble sort, which is stable: in fifo order the copies are sorted by link
    only, so each link's copies stay in sending order (the oldest first), as ours keeps
    them. Written once in C (a ``c_code`` function called from each step's ``d_step``),
    so the model's text and the verifier's compilation do not grow with every step."""
    copy = ["snd", "rcv", "typ", "mid"] + [f"f{i}" for i in range(nf)]
    slots, outbox, seen = sizes
    lines = [
        "c_code {",
        "  static int waits(int snd, int mid, int rcv) {  /* an outbox entry waits for rcv */",
        "    int o;",
        f"    for (o = 0; o < {outbox}; o++) if (now.ob[o].used && now.ob[o].snd == snd && "
        "now.ob[o].mid == mid && (now.ob[o].wait & (1 << rcv))) return 1;",
        "    return 0;",
        "  }",
        "  static void prune(void) {",
        "    int k, e, live;",
        f"    for (k = 0; k < {slots}; k++) if (now.fl[k].used && now.fl[k].typ == {ack} && "
        "!waits(now.fl[k].rcv, now.fl[k].mid, now.fl[k].snd)) "
        "memset(&now.fl[k], 0, sizeof(now.fl[k]));",
        f"    for (e = 0; e < {seen}; e++) if (now.sn[e].used) {{",
        "      live = waits(now.sn[e].snd, now.sn[e].mid, now.sn[e].rcv);",
        f"      for (k = 0; k < {slots}; k++) if (now.fl[k].used && now.fl[k].typ != {ack} && "
        "now.fl[k].snd == now.sn[e].snd && now.fl[k].rcv == now.sn[e].rcv && "
        "now.fl[k].mid == now.sn[e].mid) live = 1;",
        "      if (!live) memset(&now.sn[e], 0, sizeof(now.sn[e]));",
        "    }",
        "  }",
        "  static int idx(int *ids, int n, int mid) {",
        "    int i; for (i = 0; i < n; i++) if (ids[i] == mid) return i; return -1;",
        "  }",
        "  static void renumber(void) {",
        f"    int a, k, n, i, j, t, ids[{slots + outbox + seen}];",
        f"    for (a = 0; a < {agents}; a++) {{",
        "      n = 0;",
        "#define LIVE(m) if ((m) >= 0 && idx(ids, n, (m)) < 0) ids[n++] = (m)",
        f"      for (k = 0; k < {slots}; k++) if (now.fl[k].used && ((now.fl[k].typ != {ack} "
        f"&& now.fl[k].snd == a) || (now.fl[k].typ == {ack} && now.fl[k].rcv == a))) "
        "LIVE(now.fl[k].mid);",
        f"      for (k = 0; k < {outbox}; k++) if (now.ob[k].used && now.ob[k].snd == a) "
        "LIVE(now.ob[k].mid);",
        f"      for (k = 0; k < {seen}; k++) if (now.sn[k].used && now.sn[k].snd == a) "
        "LIVE(now.sn[k].mid);",
        "#undef LIVE",
        "      for (i = 0; i < n; i++) for (j = i + 1; j < n; j++) "
        "if (ids[j] < ids[i]) { t = ids[i]; ids[i] = ids[j]; ids[j] = t; }",
        f"      for (k = 0; k < {slots}; k++) if (now.fl[k].used && ((now.fl[k].typ != {ack} "
        f"&& now.fl[k].snd == a) || (now.fl[k].typ == {ack} && now.fl[k].rcv == a)) && "
        "now.fl[k].mid >= 0) now.fl[k].mid = idx(ids, n, now.fl[k].mid);",
        f"      for (k = 0; k < {outbox}; k++) if (now.ob[k].used && now.ob[k].snd == a) "
        "now.ob[k].mid = idx(ids, n, now.ob[k].mid);",
        f"      for (k = 0; k < {seen}; k++) if (now.sn[k].used && now.sn[k].snd == a) "
        "now.sn[k].mid = idx(ids, n, now.sn[k].mid);",
        "      now.nid[a] = n;",
        "    }",
        "  }",
    ]
    for arr, size, struct, key in (
        ("fl", slots, "Copy", ["snd", "rcv"] if fifo else copy),
        ("ob", outbox, "Out", ["snd", "mid"]),
        ("sn", seen, "Seen", ["rcv", "snd", "mid"]),
    ):
        cmp = " ".join(f"if (a->{f} != b->{f}) return a->{f} > b->{f};" for f in key)
        lines += [
            f"  static int later_{arr}(struct {struct} *a, struct {struct} *b) {{",
            f"    if (a->used != b->used) return b->used; if (!a->used) return 0; {cmp} return 0;",
            "  }",
            f"  static void sort_{arr}(void) {{",
            f"    int i, j; struct {struct} t;",
            f"    for (i = 0; i + 1 < {size}; i++) for (j = 0; j + 1 < {size} - i; j++)",
            f"      if (later_{arr}(&now.{arr}[j], &now.{arr}[j + 1])) "
            f"{{ t = now.{arr}[j]; now.{arr}[j] = now.{arr}[j + 1]; now.{arr}[j + 1] = t; }}",
            "  }",
        ]
    lines += [
        "}",
        "inline settle() { c_code { prune(); renumber(); sort_fl(); sort_ob(); sort_sn(); "
        + ("now.inv = first_invisible(); " if reduce else "")
        + "} }",
    ]
    return lines


def _first_invisible(
    agents: list[_Agent], types: list[str], slots: int, seen: int, fifo: bool, reduce: bool
) -> list[str]:
    """``first_invisible()``, which ``settle()`` stores in ``inv``: one more than the slot
    of the first copy that may arrive next and that no mode sees arrive — an ack, a copy
    the receiver's duplicate filter withholds (its (receiver, sender, id) is in the
    filter), or a copy of a type no transition of the receiver is woken by — else 0.

    While ``inv`` is set, only that copy's fates (arrival, loss, duplication) are enabled:
    every other step of the model — another copy's fate, a timer, a timeout, a world or
    scenario event — is guarded by ``inv == 0``. This is the partial-order reduction of
    our explorer (``explore._invisible``), written again from the model's own data, and it
    keeps what is compared for the same reasons: such an arrival changes no mode and no
    variable, only the network's bookkeeping (an ack clears a wait bit, a withheld copy
    is answered with an ack), so it commutes with every other step; no step it could
    disable exists — a retransmission timer of the message it belongs to cannot expire
    while it flies (``--ack-timing bounded``, the only timing under which the reduction is
    made), and it enables, never disables, a timeout waiting for a quiet network; so
    every path of the unreduced model reaches the same configurations, and the same
    states without successors, with this copy's fate moved first. No cycle is made of
    such steps alone (each consumes a copy or spends a budget), so none is postponed for
    ever. SPIN's printed configurations and its ``timeout`` dead ends are therefore the
    unreduced ones; the acks and withheld copies that would otherwise pile up and
    interleave with everything (a million states and more for the docking handshake)
    are taken one at a time. The copy chosen need not be the one ours chooses (the
    argument holds for any of them), so SPIN's state count may differ from ours."""
    if not reduce:
        return []
    heard = ", ".join(
        "{" + ", ".join(str(int(bool(ag.ca.waiting(t)))) for t in types) + "}" for ag in agents
    )
    oldest = (
        "if (k > 0 && now.fl[k - 1].snd == now.fl[k].snd && now.fl[k - 1].rcv == "
        "now.fl[k].rcv) continue;"
        if fifo
        else ""
    )
    return [
        "c_code {",
        f"  static const unsigned char heard[{len(agents)}][{max(len(types), 1)}] = {{{heard}}};",
        "  static int first_invisible(void) {",
        "    int k, e;",
        f"    for (k = 0; k < {slots}; k++) {{",
        f"      if (!now.fl[k].used) continue; {oldest}",
        f"      if (now.fl[k].typ == {len(types)} || !heard[now.fl[k].rcv][now.fl[k].typ]) "
        "return k + 1;",
        f"      if (now.fl[k].mid >= 0) for (e = 0; e < {seen}; e++) if (now.sn[e].used && "
        "now.sn[e].rcv == now.fl[k].rcv && now.sn[e].snd == now.fl[k].snd && "
        "now.sn[e].mid == now.fl[k].mid) return k + 1;",
        "    }",
        "    return 0;",
        "  }",
        "}",
    ]


def _deadlock_expr(sk: Skeleton, agents: list[_Agent]) -> str:
    """The deadlock predicate of :func:`.properties._deadlock` over the mode bits."""
    team = sk.original.team
    blocked, finals, commanded = [], [], []
    for ag in agents:
        ca, a = ag.ca, ag.a
        leaves = [int(m) for m in ca.leaves]
        final = " && ".join(f"(!{ag.bit(m)} || {int(ca.final[m])})" for m in leaves) or "1"
        if team.agents[a].operator:
            on = set()
            m = 0
            while True:
                on.add(m)
                if ca.modes[m].kind != "or":
                    break
                m = ca.modes[m].initial
            commanded.append(" || ".join(f"({ag.bit(m)} != {int(m in on)})" for m in leaves) or "0")
            continue
        finals.append(f"({final})")
        inputs = sk.inputs[a] | {e for b, e in sk.world_events if b == a}
        waits = [
            m
            for m in range(len(ca.modes))
            if any(ca.transitions[j].on for j in ca.modes[m].outgoing)
        ]
        heard = [
            m for m in waits if any(ca.transitions[j].on in inputs for j in ca.modes[m].outgoing)
        ]
        w = " || ".join(ag.bit(m) for m in waits) or "0"
        h = " || ".join(ag.bit(m) for m in heard) or "0"
        blocked.append(f"(!({final}) && ({w}) && !({h}))")
    return (
        f"(({' || '.join(blocked) or '0'}) && !({' && '.join(finals) or '1'}) && "
        f"!({' || '.join(commanded) or '0'}))"
    )


# ---------------------------------------------------------------------------- properties


class _Term:
    """A signal of a formula as a Promela expression: what a formula's getters and the
    expression compiler's numpy operations build when they read :class:`_Signals`
    instead of arrays (``__array_ufunc__`` takes the operations the compiler applies)."""

    __array_priority__ = 1000
    OPS: ClassVar[dict[str, str]] = {"add": "+", "subtract": "-", "multiply": "*"}

    def __init__(self, text: str) -> None:
        self.text = text

    def astype(self, _dtype) -> _Term:  # count_in_role sums its Booleans as floats
        return self

    def __bool__(self) -> bool:  # a choice made on a signal's value (np.where, and, or)
        raise Unsupported("it decides on a value while it is computed")

    def __float__(self) -> float:
        raise Unsupported("it converts a signal to a number")

    def __add__(self, other) -> _Term:
        return _Term(f"({self.text} + {_operand(other)})")

    def __radd__(self, other) -> _Term:
        return _Term(f"({_operand(other)} + {self.text})")

    def __array_ufunc__(self, ufunc, method: str, *inputs, **kwargs) -> _Term:
        if method == "__call__" and ufunc.__name__ in self.OPS and len(inputs) == 2:
            op = self.OPS[ufunc.__name__]
            return _Term(f"({_operand(inputs[0])} {op} {_operand(inputs[1])})")
        if method == "__call__" and ufunc.__name__ == "negative":
            return _Term(f"(-{_operand(inputs[0])})")
        # branch-free (a comparison is 0 or 1): SPIN's LTL parser reads '->' as implication
        if method == "__call__" and ufunc.__name__ == "absolute":
            x = _operand(inputs[0])
            return _Term(f"(({x}) * (1 - 2 * (({x}) < 0)))")
        if method == "__call__" and ufunc.__name__ in ("minimum", "maximum") and len(inputs) == 2:
            a, b = (_operand(v) for v in inputs)
            op = "<" if ufunc.__name__ == "minimum" else ">"
            return _Term(f"(({b}) + (({a}) - ({b})) * (({a}) {op} ({b})))")
        # (a division is not an int's: not translated)
        raise Unsupported(f"it applies {ufunc.__name__}, which is not translated")


def _operand(v) -> str:
    """A term's text, or a constant's (whole numbers only: the model's values are ints)."""
    if isinstance(v, np.ndarray) and v.size == 1:
        v = v.item()
    if isinstance(v, _Term):
        return v.text
    if not isinstance(v, (int, float, np.integer, np.floating)):
        raise Unsupported(f"it computes a {type(v).__name__}")
    return str(_int(v, "a formula's constant"))


class _Signals:
    """What a formula reads, as Promela: modes are the mode bits, a discrete variable its
    int, a parameter its value; time, plant states, series and message events are not in
    the model (as :class:`~.properties.States` refuses them for our explorer)."""

    shape = (1, 1)

    def __init__(self, agents: list[_Agent]) -> None:
        self.agents = {ag.name: ag for ag in agents}
        self.memo: dict = {}

    @property
    def t(self):
        raise Unsupported("it reads time")

    def in_modes(self, agent: str, modes: list[int]) -> _Term:
        ag = self.agents[agent]
        return _Term("(" + " || ".join(ag.bit(m) for m in modes) + ")")

    def variable(self, agent: str, j: int) -> _Term:
        ag = self.agents[agent]
        if j not in ag.var_name:
            raise Unsupported(f"it reads a variable of {agent} computed from time or state")
        return _Term(ag.var_name[j])

    def param(self, agent: str, name: str) -> _Term:
        value = self.agents[agent].consts.get(name)
        if value is None:
            raise Unsupported(f"it reads {agent}.{name}, which is not a whole number")
        return _Term(_operand(value))

    def team_param(self, name: str) -> _Term:
        return self.param(next(iter(self.agents)), name)

    def state(self, agent: str, j: int):
        raise Unsupported(f"it reads {agent}'s plant state")

    def series(self, name: str, j: int):
        raise Unsupported(f"it reads the world series '{name}'")

    def event(self, kind: str, agent: str | None, message: str):
        raise Unsupported(f"it reads {kind}() message events")


def _formula(node: N.Node, sig: _Signals) -> str:
    """A temporal-free formula as a Promela condition (as :func:`.properties.truth` reads
    it: exact, a strict comparison false at its boundary)."""
    if isinstance(node, N.Const):
        return str(int(bool(node.value)))
    if isinstance(node, N.Flag):
        return f"({_operand(node.get(sig))})"  # type: ignore[misc]
    if isinstance(node, N.Predicate):
        lhs, rhs = node.lhs(sig), node.rhs(sig)  # type: ignore[misc]
        return f"({_operand(lhs)} {node.op} {_operand(rhs)})"
    if isinstance(node, N.Not):
        return f"(!{_formula(node.children[0], sig)})"
    if isinstance(node, (N.And, N.Or)):
        op = " && " if isinstance(node, N.And) else " || "
        return "(" + op.join(_formula(c, sig) for c in node.children) + ")"
    if isinstance(node, N.Implies):
        a, b = (_formula(c, sig) for c in node.children)
        return f"(!{a} || {b})"
    raise Unsupported("it has a temporal operator inside")


def _claim(p, agents: list[_Agent]) -> str:
    """Property ``p``'s LTL formula over the model's variables (raises Unsupported), read
    from the state ``init`` starts the processes in (``started``): SPIN's first state is
    the one before, without the initial configuration's entry actions."""
    sig = _Signals(agents)
    if p.kind == "invariant":
        return f"[] (!started || {_formula(p.phi, sig)})"
    return f"[] ((started && {_formula(p.phi, sig)}) -> <> {_formula(p.psi, sig)})"


def _claim_lines(agents: list[_Agent], props: list) -> list[str]:
    """An ``ltl p<k>`` block per invariant and response property that translates (``k``
    its position in ``props``, as :func:`claims` numbers them)."""
    out = []
    for k, p in enumerate(props):
        if p.kind in ("invariant", "response"):
            try:
                out.append(f"ltl p{k} {{ {_claim(p, agents)} }}  /* {p.name} */")
            except Unsupported as exc:
                out.append(f"/* not decided: p{k} ({p.name}): {exc} */")
    return out


def claims(promela: str, props: list) -> tuple[dict[str, str], dict[str, str]]:
    """The LTL claims of an exported model (claim name: property name) and the invariant
    and response properties it has none for (property name: why)."""
    names, why = {}, {}
    for k, p in enumerate(props):
        if p.kind not in ("invariant", "response"):
            continue
        if f"ltl p{k} {{" in promela:
            names[f"p{k}"] = p.name
        else:
            found = re.search(rf"/\* not decided: p{k} \(.*?\): (.*) \*/", promela)
            why[p.name] = found.group(1) if found else "not in the model"
    return names, why


# ---------------------------------------------------------------------------- comparing


def ours(report) -> Exploration:
    """Our explorer's projected configurations, dead ends and deadlock verdict."""
    sk, g = report.skeleton, report.graph
    sizes = [len(ca.modes) for ca in sk.cteam.agents]

    def config(s) -> str:
        return "|".join("".join(str(b) for b in s.agents[a][0][:n]) for a, n in enumerate(sizes))

    sym = report.symmetry if report.symmetry is not None and report.symmetry.active else None

    def configs_of(s) -> set[str]:
        """``s``'s configuration, and under symmetry those of every state it stands for."""
        if sym is None:
            return {config(s)}
        return {config(permute(s, p)) for p in sym.group(s.cursor)}

    configs = [configs_of(s) for s in g.states]
    dead = set().union(*(configs[k] for k in np.flatnonzero(g.terminal()).tolist()))
    holds = next(v.holds for v in report.verdicts if v.prop.name == "deadlock")
    verdicts = {
        v.prop.name: bool(v.holds)
        for v in report.verdicts
        if v.prop.kind in ("invariant", "response") and v.holds is not None
    }
    undecided = {
        v.prop.name: v.message
        for v in report.verdicts
        if v.prop.kind in ("invariant", "response") and v.holds is None
    }
    return Exploration(set().union(*configs), dead, bool(holds), verdicts, len(g.states), undecided)


def check(report, opts) -> None:
    """Refuse (:class:`Unsupported`) what the comparison cannot take."""
    if not report.graph.exhaustive:
        raise Unsupported(f"our exploration stopped ({report.graph.bound})")
    if report.options.por != "basic":
        raise Unsupported(f"--por {report.options.por} (it leaves reachable states out)")
    if not any(v.prop.name == "deadlock" for v in report.verdicts):
        raise Unsupported("the deadlock property is not among the checked ones")


def run_spin(
    promela: str,
    folder: Path,
    timeout: float = 600.0,
    optimize: bool = True,
    props: list | None = None,
) -> Exploration:
    """Compile and run SPIN's exhaustive search on ``promela``; its exploration.
    ``optimize``: compile the verifier with ``-O1`` (three times the compiler's work of
    ``-O0``, which a small model's short search never earns back). ``props``: the
    properties the model was exported with; each LTL claim of it is decided by the same
    verifier (:func:`_decide`).

    A model with claims is compiled once for both: without ``-DSAFETY`` (acceptance
    cycles need it off), the exploration run under the claim ``explore`` (a single state
    that accepts nothing and allows every step, so SPIN's search is the model's own, state
    for state), each property's run under its claim."""
    why = missing()
    if why:
        raise RuntimeError(why)
    folder.mkdir(parents=True, exist_ok=True)
    names, undecided = claims(promela, props or [])
    if names:
        promela += "never explore {  /* no claim: the exploration itself */\n  do :: true od\n}\n"
    (folder / "rules.pml").write_text(promela)
    _run(["spin", "-o2", "-a", "rules.pml"], folder, timeout)
    _run(
        [
            "cc",
            "-O1" if optimize else "-O0",
            "-DPRINTF",
            "-DNOREDUCE",
            *([] if names else ["-DSAFETY"]),
            "-DVECTORSZ=4096",
            "-o",
            "pan",
            "pan.c",
        ],
        folder,
        timeout,
    )
    text = _run(
        ["./pan", "-E", "-m1000000", *(["-N", "explore"] if names else [])], folder, timeout
    )
    (folder / "pan.out").write_text(text)
    if "depth too small" in text or "errors: 0" not in text:
        raise RuntimeError("SPIN's search did not complete (see pan.out)")
    configs, dead, bad, over = set(), set(), False, False
    for line in text.splitlines():
        tag, _, rest = line.partition(" ")
        if tag in ("C", "T") and rest:
            c, flag = rest.split()
            if tag == "C":
                configs.add(c)
                over |= flag == "1"
            else:
                dead.add(c)
                bad |= flag == "1"
    if over:
        raise RuntimeError(
            "the model's slots overflowed (copies in flight, outbox or filter entries "
            f"beyond the sizes in rules.pml, more than {MAX_IDS} ids, {RAISED} raised events "
            f"or {MICRO} urgent micro-steps in one step)"
        )
    stored = re.search(r"(\d+) states, stored", text)
    verdicts = _decide(folder, names, timeout)
    return Exploration(
        configs, dead, not bad, verdicts, int(stored.group(1)) if stored else 0, undecided
    )


def _decide(folder: Path, names: dict[str, str], timeout: float) -> dict[str, bool]:
    """Each LTL claim decided by SPIN on the rules (property name: holds): one search
    per claim (``-N``) for acceptance cycles (``-a``, SPIN's nested depth-first search,
    which decides invariants and responses alike). A path that ends
    is a dead end, which SPIN's LTL semantics extends by stuttering: a response whose
    psi never comes before a dead end is violated, as ours reads it. The reduction of
    :func:`_first_invisible` keeps every such verdict: the formulas read modes and
    discrete variables, which an invisible copy's fate never changes, and every cycle of
    the reduced model passes a state where every step is explored (each invisible fate
    consumes a copy or a budget), the cycle condition of a partial-order reduction that
    keeps LTL without next."""
    out = {}
    for claim, name in names.items():
        text = _run(["./pan", "-a", "-m1000000", "-N", claim], folder, timeout)
        (folder / f"{claim}.out").write_text(text)
        errors = re.search(r"errors: (\d+)", text)
        if errors is None or "depth too small" in text:
            raise RuntimeError(f"SPIN's search of {name} did not complete (see {claim}.out)")
        out[name] = errors.group(1) == "0"
    return out


class Room(TypedDict):
    """The export's array sizes (:func:`export`'s ``slots``, ``outbox``, ``seen``)."""

    slots: int
    outbox: int
    seen: int


def room(states: Iterable[State]) -> Room:
    """The export's array sizes for a team whose explored states are ``states``: twice the
    room our exploration needed (ours delivers an ack or a withheld copy before anything
    else, a partial-order reduction; SPIN without it lets them pile up); more than that is
    an overflow, reported, never a truncated comparison."""
    slots, outbox, seen = SLOTS, OUTBOX, SEEN
    for s in states:
        slots = max(slots, 2 * len(s.inflight))
        outbox = max(outbox, 2 * len(s.outbox))
        seen = max(seen, 2 * len(s.seen))
    return Room(slots=slots, outbox=outbox, seen=seen)


def prepare(report, opts, drop: tuple[int, int] | None = None) -> str:
    """The Promela model of ``report``'s team (raises :class:`Unsupported`): made before
    anything is written, so a refused model leaves nothing behind."""
    check(report, opts)
    return export(
        report.skeleton,
        opts.losses,
        opts.duplicates,
        **room(report.graph.states),
        drop=drop,
        ack_timing=opts.ack_timing,
        order=opts.order,
        timeouts=opts.timeouts,
        props=[v.prop for v in report.verdicts],
    )


def compare(
    report, opts, folder: Path, drop: tuple[int, int] | None = None, promela: str | None = None
) -> Comparison:
    """Export ``report``'s team's rules (or take ``promela``, from :func:`prepare`), let
    SPIN explore them in ``folder`` (``rules.pml``, ``pan.out``), compare with ours."""
    if promela is None:
        promela = prepare(report, opts, drop)
    big = len(report.graph.states) >= SMALL
    props = [v.prop for v in report.verdicts]
    return Comparison(ours(report), run_spin(promela, folder, optimize=big, props=props))
