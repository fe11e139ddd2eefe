"""The engine: a declared team compiled once, then ``n`` instances of it run in lockstep.

Two sides, one folder each, and one direction between them:

* :mod:`hybridteam.engine.compile` — the compile side: a :class:`~hybridteam.model.Team`
  in, a read-only compiled team (:class:`~hybridteam.engine.compile.compiled.CTeam`) out,
  or every problem of the model at once. Names are resolved here, so a run never meets an
  unknown one.
* :mod:`hybridteam.engine.run` — the run side: a compiled team, ``n``, a seed and the
  run's settings in, a :class:`~hybridteam.trace.Trace` out. It reads the compiled team
  and never writes it; the clock, network, plant and world seams are its extension points.
  :mod:`hybridteam.engine.run.crossing` is the zero-crossing search inside a step, one
  unit with one entry point.

The run side imports the compile side, not the other way round (the compiler asks the
run side's network and world to check their own blocks of a team: that is the one call
back, made at compile time). Neither imports anything above the engine (``io``,
``export``, ``cli``, ``sweep``, ``api``, ``live``, ``logs``): ``tests/test_layers.py``.

What the packages above the engine may import from it is :data:`INTERNAL_API`, listed
here in one place and held by ``tests/test_layers.py`` for every module outside the
engine: a new need is a line added here, on purpose, not a reach into a module's insides.
"""

#: The engine's internal API: per engine module (below ``hybridteam.engine``), the names
#: code outside the engine may import from it. Mode libraries and world components import
#: none (they see :mod:`hybridteam.library` and ``WorldAccess``).
INTERNAL_API: dict[str, frozenset[str]] = {
    # compiling a team, and reading what it compiled to
    "compile.compiler": frozenset({"compile_team", "message_fields"}),
    "compile.compiled": frozenset({"CAgent", "CTeam", "CTransition", "Ctx", "Watch"}),
    "compile.scope": frozenset({"message_symbols", "resolve_mode"}),
    "compile.settings": frozenset({"default_parameters", "evaluate_setting"}),
    # running it: the loop, its state, and what a run may not exceed
    "run.simulator": frozenset({"Simulator"}),
    "run.costs": frozenset({"Costs"}),
    "run.ensemble": frozenset({"Ensemble"}),
    "run.budget": frozenset(
        {"ResourceError", "instances_within", "memory_estimate", "memory_limit", "resident_bytes"}
    ),
    "run.overrides": frozenset({"key_problem"}),
    "run.batch": frozenset({"batch_rows"}),
    "run.record": frozenset({"variables_key"}),
    # one instant (verify's abstraction runs the discrete phase on its own states)
    "run.discrete": frozenset({"discrete_phase"}),
    "run.events": frozenset({"LOCAL", "MESSAGE", "SCENARIO", "TIMER"}),
    "run.schedule": frozenset({"earliest"}),
    # messages, the world and the seams a live run fills
    "run.network": frozenset({"Message"}),
    "run.reliable": frozenset({"ACK", "Pending"}),
    "run.world": frozenset({"World"}),
    "run.access": frozenset({"EnsembleAccess"}),
    "run.plant": frozenset({"ExternalPlant"}),
}
