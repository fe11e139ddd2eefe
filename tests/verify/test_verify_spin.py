"""SPIN's second opinion on verify's verdicts (``--spin``): it agrees on the correct role
protocol and on two mutants, one breaking an invariant and one a response property. Those
tests skip where SPIN or a C compiler is missing (``.ci/run`` installs SPIN where it can);
what verify does without SPIN is tested everywhere."""

from __future__ import annotations

import json

import pytest

from hybridteam.cli import main
from hybridteam.verify import Options, spin, verify
from tests.verify.test_verify import GRANT, mutate, roles_team

needs_spin = pytest.mark.skipif(
    spin.missing() is not None, reason=f"SPIN cannot run here: {spin.missing()}"
)

RESTORED = (
    "  leadership_restored: always(implies(count_in_role(lead) == 0, eventually("
    "count_in_role(lead) == 1 or in_mode(operator, Command))))\n"
)


def opinions(report, tmp_path) -> dict[str, spin.Opinion]:
    return {o.name: o for o in spin.cross_check(report, tmp_path / "spin")}


@needs_spin
def test_spin_agrees_that_the_role_protocol_holds(tmp_path):
    report = verify(
        roles_team(tmp_path, "a", extra=RESTORED, without_c=True), Options(losses=1), replay=False
    )
    got = opinions(report, tmp_path)
    assert set(got) == {"one_leader", "b_answered", "leadership_restored"}
    assert all(o.ours is True and o.spin is True for o in got.values())
    assert "deadlock" not in got  # not a temporal property: not compared


@needs_spin
def test_spin_finds_the_mutants_violations_too(tmp_path):
    # the leader stays Lead after granting: two leaders (an invariant)
    stays = mutate(GRANT, GRANT.replace("        - to: Follow\n          on:", "        - on:"))
    report = verify(roles_team(tmp_path, "b", stays), Options(losses=0), replay=False)
    got = opinions(report, tmp_path)
    assert got["one_leader"].ours is False and got["one_leader"].spin is False
    assert got["b_answered"].agrees
    # duplicate suppression off: leadership lost for good (a response property)
    nodedupe = mutate(
        "  accept: {ack: {timeout: ack_timeout, retries: ack_retries}}",
        "  accept: {ack: {timeout: ack_timeout, retries: ack_retries, dedupe: false}}",
    )
    report = verify(
        roles_team(tmp_path, "a", nodedupe, extra=RESTORED, without_c=True),
        Options(losses=1),
        replay=False,
    )
    got = opinions(report, tmp_path)
    assert got["leadership_restored"].ours is False
    assert got["leadership_restored"].spin is False
    assert all(o.agrees for o in got.values())


@needs_spin
def test_cli_spin_flag_reports_agreement(tmp_path, capsys):
    team = tmp_path / "team.yaml"
    roles_team(tmp_path, "b", without_c=True)  # writes team.yaml beside its protocol
    code = main(
        [
            "verify",
            str(team),
            "--losses",
            "0",
            "--spin",
            "-o",
            str(tmp_path / "o"),
            "--progress",
            "none",
        ]
    )
    out = capsys.readouterr().out
    assert code == 0
    assert "spin: one_leader: agrees (holds)" in out
    data = json.loads((tmp_path / "o" / "verify.json").read_text())
    assert data["spin"]["one_leader"] == {"ours": True, "spin": True, "agrees": True, "note": ""}
    assert (tmp_path / "o" / "spin" / "skeleton.pml").is_file()


def test_cli_spin_without_spin_says_why_and_goes_on(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(spin, "TOOLS", ("no-such-model-checker",))
    team = tmp_path / "team.yaml"
    roles_team(tmp_path, "b", without_c=True)
    code = main(
        [
            "verify",
            str(team),
            "--losses",
            "0",
            "--spin",
            "-o",
            str(tmp_path / "o"),
            "--progress",
            "none",
        ]
    )
    assert code == 0  # the verdicts stand; only the second opinion is missing
    assert "spin: skipped: 'no-such-model-checker' not found on PATH" in capsys.readouterr().out
    data = json.loads((tmp_path / "o" / "verify.json").read_text())
    assert data["spin"] == {"skipped": "'no-such-model-checker' not found on PATH"}
