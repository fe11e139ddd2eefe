"""What the API reference (docs/api, built by ``.ci/run`` with warnings as errors) relies on.

The build itself runs in CI, not here (it imports every module: about a minute). These
check its two premises: every module can be imported without running anything, and a module
that re-exports names (a facade) links each to the module that defines it, so each object
has one target (docs/api/apiref.py).
"""

from __future__ import annotations

import importlib
import subprocess
import sys

from tests.conftest import ROOT

sys.path.insert(0, str(ROOT / "docs" / "api"))
apiref = importlib.import_module("apiref")  # the reference's extension, beside its conf.py


def test_importing_the_cli_main_module_runs_nothing():
    """The reference's generator imports every module; ``python -m hybridteam.cli`` still
    runs the command."""
    imported = subprocess.run(
        [sys.executable, "-c", "import hybridteam.cli.__main__"],
        cwd=ROOT,
        capture_output=True,
        text=True,
    )
    assert (imported.returncode, imported.stdout, imported.stderr) == (0, "", "")
    run = subprocess.run(
        [sys.executable, "-m", "hybridteam.cli", "validate", "examples/automata/thermostat.yaml"],
        cwd=ROOT,
        capture_output=True,
        text=True,
    )
    assert run.returncode == 0 and "ok (team)" in run.stdout


def resolve(dotted: str):
    """The object a dotted name names (module path, then attributes)."""
    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        for attr in parts[cut:]:
            obj = getattr(obj, attr)
        return obj
    raise LookupError(dotted)


def test_the_library_contract_links_every_name_to_its_home():
    import hybridteam.library as library

    homes = apiref.Reexports()("hybridteam.library")
    assert len(homes) == len(library.__all__)  # every name of the contract is listed
    for dotted, name in zip(homes, library.__all__, strict=True):
        assert dotted.rsplit(".", 1)[1] == name
        assert not dotted.startswith("hybridteam.library.")
        assert resolve(dotted) is getattr(library, name), dotted
    assert "hybridteam.laws.LawFunction" in homes  # a type alias: where it is assigned
    assert "hybridteam.model.team.Team" in homes


def test_a_package_names_its_own_modules_relative_to_itself():
    """Inside the root package's page autosummary wants ``api.Run``, not the full name;
    ``__version__`` (a string) is no object to link."""
    assert apiref.Reexports()("hybridteam") == [
        "api.Run",
        "model.team.Team",
        "api.check",
        "api.conformance",
        "api.load",
        "api.simulate",
    ]
