"""Mode libraries: found through the ``hybridteam.libraries`` entry points, imported once.

Importing a library registers its laws and world components. Third-party packages ship
libraries the same way, without touching hybridteam. A library that fails to import must
not break models that do not use it, so the failure is kept rather than raised — and
reported, with the library's name and the original error, wherever a name the library
would have registered is not found (:func:`broken_note`).
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from importlib import metadata
from typing import Any

_LOADED = False
_BROKEN: dict[str, str] = {}
#: Every registry libraries fill (:func:`registry`), for :func:`isolated` to restore.
_REGISTRIES: list[dict[str, Any]] = []


def registry() -> dict[str, Any]:
    """A new, empty registry of names that importing a mode library fills (the laws',
    the world components'): a plain dict, made here so that :func:`isolated` restores
    it with the rest of what discovery found."""
    made: dict[str, Any] = {}
    _REGISTRIES.append(made)
    return made


@contextmanager
def isolated() -> Iterator[None]:
    """A block in which mode libraries are discovered afresh, as in a new process, and
    after which everything is as it was before it: whether libraries were loaded, which
    failed, and every registry's names (those registered inside the block are dropped; a
    registry first made inside it, by a module first imported there, is left as it is).

    For tests that stand in their own ``hybridteam.libraries`` entry points and register
    laws or components of their own, without reaching into this module's state."""
    global _LOADED
    loaded, broken_before = _LOADED, dict(_BROKEN)
    names = [dict(r) for r in _REGISTRIES]
    _LOADED = False
    _BROKEN.clear()
    try:
        yield
    finally:
        _LOADED = loaded
        _BROKEN.clear()
        _BROKEN.update(broken_before)
        # (a registry made inside the block comes after the ones saved: kept as it is)
        for r, before in zip(_REGISTRIES, names, strict=False):
            r.clear()
            r.update(before)


def load_libraries() -> None:
    """Import every mode library registered under the ``hybridteam.libraries`` entry points
    (once per process)."""
    global _LOADED
    if _LOADED:
        return
    _LOADED = True
    for ep in metadata.entry_points(group="hybridteam.libraries"):
        try:
            ep.load()
        except KeyboardInterrupt:
            raise
        except BaseException as exc:  # a broken library must not break unrelated models,
            # not even one that calls sys.exit() (SystemExit) at import
            _BROKEN[ep.name] = f"{ep.value}: {type(exc).__name__}: {exc}"


def broken() -> dict[str, str]:
    """Libraries that failed to import: entry-point name -> module and original error."""
    load_libraries()
    return dict(_BROKEN)


def broken_note() -> str | None:
    """``"mode library 'x' failed to import (pkg.mod: ImportError: ...)"`` for every broken
    library, to append to an "unknown law/component" message; None when all imported."""
    failed = broken()
    if not failed:
        return None
    return "; ".join(
        f"mode library '{name}' failed to import ({why})" for name, why in sorted(failed.items())
    )
