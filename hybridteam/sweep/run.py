"""Run a study's chunks on an executor, chunk by chunk into the output folder, resumably.

Executors: in this process (``workers=1``), a local process pool (``workers=N``), or a
Dask distributed cluster (``scheduler=ADDRESS`` or a ``client``; Dask is imported only
then). They differ only in *where* :func:`~hybridteam.sweep.worker.run_chunk` runs: this
process writes every finished chunk file as results come back, so the folder always holds
whole chunks, whichever finished first. Chunk files already present are not recomputed.
Once every chunk is in, the per-setting table is aggregated from the files (never from
memory), so a resumed study and an uninterrupted one produce the same bytes.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hybridteam.model import Team
from hybridteam.progress import reporter
from hybridteam.sweep.cluster import DEFAULT_CONNECT_TIMEOUT, connect
from hybridteam.sweep.plan import Chunk, Plan, Task, spread_chunk
from hybridteam.sweep.store import (
    FORMAT,
    StudyError,
    chunk_problem,
    discard_chunk,
    finished_chunks,
    open_folder,
    recorded_chunk,
    versions,
    write_chunk,
    write_record,
)
from hybridteam.sweep.study import Study
from hybridteam.sweep.table import (
    ResultTable,
    aggregate,
    collect_runs,
    run_table,
    write_results,
)
from hybridteam.sweep.worker import run_chunk

Results = Iterator[tuple[Chunk, dict[str, list[Any]]]]

log = logging.getLogger(__name__)


@dataclass
class StudyResult:
    """What :func:`run_study` did: chunks computed now and found done, and the table."""

    plan: Plan
    computed: list[str] = field(default_factory=list)
    reused: list[str] = field(default_factory=list)
    table: ResultTable | None = None  # None while chunks are missing (stopped early)
    executor: str = ""
    wall_s: float = 0.0
    warnings: list[str] = field(default_factory=list)

    @property
    def complete(self) -> bool:
        return self.table is not None

    def warn(self, message: str) -> None:
        """A problem found and worked round (a damaged chunk computed again): kept in
        :attr:`warnings` for the caller and logged as a warning where the library speaks."""
        self.warnings.append(message)
        log.warning("%s", message)


def run_study(
    study: Study,
    out: str | Path,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    client: Any = None,
    chunk: int | None = None,
    progress: bool | str = False,
    max_chunks: int | None = None,
    fmt: str | None = None,
    connect_timeout: float = DEFAULT_CONNECT_TIMEOUT,
) -> StudyResult:
    """Run ``study`` into folder ``out`` and write its table; resume if ``out`` holds part.

    ``connect_timeout``: seconds to reach ``scheduler`` (:func:`~.cluster.connect`).

    ``max_chunks`` stops after computing that many chunks (the table is then not written):
    what an interruption does, on purpose — tests use it to check resuming.
    ``fmt`` forces the chunk file format ('parquet' or 'csv'; default: Parquet if pyarrow
    is installed). Without ``chunk``, a resumed study keeps the chunk size it was run
    with, and a new one takes the study's, made smaller where it would leave some of
    ``workers`` without a chunk (:func:`~hybridteam.sweep.plan.spread_chunk`).
    """
    out = Path(out)
    if workers is not None and workers < 1:
        raise StudyError(f"workers must be at least 1, got {workers}")
    if (scheduler is not None or client is not None) and workers not in (None, 1):
        raise StudyError("give either a number of local workers or a Dask scheduler, not both")
    if chunk is None:
        chunk = recorded_chunk(out) or spread_chunk(study, workers or 1)
    plan = Plan(study, chunk)
    record = {
        "format": FORMAT,
        "study": str(study.path),
        "team": str(study.team_path),
        "name": study.name,
        "digest": study.digest,
        "chunk": plan.chunk,
        "runs": plan.runs,
        "chunks": len(plan.chunks),
        "seed": study.seed,
        "factors": [f.name for f in study.factors],
        "axes": [a.name for a in study.axes],
        "metrics": list(study.metrics),
        "success": list(study.success),
    }
    old = open_folder(out, record)
    done = finished_chunks(out) if old is not None else {}
    unknown = sorted(set(done) - {c.id for c in plan.chunks})
    if unknown:
        raise StudyError(
            f"{out}: chunk file '{unknown[0]}' belongs to no chunk of this "
            "study; use another output folder"
        )
    result = StudyResult(plan)
    for c in plan.chunks:  # a chunk is reused only if it verifies; else it is run again
        if c.id in done and (why := chunk_problem(done[c.id], c.size)) is not None:
            result.warn(f"{done[c.id]}: {why}; computing chunk {c.id} again")
            discard_chunk(done.pop(c.id))
    result.reused = [c.id for c in plan.chunks if c.id in done]
    record["versions"] = versions()
    if old is not None and old.get("versions") not in (None, record["versions"]):
        record["earlier_versions"] = old.get("earlier_versions") or old["versions"]
        result.warn(
            f"{out}: resuming with other package versions than the chunks "
            "already there were computed with (see study.json)"
        )
    todo = [c for c in plan.chunks if c.id not in done]
    if max_chunks is not None:
        todo = todo[:max_chunks]
    start = time.perf_counter()
    if todo:  # connect first: a scheduler that cannot be reached leaves no folder behind
        results, result.executor, close = _executor(
            study.team, plan, todo, workers, scheduler, client, connect_timeout
        )
        bar = None
        try:
            write_record(out, {**record, "status": "running"})
            bar = _bar(plan, done, study.name, progress)
            for c, columns in results:
                write_chunk(out, c.id, columns, fmt)
                result.computed.append(c.id)
                if bar is not None:
                    bar.update(c.size)
        finally:
            if bar is not None:
                bar.close()
            close()
    result.wall_s = time.perf_counter() - start
    if len(result.computed) + len(result.reused) < len(plan.chunks):
        return result  # stopped early: no table, the record still says "running"
    runs = collect_runs(plan, out)
    result.table = aggregate(plan, runs)
    write_results(out, result.table, run_table(plan, runs))
    write_record(out, {**record, "status": "complete"})
    return result


def _bar(plan: Plan, done: dict[str, Path], name: str, progress: bool | str):
    """A progress reporter over the runs (``progress``: a mode of
    :mod:`hybridteam.progress`; True means a bar, False none)."""
    mode = progress if isinstance(progress, str) else "bar" if progress else "none"
    finished = sum(c.size for c in plan.chunks if c.id in done)
    return reporter(str(mode), plan.runs, name, "run", initial=finished)


def _executor(
    team: Team,
    plan: Plan,
    todo: list[Chunk],
    workers: int | None,
    scheduler: str | None,
    client: Any,
    connect_timeout: float,
) -> tuple[Results, str, Callable[[], None]]:
    """(chunk results as they finish, a description, what to call when done)."""
    tasks = (plan.task(c) for c in todo)
    if scheduler is not None or client is not None:
        return _dask(team, tasks, scheduler, client, connect_timeout)
    if workers is None or workers == 1 or len(todo) == 1:
        why = "" if workers in (None, 1) else ": one chunk to compute"  # --chunk, or resumed
        return ((t.chunk, run_chunk(team, t)) for t in tasks), f"in-process{why}", lambda: None
    return _pool(team, list(tasks), workers)


def _pool(team: Team, tasks: list[Task], workers: int) -> tuple[Results, str, Callable[[], None]]:
    from concurrent.futures import ProcessPoolExecutor, as_completed

    used = min(workers, len(tasks))
    pool = ProcessPoolExecutor(max_workers=used)
    futures = {pool.submit(run_chunk, team, t): t.chunk for t in tasks}

    def results() -> Results:
        for fut in as_completed(futures):
            yield futures[fut], fut.result()

    def close() -> None:  # on an interruption or a failure: drop what has not started
        pool.shutdown(wait=True, cancel_futures=True)

    why = f" ({len(tasks)} chunks to compute)" if used < workers else ""
    return results(), f"{used} local processes{why}", close


def _dask(
    team: Team, tasks: Iterator[Task], scheduler: str | None, client: Any, connect_timeout: float
) -> tuple[Results, str, Callable[[], None]]:
    try:
        from dask.distributed import as_completed
    except ImportError:
        raise StudyError(
            "running on a Dask cluster needs dask.distributed: pip install 'hybridteam[dask]'"
        ) from None
    own = client is None
    if own:
        client = connect(str(scheduler), connect_timeout)
    shared = client.scatter(team, broadcast=True)
    futures = {client.submit(run_chunk, shared, t, pure=False): t.chunk for t in tasks}

    def results() -> Results:
        for fut, columns in as_completed(list(futures), with_results=True):
            yield futures[fut], columns

    def close() -> None:  # on an interruption or a failure: drop what has not run
        client.cancel(list(futures))
        if own:
            client.close()

    return results(), f"Dask at {client.scheduler.address}", close
