"""Mode libraries: found through the ``hybridteam.libraries`` entry points, imported once.

Importing a library registers its laws and world components. Third-party packages ship
libraries the same way, without touching hybridteam. A library that fails to import must
not break models that do not use it, so the failure is kept rather than raised — and
reported, with the library's name and the original error, wherever a name the library
would have registered is not found (:func:`broken_note`).
"""

from __future__ import annotations

from importlib import metadata

_LOADED = False
_BROKEN: dict[str, str] = {}


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
