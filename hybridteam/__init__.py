"""hybridteam: teams of robots as hybrid systems.

Agents with plants (unicycle, holonomic, flows), hierarchical modes with control laws,
guarded transitions and messages, simulated as ensembles with exact events.
"""

from hybridteam.api import Run, load, simulate
from hybridteam.model import Team

__version__ = "0.1.0"
__all__ = ["Run", "Team", "__version__", "load", "simulate"]
