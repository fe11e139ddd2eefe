"""The run side of the engine: ``n`` instances of one compiled team advanced in lockstep.

What enters: a compiled team (:mod:`hybridteam.engine.compile`), the number of instances,
a seed (one, or one per instance), the run's duration and parameter overrides, and
optionally the seams below. What leaves: a :class:`~hybridteam.trace.Trace` (outcomes,
transitions, messages, samples): in a simulation, the same bits for the same model and
seed. The compiled team is only read.

The entry point is :class:`~.simulator.Simulator` (``Simulator(cteam, n, seed=...).run()``);
:func:`~.budget.check_budget` refuses a run that would not fit before anything is
allocated, and :mod:`.batch` resolves a library's batch request exactly as a run would.
The loop (:mod:`.simulator`) keeps the run's state in one
:class:`~.ensemble.Ensemble`, which the modules here act on —

* one step of time: :mod:`.step` (an agent's motion over a step), :mod:`.drivers` (laws,
  ``inputs:`` and flows: the only place user laws are called), :mod:`.stepsize`
  (Runge–Kutta error control), :mod:`.numerics` (numerical failure as an outcome), and
  :mod:`.crossing` (the zero-crossing search inside a step, one entry point);
* one instant: :mod:`.schedule` (the next instants due), :mod:`.discrete` (micro-steps of
  urgent and triggered transitions), :mod:`.actions`, :mod:`.events` (the event queue),
  :mod:`.state` (each agent's mode configuration), :mod:`.outcomes`;
* messages: :mod:`.network` (the lossy medium), :mod:`.reliable` (acknowledged
  messages), :mod:`.streams` (periodic data and the estimates made of it);
* the world: :mod:`.world` (the team's world components), :mod:`.access` (the
  components' :class:`~hybridteam.world.access.WorldAccess` on the ensemble);
* bookkeeping: :mod:`.overrides` (per-instance parameters), :mod:`.randomness`
  (counter-based draws), :mod:`.record` (the trace), :mod:`.outputs` (the sample grid).

Extension points
----------------
A simulation needs none of these; a live run (:mod:`hybridteam.live`, ``docs/live.md``)
fills each one, and another runtime (a different transport, a hardware-in-the-loop rig, a
co-simulation) would fill them the same way. Each is a small protocol the simulator calls
at a fixed point of its loop; nothing else of the engine needs to change. A run that
leaves the clock, the outlet and the plants unset pays an ``is None`` check for each.

* **Clock** — :class:`~.clock.Clock`, ``Simulator(clock=...)``: asked once before every
  step, it may wait, queue arrivals, or end the run. Default: none (the loop advances at
  once). Live: :class:`hybridteam.live.clock.WallClock`.
* **Network** — :class:`~.network.Outlet`, set as ``Network.outlet``: every send goes to
  it instead of the simulated links; what comes back enters through
  :meth:`~.network.Network.arrive`. Default: none (the simulated medium). Live:
  :class:`hybridteam.live.clock.WireOutlet`.
* **Plant** — :class:`~.plant.ExternalPlant`, ``Simulator(plants={agent: plant})``, a
  single run only: commanded with the held inputs at every instant, read for the agent's
  state instead of integrating it. Default: none (every plant integrated). Live:
  :class:`hybridteam.live.ros2_plant.RobotPlant`.
* **World** — ``Simulator(world=...)``, a callable ``(team, n, params) -> World`` whose
  result runs (or stands in for) the team's world components. Default:
  :class:`~.world.World`. Live: :func:`hybridteam.live.world.world_seam` (the world
  process's components, or an agent process's readings of them).
"""
