"""What a worker process's environment costs a chunk, and how a worker takes it back.

A chunk is seconds of pure-Python, numpy-heavy work in one thread. Two defaults of Dask
workers slow exactly that kind of work, and neither is the study's business, so a worker
undoes each for itself (once per process, or for the duration of a chunk), never where it
does not apply, and leaves it alone when told to (``HYBRIDTEAM_KEEP_MALLOC=1``,
``HYBRIDTEAM_KEEP_PROFILER=1``). A process pool's workers and an in-process run meet
neither: there these are no-ops.
"""

from __future__ import annotations

import os
import sys
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

#: glibc's malloc parameters (mallopt) and the values its adaptive thresholds reach on
#: 64-bit Linux: blocks up to 32 MiB from the heap, the heap trimmed past 64 MiB free
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3
_MMAP_MAX, _TRIM_AT = 32 << 20, 64 << 20
_tuned: bool | None = None


def restore_malloc() -> bool:
    """Give glibc back its adaptive behaviour where the environment turned it off.

    A Dask nanny starts workers with ``MALLOC_TRIM_THRESHOLD_=65536``; setting any malloc
    threshold turns off glibc's adaptive mmap threshold, so every numpy temporary over
    128 KiB is mapped and unmapped and the heap top trimmed again and again: measured here,
    a ladder chunk cost 2.9 s of CPU in such a worker and 1.4 s in a plain process. Fixing
    the thresholds at the values adaptation reaches (32 MiB, trim past 64 MiB) restores the
    plain process's speed (1.2–1.3 s). Once per process, only when such a variable is set,
    never with ``HYBRIDTEAM_KEEP_MALLOC=1``, and a no-op where there is no glibc. Returns
    whether it changed anything.
    """
    global _tuned
    if _tuned is not None:
        return _tuned
    _tuned = False
    env = os.environ
    if (
        env.get("HYBRIDTEAM_KEEP_MALLOC")
        or not sys.platform.startswith("linux")
        or not any(k in env for k in ("MALLOC_TRIM_THRESHOLD_", "MALLOC_MMAP_THRESHOLD_"))
    ):
        return _tuned
    try:
        import ctypes

        mallopt = ctypes.CDLL("libc.so.6").mallopt
    except (OSError, AttributeError):  # not glibc (musl): nothing to restore
        return _tuned
    _tuned = bool(mallopt(_M_MMAP_THRESHOLD, _MMAP_MAX)) and bool(
        mallopt(_M_TRIM_THRESHOLD, _TRIM_AT)
    )
    return _tuned


#: chunks running in this process under a paused profiler (a worker may run several
#: at once, one per thread): the first to start pauses it, the last to end resumes it
_pausing = 0
_lock = threading.Lock()


@contextmanager
def profiler_paused() -> Iterator[bool]:
    """Pause the Dask worker's statistical profiler while a chunk runs; yields whether it
    did.

    A Dask worker samples the stacks of its running tasks every 10 ms by default
    (``distributed.worker.profile``), on its event-loop thread, which takes the GIL from
    the task each time. Measured here on a ladder chunk (alpha study, 500 runs), the task
    then took 9–17 % longer than in the same worker with the profiler off, and the
    profiler's own bookkeeping accounts for only 1.5–1.8 % of it: the rest is the GIL
    changing hands. Only inside a Dask worker whose profiler is on, never with
    ``HYBRIDTEAM_KEEP_PROFILER=1`` (then the dashboard's profile shows our chunks); the
    sampler runs again once no chunk of this process is running.
    """
    global _pausing
    sampler, run_on_loop = _dask_sampler()
    if sampler is None:
        yield False
        return
    with _lock:  # the loop runs stop/start in the order they were asked for
        _pausing += 1
        if _pausing == 1:
            run_on_loop(lambda: sampler.stop() if sampler.is_running() else None)
    try:
        yield True
    finally:
        with _lock:
            _pausing -= 1
            if _pausing == 0:
                run_on_loop(lambda: None if sampler.is_running() else sampler.start())


def _dask_sampler() -> tuple[Any, Callable[[Callable[[], None]], None]]:
    """The profiler's periodic callback of the Dask worker running this task, and a way to
    run a function on that worker's event loop (waiting for it, at most a second); or
    ``(None, ...)`` outside a Dask worker, or where its profiler is off."""
    none = (None, lambda fn: None)
    distributed = sys.modules.get("distributed")  # a Dask worker has imported it
    if os.environ.get("HYBRIDTEAM_KEEP_PROFILER") or distributed is None:
        return none
    try:
        worker = distributed.get_worker()
    except ValueError:  # not inside a Dask task
        return none
    sampler = getattr(worker, "periodic_callbacks", {}).get("profile")
    if sampler is None:
        return none

    def run_on_loop(fn: Callable[[], None]) -> None:
        done = threading.Event()

        def call() -> None:
            try:
                fn()
            finally:
                done.set()

        try:
            worker.loop.add_callback(call)  # (thread-safe; the callback is not)
        except RuntimeError:  # the worker's loop is closing: nothing left to pause
            return
        done.wait(1.0)

    return sampler, run_on_loop
