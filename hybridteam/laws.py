"""Control laws: a registry of named, ensemble-vectorized Python callables.

A law maps what an agent knows (its state, time, parameters, variables) to plant inputs,
for ``m`` instances at once: it receives arrays of shape ``(m, ...)`` and returns ``(m, k)``.
Laws are found by registry name (``@law("transport.follow")``) or by an explicit
``package.module:function`` reference, never by evaluating user text: naming a module is the
only way a model file can bring in code, and it is visible in the file.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from importlib import metadata

import numpy as np


class LawContext:
    """What a law sees for the ``m`` instances it is evaluated on."""

    __slots__ = ("_ctx", "_params", "_pnames", "_vnames", "_xnames", "agent", "inputs")

    def __init__(self, ctx, params: Mapping[str, np.ndarray], agent: str,
                 state_names: Mapping[str, int], var_names: Mapping[str, int],
                 param_names: Mapping[str, int], inputs: tuple[str, ...]) -> None:
        self._ctx, self._params, self.agent, self.inputs = ctx, params, agent, inputs
        self._xnames, self._vnames, self._pnames = state_names, var_names, param_names

    @property
    def t(self) -> np.ndarray:
        return self._ctx.t

    @property
    def t_in_mode(self) -> np.ndarray:
        return self._ctx.t_in

    @property
    def state(self) -> np.ndarray:
        """Plant state, shape (m, d), columns in the plant's order (x, y, theta, ...)."""
        return self._ctx.x

    @property
    def size(self) -> int:
        return self._ctx.x.shape[0]

    def __getitem__(self, name: str) -> np.ndarray:
        """A binding parameter, state component, agent parameter or variable, by name."""
        if name in self._params:
            return np.broadcast_to(self._params[name], (self.size,))
        if name in self._xnames:
            return self._ctx.x[:, self._xnames[name]]
        if name in self._pnames:
            return self._ctx.p[:, self._pnames[name]]
        if name in self._vnames:
            return self._ctx.v[:, self._vnames[name]]
        raise KeyError(f"law for agent '{self.agent}' asked for unknown name '{name}'")

    def get(self, name: str, default: float) -> np.ndarray:
        try:
            return self[name]
        except KeyError:
            return np.full(self.size, float(default))


LawFunction = Callable[[LawContext], np.ndarray]


@dataclass(frozen=True)
class LawSpec:
    """A registered law: the callable and what it expects."""

    name: str
    fn: LawFunction
    plants: tuple[str, ...] | None = None
    params: dict[str, float] = field(default_factory=dict)
    doc: str = ""


_REGISTRY: dict[str, LawSpec] = {}


def law(name: str, *, plants: tuple[str, ...] | None = None,
        params: Mapping[str, float] | None = None) -> Callable[[LawFunction], LawFunction]:
    """Register ``fn`` under ``name``. ``params`` are defaults a mode binding may override."""

    def deco(fn: LawFunction) -> LawFunction:
        _REGISTRY[name] = LawSpec(name, fn, plants, dict(params or {}), (fn.__doc__ or "").strip())
        return fn

    return deco


class LawNotFound(LookupError):
    """Raised with a readable message (and candidates) when a law reference cannot be resolved."""

    def __init__(self, message: str, candidates: list[str]) -> None:
        super().__init__(message)
        self.candidates = candidates


def registered() -> list[str]:
    """Names of all registered laws (after loading installed mode libraries)."""
    load_libraries()
    return sorted(_REGISTRY)


def resolve(reference: str) -> LawSpec:
    """A law by registry name, or by explicit ``module:function`` reference."""
    if ":" in reference:
        module_name, _, attr = reference.partition(":")
        try:
            module = importlib.import_module(module_name)
        except Exception as exc:  # an import error in user code is still a model error
            raise LawNotFound(f"cannot import module '{module_name}': {exc}", []) from exc
        obj = getattr(module, attr, None)
        if isinstance(obj, LawSpec):
            return obj
        if not callable(obj):
            raise LawNotFound(f"module '{module_name}' has no function '{attr}'",
                              [n for n in dir(module) if not n.startswith("_")])
        return _REGISTRY.get(reference) or LawSpec(reference, obj, doc=obj.__doc__ or "")
    if reference not in _REGISTRY:
        load_libraries()
    if reference not in _REGISTRY:
        raise LawNotFound(f"unknown law '{reference}'", sorted(_REGISTRY))
    return _REGISTRY[reference]


_LOADED = False


def load_libraries() -> None:
    """Import every mode library registered under the ``hybridteam.libraries`` entry points.

    Importing a library registers its laws. Third-party packages ship libraries the same way,
    without touching hybridteam.
    """
    global _LOADED
    if _LOADED:
        return
    _LOADED = True
    for ep in metadata.entry_points(group="hybridteam.libraries"):
        try:
            ep.load()
        except Exception:  # a broken third-party library must not break unrelated models
            continue


@law("zero")
def zero(ctx: LawContext) -> np.ndarray:
    """All inputs zero: the robot stands still."""
    return np.zeros((ctx.size, len(ctx.inputs)))


@law("constant")
def constant(ctx: LawContext) -> np.ndarray:
    """Each input held at the binding parameter of the same name (missing ones are zero)."""
    return np.stack([ctx.get(name, 0.0) for name in ctx.inputs], axis=1) if ctx.inputs else \
        np.zeros((ctx.size, 0))
