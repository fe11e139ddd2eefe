"""A worker takes back what its process's environment costs a chunk (sweep/tuning.py):
glibc's adaptive malloc thresholds, and the GIL a Dask worker's profiler takes."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from hybridteam.sweep import tuning
from hybridteam.sweep.tuning import profiler_paused


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's mallopt")
def test_a_worker_restores_glibc_malloc_thresholds_only_where_they_were_set():
    """A Dask nanny's MALLOC_TRIM_THRESHOLD_ turns glibc's adaptive thresholds off (a
    ladder chunk then costs twice the CPU); the worker fixes them once, only then."""
    code = "from hybridteam.sweep.tuning import restore_malloc as r; print(r(), r())"

    def tuned(**env: str) -> str:
        clean = {
            k: v
            for k, v in os.environ.items()
            if k
            not in ("MALLOC_TRIM_THRESHOLD_", "MALLOC_MMAP_THRESHOLD_", "HYBRIDTEAM_KEEP_MALLOC")
        }
        done = subprocess.run(
            [sys.executable, "-c", code],
            env={**clean, **env},
            capture_output=True,
            text=True,
            check=True,
        )
        return done.stdout.strip()

    assert tuned() == "False False"
    assert tuned(MALLOC_TRIM_THRESHOLD_="65536") == "True True"
    assert tuned(MALLOC_TRIM_THRESHOLD_="65536", HYBRIDTEAM_KEEP_MALLOC="1") == "False False"


def test_outside_a_dask_worker_nothing_is_paused():
    with profiler_paused() as paused:
        assert paused is False


class _Sampler:
    """A stand-in for the worker's periodic profile callback."""

    def __init__(self) -> None:
        self.running = True
        self.calls: list[str] = []

    def is_running(self) -> bool:
        return self.running

    def stop(self) -> None:
        self.running = False
        self.calls.append("stop")

    def start(self) -> None:
        self.running = True
        self.calls.append("start")


def test_the_sampler_runs_again_only_when_the_last_chunk_of_the_process_ends(monkeypatch):
    sampler = _Sampler()
    monkeypatch.setattr(tuning, "_dask_sampler", lambda: (sampler, lambda fn: fn()))
    with profiler_paused() as first:
        assert first and not sampler.running
        with profiler_paused():  # a second thread's chunk overlapping the first
            assert not sampler.running
        assert not sampler.running  # the first chunk still runs
    assert sampler.running and sampler.calls == ["stop", "start"]


def _inside_and_after() -> tuple[bool, bool, bool]:
    from distributed import get_worker

    sampler = get_worker().periodic_callbacks["profile"]
    with profiler_paused() as paused:
        inside = sampler.is_running()
    return paused, inside, sampler.is_running()


def test_a_dask_worker_pauses_its_profiler_for_a_chunk_and_resumes_it():
    distributed = pytest.importorskip("dask.distributed")
    with (
        distributed.LocalCluster(
            n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None
        ) as cluster,
        distributed.Client(cluster) as client,
    ):
        paused, inside, after = client.submit(_inside_and_after, pure=False).result()
    assert (paused, inside, after) == (True, False, True)


def test_a_chunk_ending_as_its_worker_closes_is_not_turned_into_an_error(monkeypatch):
    """The sampler is resumed on the worker's event loop; a loop that is closing refuses
    callbacks (RuntimeError), and the chunk's result must still come back."""
    import types

    class Loop:
        def add_callback(self, fn):
            raise RuntimeError("Event loop is closed")

    worker = types.SimpleNamespace(periodic_callbacks={"profile": _Sampler()}, loop=Loop())
    fake = types.SimpleNamespace(get_worker=lambda: worker)
    monkeypatch.setitem(sys.modules, "distributed", fake)
    monkeypatch.delenv("HYBRIDTEAM_KEEP_PROFILER", raising=False)
    with profiler_paused() as paused:
        assert paused  # a profiler was found: pausing it was asked for
    assert tuning._pausing == 0
