"""Ensemble state of one agent and the vectorized mode-tree operations on it.

The configuration of ``n`` instances is kept as arrays: ``active[i, m]`` says whether mode
``m`` is active in instance ``i``; ``child[i, m]`` is the active child of an OR-mode and
``last[i, m]`` the child it had when last exited (what history restores). Entering and
exiting act on a whole index array of instances at once, so a transition taken by 900 of
1000 instances costs one set of numpy operations, not 900 Python calls.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from hybridteam.arrays import every, gather
from hybridteam.engine.compile.compiled import CAgent, Ctx, Entry
from hybridteam.engine.compile.values import transition_delay
from hybridteam.engine.run.world import AgentView

if TYPE_CHECKING:
    from hybridteam.engine.run.record import Recorder
    from hybridteam.engine.run.streams import Inbox
    from hybridteam.engine.run.world import World


class AgentState:
    """Arrays of one agent over the ensemble (leading axis: instance)."""

    def __init__(self, ca: CAgent, everyone: np.ndarray) -> None:
        """``everyone``: the ensemble's read-only index of every instance."""
        n = everyone.size
        self.ca = ca
        m_count = len(ca.modes)
        self.x = np.zeros((n, len(ca.plant.state_names)))
        self.u = np.zeros((n, len(ca.plant.input_names)))
        self.v = np.zeros((n, len(ca.var_index)))
        self.p = np.tile(ca.param_defaults, (n, 1))
        self.active = np.zeros((n, m_count), bool)
        self.child = np.full((n, m_count), -1, np.intp)
        self.last = np.full((n, m_count), -1, np.intp)
        self.entry = np.zeros((n, m_count))
        self.deadline = np.full((n, max(len(ca.after), 1)), np.inf)
        self.driver = np.zeros(n, np.intp)
        #: the driver every instance is under, -1 where they differ (kept by
        #: update_drivers: sampling laws asks at every instant, drivers change at switches)
        self.single_driver = 0
        self.rk = np.zeros(n, bool)
        self.next_tick = np.full(n, np.inf)
        self.truth = np.zeros((len(ca.watches), n), bool)
        self.watch_modes = np.array([w.mode for w in ca.watches], np.intp)
        self.after_slots = np.array([ca.transitions[j].after_slot for j in ca.after], np.intp)
        self.after_sources = np.array([ca.transitions[j].source for j in ca.after], np.intp)
        self.watched = np.zeros((len(ca.watches), n), bool)  # refreshed on mode changes
        #: whether a watched atom may read stream estimates (``est_*``), which a message
        #: changes without any transition: its truths are then refreshed after every event
        self.watch_estimates = any(
            reads_estimates(w.atom if w.owner is None else w.owner) for w in ca.watches
        )
        #: whether an urgent guard may change its answer while no transition fires (see
        #: discrete_phase): it reads stream estimates, or it is not a plain expression (the
        #: verifier's skeleton answers free comparisons from its oracle)
        self.urgent_volatile = any(_volatile(ca.transitions[j].guard) for j in ca.eventless)
        self.inbox: Inbox | None = None  # stream estimates, when the team has streams
        self.world: World | None = None  # the team's world components, if any
        self.memory: dict[str, np.ndarray] = {}  # what laws keep between periods
        #: runs a mode's entry actions, ``entered(mode, instances)``: set by the ensemble
        #: where the agent has some (:func:`.actions.entry_actions`)
        self.entered: Callable[[int, np.ndarray], None] | None = None
        #: every instance's index, read-only: what a law's world view gives as its
        #: instances when it runs on all of them (most ticks), without building it
        self.everyone = everyone

    def ctx(
        self,
        idx: np.ndarray | slice,
        t: np.ndarray,
        owner: int | None = None,
        m: dict[str, np.ndarray] | None = None,
        law: bool = False,
        lazy: bool = False,
    ) -> Ctx:
        """Evaluation context for instances ``idx`` (``t`` and ``m`` already restricted);
        with the agent's world view only for a ``law`` (no expression reads one). ``lazy``:
        the time in the mode is computed where it is read (:class:`.Ctx`'s ``since``), for
        a caller that is done with the context before any mode is entered."""
        # (a column, then the rows: numpy 2 indexes an integer and an array together through
        # its general index iterator, four times slower)
        timed = owner is not None and owner >= 0
        since = (self.entry[:, owner], idx) if timed and lazy else None
        t_in = t - self.entry[:, owner][idx] if timed and not lazy else None
        e = self.inbox.view(idx) if self.inbox is not None else None
        w = AgentView(self.world, self.ca.index, idx, self.memory, self.everyone) if law else None
        return Ctx(
            gather(self.x, idx),
            gather(self.v, idx),
            gather(self.p, idx),
            t,
            t_in,
            m,
            e,
            w,
            since,
            (self.active, idx),
        )

    # ----------------------------------------------------------------- configuration
    def exit(
        self, root: int, idx: np.ndarray, t: np.ndarray, rec: Recorder, inside: bool = False
    ) -> None:
        """Exit the subtree of ``root`` in instances ``idx`` (``t`` is the global time
        array); ``inside``: only below ``root`` (a domain that stays active)."""
        ca = self.ca
        for m in ca.modes[root].subtree[1:] if inside else ca.modes[root].subtree:
            sel = idx[self.active[:, m][idx]]
            if sel.size == 0:
                continue
            if m != 0:
                rec.interval(ca.index, m, sel, self.entry[:, m][sel], t[sel])
            if ca.modes[m].kind == "or":
                self.last[:, m][sel] = self.child[:, m][sel]
                self.child[:, m][sel] = -1
            self.active[:, m][sel] = False

    def activate(self, m: int, idx: np.ndarray, t: np.ndarray) -> None:
        ca = self.ca
        self.active[:, m][idx] = True
        self.entry[:, m][idx] = t[idx]
        parent = ca.modes[m].parent
        if parent >= 0 and ca.modes[parent].kind == "or":
            self.child[:, parent][idx] = m
        if self.entered is not None and ca.modes[m].on_entry:
            self.entered(m, idx)
        for j in ca.modes[m].outgoing:
            tr = ca.transitions[j]
            if tr.after is not None:
                delay = transition_delay(tr, self.ctx(idx, t[idx]), idx)
                self.deadline[:, tr.after_slot][idx] = t[idx] + delay

    def enter_default(
        self, m: int, idx: np.ndarray, t: np.ndarray, deep: bool = False, restore: bool = False
    ) -> None:
        """Complete the entry of an already-activated mode: initial children, or history
        (``deep``: the whole remembered configuration below; ``restore``: this mode's own
        remembered child, as a shallow history of a parallel parent asks)."""
        if idx.size == 0:
            return
        mode = self.ca.modes[m]
        if mode.kind == "and":
            # history on a parallel mode is its regions' history: every region is active
            # whenever the mode is, so what is remembered is each region's configuration
            # (shallow: each region's active child; deep: everything below)
            for r in mode.children:
                self.activate(r, idx, t)
                self.enter_default(
                    r, idx, t, deep or mode.history == "deep", restore or mode.history == "shallow"
                )
        elif mode.kind == "or":
            restore = restore or deep or mode.history != "none"
            deeper = deep or mode.history == "deep"
            if not restore:
                self.enter(mode.default, idx, t)  # type: ignore[arg-type]  # (an 'or' mode has its default)
                return
            choice = self.last[:, m][idx]
            fresh = mode.history_default or mode.default
            if fresh.targets == {mode.initial}:  # type: ignore[union-attr]  # (ditto)
                # nothing remembered: the initial child (below it nothing is either)
                choice = np.where(choice < 0, mode.initial, choice)
            elif (choice < 0).any():  # a deeper default, or the history's own
                self.enter(fresh, idx[choice < 0], t)  # type: ignore[arg-type]  # (ditto)
            for c in mode.children:
                sub = idx[choice == c]
                if sub.size:
                    self.activate(c, sub, t)
                    self.enter_default(c, sub, t, deeper)

    def enter(self, entry: Entry, idx: np.ndarray, t: np.ndarray, deep: bool = False) -> None:
        """Enter as ``entry`` says: its first mode, then down through its marked modes, in
        document order (a parallel mode's unmarked regions by default), to its targets,
        which complete their entry (by deep history when ``deep``)."""
        if not entry.active_first:
            self.activate(entry.first, idx, t)
        self._enter_below(entry.first, entry, idx, t, deep)

    def _enter_below(
        self, m: int, entry: Entry, idx: np.ndarray, t: np.ndarray, deep: bool
    ) -> None:
        if m in entry.targets:
            self.enter_default(m, idx, t, deep)
            return
        for c in self.ca.modes[m].children:  # an OR mode has one marked child
            if c in entry.marks:
                self.activate(c, idx, t)
                self._enter_below(c, entry, idx, t, deep)
            elif self.ca.modes[m].kind == "and":
                self.activate(c, idx, t)
                self.enter_default(c, idx, t)

    def update_drivers(self, idx: np.ndarray) -> None:
        """After a configuration change: which driver (law/flow) is in charge — the deepest
        active mode that declares one — and which atoms are watched."""
        ca = self.ca
        drv = np.zeros(idx.size, np.intp)
        for m in ca.driver_modes:
            sel = self.active[:, m][idx] & (drv == 0)
            drv[sel] = ca.modes[m].driver
        self.driver[idx] = drv
        first = self.driver[0]
        self.single_driver = int(first) if every(self.driver == first) else -1
        needs = np.array([d.needs_rk for d in ca.drivers], bool)
        self.rk[idx] = needs[drv]
        if self.watch_modes.size:
            self.watched[:, idx] = self.active.take(idx, 0).take(self.watch_modes, 1).T

    def next_timer(self, idx: np.ndarray, t: np.ndarray) -> np.ndarray:
        """Earliest ``after:`` deadline still ahead of ``t`` among active transitions.

        A deadline that has passed with its guard false is no longer a scheduling point:
        from then on the guard's atoms are watched like any urgent guard.
        """
        if not self.after_slots.size:
            return np.full(idx.size, np.inf)
        # one gather for every ``after:`` transition (not a loop over them)
        # (take: a[idx][:, cols] without numpy 2's general index iterator, see gather)
        d = self.deadline.take(idx, 0).take(self.after_slots, 1)
        live = self.active.take(idx, 0).take(self.after_sources, 1) & (d > t[:, None])
        return np.minimum.reduce(np.where(live, d, np.inf), axis=1)

    def leaf_paths(self, i: int) -> list[str]:
        """Active leaf modes of instance ``i`` (for messages)."""
        ca = self.ca
        return [ca.modes[m].path for m in ca.leaves if self.active[i, m]]


def _volatile(guard) -> bool:
    """Whether a guard can change truth without a transition (see ``urgent_volatile``):
    it reads stream estimates, or it is not a compiled expression (no ``names``)."""
    if guard is None:
        return False
    return getattr(guard, "names", None) is None or reads_estimates(guard)


def reads_estimates(expr) -> bool:
    """Whether an expression (its names) or an atom (its text, a superset) reads stream
    estimates (``est_*``), which a copy's arrival changes."""
    names = getattr(expr, "names", None)
    if names is not None:
        return any(n.startswith("est_") for n in names)
    return "est_" in expr.source
