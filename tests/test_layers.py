"""The layering rules of DESIGN (docs/design.md), checked on the source's imports (AST).

Every ``import`` and ``from ... import`` in a module counts, wherever it is (inside a
function too), relative imports resolved. Imports under ``if TYPE_CHECKING:`` count for
the rules about the engine and the mode libraries (a type hint naming an engine class is
exactly the coupling these rules forbid); the rule on the lowest layers is about runtime
dependencies, so type-only imports are allowed there (``model`` annotates an agent's
robot preset without importing the robots package).
"""

from __future__ import annotations

import ast
import shutil
from dataclasses import dataclass
from pathlib import Path

from hybridteam.engine import INTERNAL_API

ROOT = Path(__file__).resolve().parents[1]


@dataclass(frozen=True)
class Import:
    module: str  # the importing module, dotted (hybridteam.modes.ladder.world)
    target: str  # the imported module, dotted
    line: int
    type_only: bool


def _dotted(path: Path, root: Path, package: str) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join([package, *parts])


def _type_checking(node: ast.If) -> bool:
    test = node.test
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def imports_of(path: Path, module: str, is_package: bool) -> list[Import]:
    """Every import in one source file, relative ones resolved against ``module``."""
    tree = ast.parse(path.read_text(), filename=str(path))
    found: list[Import] = []
    base = module.split(".") if is_package else module.split(".")[:-1]

    def visit(node: ast.AST, type_only: bool) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and _type_checking(child):
                for stmt in child.body:
                    visit_stmt(stmt, True)
                for stmt in child.orelse:
                    visit_stmt(stmt, type_only)
                continue
            visit_stmt(child, type_only)

    def visit_stmt(node: ast.AST, type_only: bool) -> None:
        if isinstance(node, ast.Import):
            found.extend(Import(module, a.name, node.lineno, type_only) for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                anchor = base[: len(base) - node.level + 1]
                target = ".".join([*anchor, node.module] if node.module else anchor)
            else:
                target = node.module or ""
            # ``from pkg import sub`` may import a submodule: count pkg.sub as well
            found.append(Import(module, target, node.lineno, type_only))
            found.extend(
                Import(module, f"{target}.{a.name}", node.lineno, type_only)
                for a in node.names
                if a.name != "*"
            )
        else:
            visit(node, type_only)

    visit(tree, False)
    return found


def all_imports(framework: Path, modes: Path) -> list[Import]:
    out: list[Import] = []
    for root, package in ((framework, "hybridteam"), (modes, "hybridteam.modes")):
        for path in sorted(root.rglob("*.py")):
            name = _dotted(path, root, package)
            out += imports_of(path, name, path.name == "__init__.py")
    return out


def _under(name: str, *prefixes: str) -> bool:
    return any(name == p or name.startswith(p + ".") for p in prefixes)


LOWEST = (
    "hybridteam.errors",
    "hybridteam.model",
    "hybridteam.expr",
    "hybridteam.dynamics",
    "hybridteam.trace",
    "hybridteam.arrays",
    "hybridteam.floatpaths",  # (the float paths' switch: the standard library and numpy only)
)
ABOVE_ENGINE = (
    "hybridteam.io",
    "hybridteam.export",
    "hybridteam.cli",
    "hybridteam.sweep",
    "hybridteam.api",
    "hybridteam.kinds",
    "hybridteam.live",
    "hybridteam.logs",
)
#: The one call the lowest layers make upwards: a team's ``_repr_html_`` draws its state
#: diagram through hybridteam.notebook when Jupyter asks for it (imported inside the method,
#: so never at import: tests/test_lazy_package.py checks that loading the model does not
#: load it). Displaying is the object's own job in Jupyter's protocol; registering the
#: display with IPython at import was the alternative this replaces.
DISPLAY = frozenset({("hybridteam.model.team", "hybridteam.notebook")})
#: What a mode library may import of hybridteam.
LIBRARY_API = ("hybridteam.library", "hybridteam.world.geometry")
#: The engine's two sides (docs/design.md, "The engine's seams"), and the crossing search,
#: entered through its package only.
COMPILE, RUN = "hybridteam.engine.compile", "hybridteam.engine.run"
CROSSING = "hybridteam.engine.run.crossing"
#: a namedtuple's public API, whose names start with '_' so as not to clash with fields
NAMEDTUPLE_API = frozenset({"_replace", "_asdict", "_fields", "_make", "_field_defaults"})


def _private(dotted: str) -> bool:
    """Whether a dotted name has a private part (``_name``, not ``__init__``)."""
    return any(p.startswith("_") and not p.startswith("__") for p in dotted.split("."))


def private_attributes(folder: Path, package: str) -> list[str]:
    """``module:line`` of every private attribute read on anything but ``self`` or
    ``cls`` in the package (the live runtime reaches the engine's objects through their
    public names only)."""
    found = []
    for path in sorted(folder.rglob("*.py")):
        module = _dotted(path, folder, package)
        for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
            if (
                isinstance(node, ast.Attribute)
                and _private(node.attr)
                and node.attr not in NAMEDTUPLE_API
                and not (isinstance(node.value, ast.Name) and node.value.id in ("self", "cls"))
            ):
                found.append(f"{module}:{node.lineno} reads .{node.attr}")
    return found


def _in_internal_api(target: str) -> bool:
    """Whether an imported engine name is the engine's internal API: one of its packages,
    a module listed in ``INTERNAL_API``, or a name that module lists."""
    rest = target.removeprefix("hybridteam.engine").removeprefix(".")
    module, _, name = rest.rpartition(".")
    return (
        rest in ("", "compile", "run")
        or rest in INTERNAL_API
        or name in INTERNAL_API.get(module, ())
    )


def violations(imports: list[Import]) -> list[str]:
    """Every broken rule, as ``module:line imports target (rule)``."""
    bad: dict[tuple[str, int, str], str] = {}  # one report per statement and rule
    # the crossing search's own modules (each imports something, so each is an importer)
    inside_crossing = {
        imp.module for imp in imports if _under(imp.module, CROSSING) and imp.module != CROSSING
    }

    def report(imp: Import, rule: str) -> None:
        bad.setdefault(
            (imp.module, imp.line, rule), f"{imp.module}:{imp.line} imports {imp.target} ({rule})"
        )

    for imp in imports:
        m, t = imp.module, imp.target
        if not t.startswith("hybridteam"):
            continue
        if _under(m, "hybridteam.modes"):
            own = m.split(".")[:3]  # hybridteam.modes.<lib>
            if not (_under(t, *LIBRARY_API) or _under(t, ".".join(own))):
                report(
                    imp,
                    "a mode library imports only hybridteam.library and hybridteam.world.geometry",
                )
            continue
        if _under(t, "hybridteam.modes"):
            report(imp, "the framework never imports a mode library")
        if _under(m, "hybridteam.world") and _under(t, "hybridteam.engine", *ABOVE_ENGINE):
            report(imp, "world components see the engine only through WorldAccess")
        if _under(m, "hybridteam.engine") and _under(t, *ABOVE_ENGINE):
            report(imp, "the engine never imports io, export, cli, sweep, api, kinds, live or logs")
        if _under(m, COMPILE) and _under(t, RUN):
            report(imp, "the engine's compile side never imports its run side")
        if _under(t, *inside_crossing) and not _under(m, CROSSING):
            report(
                imp, "the crossing search is entered through hybridteam.engine.run.crossing only"
            )
        if (
            not _under(m, "hybridteam.engine", "hybridteam.world")
            and _under(t, "hybridteam.engine")
            and not _in_internal_api(t)
        ):
            report(imp, "code outside the engine imports only hybridteam.engine.INTERNAL_API")
        if _under(m, "hybridteam.io") and _under(
            t, "hybridteam.sweep", "hybridteam.kinds", "hybridteam.cli", "hybridteam.export"
        ):
            report(imp, "io never imports sweep, kinds, cli or export")
        if (
            _under(m, *LOWEST)
            and not imp.type_only
            and not _under(t, *LOWEST)
            and not any(m == a and _under(t, b) for a, b in DISPLAY)
        ):
            report(imp, "the lowest layers (LOWEST) import nothing above them")
    return list(bad.values())


def test_the_source_keeps_its_layers():
    found = all_imports(ROOT / "hybridteam", ROOT / "modes")
    assert len(found) > 300  # the walk saw the code base, not an empty folder
    assert violations(found) == []


def test_the_engine_internal_api_is_what_is_used_and_public():
    """``INTERNAL_API`` lists public names that exist, each imported by some module outside
    the engine: the list is the engine's surface as used, not a wish list that rots."""
    import importlib

    found = all_imports(ROOT / "hybridteam", ROOT / "modes")
    used = {imp.target for imp in found if not _under(imp.module, "hybridteam.engine")}
    for module, names in INTERNAL_API.items():
        loaded = importlib.import_module(f"hybridteam.engine.{module}")
        for name in names:
            assert not _private(name) and hasattr(loaded, name), (module, name)
            assert f"hybridteam.engine.{module}.{name}" in used, (module, name)


def test_the_live_runtime_and_verify_read_no_private_name(tmp_path):
    """hybridteam.live and hybridteam.verify reach the engine's objects through public
    names only (a namedtuple's ``_replace`` is public); the check sees a planted private
    read."""
    assert private_attributes(ROOT / "hybridteam" / "live", "hybridteam.live") == []
    assert private_attributes(ROOT / "hybridteam" / "verify", "hybridteam.verify") == []
    planted = tmp_path / "live"
    planted.mkdir()
    (planted / "clock.py").write_text("def f(ens):\n    return ens.network._given\n")
    assert private_attributes(planted, "hybridteam.live") == [
        "hybridteam.live.clock:2 reads ._given"
    ]


def test_each_rule_catches_a_broken_import(tmp_path):
    """A copy of the tree with one forbidden import per rule: each one is reported, at
    its line, and nothing else is."""
    framework, modes = tmp_path / "hybridteam", tmp_path / "modes"
    shutil.copytree(ROOT / "hybridteam", framework, ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copytree(ROOT / "modes", modes, ignore=shutil.ignore_patterns("__pycache__"))
    planted = {
        modes / "ladder" / "world.py": "from hybridteam.engine.run.events import LOCAL\n",
        modes / "transport" / "laws.py": "from hybridteam.laws import law\n",
        framework / "world" / "carried.py": "if TYPE_CHECKING:\n"
        "    from hybridteam.engine.run.ensemble import E\n",
        framework / "io" / "loader.py": "def f():\n    from hybridteam.sweep import study\n",
        framework / "model" / "team.py": "import hybridteam.engine\n",
        framework / "engine" / "run" / "state.py": "from ...export import style\n",
        framework / "api.py": "from hybridteam.modes.ladder import simulate\n",
        framework / "engine" / "run" / "step.py": "from hybridteam.live.wire import Codec\n",
        framework / "live" / "run.py": "from hybridteam.engine.run.network import _given\n",
        framework / "engine" / "compile" / "scope.py": "def f():\n    from ..run import state\n",
        framework / "engine" / "run" / "outputs.py": "from .crossing.segment import Segment\n",
        framework / "notebook.py": "from hybridteam.engine.run.crossing import find_crossings\n",
    }
    for path, line in planted.items():
        path.write_text(path.read_text() + line)
    bad = violations(all_imports(framework, modes))
    assert len(bad) == len(planted), bad
    expected = [
        "hybridteam.modes.ladder.world:",
        "hybridteam.modes.transport.laws:",
        "hybridteam.world.carried:",
        "hybridteam.io.loader:",
        "hybridteam.model.team:",
        "hybridteam.engine.run.state:",
        "hybridteam.api:",
        "hybridteam.engine.run.step:",
        "hybridteam.live.run:",
        "hybridteam.engine.compile.scope:",
        "hybridteam.engine.run.outputs:",
        "hybridteam.notebook:",
    ]
    for prefix in expected:
        assert any(b.startswith(prefix) for b in bad), (prefix, bad)
    assert any("state:" in b and "imports hybridteam.export " in b for b in bad)  # relative
