"""Sphinx configuration of the API reference (built by ``.ci/run``, warnings as errors).

The module pages are generated at build time (autosummary, recursive from the package), so
a module that moves or is added needs no edit here; they are written to ``_generated/``,
which is not kept in the repository.

Each object is documented once, at the module that defines it (``apiref.py`` beside this
file says how), so a cross-reference finds one target.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))  # apiref, the reference's own extension

from apiref import Reexports

project = "hybridteam"
author = "the hybridteam authors"
extensions = ["sphinx.ext.autodoc", "sphinx.ext.autosummary", "apiref"]
templates_path = ["_templates"]
exclude_patterns = ["_build"]
root_doc = "index"

autosummary_generate = True
autodoc_default_options = {"members": True, "show-inheritance": True}
autodoc_member_order = "bysource"
autodoc_typehints = "signature"
#: optional dependencies of optional packages (ROS 2, rosbag2, Dask, pandas, STL oracle):
#: the reference documents those modules whether or not the extras are installed
autodoc_mock_imports = ["rclpy", "std_msgs", "geometry_msgs", "nav_msgs", "sensor_msgs",
                        "rosbags", "dask", "distributed", "pandas", "rtamt"]
html_theme = "alabaster"
autosummary_context = {"reexports": Reexports()}
