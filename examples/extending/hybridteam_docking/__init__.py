"""A small mode library built only on ``hybridteam.library``: robots seek a charging dock.

- law ``docking.seek``: drive straight at the dock, proportionally, at most ``vmax``;
- world component ``docking.station``: the dock, which raises ``docked`` in a robot the
  first time it comes within ``radius``, records when, and offers a batch fast path that
  stands in for the engine on plain docking teams (studies of many runs).

Importing the package registers both; hybridteam imports it through the
``hybridteam.libraries`` entry point in ``pyproject.toml``.
"""

from . import seek, station  # noqa: F401  (registers the law and the world component)
