"""Partial search (``--storage hashcompact|bitstate``): the visited sets keep and find
hashes, their omission estimates are the closed forms, a partial search of the verify
test models finds every invariant and deadlock counterexample the exact one finds (the
same states, paths and replays), says it is partial with its coverage, and refuses what
it cannot check with one message."""

from __future__ import annotations

import json
import math
import random
from dataclasses import replace

import numpy as np
import pytest

from hybridteam.cli import main
from hybridteam.verify import NotInPartialSearch, Options, verify
from hybridteam.verify.properties import PARTIAL_LIVENESS
from hybridteam.verify.storage import Bitstate, HashCompact, PartialStore, digest, omissions
from tests.verify.test_verify import (
    GRANT,
    NO_OPERATOR,
    REQUEST,
    docking,
    mutate,
    roles_team,
    verdicts,
)


def _keys(n: int, seed: int) -> list[bytes]:
    rng = random.Random(seed)
    return [rng.randbytes(12) for _ in range(n)]


def test_hashcompact_finds_every_hash_after_the_table_grows():
    table = HashCompact(slots=16)
    keys = _keys(3000, 1)
    for k in keys:
        assert not table.contains(digest(k))
        table.add(digest(k))
    assert table.count == 3000 and table.mask + 1 >= 6000  # grew from 16 slots, half full
    assert all(table.contains(digest(k)) for k in keys)
    assert not any(table.contains(digest(k)) for k in _keys(3000, 2))
    # the expected omissions: each of n states meets each earlier hash w.p. 2**-64
    c = table.coverage(3000)
    assert c.expected_omissions == 3000 * 2999 / 2**65
    # the chance of any: 1 - (1 - 2**-64)**(pairs), to first order the expectation
    assert c.any_omission == pytest.approx(3000 * 2999 / 2**65, rel=1e-6)


def test_bitstate_omission_estimate_is_the_bloom_filter_closed_form():
    # one hash function: the i-th state is taken for a visited one with probability
    # 1 - exp(-i/m); summed, n - (1 - exp(-n/m)) / (1 - exp(-1/m)) (a geometric series)
    n, m = 5000, 20_000
    closed = n - (1 - math.exp(-n / m)) / (1 - math.exp(-1 / m))
    assert omissions(n, m, 1) == pytest.approx(closed, rel=1e-9)
    # and the filter's false positives are what the formula says: n keys in, then
    # fresh keys probed, each a false positive w.p. (1 - exp(-k n / m))**k
    bits = Bitstate(megabytes=8192 / 2**20, hash_functions=3)  # 65,536 bits
    for k in _keys(8000, 3):
        bits.add(digest(k))
    p = (1 - math.exp(-3 * 8000 / bits.m)) ** 3  # 0.0288
    probes = 20_000
    hits = sum(bits.contains(digest(k)) for k in _keys(probes, 4))
    sd = math.sqrt(probes * p * (1 - p))  # binomial: about 24 of about 576
    assert abs(hits - probes * p) < 4 * sd
    c = bits.coverage(8000)
    assert c.hash_factor == 65_536 / 8000 and c.hash_functions == 3
    assert c.expected_omissions == omissions(8000, 65_536, 3)


def test_a_partial_search_of_a_holding_protocol_has_the_exact_counts(tmp_path):
    team = roles_team(tmp_path, "b")
    exact = verify(team, Options(losses=1), replay=False)
    for storage in ("hashcompact", "bitstate"):
        r = verify(team, Options(losses=1, storage=storage), replay=False)
        g = r.graph
        assert isinstance(g.states, PartialStore)
        assert len(g.states) == len(exact.graph.states)  # no omission at this size
        assert g.transitions == exact.graph.transitions
        assert len(g.edges) == len(exact.graph.edges)
        assert list(g.parent) == list(exact.graph.parent)
        assert not g.exhaustive and g.coverage is not None and g.coverage.storage == storage
        v = verdicts(r)
        assert v["one_leader"].holds is True and v["deadlock"].holds is True
        assert v["b_answered"].holds is None and v["b_answered"].message == PARTIAL_LIVENESS
        summary = r.summary()
        assert summary["search"] == "partial" and summary["exhaustive"] is False
        assert summary["properties"]["one_leader"]["verdict"] == "holds (partial search)"
        assert summary["coverage"]["estimated_coverage"] > 0.999999
        # a state no longer held whole is computed again along its path: the same state
        k = len(g.states) - 1
        assert g.states[k] == exact.graph.states[k] and g.states[0] == exact.graph.states[0]


def test_a_small_bit_array_omits_states_and_says_so(tmp_path):
    team = roles_team(tmp_path, "b")
    exact = verify(team, Options(losses=1), replay=False)
    # 4,096 bits for 2,275 states: a hash factor below 2, many omissions
    r = verify(team, Options(losses=1, storage="bitstate", bitstate_mb=512 / 2**20), replay=False)
    c = r.graph.coverage
    assert c is not None and c.states == len(r.graph.states) < len(exact.graph.states)
    assert c.hash_factor == 4096 / c.states and c.hash_factor < 4
    assert c.expected_omissions > 1 and c.coverage < 0.99
    assert c.any_omission == pytest.approx(1 - math.exp(-c.expected_omissions), rel=1e-12)
    assert "PARTIAL search (bitstate" in c.words() and "expected omissions" in c.words()


BAD_GRANT = mutate(GRANT, GRANT.replace("        - to: Follow\n          on:", "        - on:"))
BAD_REQUEST = mutate(REQUEST, REQUEST.replace("to: Requesting", "to: Lead"))
CONFIRM_ALL = mutate(
    "        - {on: accept, do: [{send: reject, to: sender}]}",
    "        - {on: accept, do: [{send: confirm, to: sender}]}",
)
DENY = "        - on: request\n          do: [{send: deny, to: sender}]\n        - to: Offering"
SAFETY_MUTANTS = {  # the invariant counterexamples of test_verify.py
    "leader_stays_lead": ("b", BAD_GRANT, "", Options(losses=0), "one_leader"),
    "requester_leads": ("b", BAD_REQUEST, "", Options(losses=0), "one_leader"),
    "offer_confirmed_to_all": ("a", CONFIRM_ALL, "", Options(losses=0), "one_leader"),
    "operator_called_on_own_timeouts": (
        "bc",
        mutate(DENY, "        - to: Offering"),
        NO_OPERATOR,
        Options(losses=0, timeouts="own"),
        "no_operator",
    ),
}


def _same_counterexamples(team, opts: Options, name: str, storages: tuple[str, ...]) -> None:
    exact = verify(team, opts)
    e = verdicts(exact)[name]
    assert e.holds is False
    for storage in storages:
        partial = verify(team, replace(opts, storage=storage))
        p = verdicts(partial)[name]
        assert p.holds is False and (p.state, p.others) == (e.state, e.others)
        assert partial.counterexample(p) == exact.counterexample(e)
        assert partial.configurations(p) == exact.configurations(e)
        _, r, _ = partial.replays[name]
        assert r.reproduced and partial.replays[name][0] == exact.replays[name][0]


@pytest.mark.parametrize(
    "mutant",
    [
        pytest.param(m, marks=[pytest.mark.slow] if SAFETY_MUTANTS[m][0] != "b" else [])
        for m in sorted(SAFETY_MUTANTS)
    ],
)
def test_partial_search_finds_every_invariant_counterexample(tmp_path, mutant):
    """(The mutants with the scenario's first request alone are small; the others take
    seconds, three explorations each.)"""
    events, protocol, extra, opts, name = SAFETY_MUTANTS[mutant]
    team = roles_team(tmp_path, events, protocol, extra)
    _same_counterexamples(team, opts, name, ("hashcompact", "bitstate"))


@pytest.mark.slow
def test_partial_search_finds_the_docking_deadlock(tmp_path):
    team = docking(tmp_path, False)
    _same_counterexamples(team, Options(losses=1), "deadlock", ("hashcompact",))


def test_responses_are_refused_in_a_partial_search(tmp_path, capsys):
    team = roles_team(tmp_path, "b")
    with pytest.raises(NotInPartialSearch, match="'b_answered' is a response"):
        verify(team, Options(losses=0, storage="bitstate"), only=["b_answered"])
    out = tmp_path / "out"
    base = ["verify", str(tmp_path / "team.yaml"), "-o", str(out), "--progress", "none"]
    assert main([*base, "--storage", "hashcompact", "-p", "b_answered"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "needs the whole state graph" in err[0]
    assert not out.exists()


@pytest.mark.parametrize(
    ("flags", "words"),
    [
        (["--storage", "bitstate", "--bitstate-mb", "0"], "--bitstate-mb must be"),
        (["--storage", "bitstate", "--bitstate-mb", "nan"], "--bitstate-mb must be"),
        (["--storage", "bitstate", "--hash-functions", "0"], "--hash-functions must be 1 to 32"),
        (
            ["--storage", "bitstate", "--bitstate-mb", "1024", "--max-memory", "1"],
            "--bitstate-mb 1024: the bit array would take more than half of the memory "
            "limit of 1 GB",
        ),
        (["--bitstate-mb", "8"], "--bitstate-mb applies to --storage bitstate, not exact"),
        (["--storage", "hashcompact", "--hash-functions", "2"], "applies to --storage bitstate"),
        (["--storage", "hashcompact", "--spin"], "--spin compares a whole exploration"),
        (["--storage", "bitstate", "--spin-rules"], "--spin-rules compares a whole exploration"),
        (["--jobs", "0"], "--jobs must be at least 1, got 0"),
    ],
)
def test_bad_storage_and_jobs_flags_are_one_message_exit_2(tmp_path, capsys, flags, words):
    roles_team(tmp_path, "b")
    out = tmp_path / "out"
    assert main(["verify", str(tmp_path / "team.yaml"), "-o", str(out), *flags]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words in err[0] and "Traceback" not in err[0]
    assert not out.exists()


def test_cli_says_partial_with_its_coverage(tmp_path, capsys):
    roles_team(tmp_path, "b", BAD_REQUEST)
    out = tmp_path / "out"
    argv = ["verify", str(tmp_path / "team.yaml"), "--losses", "0", "-o", str(out)]
    assert main([*argv, "--progress", "none", "--storage", "bitstate"]) == 1
    printed = capsys.readouterr().out
    assert "PARTIAL search (bitstate, 64.0 MB, hash factor" in printed
    assert "exhaustive" not in printed.replace("not exhaustive", "")
    assert "one_leader: VIOLATED" in printed and "replayed in the simulator: REPRODUCED" in printed
    assert "b_answered: NOT CHECKED (partial search: a response needs" in printed
    summary = json.loads((out / "verify.json").read_text())
    assert summary["search"] == "partial" and summary["exhaustive"] is False
    cov = summary["coverage"]
    assert cov["hash_functions"] == 3 and cov["hash_factor"] == 64 * 2**23 / summary["states"]
    assert summary["options"]["storage"] == "bitstate" and summary["options"]["bitstate_mb"] == 64
    assert np.isclose(cov["expected_omissions"], omissions(summary["states"], 64 * 2**23, 3))


@pytest.mark.parametrize(
    ("options", "words"),
    [
        (Options(storage="hash"), "no partial storage 'hash'"),
        (Options(storage="bitstate", bitstate_mb=0), "with 0 MB"),
        (Options(storage="bitstate", hash_functions=0), "and 0 hash functions"),
        (Options(jobs=0), "jobs must be at least 1, got 0"),
    ],
)
def test_the_api_refuses_bad_storage_and_jobs(tmp_path, options, words):
    with pytest.raises(ValueError, match=words):
        verify(roles_team(tmp_path, "b"), options, replay=False)
