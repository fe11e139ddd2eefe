"""The transport library: the architecture paper's box-carrying team (Chaimowicz et al.).

Laws for the Labmate (``transport.follow``, ``transport.dock_arm``), the XR4000
(``transport.follow_holonomic``, ``transport.approach``) and the Scout
(``transport.match``); Lead roles are composite modes of constant inputs in the team file.
See README.md for the equations, parameters and a team that uses them.
"""

from . import approach, laws  # noqa: F401  (registers the laws)
