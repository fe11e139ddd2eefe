"""hybridteam: teams of robots as hybrid systems.

Agents with plants (unicycle, holonomic, flows), hierarchical modes with control laws,
guarded transitions and messages, simulated as ensembles with exact events.
"""

from hybridteam.api import Run, check, conformance, load, simulate
from hybridteam.model import Team

__version__ = "0.1.0"


def _notebook() -> None:
    """Teams draw themselves in Jupyter (a no-op outside IPython)."""
    from hybridteam.notebook import enable

    enable()


_notebook()
__all__ = ["Run", "Team", "__version__", "check", "conformance", "load", "simulate"]
