"""The root package is lazy: a mode library pays for the contract it imports, not for the
simulator, and nothing is registered with IPython at import (issue 46, *Real layers*).

Each check runs in a fresh interpreter, since this one has long imported everything.
"""

from __future__ import annotations

import json
import subprocess
import sys

from tests.conftest import ROOT

#: modules a library never needs: the simulator, the API above it and its neighbours
HEAVY = (
    "hybridteam.engine",
    "hybridteam.api",
    "hybridteam.io",
    "hybridteam.export",
    "hybridteam.sweep",
    "hybridteam.cli",
    "hybridteam.notebook",
    "hybridteam.trace",
)


def loaded_after(code: str) -> list[str]:
    """The hybridteam modules a fresh interpreter holds after running ``code``."""
    probe = (
        f"{code}\nimport json, sys\n"
        "print(json.dumps(sorted(m for m in sys.modules if m.startswith('hybridteam'))))"
    )
    proc = subprocess.run(
        [sys.executable, "-c", probe], cwd=ROOT, capture_output=True, text=True, check=True
    )
    return json.loads(proc.stdout.splitlines()[-1])


def test_importing_the_library_contract_loads_no_simulator():
    loaded = loaded_after("import hybridteam.library")
    assert "hybridteam.library" in loaded
    heavy = [m for m in loaded if any(m == h or m.startswith(h + ".") for h in HEAVY)]
    assert heavy == []


def test_importing_the_root_package_loads_only_itself():
    assert loaded_after("import hybridteam") == ["hybridteam"]


def test_every_documented_name_resolves_and_runs():
    """``ht.NAME`` for each name of ``__all__`` (and ``dir``), ``from hybridteam import``,
    and a run through the lazy names: the thermostat's first switch at ln(11/8)/K."""
    code = """
import math
import hybridteam as ht
from hybridteam import Run, Team, check, conformance, load, simulate
assert sorted(ht.__all__) == ["Run", "Team", "__version__", "check", "conformance", "load",
                              "simulate"]
assert set(ht.__all__) <= set(dir(ht))
import hybridteam.api as api, hybridteam.model as model
assert (Run, check, conformance, load, simulate) == (
    api.Run, api.check, api.conformance, api.load, api.simulate)
assert Team is model.Team and ht.Team is Team and ht.__version__ == "0.1.0"
run = ht.simulate(ht.load("examples/automata/thermostat.yaml"), duration=10.0)
assert isinstance(run, ht.Run)
import sys
assert "hybridteam.sweep" not in sys.modules
assert ht.sweep.restrict is sys.modules["hybridteam.sweep"].restrict  # a subpackage, on use
switch = run.transitions["t"][1]  # row 0 enters Heat at t = 0
assert abs(switch - math.log(11 / 8) / 0.1) < 1e-9, switch
"""
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    proc = subprocess.run(
        [sys.executable, "-c", "import hybridteam as ht; ht.nothing"],
        cwd=ROOT,
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 1
    assert "module 'hybridteam' has no attribute 'nothing'" in proc.stderr


def test_nothing_is_registered_with_ipython_at_import():
    """Inside a (stand-in) IPython shell, importing hybridteam and using it registers no
    formatter; a team and a run display through their own ``_repr_html_``."""
    code = """
import sys, types
registered = []
class Formatter:
    def for_type(self, *args):
        registered.append(args)
shell = types.SimpleNamespace(
    display_formatter=types.SimpleNamespace(formatters={"text/html": Formatter()}))
sys.modules["IPython"] = types.SimpleNamespace(get_ipython=lambda: shell,
                                            version_info=(9, 0))  # matplotlib reads it
import hybridteam as ht
team = ht.load("examples/automata/thermostat.yaml")
assert registered == [], registered
assert "hybridteam.notebook" not in sys.modules
assert "<svg" in team._repr_html_()
"""
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
