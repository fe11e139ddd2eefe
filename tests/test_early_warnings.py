"""Early warnings (issue 16, item 4): settings that cannot work are said before running.

With 0.25 s of latency each way an acknowledged message needs more than 0.5 s for its ack
to come back; the protocol's default ack timeout of 0.1 s would resend every one of them
and, after the retries, report it undeliverable — the run said ``ok`` all the same.
"""

from __future__ import annotations

from hybridteam.cli import main
from tests.test_end_rule import TEAM


def test_an_ack_timeout_shorter_than_a_round_trip_is_a_warning(tmp_path, capsys):
    slow = tmp_path / "slow.yaml"
    slow.write_text(TEAM.replace("network: {latency: 0.03}", "network: {latency: 0.25}"))
    assert main(["validate", str(slow)]) == 0
    err = capsys.readouterr().err
    assert ":6:3: agents.xr4000: agent 'xr4000' resends request, grant, deny, offer, accept, " \
           "confirm, reject, announce, takeover after 0.1 s without an acknowledgement, but a " \
           "round trip to 'labmate' takes up to 0.5 s" in err
    assert "make the ack timeout longer than 0.5 s (e.g. ack_timeout: 1.05) (warning)" in err
    assert main(["validate", "--strict", str(slow)]) == 2
    capsys.readouterr()
    assert main(["run", str(slow), "-o", str(tmp_path / "out"), "--no-views",
                 "--duration", "1"]) == 0
    assert "round trip to 'labmate' takes up to 0.5 s" in capsys.readouterr().err  # run warns
    fixed = tmp_path / "fixed.yaml"
    fixed.write_text(slow.read_text().replace("parameters: {speed: 0.3}",
                                              "parameters: {speed: 0.3, ack_timeout: 1.05}"))
    assert main(["validate", str(fixed)]) == 0
    assert "warning" not in capsys.readouterr().err
