"""Where a diagram's edge labels go: on their edge, clear of every box and other label.

Each label tries spots along its curve (the middle first, then further out, and beside the
curve on either side); the first spot whose estimated text box meets nothing taken is
used. A label that finds none becomes a footnote: a short ``(k)`` on the edge and the text
in a list under the diagram — a crowded protocol stays readable instead of its labels
piling up on each other. Sizes are estimated from the character count (DejaVu Sans, a
generous 0.62 em per character), so the check is conservative.
"""

from __future__ import annotations

from collections.abc import Iterable

Rect = tuple[float, float, float, float]  # x0, y0, x1, y1 (points, y down)
EM = 0.62  # average character width over the font size, rounded up
MARGIN = 2.0


def text_size(lines: list[str], size: float) -> tuple[float, float]:
    """Estimated width and height of text lines in points (with a margin)."""
    width = max((len(s) for s in lines), default=0) * size * EM
    return width + 2 * MARGIN, len(lines) * size * 1.25 + 2 * MARGIN


def overlaps(a: Rect, b: Rect) -> bool:
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


class Placer:
    """The taken areas of a drawing and the footnotes made so far."""

    def __init__(self, blocked: Iterable[Rect] = ()) -> None:
        self.taken: list[Rect] = list(blocked)
        self.notes: list[str] = []

    def free(self, r: Rect) -> bool:
        return not any(overlaps(r, o) for o in self.taken)

    def place(
        self, spots: Iterable[tuple[float, float]], w: float, h: float
    ) -> tuple[float, float] | None:
        """The first of ``spots`` (centres) where a ``w`` x ``h`` box is free; taken."""
        for x, y in spots:
            r = (x - w / 2, y - h / 2, x + w / 2, y + h / 2)
            if self.free(r):
                self.taken.append(r)
                return x, y
        return None

    def footnote(self, text: str) -> str:
        """The marker of the footnote holding ``text``: a text already noted keeps its
        number (three robots playing one protocol have the same handshake edge, and three
        identical notes under a diagram read as three different ones)."""
        if text not in self.notes:
            self.notes.append(text)
        return f"({self.notes.index(text) + 1})"
