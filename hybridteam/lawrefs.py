"""Where a model file may reach Python: the trust rules for ``module:function`` references.

A YAML file alone never runs code. A law reference ``module:function`` may name

- a module **beside the team file** (a model folder with Python files in it is code, like a
  project: it is imported as the team is loaded, by ``validate`` too), or
- a module of an **installed mode library** (a package registered under the
  ``hybridteam.libraries`` entry points, already imported when libraries load),

and the function must be **registered with** ``@law``. Anything else — ``os:system``,
``code:interact``, ``this:s``, any module merely importable from the Python path — is
refused before anything is imported or called, with the rule in the message.

Modules beside a team file are loaded under a private name per folder, so a team's
``laws.py`` never collides with another folder's ``laws.py`` or shadows a module of the
same name elsewhere (``json.py`` beside a team does not replace the standard ``json``).
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import sys
from importlib import metadata
from pathlib import Path
from types import ModuleType

from hybridteam.discovery import load_libraries


class RefusedReference(LookupError):
    """A ``module:function`` reference outside the places a model may name Python."""


def library_packages() -> list[str]:
    """Packages of the installed mode libraries (an entry point naming a module ``a.b.c``
    allows the package ``a.b`` it lives in; one naming a package allows that package)."""
    load_libraries()
    out = []
    for ep in metadata.entry_points(group="hybridteam.libraries"):
        module = ep.value.split(":")[0].strip()
        loaded = sys.modules.get(module)
        out.append(
            module
            if loaded is None or hasattr(loaded, "__path__")
            else module.rpartition(".")[0] or module
        )
    return out


def _beside(folder: str | None, top: str) -> Path | None:
    """The file or package of module ``top`` in ``folder``, if there is one."""
    if not folder or not top.isidentifier():
        return None
    base = Path(folder)
    if (base / f"{top}.py").is_file():
        return base / f"{top}.py"
    if (base / top / "__init__.py").is_file():
        return base / top / "__init__.py"
    return None


def is_beside(folder: str | None, module: str) -> bool:
    """Whether ``folder`` (a team file's) holds the module ``module``."""
    return _beside(folder, module) is not None


def import_model_module(module_name: str, folder: str | None) -> ModuleType:
    """The module a model's ``module:function`` names, imported only from the allowed
    places (see the module docstring); :class:`RefusedReference` otherwise."""
    parts = module_name.split(".")
    if not all(p.isidentifier() for p in parts):
        raise RefusedReference(f"'{module_name}' is not a module name")
    found = _beside(folder, parts[0])
    if found is not None and folder is not None:  # (found only in a folder given)
        return _load_beside(found, parts, folder)
    for package in library_packages():
        if module_name == package or module_name.startswith(package + "."):
            return importlib.import_module(module_name)
    where = f"beside the team file (in {folder})" if folder else "beside a team file"
    raise RefusedReference(
        f"module '{module_name}' is not {where} nor part of an installed mode library; "
        "a model names Python only there (put the module next to the team file, or "
        "install it as a library)"
    )


def _load_beside(path: Path, parts: list[str], folder: str) -> ModuleType:
    """Import ``parts`` (top-level module at ``path``) under a private per-folder name,
    with the folder on the path while it runs (so it may import its siblings)."""
    private = f"_hybridteam_model_{hashlib.sha1(folder.encode()).hexdigest()[:12]}_{parts[0]}"
    sys.path.insert(0, folder)
    try:
        if private not in sys.modules:
            package = path.name == "__init__.py"
            spec = importlib.util.spec_from_file_location(
                private, path, submodule_search_locations=[str(path.parent)] if package else None
            )
            assert spec is not None and spec.loader is not None
            module = importlib.util.module_from_spec(spec)
            sys.modules[private] = module
            try:
                spec.loader.exec_module(module)
            except BaseException:
                del sys.modules[private]
                raise
        return importlib.import_module(".".join([private, *parts[1:]]))
    finally:
        sys.path.remove(folder)
