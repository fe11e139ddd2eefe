"""The settings of a team's ``network:`` and ``world:`` blocks: checked, and evaluated.

A link's latency, jitter and loss and a world component's numeric settings are numbers or
expressions of team parameters, so an ensemble or a study can give each instance its own.
Their meaning lives here once, for both sides of the engine: the compiler checks them on
the team's own parameter values (:func:`check_network`, :func:`check_world`: a file that
compiles names known agents and components, known settings of the right types, and
expressions that compile), and the run side evaluates them per instance
(:func:`evaluate_setting` in :mod:`hybridteam.engine.run.network`; :func:`component_values`
in :mod:`hybridteam.engine.run.world` and for a library's batch request,
:mod:`hybridteam.engine.run.batch`), each value range-checked (:mod:`.values`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from hybridteam.discovery import broken_note
from hybridteam.engine.compile.values import require
from hybridteam.errors import DocPath, ModelError, did_you_mean
from hybridteam.expr import ExpressionError, compile_expression
from hybridteam.world.component import WorldComponent, lookup, registered

if TYPE_CHECKING:
    from hybridteam.model import Team


def default_parameters(team: Team) -> dict[str, np.ndarray]:
    """The team's parameters at their declared values, as one instance of settings."""
    return {name: np.array([float(v)]) for name, v in team.parameters.items()}


def evaluate_setting(text: str | float, team_params: dict[str, np.ndarray], n: int) -> np.ndarray:
    """A link setting per instance (numbers broadcast; expressions over team parameters)."""
    if not isinstance(text, str):
        return np.full(n, float(text))
    symbols = {name: (lambda c, v=v: v) for name, v in team_params.items()}
    return np.broadcast_to(
        np.asarray(compile_expression(text, symbols)(None), dtype=float), (n,)
    ).copy()


def check_network(team: Team) -> list[ModelError]:
    """Problems in a team's ``network:`` block (unknown agents, bad expressions)."""
    names = [a.name for a in team.agents]
    errors: list[ModelError] = []
    net = team.network
    for (sender, receiver), link in net.links.items():
        for who in (sender, receiver):
            if who not in names:
                errors.append(
                    ModelError(
                        link.where,
                        f"unknown agent '{who}' in link",
                        hint=did_you_mean(who, names),
                        at_key=True,
                    )
                )
    for agent in net.rate_limits:
        if agent not in names:
            errors.append(
                ModelError(
                    (*net.where, "rate_limits", agent),
                    f"unknown agent '{agent}'",
                    hint=did_you_mean(agent, names),
                    at_key=True,
                )
            )
    defaults = default_parameters(team)
    for link in [net.default, *net.links.values()]:
        for what in ("latency", "jitter", "loss"):
            text = getattr(link, what)
            try:  # the team's own values must give a sensible setting (studies may not)
                require(
                    evaluate_setting(text, defaults, 1),
                    (*link.where, what),
                    f"the link's {what}",
                    str(text),
                    low=0.0,
                    high=1.0 if what == "loss" else np.inf,
                )
            except ExpressionError as exc:
                errors.append(
                    ModelError((*link.where, what), exc.message, offset=exc.offset, hint=exc.hint)
                )
            except ModelError as exc:
                errors.append(ModelError(exc.path, exc.message.replace(" in instance 0", "")))
    return errors


def check_world(team: Team) -> list[ModelError]:
    """Problems in a team's ``world:`` list: unknown components, settings, expressions."""
    errors: list[ModelError] = []
    symbols = {name: (lambda c: 0.0) for name in team.parameters}
    for spec in team.world:
        try:
            cls = lookup(spec.use)
        except KeyError:
            note = broken_note()
            errors.append(
                ModelError(
                    (*spec.where, "use"),
                    f"unknown world component '{spec.use}'" + (f" ({note})" if note else ""),
                    hint=did_you_mean(spec.use, registered()),
                )
            )
            continue
        before = len(errors)
        for key, value in spec.values.items():
            where = (*spec.where, "with", key)
            if key not in cls.params:
                errors.append(
                    ModelError(
                        where,
                        f"'{spec.use}' has no setting '{key}'",
                        hint=did_you_mean(key, list(cls.params)),
                        at_key=True,
                    )
                )
                continue
            default = cls.params[key]
            if key in cls.per_instance and isinstance(value, list):
                errors += [
                    ModelError((*where, *at), exc.message, offset=exc.offset, hint=exc.hint)
                    for at, exc in _nested_errors(value, symbols)
                ]
            if _numeric(default):
                if isinstance(value, str):
                    try:
                        compile_expression(value, symbols)
                    except ExpressionError as exc:
                        errors.append(
                            ModelError(where, exc.message, offset=exc.offset, hint=exc.hint)
                        )
                elif not _numeric(value):
                    errors.append(
                        ModelError(where, f"expected a number or an expression, got {value!r}")
                    )
            elif type(value) is not type(default):
                kind = {bool: "true or false", str: "a string", list: "a list"}.get(
                    type(default), f"a {type(default).__name__}"
                )
                errors.append(ModelError(where, f"expected {kind}, got {value!r}"))
        if len(errors) == before:  # the component's own checks, on well-typed settings
            errors += [
                ModelError((*spec.where, "with", *e.path), e.message, hint=e.hint, at_key=e.at_key)
                for e in cls.check(team, spec.values)
            ]
    return errors


def _nested_errors(
    value: Any, symbols: Mapping[str, Any], at: tuple[int, ...] = ()
) -> list[tuple[tuple[int, ...], ExpressionError]]:
    """Expressions inside a list setting that do not compile, with their places in it."""
    if isinstance(value, str):
        try:
            compile_expression(value, symbols)
        except ExpressionError as exc:
            return [(at, exc)]
        return []
    if isinstance(value, list):
        return [e for k, v in enumerate(value) for e in _nested_errors(v, symbols, (*at, k))]
    return []


def _numeric(value: Any) -> bool:
    """A number setting (evaluated per instance), as opposed to a literal; bools are not."""
    return isinstance(value, float | int) and not isinstance(value, bool)


def component_values(
    cls: type[WorldComponent],
    given: Mapping[str, Any],
    team_params: Mapping[str, np.ndarray],
    n: int,
    where: DocPath = (),
) -> dict[str, Any]:
    """Settings with defaults filled in; numeric ones as (n,) arrays, one per instance,
    each a finite number (a ModelError at ``where`` + ``with.<key>`` otherwise)."""
    symbols = {k: (lambda c, v=v: v) for k, v in team_params.items()}
    out: dict[str, Any] = {}
    for key, default in cls.params.items():
        value = given.get(key, default)
        if _numeric(default):
            text = str(value)
            if isinstance(value, str):
                value = compile_expression(value, symbols)(None)
            value = np.broadcast_to(np.asarray(value, dtype=float), (n,)).copy()
            out[key] = require(value, (*where, "with", key), f"setting '{key}'", text)
        elif key in cls.per_instance:
            out[key] = _nested_values(value, symbols, n, (*where, "with", key))
        else:
            out[key] = value
    return out


def _nested_values(value: Any, symbols: Mapping[str, Any], n: int, where: DocPath) -> Any:
    """A list setting with every expression inside it evaluated per instance: ``(n,)``
    arrays where the file has text, the literal numbers and everything else as they are."""
    if isinstance(value, str):
        got = np.broadcast_to(
            np.asarray(compile_expression(value, symbols)(None), float), (n,)
        ).copy()
        return require(got, where, "the expression", value)
    if isinstance(value, list):
        return [_nested_values(v, symbols, n, (*where, k)) for k, v in enumerate(value)]
    return value
