"""The public switch of the float paths: a single run's work on Python floats, or arrays only.

Where an array version costs a numpy dispatch (about 1 µs) per operation for one number, a
single run takes a path on Python floats that gives the same bits (``docs/design.md``,
"Performance"). Those paths must never change a trace, and the way to check that is to run
the same model both ways. This switch turns them off, so the check goes through one
documented setting instead of patching the engine's or a library's private names:

- the environment: ``HYBRIDTEAM_FLOAT_PATHS=off`` (or ``0``, ``false``, ``no``) before the
  process starts, for comparing two command-line runs; any other value, or none, leaves
  them on;
- in Python: ``with FLOAT_PATHS.off(): ...`` (a mode library reads it as
  ``hybridteam.library.FLOAT_PATHS``).

It covers the crossing search's float forms (its checkpoints' truths, the dense bracket
and the judgement of a flip, :attr:`hybridteam.expr.Atom.row`), the last few brackets of
:func:`~hybridteam.engine.run.crossing.illinois.illinois`, a carried payload's settling
and the ladder library's law and corridor instant. A hot path reads one attribute
(:attr:`FloatPaths.on`), which costs about as much as a local comparison.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager

#: The environment variable that turns the float paths off for a whole process.
ENV = "HYBRIDTEAM_FLOAT_PATHS"


class FloatPaths:
    """Whether the float paths are taken (:attr:`on`); :meth:`off` turns them off for a
    block. One instance, :data:`FLOAT_PATHS`, is read by every path."""

    __slots__ = ("on",)

    def __init__(self, on: bool) -> None:
        self.on = on

    @contextmanager
    def off(self) -> Iterator[None]:
        """Arrays only inside the block (the setting before it is restored after, also on
        an error)."""
        before, self.on = self.on, False
        try:
            yield
        finally:
            self.on = before


#: What the environment variable may say to turn the float paths off.
OFF = frozenset({"off", "0", "false", "no"})
#: The process's switch, on unless the environment says off.
FLOAT_PATHS = FloatPaths(os.environ.get(ENV, "on").strip().lower() not in OFF)
