"""The ``obstacles`` component's settings, read and checked: static geometry (walls,
circles, boxes), footprint radii, and ``detect`` rules with the rings they read.

Kept apart from the component's per-instant work (:mod:`hybridteam.world.obstacles`): every
problem is collected with its path into the settings, so a team file's mistakes are
reported together, before anything runs.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import fields
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from hybridteam.errors import ModelError, ModelErrors, did_you_mean
from hybridteam.world.collisions import MODES
from hybridteam.world.sensors import RangeRing

if TYPE_CHECKING:
    from hybridteam.model import Agent, Team

_RULE_KEYS = ("agent", "sensor", "beams", "sector", "below", "raise", "ring")


class Rule(NamedTuple):
    """A ``detect`` rule, resolved: agent index, sensor, beam indices, threshold, event."""

    agent: int
    sensor: str
    beams: np.ndarray
    below: float
    event: str


def _number(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool)


def _entry(v: Any) -> bool:
    """A number of a geometry row: a number, an expression of team parameters (as written)
    or its values per instance (as the engine hands them over)."""
    return _number(v) or isinstance(v, str | np.ndarray)


def _rows(
    values: Any, size: int, key: str, form: str, problems: list[ModelError], n: int
) -> np.ndarray:
    """A list of ``size``-number rows as a float array ``(n, r, size)``, one geometry per
    instance; problems recorded. An expression not evaluated yet (``validate``) is NaN:
    what is checked of its value is checked once it has one."""
    rows = []
    for k, row in enumerate(values or []):
        if isinstance(row, list) and len(row) == size and all(map(_entry, row)):
            rows.append(row)
        else:
            problems.append(
                ModelError(
                    (key, k),
                    f"expected {form} (numbers or expressions of team parameters), got {row!r}",
                )
            )
    out = np.empty((n, len(rows), size))
    for k, row in enumerate(rows):
        for j, v in enumerate(row):
            out[:, k, j] = np.nan if isinstance(v, str) else v
    return out


def planar(agent: Agent) -> bool:
    return agent.plant.kind in ("unicycle", "holonomic") or {"x", "y"} <= set(agent.plant.state)


def _ring(agent: Agent, rule: Mapping[str, Any], at: tuple) -> RangeRing | ModelError:
    """The ring a rule reads: given inline, else the agent's model's sensor."""
    sensor = rule["sensor"]
    if "ring" in rule:
        spec, keys = rule["ring"], [f.name for f in fields(RangeRing) if f.name != "name"]
        if not (isinstance(spec, dict) and {"count", "max_range"} <= set(spec) <= set(keys)):
            bad = [k for k in spec if k not in keys] if isinstance(spec, dict) else []
            return ModelError(
                (*at, "ring"),
                f"expected a mapping of {', '.join(keys)} (count and max_range required)",
                hint=did_you_mean(str(bad[0]), keys) if bad else None,
            )
        try:
            return RangeRing(**{**spec, "name": sensor})
        except (TypeError, ValueError) as exc:
            return ModelError((*at, "ring"), str(exc))
    preset = getattr(agent, "preset", None)
    if preset is None:
        return ModelError(
            (*at, "sensor"),
            f"agent '{agent.name}' has no robot model to take '{sensor}' from",
            hint="give the ring inline: ring: {count: 24, max_range: 0.5}",
        )
    try:
        return preset.ring(sensor)
    except (ModelError, ModelErrors) as exc:
        e = exc if isinstance(exc, ModelError) else exc.errors[0]
        return ModelError((*at, "sensor"), f"agent '{agent.name}': {e.message}", hint=e.hint)


def _beams(ring: RangeRing, rule: Mapping[str, Any], at: tuple) -> np.ndarray | ModelError:
    """Indices of the beams a rule watches: listed, in a sector, or every beam."""
    if "beams" in rule and "sector" in rule:
        return ModelError(at, "give 'beams' or 'sector', not both")
    if "beams" in rule:
        b = rule["beams"]
        if not (
            isinstance(b, list)
            and b
            and all(
                isinstance(i, int) and not isinstance(i, bool) and 0 <= i < ring.count for i in b
            )
        ):
            return ModelError(
                (*at, "beams"), f"expected beam indices 0..{ring.count - 1}, got {b!r}"
            )
        return np.array(b, np.intp)
    if "sector" in rule:
        s = rule["sector"]
        if not (isinstance(s, list) and len(s) == 2 and all(map(_number, s)) and s[0] < s[1]):
            return ModelError(
                (*at, "sector"),
                "expected [from_deg, to_deg] with from < to "
                f"(counter-clockwise from the heading), got {s!r}",
            )
        width = s[1] - s[0]
        off = (np.degrees(ring.angles) - s[0] + 1e-9) % 360.0
        sel = np.flatnonzero((off <= width + 2e-9) | (width >= 360.0))
        if not sel.size:
            return ModelError((*at, "sector"), f"no beam of '{ring.name}' points within {s}")
        return sel
    return np.arange(ring.count)


def parse_settings(
    team: Team, values: Mapping[str, Any], n: int = 1
) -> tuple[dict[str, Any], list[ModelError]]:
    """Geometry (``(n, r, size)`` arrays: walls, circles, boxes in every one of ``n``
    instances), rules, inline rings and radii from the settings, and every problem."""
    problems: list[ModelError] = []
    names = [a.name for a in team.agents]
    out: dict[str, Any] = {
        "walls": _rows(values.get("walls"), 4, "walls", "[x0, y0, x1, y1]", problems, n),
        "circles": _rows(values.get("circles"), 3, "circles", "[x, y, r]", problems, n),
        "boxes": _rows(
            values.get("boxes"), 5, "boxes", "[cx, cy, width, depth, theta_deg]", problems, n
        ),
        "rules": [],
        "rings": {},
        "radius": {},
    }
    mode = values.get("on_collision", "outcome")
    if mode not in MODES:
        problems.append(
            ModelError(
                ("on_collision",),
                f"expected one of {', '.join(MODES)}, got {mode!r}",
                hint=did_you_mean(str(mode), MODES),
            )
        )
    circles, boxes = out["circles"], out["boxes"]
    for k in np.flatnonzero((circles[..., 2] <= 0).any(axis=0)).tolist():
        problems.append(ModelError(("circles", int(k)), "a circle's radius must be positive"))
    for k in np.flatnonzero(((boxes[..., 2] <= 0) | (boxes[..., 3] <= 0)).any(axis=0)).tolist():
        problems.append(ModelError(("boxes", int(k)), "a box's width and depth must be positive"))
    boxes[..., 4] = np.radians(boxes[..., 4])
    for k, row in enumerate(values.get("radius") or []):
        if not (isinstance(row, list) and len(row) == 2 and _number(row[1]) and row[1] >= 0):
            problems.append(
                ModelError(("radius", k), f"expected [agent, radius >= 0], got {row!r}")
            )
        elif row[0] not in names:
            problems.append(
                ModelError(
                    ("radius", k, 0),
                    f"unknown agent {row[0]!r}",
                    hint=did_you_mean(str(row[0]), names),
                )
            )
        else:
            out["radius"][names.index(row[0])] = float(row[1])
    for k, rule in enumerate(values.get("detect") or []):
        at = ("detect", k)
        missing = [
            key
            for key in ("agent", "sensor", "below", "raise")
            if not isinstance(rule, dict) or key not in rule
        ]
        if missing:
            problems.append(
                ModelError(at, f"a rule needs {', '.join(missing)} (keys: {', '.join(_RULE_KEYS)})")
            )
            continue
        if not isinstance(rule["sensor"], str):
            problems.append(
                ModelError((*at, "sensor"), f"expected a sensor name, got {rule['sensor']!r}")
            )
            continue
        bad = [key for key in rule if key not in _RULE_KEYS]
        problems += [
            ModelError(
                (*at, key),
                f"a detect rule has no key {key!r}",
                hint=did_you_mean(str(key), _RULE_KEYS),
                at_key=True,
            )
            for key in bad
        ]
        if rule["agent"] not in names:
            problems.append(
                ModelError(
                    (*at, "agent"),
                    f"unknown agent {rule['agent']!r}",
                    hint=did_you_mean(str(rule["agent"]), names),
                )
            )
            continue
        a = names.index(rule["agent"])
        if not planar(team.agents[a]):
            problems.append(
                ModelError(
                    (*at, "agent"), f"agent {rule['agent']!r} has no position (x, y) to sense from"
                )
            )
            continue
        if not (isinstance(rule["raise"], str) and rule["raise"].isidentifier()):
            problems.append(
                ModelError((*at, "raise"), f"expected an event name, got {rule['raise']!r}")
            )
        ring = _ring(team.agents[a], rule, at)
        if isinstance(ring, ModelError):
            problems.append(ring)
            continue
        key = (a, str(rule["sensor"]))
        if out["rings"].setdefault(key, ring) != ring:
            problems.append(
                ModelError(
                    (*at, "ring"),
                    f"another rule gives agent {rule['agent']!r} a different '{key[1]}' ring",
                )
            )
        beams = _beams(ring, rule, at)
        below = rule["below"]
        if not (_number(below) and 0 < below <= ring.max_range):
            problems.append(
                ModelError(
                    (*at, "below"),
                    f"expected a range in (0, max_range = {ring.max_range:g}], got {below!r}",
                )
            )
        elif isinstance(beams, ModelError):
            problems.append(beams)
        else:
            out["rules"].append(Rule(a, key[1], beams, float(below), str(rule["raise"])))
    return out, problems
