"""Shared look of all views: one colour per mode, the same in diagrams, timelines and plots.

A mode keeps its colour across views and runs of the same model because colours are
assigned from the model's mode list (pre-order), not from what a run happened to visit.
"""

from __future__ import annotations

from collections.abc import Iterable

# Okabe–Ito (colour-blind safe) then Tableau 10, without near-duplicates
PALETTE = (
    "#0072B2", "#E69F00", "#009E73", "#CC79A7", "#56B4E9", "#D55E00", "#F0E442",
    "#4E79A7", "#F28E2B", "#59A14F", "#B07AA1", "#9C755F", "#76B7B2", "#EDC948",
    "#BAB0AC", "#FF9DA7",
)
FINAL = "#7F7F7F"
FONT = "DejaVu Sans"


def mode_colors(paths: Iterable[str], finals: Iterable[str] = ()) -> dict[str, str]:
    """Colour of each mode path, in the order given; final modes are grey.

    A path listed twice keeps its first colour.
    """
    finals = set(finals)
    out: dict[str, str] = {}
    k = 0
    for path in paths:
        if path in out:
            continue
        if path in finals:
            out[path] = FINAL
            continue
        out[path] = PALETTE[k % len(PALETTE)]
        k += 1
    return out


def team_mode_colors(agents: Iterable[Iterable[tuple[str, bool]]]) -> dict[str, str]:
    """One colour per mode path across a whole team, given each agent's (path, final) pairs.

    The same path in two agents (both robots' ``Transport.Lead``) gets the same colour, so a
    reader compares roles at a glance; different modes never share a colour, so a legend
    entry is unambiguous.
    """
    paths: list[str] = []
    finals: list[str] = []
    for modes in agents:
        for path, final in modes:
            paths.append(path)
            if final:
                finals.append(path)
    return mode_colors(paths, finals)


def text_color(background: str) -> str:
    """Black or white, whichever reads better on ``background`` (#rrggbb)."""
    r, g, b = (int(background[i : i + 2], 16) / 255 for i in (1, 3, 5))
    luminance = 0.2126 * r + 0.7152 * g + 0.0722 * b
    return "#000000" if luminance > 0.5 else "#FFFFFF"
