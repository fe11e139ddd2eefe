"""The zero-crossing search: where, inside one integration step, a watched guard or
invariant atom changed sign.

What enters: the ensemble (:class:`~hybridteam.engine.run.ensemble.Ensemble`), the
instances that just took a step, each agent's state at the step's end and its
:class:`~hybridteam.engine.run.step.AgentStep` (how it moved: an exact arc or a
Runge–Kutta step with dense output). What leaves: the earliest located crossing per
instance, each agent's atom truths at the step's end, and the searched agents'
:class:`~.segment.Segment` (the true states at the trial points, so the loop need not
integrate to the crossing again). Nothing here writes the ensemble.

The entry point is :func:`find_crossings` (with :func:`watch_truth`, the truths of an
agent's watched atoms at given states, which the loop also asks for where a transition
makes an atom watched and on an external plant's readings); the simulator
(:mod:`hybridteam.engine.run.simulator`) calls nothing else here. Inside:

* :mod:`.search` — which atoms flipped in which sub-interval, whether a flip can matter
  (``_relevant``, ``_foregone``), and the search over them;
* :mod:`.segment` — one agent's motion over the step and the bracket narrowing on it;
* :mod:`.illinois` — the Illinois (modified regula falsi) narrowing of many brackets at
  once;
* :mod:`.floats` — a single run's search on Python floats: the same operations on the
  same doubles as the array version, cheaper for one row (``tests/engine/test_row_form.py``
  compares the two).
"""

from hybridteam.engine.run.crossing.search import find_crossings, watch_truth

__all__ = ["find_crossings", "watch_truth"]
