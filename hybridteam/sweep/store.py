"""The output folder of a study: chunk files, ``study.json``, atomic writes.

Each finished chunk is one file, ``chunks/<id>.parquet`` (pyarrow installed) or
``chunks/<id>.csv``, written under a temporary name and renamed — so a file that exists is
complete, and an interrupted study resumes by skipping the chunks whose file exists.
``study.json`` holds the digest of the study and team files, the chunk size and the package
versions; resuming into a folder of another study (or another chunk size, which would cut
the runs differently) is refused instead of silently mixing results.

CSV floats are written with ``repr`` (shortest round-trip digits), so a table aggregated
from CSV chunks is bit for bit the one aggregated from Parquet chunks.
"""

from __future__ import annotations

import csv
import importlib.metadata
import io
import json
import os
import platform
from pathlib import Path
from typing import Any

from hybridteam.trace import write_atomic

FORMAT = "hybridteam.study"
INT_COLUMNS = ("run", "setting", "member", "repetition", "seed")
STR_COLUMNS = ("outcome",)


class StudyError(Exception):
    """A study that cannot run as asked (another study in the folder, dask missing...)."""


def have_pyarrow() -> bool:
    try:
        import pyarrow.parquet  # noqa: F401
    except ImportError:
        return False
    return True


def versions() -> dict[str, str]:
    """Versions of what can change results, recorded beside them."""
    out = {"python": platform.python_version()}
    for name in ("hybridteam", "numpy", "scipy", "pydantic", "dask", "distributed", "pyarrow"):
        try:
            out[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            continue
    return out


# ------------------------------------------------------------------ chunk files
def chunk_dir(out: Path) -> Path:
    return out / "chunks"


def finished_chunks(out: Path) -> dict[str, Path]:
    """Chunk id -> file, for every complete chunk file in ``out`` (temporaries ignored)."""
    folder = chunk_dir(out)
    if not folder.is_dir():
        return {}
    return {
        p.stem: p
        for p in sorted(folder.iterdir())
        if p.suffix in (".parquet", ".csv") and not p.name.startswith(".")
    }


def write_chunk(
    out: Path, chunk_id: str, columns: dict[str, list[Any]], fmt: str | None = None
) -> Path:
    """Write one chunk's rows atomically; ``fmt`` 'parquet' or 'csv' (default: best)."""
    fmt = fmt or ("parquet" if have_pyarrow() else "csv")
    folder = chunk_dir(out)
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{chunk_id}.{fmt}"
    tmp = folder / f".{chunk_id}.{fmt}.{os.getpid()}.tmp"
    try:
        if fmt == "parquet":
            import pyarrow as pa
            import pyarrow.parquet as pq

            pq.write_table(pa.table(columns), tmp)
        else:
            tmp.write_text(_csv_text(columns), encoding="utf-8", newline="")
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    write_atomic(_sum_path(path), f"{_digest(path)}  {path.name}\n")
    return path


def _sum_path(path: Path) -> Path:
    return path.with_name(path.name + ".sha256")


def _digest(path: Path) -> str:
    import hashlib

    return hashlib.sha256(path.read_bytes()).hexdigest()


def chunk_problem(path: Path, rows: int) -> str | None:
    """Why a chunk file cannot be trusted (no checksum, a checksum that does not match, not
    the rows its chunk has), or None. A chunk is written, then its checksum: a file a
    crash, a copy or a hand cut short is never taken for a finished chunk."""
    sums = _sum_path(path)
    if not sums.is_file():
        return "it has no checksum"
    try:
        expected = sums.read_text(encoding="utf-8").split()[0]
        if expected != _digest(path):
            return "its checksum does not match"
        got = len(next(iter(read_chunk(path).values()), []))
    except (OSError, ValueError, IndexError, KeyError, StudyError, StopIteration) as exc:
        return f"it cannot be read ({exc})"
    except Exception as exc:  # a Parquet reader's own errors on a damaged file
        return f"it cannot be read ({type(exc).__name__})"
    if got != rows:
        return f"it holds {got} rows, not {rows}"
    return None


def discard_chunk(path: Path) -> None:
    path.unlink(missing_ok=True)
    _sum_path(path).unlink(missing_ok=True)


def read_chunk(path: Path) -> dict[str, list[Any]]:
    if path.suffix == ".parquet":
        if not have_pyarrow():
            raise StudyError(
                f"{path}: reading Parquet chunks needs pyarrow "
                "(pip install pyarrow), as when they were written"
            )
        import pyarrow.parquet as pq

        return pq.read_table(path).to_pydict()
    with path.open(encoding="utf-8", newline="") as f:
        rows = list(csv.reader(f))
    header, body = rows[0], rows[1:]
    cols: dict[str, list[Any]] = {}
    for j, name in enumerate(header):
        kind = int if name in INT_COLUMNS else str if name in STR_COLUMNS else float
        cols[name] = [kind(row[j]) for row in body]
    return cols


def _csv_text(columns: dict[str, list[Any]]) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(columns)
    for row in zip(*columns.values(), strict=True):
        w.writerow([repr(v) if isinstance(v, float) else v for v in row])
    return buf.getvalue()


# ------------------------------------------------------------------ study.json
def open_folder(out: Path, record: dict[str, Any]) -> dict[str, Any] | None:
    """Check that ``out`` is new, or holds this very study; return its old record if any.

    ``record`` carries ``digest`` and ``chunk``; a mismatch is a :class:`StudyError` that
    says what differs and what to do.
    """
    path = out / "study.json"
    if out.exists() and not out.is_dir():
        raise StudyError(f"output '{out}' exists and is not a folder")
    if not path.exists():
        if any((out / name).exists() for name in ("trace.json", "summary.json", "INCOMPLETE")):
            raise StudyError(
                f"{out}: holds the outputs of 'hybridteam run'; give the study a folder of its own"
            )
        if finished_chunks(out):
            raise StudyError(f"{out}: holds chunk files but no study.json; use an empty folder")
        return None
    try:
        old = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise StudyError(f"{path}: cannot read ({exc}); use another output folder") from None
    if not isinstance(old, dict) or old.get("format") != FORMAT:
        raise StudyError(f"{path}: not a hybridteam study record; use another output folder")
    if old.get("digest") != record["digest"]:
        raise StudyError(
            f"{out}: holds results of another study (the study or team file "
            "changed); use another output folder, or delete this one to "
            "start over"
        )
    if old.get("chunk") != record["chunk"]:
        raise StudyError(
            f"{out}: was run with chunk size {old.get('chunk')}, not "
            f"{record['chunk']}; resume with --chunk {old.get('chunk')}"
        )
    return old


def recorded_chunk(out: Path) -> int | None:
    """The chunk size the study in ``out`` was run with, or None (no readable record).

    Resuming without ``--chunk`` goes on with it: the chunk size a first run chose for its
    workers must not make the same command with other workers refuse the folder.
    """
    try:
        old = json.loads((out / "study.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    chunk = old.get("chunk") if isinstance(old, dict) else None
    return chunk if isinstance(chunk, int) and not isinstance(chunk, bool) and chunk >= 1 else None


def write_record(out: Path, record: dict[str, Any]) -> None:
    out.mkdir(parents=True, exist_ok=True)
    write_atomic(out / "study.json", json.dumps(record, indent=2) + "\n")
