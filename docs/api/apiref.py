"""The API reference's one rule, as a Sphinx extension: each object is documented once.

An object is documented at the module that defines it, so a cross-reference finds one
target. A module that only re-exports names (a package's ``__init__``, the
``hybridteam.library`` contract) gets its docstring and a table of its names linking to
their homes (:class:`Reexports`, called from the module template); other modules document
what they define, not what their ``__all__`` imports (the template's
``:ignore-module-all:``).
"""

from __future__ import annotations

import importlib
import inspect
import sys
from typing import Any


class Reexports:
    """``reexports(modname)`` in a template: the objects a module's ``__all__`` imports
    from elsewhere, each named from the module it may be written relative to (a package's
    own submodules without the package's prefix, as autosummary asks), in ``__all__``'s
    order; modules and plain values are left out. (A class instance rather than a
    function, so Sphinx can keep it in its pickled configuration.)"""

    def __call__(self, modname: str) -> list[str]:
        module = importlib.import_module(modname)
        names = []
        for name in getattr(module, "__all__", ()):
            value = getattr(module, name)
            if not (inspect.isclass(value) or callable(value)):
                continue
            home = getattr(value, "__module__", "")
            if home.startswith("hybridteam") and home != modname:
                dotted = f"{home}.{value.__qualname__}"
            else:  # a type alias (``LawFunction = Callable[...]``): where it is assigned
                dotted = _assigned(value, name, modname)
                if dotted is None:
                    continue
            names.append(dotted.removeprefix(modname + "."))
        return names

    def __eq__(self, other: object) -> bool:  # one behaviour: any two are the same value
        return isinstance(other, Reexports)

    def __hash__(self) -> int:
        return hash(Reexports)


def _assigned(value: Any, name: str, facade: str) -> str | None:
    """``module.name`` of the (non-package) hybridteam module that binds ``name`` to
    ``value``, other than ``facade``; None if there is none."""
    for modname, module in sorted(sys.modules.items()):
        if (
            modname.startswith("hybridteam")
            and modname != facade
            and not hasattr(module, "__path__")
            and getattr(module, name, None) is value
        ):
            return f"{modname}.{name}"
    return None


def skip_field_aliases(
    app: Any, what: str, name: str, obj: Any, skip: bool, options: Any
) -> bool | None:
    """A named tuple's fields are listed in its signature; their generated entries
    ("Alias for field number N") would only add a target per field name (``type``) for
    type annotations of the same word to collide with."""
    doc = getattr(obj, "__doc__", None) or ""
    if what == "class" and doc.startswith("Alias for field number"):
        return True
    return None


def setup(app: Any) -> dict[str, Any]:
    app.connect("autodoc-skip-member", skip_field_aliases)
    return {"parallel_read_safe": True}
