"""hybridteam: teams of robots as hybrid systems.

Agents with plants (unicycle, holonomic, flows), hierarchical modes with control laws,
guarded transitions and messages, simulated as ensembles with exact events.

The package is lazy (PEP 562): ``import hybridteam`` loads nothing but this module, and
the names below import what they need on first use (``ht.simulate`` the API and the
engine). So a mode library importing :mod:`hybridteam.library` pays for the contract it
uses, not for the simulator. Runs and teams show themselves in Jupyter through their own
``_repr_html_`` methods; nothing is registered with IPython.
"""

from __future__ import annotations

import importlib
import importlib.util
from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"

#: each public name and the module that defines it, imported on first use
_HOMES = {
    "Run": "hybridteam.api",
    "Team": "hybridteam.model",
    "check": "hybridteam.api",
    "conformance": "hybridteam.api",
    "load": "hybridteam.api",
    "simulate": "hybridteam.api",
}

__all__ = ["Run", "Team", "__version__", "check", "conformance", "load", "simulate"]

if TYPE_CHECKING:  # what type checkers and editors see: the same names, eagerly
    from hybridteam.api import Run, check, conformance, load, simulate
    from hybridteam.model import Team


def __getattr__(name: str) -> Any:
    """Import a public name's module on first use and keep the name here; a subpackage or
    module (``hybridteam.sweep``) is imported when first asked for, as it was reachable
    before the package was lazy."""
    home = _HOMES.get(name)
    if home is not None:
        value = getattr(importlib.import_module(home), name)
    elif (
        name.isidentifier()
        and not name.startswith("_")
        and importlib.util.find_spec(f"{__name__}.{name}") is not None
    ):
        value = importlib.import_module(f"{__name__}.{name}")
    else:
        raise AttributeError(f"module 'hybridteam' has no attribute {name!r}")
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
