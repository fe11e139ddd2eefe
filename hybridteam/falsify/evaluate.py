"""Simulate a generation of candidates: one ensemble per chunk, on the study executors.

A generation is split into one chunk per worker and each chunk runs as a study chunk does
(:func:`hybridteam.sweep.worker.run_chunk`), in this process, in a local process pool, or
on a Dask cluster; the pool or the cluster's client lives for the whole search.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from hybridteam.model import Team
from hybridteam.sweep.cluster import DEFAULT_CONNECT_TIMEOUT, connect
from hybridteam.sweep.plan import Chunk, Task
from hybridteam.sweep.worker import run_chunk


class Evaluator:
    """``evaluator(x, seeds) -> (robustness, outcomes)`` for a requirement of ``team``."""

    def __init__(
        self,
        team: Team,
        requirement: str,
        keys: list[str],
        *,
        workers: int | None = None,
        scheduler: str | None = None,
        connect_timeout: float = DEFAULT_CONNECT_TIMEOUT,
    ) -> None:
        self.team, self.requirement, self.keys = team, requirement, keys
        self.workers = workers or 1
        self.where = "in-process"
        self._pool: Any = None
        self._client: Any = None
        self._shared: Any = team
        if scheduler is not None:
            self._client = connect(scheduler, connect_timeout)
            self._shared = self._client.scatter(team, broadcast=True)
            self.workers = max(1, len(self._client.scheduler_info().get("workers", {})))
            self.where = f"Dask at {self._client.scheduler.address}"
        elif self.workers > 1:
            from concurrent.futures import ProcessPoolExecutor

            self._pool = ProcessPoolExecutor(max_workers=self.workers)
            self.where = f"{self.workers} local processes"

    def tasks(self, x: np.ndarray, seeds: np.ndarray) -> list[Task]:
        size = len(seeds)
        per = math.ceil(size / min(self.workers, size))
        out = []
        for start in range(0, size, per):
            stop = min(start + per, size)
            rows = slice(start, stop)
            k = stop - start
            out.append(
                Task(
                    Chunk(f"g{start}", 0, start, stop),
                    [0] * k,
                    {key: x[rows, j].copy() for j, key in enumerate(self.keys)},
                    [int(s) for s in seeds[rows]],
                    [0] * k,
                    [0] * k,
                    (),
                    False,
                )
            )
        return out

    def __call__(self, x: np.ndarray, seeds: np.ndarray) -> tuple[np.ndarray, list[str]]:
        tasks = self.tasks(x, seeds)
        if self._client is not None:
            futures = [self._client.submit(run_chunk, self._shared, t, pure=False) for t in tasks]
            parts = self._client.gather(futures)
        elif self._pool is not None and len(tasks) > 1:
            parts = list(self._pool.map(run_chunk, [self.team] * len(tasks), tasks))
        else:
            parts = [run_chunk(self.team, t) for t in tasks]
        rho = np.concatenate([np.asarray(p[f"req_{self.requirement}_rho"], float) for p in parts])
        outcomes = [o for p in parts for o in p["outcome"]]
        return rho, outcomes

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
        if self._client is not None:
            self._client.close()
