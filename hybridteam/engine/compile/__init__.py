"""The compile side of the engine: a declared team in, a read-only compiled team out.

What enters: a :class:`~hybridteam.model.Team` (plain declarations, from YAML or Python)
and the mode libraries' registered laws. What leaves: a
:class:`~hybridteam.engine.compile.compiled.CTeam` — flat, indexed modes and transitions
whose guards, flows, inputs and actions are numpy callables with every name resolved — or
one :class:`~hybridteam.errors.ModelErrors` carrying every problem found, each at its
document path. Nothing here allocates per-instance state or advances time; the run side
(:mod:`hybridteam.engine.run`) reads the compiled team and never writes it.

Modules: :mod:`.compiler` (the entry point, :func:`~.compiler.compile_team`, an agent in
four steps), :mod:`.scope` (the names an expression may read, and the error collector),
:mod:`.bindings` (what drives a mode's plant: law, ``inputs:`` or flow),
:mod:`.transitions` (targets, exit and entry paths, guards, actions, precedence),
:mod:`.protocols` (what protocols add: message policies, streams, estimate names),
:mod:`.compiled` (the compiled structures and the expression context ``Ctx``),
:mod:`.settings` (the ``network:`` and ``world:`` blocks' settings: checked here, evaluated
per instance by the run side) and :mod:`.values` (the range checks a model's evaluated
values must pass: the compiler runs them on the team's own values, the run side per
instance, so ``validate`` refuses what ``run`` refuses).

Nothing here imports the run side (``tests/test_layers.py``): what both sides need of a
model's values (:mod:`.settings`, :mod:`.values`) lives here, and the run side imports it.
"""
