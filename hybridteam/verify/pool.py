"""Successors on several cores: a pool of worker processes, each with its own machine.

Computing a successor (the engine's discrete phase on a batch of instances) is most of an
exploration's time; storing and numbering states is a smaller part. So the explorer keeps
the store, the graph and the BFS order in its own process and hands chunks of jobs
``(state, choice, tape)`` to the workers, several chunks ahead, and takes the results
back *in the order the jobs were made*. A worker sends each successor as its key in its
own part numbers (:func:`~.store.state_key`; a few bytes, not the state's objects) with
the parts it numbered since its last chunk, and the explorer renumbers the keys into its
own (:class:`~.store.Renumber`). The states are then numbered, the edges added and the
free comparisons' retries queued exactly as one process does: the graph — state
numbers, parents, edges, verdicts and counterexamples — is the same, bit for bit, for
any number of jobs. (Partitioning the states between owner processes would spread the
store too, but make the numbering depend on how the exchanges interleave; on a few cores
the store is not what limits.)

Each worker is forked with the skeleton and builds its machine once (``make``): the
successor function is whatever the explorer's factory builds, through its
``run(jobs) -> results`` seam. Workers ignore Ctrl-C; the explorer's process receives
it, and on it or on any error the pool is terminated and its processes joined before the
exception goes on (:meth:`Pool.__exit__`): no worker outlives the check. A worker that
dies (killed, out of memory) takes its chunk with it, and ``multiprocessing`` would wait
for that chunk forever: while waiting, the pool checks every second that each worker it
started is alive, and ends the check with :class:`WorkerDied` if one is not.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
from collections import deque
from collections.abc import Callable, Iterator
from typing import Any, Protocol

from hybridteam.verify.store import Parts, Renumber, state_key

#: The machine of this worker process (built once, by :func:`_start`).
_machine: Any = None
#: This worker's part numbers, and how many of them it has sent.
_parts = Parts()
_sent = 0


class Successors(Protocol):
    """What a worker computes with: the explorer's machine's seam."""

    def run(self, jobs: list[tuple]) -> list: ...


class WorkerDied(RuntimeError):
    """A worker process ended while the check needed it."""


def _start(make: Callable[[], Successors], started) -> None:
    global _machine
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the explorer's process handles Ctrl-C
    started.put(os.getpid())
    _machine = make()


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


def _run(jobs: list[tuple]) -> tuple[int, list, list[tuple[bytes, bool, int]]]:
    """This worker's id, the parts it numbered since its last chunk, and each job's
    successor as ``(key, zeno, reads)``."""
    global _sent
    out = [(state_key(_parts, r.state), r.zeno, r.reads) for r in _machine.run(jobs)]
    new = _parts.values[_sent:]
    _sent = len(_parts.values)
    return os.getpid(), new, out


class Pool:
    """``workers`` forked processes computing successors; a context manager that always
    ends them (joined on success, terminated on an error or Ctrl-C)."""

    def __init__(self, make: Callable[[], Successors], workers: int) -> None:
        self.workers = workers
        ctx = multiprocessing.get_context("fork")
        self._started = ctx.SimpleQueue()  # each worker's process id, as it starts
        self._pids: set[int] = set()
        # fork: the skeleton and the machine factory reach the workers without pickling
        self._pool = ctx.Pool(workers, _start, (make, self._started))

    def __enter__(self) -> Pool:
        return self

    def __exit__(self, kind, value, tb) -> None:
        if kind is None:
            self._pool.close()
        else:
            self._pool.terminate()
        self._pool.join()
        self._started.close()

    def in_order(
        self, level: Iterator[list], retries: list, size: int, renumber: Renumber
    ) -> Iterator[tuple]:
        """``(chunk, results)`` of the level's chunks, then of chunks of ``retries`` (which
        the caller extends while it takes the results), in that order; up to two chunks
        a worker are being computed meanwhile. A chunk's items are ``(tag, *job)``: the
        workers get the jobs, the tags (the explorer's state numbers) stay here. The
        results are ``(key, zeno, reads)``, keys in ``renumber``'s part numbers."""
        pending: deque = deque()
        done = 0
        while True:
            while len(pending) < 2 * self.workers:
                chunk = next(level, None)
                if chunk is None:
                    chunk = retries[done : done + size]
                    done += len(chunk)
                    if not chunk:
                        break
                jobs = [item[1:] for item in chunk]
                pending.append((chunk, self._pool.apply_async(_run, (jobs,))))
            if not pending:
                return
            chunk, result = pending.popleft()
            source, new, out = self._wait(result)
            renumber.learn(source, new)
            yield chunk, [(renumber.key(source, key), zeno, reads) for key, zeno, reads in out]

    def _wait(self, result) -> list:
        """``result``'s value, checking every second that no worker has died."""
        while True:
            try:
                return result.get(timeout=1.0)
            except multiprocessing.TimeoutError:
                while not self._started.empty():
                    self._pids.add(self._started.get())
                dead = sorted(p for p in self._pids if not _alive(p))
                if dead:
                    raise WorkerDied(
                        f"worker process {dead[0]} of verify --jobs {self.workers} ended "
                        "while it computed successors (killed, or out of memory?)"
                    ) from None
