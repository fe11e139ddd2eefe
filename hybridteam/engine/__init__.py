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
"""
