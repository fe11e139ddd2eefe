"""A falsification's folder: ``falsify.json`` (every simulation, resumable), the
convergence plot, and the replay of the best candidate as an ordinary run folder."""

from __future__ import annotations

import hashlib
import json
import math
import shlex
from pathlib import Path
from typing import Annotated, Any

import numpy as np
from pydantic import AfterValidator, BaseModel, ConfigDict, Field, model_validator

from hybridteam.falsify.search import Generation, Search, Vary
from hybridteam.trace import write_atomic
from hybridteam.trace_schema import first_problem

FORMAT, VERSION = "hybridteam.falsify", 1
RECORD = "falsify.json"


def digest(team_text: str, settings: dict[str, Any]) -> str:
    """What a resumed search must share with the one it continues (not the budget)."""
    blob = json.dumps(settings, sort_keys=True) + "\0" + team_text
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


def read_record(out: Path, key: str) -> list[Generation] | str:
    """The generations of an earlier search with the same settings; a problem (text) if
    the folder holds something else; [] for a new folder."""
    path = out / RECORD
    if not path.exists():
        if any(out.glob("*")) and not (out / "replay").exists():
            return f"output '{out}' is not empty and holds no falsification"
        return []
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError) as exc:
        return f"{path}: unreadable ({exc})"
    problem = first_problem(Record, data, "a search's record")
    if problem is not None:  # replaced or edited: nothing of it is used
        return f"{path}: cannot resume from it: {problem[1]}"
    if data.get("format") != FORMAT or data.get("digest") != key:
        return (
            f"output '{out}' holds a different search (other team, requirement, ranges, "
            "method or seeds); use another folder"
        )
    return [Generation.from_json(g) for g in data.get("generations", [])]


Finite = Annotated[float, Field(allow_inf_nan=False)]


def _robustness(value: Any) -> Any:
    """A finite number, or ``"inf"``/``"-inf"`` (a Boolean verdict, as :func:`_json`
    writes it)."""
    ok = (
        value in ("inf", "-inf")
        if isinstance(value, str)
        else (
            isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
        )
    )
    if not ok:
        raise ValueError(f"expected a finite number, 'inf' or '-inf', got {value!r:.40}")
    return value


Robustness = Annotated[Any, AfterValidator(_robustness)]


class GenerationRecord(BaseModel):
    """One generation as :meth:`Generation.to_json` writes it: every list one entry per
    candidate, each candidate one value per searched key."""

    x: list[list[Finite]] = Field(min_length=1)
    seeds: list[Annotated[int, Field(ge=0, lt=2**63)]]
    robustness: list[Robustness]
    outcomes: list[str]

    @model_validator(mode="after")
    def _one_entry_per_candidate(self) -> GenerationRecord:
        if not len(self.x) == len(self.seeds) == len(self.robustness) == len(self.outcomes):
            raise ValueError(
                f"x, seeds, robustness and outcomes have {len(self.x)}, "
                f"{len(self.seeds)}, {len(self.robustness)} and "
                f"{len(self.outcomes)} entries; expected one per candidate"
            )
        return self


class Record(BaseModel):
    """What a resumed search reads of ``falsify.json`` (the rest is written for readers)."""

    model_config = ConfigDict(extra="allow")

    format: str
    digest: str
    vary: list[dict[str, Any]]
    generations: list[GenerationRecord] = Field(default_factory=list)

    @model_validator(mode="after")
    def _a_value_per_key(self) -> Record:
        for k, g in enumerate(self.generations):
            for row in g.x:
                if len(row) != len(self.vary):
                    raise ValueError(
                        f"generations[{k}].x: a candidate has {len(row)} "
                        f"value(s), the search varies {len(self.vary)} key(s)"
                    )
        return self


def replay_args(team_path: str, search: Search, i: int, out: Path) -> list[str]:
    """``hybridteam run`` arguments that replay simulation ``i`` exactly (values in repr,
    the shortest text that reads back as the same float)."""
    x, seeds, _, _ = search.flat()
    args = ["hybridteam", "run", team_path, "--seed", str(int(seeds[i]))]
    for v, value in zip(search.varies, x[i].tolist(), strict=True):
        args += ["--set", f"{v.key}={value!r}"]
    return [*args, "-o", str(out / "replay")]


def write_record(
    out: Path,
    key: str,
    settings: dict[str, Any],
    search: Search,
    extra: dict[str, Any] | None = None,
) -> None:
    x, seeds, rho, outcomes = search.flat()
    best = search.best() if len(rho) else None
    data: dict[str, Any] = {
        "format": FORMAT,
        "version": VERSION,
        "digest": key,
        **settings,
        "simulations": search.evaluations,
        "falsified_after": search.first_falsified(),
        "best": None
        if best is None
        else {
            "values": {v.key: float(x[best, j]) for j, v in enumerate(search.varies)},
            "seed": int(seeds[best]),
            "robustness": _json(float(rho[best])),
            "outcome": outcomes[best],
            "simulation": best + 1,
        },
        **(extra or {}),
        "generations": [g.to_json() for g in search.generations],
    }
    write_atomic(out / RECORD, json.dumps(data, indent=1) + "\n")


def _json(r: float) -> float | str:
    return r if math.isfinite(r) else ("inf" if r > 0 else "-inf")


def write_convergence(out: Path, search: Search, title: str) -> Path:
    """Best robustness so far against simulations, each simulation a dot; the zero line
    is where the requirement breaks."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.ticker import MaxNLocator

    from hybridteam.export.figures import save_figure

    rho = search.flat()[2]
    k = np.arange(1, len(rho) + 1)
    fig = Figure(figsize=(8.5, 4.0), dpi=110)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    fin = np.isfinite(rho)
    finite = rho[fin]
    lo = min(float(finite.min()), 0.0) if finite.size else -1.0
    hi = max(float(finite.max()), 0.0) if finite.size else 1.0
    span = (hi - lo) or 1.0
    top, bottom = hi + 0.12 * span, lo - 0.12 * span  # where Boolean verdicts (+-inf) sit
    shown = np.clip(rho, bottom, top)
    if finite.size:
        ax.plot(k[fin], finite, ".", color="#9E9E9E", markersize=4, label="each simulation")
    for mask, y, marker, text in (
        (rho == np.inf, top, "^", "held by a Boolean (+inf)"),
        (rho == -np.inf, bottom, "v", "broken by a Boolean (-inf)"),
    ):
        if mask.any():
            ax.plot(
                k[mask], np.full(mask.sum(), y), marker, color="#9E9E9E", markersize=4, label=text
            )
    best = np.minimum.accumulate(shown)
    ax.step(k, best, where="post", color="#1565C0", linewidth=1.8, label="best so far")
    ax.set_xlim(0.5, max(len(rho), 1) + 0.5)
    ax.set_ylim(bottom - 0.05 * span, top + 0.05 * span)
    if not fin.all():  # name the rows where the Boolean verdicts sit
        ticks = (
            [t for t in ax.get_yticks() if lo - 1e-12 <= t <= hi + 1e-12] if finite.size else [0.0]
        )
        ax.set_yticks([bottom, *ticks, top], ["-inf", *(f"{t:g}" for t in ticks), "+inf"])
    ax.axhline(0.0, color="#C62828", linestyle="--", linewidth=1.0, label="violated below")
    first = search.first_falsified()
    if first is not None:
        ax.axvline(first, color="#C62828", linewidth=0.8, alpha=0.5)
        ax.annotate(
            f"first violation: simulation {first}",
            (first, 0),
            xytext=(6, 8),
            textcoords="offset points",
            fontsize=8,
            color="#C62828",
        )
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlabel("simulations")
    ax.set_ylabel("robustness")
    ax.set_title(title, fontsize=10)
    ax.grid(color="#EEEEEE")
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    path = out / "convergence.png"
    save_figure(fig, path)
    return path


def command_line(args: list[str]) -> str:
    return " ".join(shlex.quote(a) for a in args)


def settings_of(
    requirement: str,
    formula: str,
    varies: list[Vary],
    seeds: int,
    base_seed: int,
    method: str,
    population: int,
    search_seed: int,
) -> dict[str, Any]:
    return {
        "requirement": requirement,
        "formula": formula,
        "vary": [{"key": v.key, "lo": v.lo, "hi": v.hi} for v in varies],
        "seeds": seeds,
        "base_seed": base_seed,
        "method": method,
        "population": population,
        "search_seed": search_seed,
    }
