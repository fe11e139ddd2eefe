"""Errors raised while building or checking a model, before anything runs.

A :class:`ModelError` carries the *document path* of the offending field (``agents.ball.
modes.Fall.flow.h``) and, for expressions, the character offset inside the expression text.
The YAML layer turns that into ``file:line:column`` using the positions it recorded; models
built in Python keep the path alone.
"""

from __future__ import annotations

import difflib
import re
from collections.abc import Iterable

DocPath = tuple[str | int, ...]

# what a terminal acts on instead of showing: C0 and C1 controls but tab and newline (ESC
# starts colour codes and OSC window-title sequences, BEL rings, CR overwrites the line),
# DEL, the bidirectional overrides that reorder what is shown, and lone surrogates (which
# cannot be written out at all)
_CONTROL = re.compile(
    "[\x00-\x08\x0b-\x1f\x7f-\x9f\u061c\u200e\u200f\u202a-\u202e\u2066-\u2069\ud800-\udfff]"
)


def printable(text: str) -> str:
    """``text`` safe to print to a terminal: every control character shown as its Python
    escape (``\\x1b``, ``\\u202e``), so a name read from a file can say anything but
    can neither recolour, retitle nor rewrite the terminal it is printed on."""
    return _CONTROL.sub(lambda m: ascii(m.group())[1:-1], text)


def closest(name: str, candidates: Iterable[str]) -> str | None:
    """The candidate closest to ``name`` (case-insensitive), or None."""
    pool = [c for c in candidates if isinstance(c, str) and not c.startswith("__")]
    if not isinstance(name, str) or not pool or name in pool:
        return None
    by_lower = {c.lower(): c for c in reversed(pool)}  # first spelling wins
    match = difflib.get_close_matches(name.lower(), list(by_lower), n=1, cutoff=0.6)
    return by_lower[match[0]] if match else None


def did_you_mean(name: str, candidates: Iterable[str]) -> str | None:
    """``"did you mean 'guard'?"`` for the closest candidate, else None."""
    match = closest(name, candidates)
    return f"did you mean {match!r}?" if match else None


def render_path(path: DocPath) -> str:
    """``("agents", "ball", "modes", 2)`` -> ``agents.ball.modes[2]``."""
    out = ""
    for part in path:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += ("." if out else "") + str(part)
    return out


class ModelError(ValueError):
    """A problem in a model, located by its path in the document it came from."""

    def __init__(
        self,
        path: DocPath,
        message: str,
        *,
        offset: int | None = None,
        hint: str | None = None,
        at_key: bool = False,
    ) -> None:
        self.path = tuple(path)
        self.at_key = at_key  # point at the key (a mode's name) rather than its value
        self.message = message
        self.offset = offset
        self.hint = hint
        text = f"{render_path(self.path)}: {message}" if self.path else message
        if hint:
            text += f"; {hint}"
        super().__init__(text)


class ModelErrors(ValueError):
    """Several model errors found in one pass (the checker reports them all)."""

    def __init__(self, errors: list[ModelError]) -> None:
        self.errors = errors
        super().__init__("\n".join(str(e) for e in errors))
