"""The ladder library: two omni robots carry a ladder round a corridor corner (Asahiro et al.).

Pure numpy kernels, independent of the engine: guide paths (:mod:`.guide`), the per-robot
control law (:mod:`.law`), the vectorized stepper (:mod:`.kernel`) and its scalar
cross-check (:mod:`.reference`). See README.md for the choices the paper leaves open.
"""

from . import carry, world  # noqa: F401  (registers the law and the world component)
from .kernel import OUTCOMES, Result, simulate
from .params import Pairs, Robot, Scenario, Settings, random_pairs, sample_run

__all__ = [
    "OUTCOMES",
    "Pairs",
    "Result",
    "Robot",
    "Scenario",
    "Settings",
    "random_pairs",
    "sample_run",
    "simulate",
]
