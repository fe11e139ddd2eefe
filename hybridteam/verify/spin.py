"""A second opinion from SPIN: the explored skeleton as a Promela model, verdicts compared.

What is exported is the skeleton's reachable state graph as the explorer found it (each
state a number, its successors, and per property the truth of its formulas in it), not
the team's rules: SPIN then decides each invariant and response property on that graph
with its own algorithms (a never claim from the LTL formula, nested depth-first search
for acceptance cycles), independently of ours (sparse strongly connected components,
backward search). A disagreement means one of the two property checks is wrong. The
exploration itself, shared by both, is what the simulator cross-checks (replays and
``tests/verify/test_verify.py``).

The graph is held in C arrays (declared in a ``c_decl``, defined in ``graph.c``), so a
model of a hundred thousand states still compiles in seconds; a step picks one successor
nondeterministically in one atomic statement. A dead end is a blocked process, which
SPIN's LTL semantics extends by stuttering, as ours reads it (no answer ever comes).
``deadlock`` is not compared (it is a classification of dead ends, not a temporal
property); neither is an exploration cut short by a bound (:mod:`.bounds`: SPIN would read
the cut states as dead ends).
"""

from __future__ import annotations

import re
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hybridteam.verify.properties import Verdict, truths

#: What a comparison needs on the machine.
TOOLS = ("spin", "cc")


@dataclass
class Opinion:
    """SPIN's verdict on one property, beside ours."""

    name: str
    ours: bool
    spin: bool | None  # None: SPIN's search did not complete
    note: str = ""

    @property
    def agrees(self) -> bool:
        return self.spin is not None and self.spin == self.ours


def missing() -> str | None:
    """Why SPIN cannot run here, or None."""
    absent = [t for t in TOOLS if shutil.which(t) is None]
    if absent:
        return f"{' and '.join(repr(t) for t in absent)} not found on PATH"
    return None


def compared(report) -> list[Verdict]:
    """The verdicts SPIN can give a second opinion on."""
    return [
        v
        for v in report.verdicts
        if v.holds is not None and v.prop.kind in ("invariant", "response")
    ]


def model(report) -> tuple[str, str]:
    """The Promela model of ``report``'s explored graph and its compared properties, and
    the C file of the graph's arrays (SPIN limits the text of a ``c_decl``, so the model
    declares them and the verifier is compiled with that file)."""
    g, sk = report.graph, report.skeleton
    n = len(g.states)
    indptr, indices = g.edges.csr()
    arrays = [
        f"int first[{n + 1}] = {{{_list(indptr)}}};",
        f"int succ[{max(indices.size, 1)}] = {{{_list(indices) or '0'}}};",
    ]
    declared = ["  extern int first[];", "  extern int succ[];"]
    bits, claims, sets = [], [], []
    for k, v in enumerate(compared(report)):
        p = v.prop
        parts = [("ok", p.phi)] if p.kind == "invariant" else [("phi", p.phi), ("psi", p.psi)]
        for tag, node in parts:
            name = f"{tag}{k}"
            assert node is not None  # (a property of two formulas has both)
            truth = truths(node, sk, g).astype(np.uint8)
            arrays.append(f"unsigned char {name}_at[{n}] = {{{_list(truth)}}};")
            declared.append(f"  extern unsigned char {name}_at[];")
            bits.append(f"bit {name} = {int(truth[0])};")
            sets.append(f"now.{name} = {name}_at[now.s];")
        formula = f"[] ok{k}" if p.kind == "invariant" else f"[] (phi{k} -> <> psi{k})"
        claims.append(f"ltl p{k} {{ {formula} }}  /* {p.name} */")
    head = (
        f"/* hybridteam verify: the explored skeleton of team '{sk.original.team.name}', "
        f"{n} states, {len(g.edges)} edges */"
    )
    return "\n".join(
        [
            head,
            "c_decl {",
            *declared,
            "}",
            "int s = 0;",
            "int k = 0;",
            *bits,
            "active proctype skeleton() {",
            "  do",
            "  :: c_expr { first[now.s] < first[now.s + 1] } ->",
            "     atomic {",
            "       c_code { now.k = first[now.s]; };",
            "       do",
            "       :: c_expr { now.k + 1 < first[now.s + 1] } -> k++",
            "       :: true -> break",
            "       od;",
            "       c_code { now.s = succ[now.k]; now.k = 0; " + " ".join(sets) + " }",
            "     }",
            "  od",
            "}",
            *claims,
            "",
        ]
    ), "\n".join([head, *arrays, ""])


def _list(values) -> str:
    return ",".join(map(str, np.asarray(values).tolist()))


def cross_check(report, folder: Path, timeout: float = 600.0) -> list[Opinion]:
    """Write ``folder/skeleton.pml`` and ``graph.c``, compile SPIN's verifier and run it on
    every compared property; raises RuntimeError when SPIN cannot run or fails."""
    why = missing()
    if why:
        raise RuntimeError(why)
    if not report.graph.exhaustive:
        raise RuntimeError(
            f"the exploration stopped ({report.graph.bound}): SPIN would "
            "read the states cut off as dead ends"
        )
    folder.mkdir(parents=True, exist_ok=True)
    promela, arrays = model(report)
    (folder / "skeleton.pml").write_text(promela)
    (folder / "graph.c").write_text(arrays)
    _run(["spin", "-a", "skeleton.pml"], folder, timeout)
    _run(
        ["cc", "-O1", "-DNOREDUCE", "-DVECTORSZ=256", "-o", "pan", "pan.c", "graph.c"],
        folder,
        timeout,
    )
    out = []
    for k, v in enumerate(compared(report)):
        text = _run(["./pan", "-a", "-m10000000", "-w24", "-N", f"p{k}"], folder, timeout)
        (folder / f"{v.prop.name}.out").write_text(text)
        errors = re.search(r"errors: (\d+)", text)
        incomplete = "depth too small" in text or "max search depth too small" in text
        spin = None if errors is None or incomplete else int(errors.group(1)) == 0
        note = "" if spin is not None else "SPIN's search did not complete (see its output)"
        out.append(Opinion(v.prop.name, bool(v.holds), spin, note))
    return out


def _run(cmd: list[str], folder: Path, timeout: float) -> str:
    try:
        done = subprocess.run(cmd, cwd=folder, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        raise RuntimeError(f"'{' '.join(cmd)}' took more than {timeout:.0f} s") from None
    if done.returncode != 0:
        tail = (done.stdout + done.stderr).strip().splitlines()[-3:]
        raise RuntimeError(f"'{' '.join(cmd)}' failed: {' / '.join(tail)}")
    return done.stdout
