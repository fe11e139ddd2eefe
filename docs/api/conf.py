"""Sphinx configuration of the API reference (built by ``.ci/run``, warnings as errors).

The module pages are generated at build time (autosummary, recursive from the package), so
a module that moves or is added needs no edit here; they are written to ``_generated/``,
which is not kept in the repository.

Each object is documented once, at the module that defines it (``apiref.py`` beside this
file says how), so a cross-reference finds one target.
"""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE))  # apiref, the reference's own extension
# every build generates the module pages afresh: a page left by a module that has moved
# would be a page no table of contents includes
shutil.rmtree(HERE / "_generated", ignore_errors=True)

from apiref import Reexports  # noqa: E402 (found through the path set above)

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
#: optional dependencies of optional packages (ROS 2, rosbag2, Dask, pandas, STL oracle,
#: the compiled exploration loop):
#: the reference documents those modules whether or not the extras are installed
autodoc_mock_imports = [
    "rclpy",
    "std_msgs",
    "geometry_msgs",
    "nav_msgs",
    "sensor_msgs",
    "rosbags",
    "dask",
    "distributed",
    "pandas",
    "rtamt",
    "numba",
]
html_theme = "alabaster"
autosummary_context = {"reexports": Reexports()}
