"""The file kinds hybridteam reads, and dispatch to them: ``load_any``, ``validate``, ``schema``.

Each package that defines a kind of file declares it as a
:class:`~hybridteam.io.filekind.FileKind` in a ``FILE_KINDS`` tuple — team and protocol
files in :mod:`hybridteam.io.loader`, studies in :mod:`hybridteam.sweep.study`. This module
sits above both and is the only place that knows all of them: it reads a file once, tells
its kind (its ``kind:`` key, or the keys only that kind has) and hands the parsed document
to that kind's loader. So ``io`` never imports ``sweep``, and a study is parsed once.
"""

from __future__ import annotations

import importlib
import os

from pydantic import BaseModel

from hybridteam.io.filekind import FileKind, Loaded, detect, kind_error, read_document

#: Modules that declare ``FILE_KINDS``, in the order their marks are tried.
_PROVIDERS = ("hybridteam.io.loader", "hybridteam.sweep.study")


def kinds() -> dict[str, FileKind]:
    """Every file kind by name (providers imported on first use)."""
    out: dict[str, FileKind] = {}
    for module in _PROVIDERS:
        for kind in importlib.import_module(module).FILE_KINDS:
            out[kind.name] = kind
    return out


def load_any(source: str | os.PathLike) -> Loaded:
    """Load and fully validate any hybridteam file (kind told from its keys); raises
    :class:`~hybridteam.io.filekind.InputErrors` with located messages."""
    doc = read_document(source)
    known = kinds()
    name = detect(doc.data, list(known.values()))
    if name not in known:
        raise kind_error(doc, name, list(known))
    return known[name].load(doc)


def schema(name: str) -> type[BaseModel]:
    """The pydantic schema of a file kind (KeyError for an unknown kind)."""
    return kinds()[name].schema()
