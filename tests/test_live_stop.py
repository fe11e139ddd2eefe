"""A live process stopped as its run ends keeps its trace.

``launch`` stops the processes outside the end rule (SIGTERM) once the end rule's have
ended; when every process reaches the run's end at once, such a stop can come while a
process is writing its folder, after its run. It must then be ignored as during the run
(the run is over), not end the process with nothing written: ``launch`` would report
the agent as having left no trace.
"""

from __future__ import annotations

import os
import signal
from pathlib import Path

import pytest

import hybridteam.cli.live as live_cli
from hybridteam.cli import main

HANDSHAKE = Path(__file__).parents[1] / "tests" / "fixtures" / "live" / "handshake.yaml"


def test_a_stop_while_the_folder_is_written_does_not_lose_the_trace(tmp_path, monkeypatch,
                                                                     capsys):
    """Both agents of the handshake in one process; SIGINT (the handler is the same as
    for launch's SIGTERM, and SIGINT is one pytest survives when it is not handled)
    raised just as the folder is being written: the folder is written, exit 0, and the
    process's own handlers are back afterwards."""
    original = live_cli.write_folder

    def stopped_while_writing(out, trace, summary):
        os.kill(os.getpid(), signal.SIGINT)  # delivered to this thread before kill returns
        original(out, trace, summary)

    monkeypatch.setattr(live_cli, "write_folder", stopped_while_writing)
    before = signal.getsignal(signal.SIGINT)
    out = tmp_path / "out"
    try:
        code = main(["live", str(HANDSHAKE), "--agent", "requester", "--agent", "granter",
                     "--listen", "127.0.0.1:0", "--time-scale", "4", "-o", str(out)])
    except KeyboardInterrupt:
        pytest.fail("the stop signal ended the process while it wrote its folder")
    assert code == 0, capsys.readouterr().err
    assert (out / "trace.json").is_file() and (out / "summary.json").is_file()
    assert signal.getsignal(signal.SIGINT) is before
