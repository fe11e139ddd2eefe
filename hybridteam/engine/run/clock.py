"""The engine's clock seam: what the loop does between one step and the next.

A simulation has no clock: the loop advances to its next instant at once, and a run is a
pure function of the model and the seed. A live run (:mod:`hybridteam.live`) gives the
:class:`~.simulator.Simulator` a clock that keeps run time in step with the wall clock:
before each step it sleeps until the next scheduled instant is due, and wakes early when
a datagram arrives, which it puts on the event queue (:meth:`.network.Network.arrive`) so
that the step ends at the arrival. It may also end the run (a signal, the wall clock
running out) with :meth:`.ensemble.Ensemble.finish`.

Implementing another clock: a class with :meth:`Clock.advance`, passed as
``Simulator(cteam, n, clock=...)``. It is called once before every step with the
ensemble, whose next scheduled instant :func:`.schedule.earliest` gives; it may block
until that instant is due, put whatever arrived meanwhile on the event queue at its
arrival time (:meth:`.network.Network.arrive`, never earlier than the ensemble's present,
so the step ends there), or end the run (:meth:`.ensemble.Ensemble.finish`). It must not
move the ensemble's time itself: the step does. The live implementation is
:class:`hybridteam.live.clock.WallClock` (``hybridteam/live/clock.py``). A clock on
simulated time that queues copies as a simulation's medium would (a log's replay,
:class:`hybridteam.logs.conformance.ReplayClock`) says so with ``simulated_time = True``:
the run then holds quiet stream copies as a simulation does (:mod:`.quiet`), so a
simulated run's replay takes the simulation's steps.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol

if TYPE_CHECKING:
    from hybridteam.engine.run.ensemble import Ensemble


class Clock(Protocol):
    """Asked by the simulator's loop before every step of a live run."""

    def advance(self, ens: Ensemble) -> None:
        """Wait until the ensemble's next scheduled instant is due on this clock, or until
        something arrives before it (queued as an event at its arrival time)."""
