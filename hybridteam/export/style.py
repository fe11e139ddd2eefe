"""Shared look of all views: one colour per mode, the same in diagrams, timelines and plots.

A mode keeps its colour across views and runs of the same model because colours are
assigned from the model's mode list (pre-order), not from what a run happened to visit.
"""

from __future__ import annotations

from collections.abc import Iterable

from matplotlib import patheffects

# Okabe–Ito (colour-blind safe), then Tableau 10 and a few of ColorBrewer's Dark2 and
# Tableau's, without near-duplicates: 24 colours before a colour is used twice
PALETTE = (
    "#0072B2",
    "#E69F00",
    "#009E73",
    "#CC79A7",
    "#56B4E9",
    "#D55E00",
    "#F0E442",
    "#4E79A7",
    "#F28E2B",
    "#59A14F",
    "#B07AA1",
    "#9C755F",
    "#76B7B2",
    "#EDC948",
    "#BAB0AC",
    "#FF9DA7",
    "#7570B3",
    "#E7298A",
    "#66A61E",
    "#A6761D",
    "#17BECF",
    "#BCBD22",
    "#1F3A93",
    "#8B0000",
)
COPY_TINTS = (0.45, 0.7)  # how much white a protocol state's copy of a role body mixes in
#: Final modes: muted tones, one per final mode (an Arrived and a Stuck must not look alike),
#: still set apart from the palette's bright colours; the first is ``FINAL``
FINALS = ("#7F7F7F", "#3B3B3B", "#A89F91", "#5F7A8A", "#8C6D62", "#6B8E6B", "#B5B5B5", "#4F4F6F")
FINAL = FINALS[0]
HALO = [patheffects.withStroke(linewidth=2.5, foreground="white")]  # text over drawings
FONT = "DejaVu Sans"


def mode_colors(paths: Iterable[str], finals: Iterable[str] = ()) -> dict[str, str]:
    """Colour of each mode path, in the order given; final modes take muted tones, a
    different one each (``FINALS``).

    A path listed twice keeps its first colour.
    """
    finals = set(finals)
    out: dict[str, str] = {}
    k = f = 0
    for path in paths:
        if path in out:
            continue
        if path in finals:
            out[path] = FINALS[f % len(FINALS)]
            f += 1
            continue
        out[path] = PALETTE[k % len(PALETTE)]
        k += 1
    return out


def team_mode_colors(agents: Iterable[Iterable[tuple]]) -> dict[str, str]:
    """One colour per mode path across a whole team, given each agent's ``(path, final)`` or
    ``(path, final, role)`` entries.

    The same path in two agents (both robots' ``Transport.Lead``) gets the same colour, so a
    reader compares roles at a glance. A protocol copies a role body into several of its
    states (``Offering`` leads like ``Lead``; ``Requesting`` follows like ``Follow``): the
    first state of each role gets palette colours, the others and their submodes a tint of
    them (``Offering.Curve`` a pale ``Lead.Curve``), since the robot is doing the same thing
    while the handshake goes on. Otherwise different modes share a colour only when a team
    has more modes than the palette has colours.
    """
    paths: list[str] = []
    finals: list[str] = []
    roles: dict[str, str] = {}
    for modes in agents:
        for path, final, *role in modes:
            if path not in roles:
                paths.append(path)
                roles[path] = role[0] if role and role[0] else ""
            if final:
                finals.append(path)
    copy_of = role_copies((p, roles[p]) for p in paths)
    counterpart: dict[str, tuple[str, int]] = {}  # a copy's mode -> (the original, k)
    for path in paths:
        for state, (original, k) in copy_of.items():
            if path == state or path.startswith(state + "."):
                counterpart[path] = (original + path[len(state) :], k)
    out = mode_colors([p for p in paths if p not in counterpart], finals)
    for path in paths:
        if path in counterpart:
            original, k = counterpart[path]
            base = out.get(original)
            out[path] = (
                tint(base, COPY_TINTS[min(k, len(COPY_TINTS)) - 1])
                if base
                else PALETTE[len(out) % len(PALETTE)]
            )
    return out


def role_copies(states: Iterable[tuple[str, str]]) -> dict[str, tuple[str, int]]:
    """Of ``(path, role)`` pairs in declaration order (role "" for none): each protocol state
    that is not the first of its role among its siblings -> (that first state, k), k = 1, 2,
    ... in order. The first (``Lead``, ``Follow``) stands for the role; the others
    (``Offering``, ``Requesting``, ``Accepting``) carry copies of its body. The diagram's
    roles view and the mode colours both follow this rule."""
    first: dict[tuple[str, str], str] = {}
    count: dict[tuple[str, str], int] = {}
    out: dict[str, tuple[str, int]] = {}
    for path, role in states:
        if not role:
            continue
        key = (path.rpartition(".")[0], role)
        if key in first:
            count[key] = count.get(key, 0) + 1
            out[path] = (first[key], count[key])
        else:
            first[key] = path
    return out


def tint(color: str, white: float) -> str:
    """``color`` (#rrggbb) mixed with a fraction ``white`` of white."""
    rgb = (int(color[i : i + 2], 16) for i in (1, 3, 5))
    return "#" + "".join(f"{round(c + (255 - c) * white):02X}" for c in rgb)


def text_color(background: str) -> str:
    """Black or white, whichever reads better on ``background`` (#rrggbb)."""
    r, g, b = (int(background[i : i + 2], 16) / 255 for i in (1, 3, 5))
    luminance = 0.2126 * r + 0.7152 * g + 0.0722 * b
    return "#000000" if luminance > 0.5 else "#FFFFFF"
