"""Control laws: a registry of named, ensemble-vectorized Python callables.

A law maps what an agent knows (its state, time, parameters, variables) to plant inputs,
for ``m`` instances at once: it receives arrays of shape ``(m, ...)`` and returns ``(m, k)``.
Laws are found by registry name (``@law("transport.follow")``) or by an explicit
``package.module:function`` reference, never by evaluating user text: naming a module is the
only way a model file can bring in code, and it is visible in the file.
"""

from __future__ import annotations

import ast
import functools
import inspect
import math
import textwrap
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike

from hybridteam.arrays import spread
from hybridteam.discovery import broken_note, load_libraries, registry
from hybridteam.floatpaths import FLOAT_PATHS, ON_FLOATS, Ops, float_form
from hybridteam.lawrefs import RefusedReference, import_model_module, is_beside


class StreamInbox(Protocol):
    """The latest copies of the data streams an agent received, for the rows a law runs
    on: what :meth:`LawContext.estimate` reads. ``message`` is a stream's message type,
    ``who`` one sender per row (an agent index; -1 where nothing has arrived)."""

    def carries(self, message: str, /) -> bool:
        """Whether some protocol of the team sends this stream (else a law asking for it
        has a wrong name)."""
        ...

    def sender(self, message: str, sender: np.ndarray | None = None, /) -> np.ndarray:
        """The chosen sender per row: ``sender`` where given, else the most recent one."""
        ...

    def fields(self, message: str, who: np.ndarray, /) -> dict[str, np.ndarray]:
        """Every field of the latest copies from senders ``who``: name -> ``(m,)``."""
        ...

    def sent(self, message: str, sender: np.ndarray | None = None, /) -> np.ndarray:
        """When the chosen sender's latest copy was sent (-inf where none arrived)."""
        ...


class LawWorld(Protocol):
    """One agent's window on the world components and on its law's memory, for the rows a
    law runs on: what :meth:`LawContext.sense`, :meth:`~LawContext.recall` and
    :meth:`~LawContext.keep` read and write."""

    def instances(self) -> np.ndarray:
        """Which ensemble instances the rows are."""
        ...

    def sense(self, name: str, /) -> np.ndarray:
        """What a world component lets this agent sense as ``name``: ``(m, ...)``."""
        ...

    def recall(self, name: str, initial: float, /) -> np.ndarray:
        """The memory ``name`` per row (``initial`` where never kept)."""
        ...

    def keep(self, name: str, values: np.ndarray, /) -> None:
        """Store the memory ``name`` for these rows."""
        ...


class LawRows(Protocol):
    """The engine's side of a :class:`LawContext`: the ``m`` instances a law is evaluated
    on, as the engine holds them. Every array has ``m`` rows; columns are addressed by
    the name indexes the context is built with (a plant's state order, the agent's
    parameters and variables). The engine's implementation is its expression context
    (``hybridteam.engine.compile.compiled.Ctx``), which also evaluates binding parameters:
    the context hands this same object to them."""

    @property
    def state(self) -> np.ndarray:
        """Plant states ``(m, d)``."""
        ...

    @property
    def parameters(self) -> np.ndarray:
        """Agent parameters, team parameters included, after a run's overrides ``(m, P)``."""
        ...

    @property
    def variables(self) -> np.ndarray:
        """Discrete variables ``(m, V)``."""
        ...

    @property
    def time(self) -> np.ndarray:
        """Time of each instance ``(m,)``."""
        ...

    @property
    def time_in_mode(self) -> np.ndarray:
        """Time since the law's mode was entered ``(m,)``."""
        ...

    @property
    def streams(self) -> StreamInbox | None:
        """The agent's received data streams (None for a team without data streams)."""
        ...

    @property
    def world(self) -> LawWorld:
        """The agent's world components and law memory."""
        ...


class LawContext:
    """What a law sees for the ``m`` instances it is evaluated on.

    Built by the engine over a :class:`LawRows` (its view of those instances); a law
    reads only the members below, which are the stable contract (``docs/extending.md``).
    """

    __slots__ = (
        "_ctx",
        "_params",
        "_pnames",
        "_tables",
        "_values",
        "_vnames",
        "_xnames",
        "agent",
        "inputs",
    )

    def __init__(
        self,
        ctx: LawRows,
        params: Mapping[str, Callable[[LawRows], Any]],
        agent: str,
        state_names: Mapping[str, int],
        var_names: Mapping[str, int],
        param_names: Mapping[str, int],
        inputs: tuple[str, ...],
        tables: dict[tuple[str | int, ...], np.ndarray | None] | None = None,
    ) -> None:
        """``params``: the binding's parameters as expressions of ``ctx``, evaluated when
        the law first reads each (a law reads some of them in some modes, and each is
        evaluated at most once per call). ``tables``: where :meth:`table` keeps the
        columns of the names it was asked for, and constant binding parameters their
        values, kept by the caller from one call to the next (the names' meaning is fixed
        for a binding)."""
        self._ctx, self._params, self.agent, self.inputs = ctx, params, agent, inputs
        self._xnames, self._vnames, self._pnames = state_names, var_names, param_names
        self._values: dict[str, np.ndarray] = {}
        self._tables = {} if tables is None else tables

    @property
    def t(self) -> np.ndarray:
        """Time of each instance, shape (m,)."""
        return self._ctx.time

    @property
    def t_in_mode(self) -> np.ndarray:
        """Time since the law's mode was entered, shape (m,)."""
        return self._ctx.time_in_mode

    @property
    def state(self) -> np.ndarray:
        """Plant state, shape (m, d), columns in the plant's order (x, y, theta, ...)."""
        return self._ctx.state

    @property
    def size(self) -> int:
        """``m``: how many instances (rows) the law is evaluated on."""
        return self._ctx.state.shape[0]

    def __getitem__(self, name: str) -> np.ndarray:
        """A binding parameter, state component, agent parameter or variable, by name."""
        if name in self._params:
            if name not in self._values:
                self._values[name] = self._binding(name)
            return self._values[name]
        if name in self._xnames:
            return self._ctx.state[:, self._xnames[name]]
        if name in self._pnames:
            return self._ctx.parameters[:, self._pnames[name]]
        if name in self._vnames:
            return self._ctx.variables[:, self._vnames[name]]
        raise KeyError(f"law for agent '{self.agent}' asked for unknown name '{name}'")

    def table(self, names: tuple[str, ...]) -> np.ndarray:
        """Several names at once, shape (m, k): column j is ``self[names[j]]`` as floats.

        A law reading many agent parameters (the ladder robots read nine) gets them in one
        gather instead of one lookup and one array each; names that are not all agent
        parameters are read one by one, with :meth:`__getitem__`'s precedence.
        """
        try:
            cols = self._tables[names]
        except KeyError:
            cols = self._tables[names] = self._columns(names)
        if cols is not None:
            # parameters[:, cols], without numpy 2's index iterator
            return self._ctx.parameters.take(cols, 1)
        out = np.empty((self.size, len(names)))
        for j, n in enumerate(names):
            out[:, j] = self[n]
        return out

    def _binding(self, name: str) -> np.ndarray:
        """Binding parameter ``name``'s values. One that reads no name (a number, the
        law's default) is the same read-only array at every call of this size, kept with
        the binding's tables under ``(name, size)``."""
        expr = self._params[name]
        if getattr(expr, "names", None) != frozenset():
            return spread(expr(self._ctx), (self.size,))
        key = (name, self.size)
        kept = self._tables.get(key)
        if kept is None:
            kept = self._tables[key] = spread(expr(self._ctx), (self.size,))
        return kept

    def _columns(self, names: tuple[str, ...]) -> np.ndarray | None:
        """The parameter columns of ``names`` if every one is an agent parameter that no
        binding parameter or state component hides, else None."""
        p = self._pnames
        if (
            self._params.keys().isdisjoint(names)
            and self._xnames.keys().isdisjoint(names)
            and p.keys() >= set(names)
        ):
            return np.array([p[n] for n in names], np.intp)
        return None

    def estimate(
        self, message: str, sender: np.ndarray | int | None = None, extrapolate: bool = False
    ) -> Estimate:
        """The latest copy of a data stream (``message``) this agent received, per instance:
        from ``sender`` (an agent index, or one per instance), else the most recent sender.

        ``extrapolate`` dead-reckons a pose stream over the copy's age: fields x, y, theta
        with v, omega (a unicycle's arc) or vx, vy, omega (a holonomic robot's line), or
        all of them (the rule is in :func:`_dead_reckon`) — the paper's x̂_l for a leader
        whose last message is a few periods old.
        """
        view = self._ctx.streams
        if view is None or not view.carries(message):
            raise KeyError(
                f"law for agent '{self.agent}' asked for stream '{message}', "
                "which no protocol of this team sends"
            )
        who = view.sender(message, None if sender is None else np.asarray(sender))
        fields = view.fields(message, who)
        age = self.t - view.sent(message, who)
        if extrapolate:
            if age.size == 1 and FLOAT_PATHS.on:  # a single run's tick: on floats
                fields = _dead_reckon_one(fields, age.item(0))
            else:
                fields = _dead_reckon(fields, np.where(np.isfinite(age), age, 0.0))
        return Estimate(fields, age, who)

    @property
    def instances(self) -> np.ndarray:
        """Which ensemble instances these rows are (e.g. to key per-instance caches)."""
        return self._ctx.world.instances()

    def sense(self, name: str) -> np.ndarray:
        """What a world component lets this robot sense (a grasp offset, the ladder's ends),
        computed from the whole team's state at this instant; shape (m, ...)."""
        return self._ctx.world.sense(name)

    def recall(self, name: str, initial: float = 0.0) -> np.ndarray:
        """The law's memory ``name`` per instance (``initial`` before it was ever kept):
        the state of a discrete-time controller, kept from one period to the next."""
        return self._ctx.world.recall(name, initial)

    def keep(self, name: str, values: ArrayLike) -> None:
        """Store the law's memory ``name`` for these instances (read back by :meth:`recall`)."""
        self._ctx.world.keep(name, np.asarray(values, dtype=float))

    def capture(
        self, name: str, who: np.ndarray, fresh: Mapping[str, np.ndarray], where: np.ndarray
    ) -> dict[str, np.ndarray]:
        """Values measured once per reference, kept until the reference changes.

        Where ``where`` holds and ``who`` (a teammate's index, say the leader) differs from
        the one the values were last captured for, or the law's mode was entered again since
        (a follower that led in between, then follows the same robot), ``fresh`` is taken
        and kept in the law's memory (``name.<key>``); elsewhere the kept values stay.
        Returns the kept values, NaN where nothing was captured yet. This is how a follower
        holds the place it had when a new leader took over, instead of a place fixed
        relative to whoever leads.
        """
        had = self.recall(f"{name}.who", -1.0)
        entered = self.t - self.t_in_mode
        had_entry = self.recall(f"{name}.entry", np.nan)
        again = ~(np.abs(entered - had_entry) <= 1e-6)  # NaN (never) counts as again
        new = np.asarray(where, bool) & ((np.asarray(who, float) != had) | again)
        kept = {k: self.recall(f"{name}.{k}", np.nan) for k in fresh}
        if new.any():
            for k, v in fresh.items():
                kept[k] = np.where(new, v, kept[k])
                self.keep(f"{name}.{k}", kept[k])
            self.keep(f"{name}.who", np.where(new, who, had))
            self.keep(f"{name}.entry", np.where(new, entered, had_entry))
        return kept

    def get(self, name: str, default: float) -> np.ndarray:
        try:
            return self[name]
        except KeyError:
            return np.full(self.size, float(default))


class Estimate:
    """A teammate's state as last heard: ``est["x"]``, ``est.age`` (s since it was sent;
    inf before the first copy), ``est.sender``, ``est.valid`` (a copy has arrived)."""

    __slots__ = ("age", "fields", "sender")

    def __init__(self, fields: dict[str, np.ndarray], age: np.ndarray, sender: np.ndarray) -> None:
        self.fields, self.age, self.sender = fields, age, sender

    @property
    def valid(self) -> np.ndarray:
        return self.sender >= 0

    def __getitem__(self, name: str) -> np.ndarray:
        return self.fields[name]


def _dead_reckon(f: dict[str, np.ndarray], age: np.ndarray) -> dict[str, np.ndarray]:
    """A pose copy moved on by ``age`` seconds under the velocity it was sent with.

    A unicycle under a held input moves on an arc (``v``, ``omega``: constant in its own
    frame), a holonomic base on a straight line (``vx``, ``vy``: constant in the world
    frame) while it turns with ``omega``. A copy with only one of the two velocity forms is
    moved that way. A copy with both (the role-assignment stream sends ``v``, ``vx``, ``vy``
    and ``omega`` from every plant) is moved on the arc when its world velocity lies along
    its heading (lateral speed ``-vx sin(theta) + vy cos(theta)`` zero to 1e-9 relative),
    which every unicycle's does, and on the line otherwise. Exact for every unicycle, and
    for every holonomic base that does not turn or moves off its heading; a holonomic base
    driving exactly along its heading while turning is taken for a unicycle (off by at most
    ``|v omega| age^2 / 2``).
    """
    out = dict(f)
    if not {"x", "y", "theta"} <= f.keys():
        return out
    w = f.get("omega", np.zeros_like(age))
    zero = np.zeros_like(age)  # (the velocity forms a copy does not carry: unused)
    out["x"], out["y"], out["theta"] = _reckoned(
        f["x"],
        f["y"],
        f["theta"],
        w,
        age,
        f.get("v", zero),
        f.get("vx", zero),
        f.get("vy", zero),
        arc="v" in f,
        line="vx" in f and "vy" in f,
    )
    return out


def _dead_reckon_one(f: dict[str, np.ndarray], age: float) -> dict[str, np.ndarray]:
    """:func:`_dead_reckon` of one row (a single run's tick; ``age`` infinite before the
    first copy), on Python floats: about a third of its cost on arrays of one, the same
    bits (:func:`_reckoned`'s float form)."""
    out = dict(f)
    if not {"x", "y", "theta"} <= f.keys():
        return out
    x, y, theta = _reckoned_on_floats(
        f["x"].item(0),
        f["y"].item(0),
        f["theta"].item(0),
        f["omega"].item(0) if "omega" in f else 0.0,
        age if math.isfinite(age) else 0.0,
        f["v"].item(0) if "v" in f else 0.0,
        f["vx"].item(0) if "vx" in f else 0.0,
        f["vy"].item(0) if "vy" in f else 0.0,
        arc="v" in f,
        line="vx" in f and "vy" in f,
    )
    out["x"], out["y"], out["theta"] = np.array([x]), np.array([y]), np.array([theta])
    return out


def _reckoned(
    x: Any,
    y: Any,
    th0: Any,
    w: Any,
    age: Any,
    v: Any,
    vx: Any,
    vy: Any,
    arc: bool,
    line: bool,
    ops: Ops = np,
) -> tuple[Any, Any, Any]:
    """:func:`_dead_reckon`'s pose ``(x, y, theta)``, written once over ``ops`` (numpy for
    arrays; :func:`~hybridteam.floatpaths.float_form` makes its form on floats). ``arc``:
    the copy carries ``v`` (move on the arc where the world velocity lies along the
    heading, or where there is no ``vx, vy``); ``line``: it carries ``vx, vy``."""
    w = ops.where(w == w, w, 0.0)  # a NaN turn rate turns nothing
    a = w * age
    if arc:
        # exact arc: chord length v*age*sinc(a/2), along the mean heading (arrays.sinc's
        # operations on a / 2 pi: y = pi x, the machine epsilon where that is 0, sin(y) / y;
        # never a division by zero)
        turn = np.pi * (a / (2 * np.pi))
        turn = ops.where(turn, turn, _EPS)
        chord = v * age * (ops.sin(turn) / turn)
        mid = th0 + a / 2
        ax, ay = x + chord * ops.cos(mid), y + chord * ops.sin(mid)
        if line:
            lateral = -vx * ops.sin(th0) + vy * ops.cos(th0)
            along = abs(lateral) <= 1e-9 * (1.0 + ops.hypot(vx, vy))
            ax, ay = ops.where(along, ax, x + vx * age), ops.where(along, ay, y + vy * age)
    elif line:
        ax, ay = x + vx * age, y + vy * age
    else:
        ax, ay = x, y
    return ax, ay, th0 + w * age


#: machine epsilon: where sinc's argument is 0 (arrays.sinc)
_EPS = float(np.finfo(float).eps)


def _hypot(a: float, b: float) -> float:
    """``np.hypot`` itself on one pair (``math.hypot`` could differ in the last bit)."""
    return float(np.hypot(a, b))


_reckoned_on_floats = float_form(_reckoned, {**ON_FLOATS, "hypot": _hypot})


#: What ``@law`` registers: a function of the :class:`LawContext` of ``m`` instances that
#: returns their plant inputs, shape ``(m, k)``: one column per input of the plant.
LawFunction = Callable[[LawContext], np.ndarray]


@functools.cache
def asked_names(fn: LawFunction) -> frozenset[str]:
    """The names a law reads as ``ctx["name"]`` with a literal name (from its source):
    what must exist for the agent that binds it. ``ctx.get(name, default)`` is not among
    them (it has a default); names built at run time cannot be known here."""
    try:
        tree = ast.parse(textwrap.dedent(inspect.getsource(fn)))
    except (OSError, TypeError, SyntaxError):
        return frozenset()
    func = next((n for n in ast.walk(tree) if isinstance(n, ast.FunctionDef | ast.Lambda)), None)
    if func is None or not func.args.args:
        return frozenset()
    ctx = func.args.args[0].arg
    return frozenset(
        n.slice.value
        for n in ast.walk(func)
        if isinstance(n, ast.Subscript)
        and isinstance(n.value, ast.Name)
        and n.value.id == ctx
        and isinstance(n.slice, ast.Constant)
        and isinstance(n.slice.value, str)
    )


@dataclass(frozen=True)
class LawSpec:
    """A registered law: the callable and what it expects."""

    name: str
    fn: LawFunction
    plants: tuple[str, ...] | None = None
    params: dict[str, float] = field(default_factory=dict)
    doc: str = ""

    @property
    def summary(self) -> str:
        """What the law does: its docstring's first paragraph on one line. A summary may
        run over several lines of source; cutting at the first line ended mid-sentence."""
        return " ".join(self.doc.split("\n\n", 1)[0].split())


_REGISTRY: dict[str, LawSpec] = registry()


def law(
    name: str, *, plants: tuple[str, ...] | None = None, params: Mapping[str, float] | None = None
) -> Callable[[LawFunction], LawFunction]:
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


def resolve(reference: str, folder: str | None = None) -> LawSpec:
    """A law by registry name, or by ``module:function`` reference.

    A module is imported only from ``folder`` (the team file's) or an installed mode
    library, and the function must be registered with :func:`law`
    (:mod:`hybridteam.lawrefs` has the rules); it keeps its registration (defaults,
    plants) whatever name it is referenced by.
    """
    if ":" in reference:
        module_name, _, attr = reference.partition(":")
        try:
            module = import_model_module(module_name.strip(), folder)
        except RefusedReference as exc:
            raise LawNotFound(str(exc), []) from None
        except Exception as exc:  # an import error in user code is still a model error
            raise LawNotFound(
                f"cannot import module '{module_name}': {type(exc).__name__}: {exc}", []
            ) from exc
        obj = getattr(module, attr, None)
        if obj is None:
            raise LawNotFound(
                f"module '{module_name}' has no function '{attr}'",
                [n for n in dir(module) if not n.startswith("_")],
            )
        spec = (
            obj
            if isinstance(obj, LawSpec)
            else next((s for s in _REGISTRY.values() if s.fn is obj), None)
        )
        if spec is None:
            raise LawNotFound(
                f"'{reference}' is not a registered law: decorate the function "
                "with @law(...) from hybridteam.library",
                [],
            )
        return spec
    if reference not in _REGISTRY:
        load_libraries()
    if reference not in _REGISTRY:
        note = broken_note()
        prefix, _, function = reference.rpartition(".")
        if prefix and is_beside(folder, prefix.split(".")[0]):  # a user module, unimported
            note = (
                f"a law in a module beside the team file is named by module:function, "
                f"e.g. '{prefix}:{function}'"
            )
        raise LawNotFound(
            f"unknown law '{reference}'" + (f" ({note})" if note else ""), sorted(_REGISTRY)
        )
    return _REGISTRY[reference]


@law("zero")
def zero(ctx: LawContext) -> np.ndarray:
    """All inputs zero: the robot stands still."""
    return np.zeros((ctx.size, len(ctx.inputs)))


@law("constant")
def constant(ctx: LawContext) -> np.ndarray:
    """Each input held at the binding parameter of the same name (missing ones are zero)."""
    return (
        np.stack([ctx.get(name, 0.0) for name in ctx.inputs], axis=1)
        if ctx.inputs
        else np.zeros((ctx.size, 0))
    )
