"""``verify``'s bounds (:mod:`hybridteam.verify.bounds`): a skeleton that is not finite (an
unbounded counter) stops, naming the variable; a team too big for the engine's batch is
taken in smaller batches or refused with an estimate; a process past ``--max-memory``
stops. Each bound is reported, and the states left unexpanded are not dead ends."""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

from hybridteam import load
from hybridteam.cli import main
from hybridteam.engine.compile.compiler import compile_team
from hybridteam.engine.run.budget import memory_estimate
from hybridteam.verify import Options, verify

COUNTERS = """\
team: counters
agents:
  a:
    plant: {kind: flow, state: {x: 0.0}}
    variables: {n: 0}
    modes:
      A:
        transitions:
          - {to: A, after: 1, do: [n = n + 1]}
  b:
    plant: {kind: flow, state: {x: 0.0}}
    variables: {m: 0}
    modes:
      B:
        transitions:
          - {to: B, after: 2, do: [m = m + 2]}
simulation: {duration: 10}
"""

BOUNDED = """\
team: bounded
agents:
  a:
    plant: {kind: flow, state: {x: 0.0}}
    variables: {n: 0}
    modes:
      A:
        transitions:
          - {to: A, after: 1, guard: n < 5, do: [n = n + 1]}
simulation: {duration: 10}
"""


def roles(k: int) -> str:
    """A role team of ``k`` robots (one leader) and the operator, with a request."""
    robot = (
        "  {name}:\n    plant: {{kind: unicycle, state: {{x: {x}, y: 0, theta: 0}}}}\n"
        "{var}    modes:\n      Transport:\n        protocol: role_assignment\n"
        "        initial: {initial}\n        roles:\n"
        "          lead: {{inputs: {{v: 0.1, omega: 0}}}}\n"
        "          follow: {{inputs: {{v: 0.1, omega: 0}}}}\n"
    )
    agents = "".join(
        robot.format(
            name=f"r{i}",
            x=-i,
            initial="Lead" if i == 0 else "Follow",
            var="" if i == 0 else "    variables: {leader: id_r0}\n",
        )
        for i in range(k)
    )
    return (
        f"team: roles{k}\nagents:\n{agents}  operator:\n    operator: role_assignment\n"
        "scenario:\n  - {at: 1.0, agent: r1, raise: want_lead}\nsimulation:\n"
        "  duration: 2.0\n"
    )


def team_of(tmp_path: Path, text: str, name: str = "team.yaml"):
    path = tmp_path / name
    path.write_text(text)
    return load(path)


def test_two_unbounded_counters_stop_at_the_value_bound_naming_the_variable(tmp_path):
    # n takes i, m takes 2j after i and j firings; level d holds the d + 1 states with
    # i + j = d. n's 11th value (10) appears at level 10: levels 0..10 hold 1 + ... + 11
    # = 66 states, and the exploration stops there, n named first (agent a)
    report = verify(team_of(tmp_path, COUNTERS), Options(max_values=10), replay=False)
    g = report.graph
    assert len(g.states) == 66
    assert not g.exhaustive
    assert g.bound is not None and g.bound.startswith(
        "variable 'n' of agent 'a' took more than 10 different values (0 to 10 so far)"
    )
    assert len(g.cut) == 11  # the last level's states: unknown successors, not dead ends
    assert not g.terminal()[sorted(g.cut)].any()
    assert report.summary()["bound"] == g.bound


def test_a_counter_bounded_by_a_guard_is_explored_to_its_end(tmp_path):
    report = verify(team_of(tmp_path, BOUNDED), replay=False)
    assert len(report.graph.states) == 6  # n = 0..5
    assert report.graph.exhaustive and report.graph.bound is None


def test_a_counter_on_the_command_line_ends_with_the_variable_named(tmp_path, capsys):
    (tmp_path / "team.yaml").write_text(
        COUNTERS.split("  b:\n")[0] + "simulation: {duration: 10}\n"
    )
    out = tmp_path / "out"
    assert main(["verify", str(tmp_path / "team.yaml"), "-o", str(out), "--progress", "log"]) == 0
    printed, progress = capsys.readouterr()
    # the progress stream says so as soon as exploring stops (before any replay)
    assert "hybridteam: verify: stopped: variable 'n' of agent 'a'" in progress
    # the default bound: 257 values 0..256, one state each
    assert "skeleton of 257 states" in printed
    assert "bounded: not exhaustive" in printed
    assert (
        "  stopped: variable 'n' of agent 'a' took more than 256 different values "
        "(0 to 256 so far)" in printed
    )
    assert "deadlock: holds (bounded)" in printed
    summary = json.loads((out / "verify.json").read_text())
    assert summary["bound"].startswith("variable 'n' of agent 'a'")
    assert summary["options"]["max_values"] == 256


def test_the_inbox_estimate_grows_with_the_square_of_the_agents(tmp_path):
    # role_assignment's stream 'state' carries 7 fields; each agent keeps, per sender,
    # the fields and the send time: k * k * 8 numbers of 8 bytes per instance
    small = compile_team(team_of(tmp_path, roles(10), "r10.yaml"))
    large = compile_team(team_of(tmp_path, roles(20), "r20.yaml"))
    one_small = memory_estimate(small, 1, 0.0, 1.0)[0]
    one_large = memory_estimate(large, 1, 0.0, 1.0)[0]
    assert one_small >= 8 * 11 * 11 * 8 and one_large >= 8 * 21 * 21 * 8
    # the growth from 11 to 21 agents: the inbox's (21² - 11²) * 64 bytes, plus ten more
    # agents' linear share (under 2 kB each)
    growth = one_large - one_small
    assert 8 * 8 * (21 * 21 - 11 * 11) <= growth <= 8 * 8 * (21 * 21 - 11 * 11) + 10 * 2000


def test_a_big_team_is_taken_in_batches_that_fit_half_the_memory_limit(tmp_path):
    team = team_of(tmp_path, roles(60))
    one = 8 * 61 * 61 * 8  # the inbox of one instance, the bulk of its estimate
    limit = 20e6
    report = verify(team, Options(max_memory=limit, max_states=50), replay=False)
    batch = report.graph.batch
    assert 1 <= batch < 2048
    assert batch * one <= limit / 2  # not the default 2048 * 238 kB = 488 MB
    # and not needlessly small: each agent adds under 2 kB beside the inbox
    assert batch >= limit / 2 / (one + 61 * 2000)


def test_a_team_whose_one_state_does_not_fit_is_refused_with_the_estimate(tmp_path, capsys):
    (tmp_path / "team.yaml").write_text(roles(60))
    code = main(
        [
            "verify",
            str(tmp_path / "team.yaml"),
            "-o",
            str(tmp_path / "out"),
            "--max-memory",
            "0.0002",
        ]
    )
    err = capsys.readouterr().err
    assert code == 2
    # the inbox (61 agents, 8 numbers per sender) and the Zeno rings (100 transition times
    # each), plus under 2 kB of each agent's other arrays
    about = re.match(r"hybridteam: error: verify would need about ([\d.]+) kB", err)
    floor = 8 * 61 * 61 * 8 + 61 * 100 * 8
    assert about is not None and floor <= float(about.group(1)) * 1e3 <= floor + 61 * 2000
    assert "more than 50% of the limit of 200 kB: raise the limit (--max-memory GB)" in err
    assert len(err.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists()


def test_a_process_past_the_memory_limit_stops_and_says_so(tmp_path, monkeypatch):
    # the resident size is the system's; here it reads 5 GB from the first batch on
    monkeypatch.setattr(sys.modules["hybridteam.verify.explore"], "resident_bytes", lambda: 5e9)
    # (the Python loop, which checks after each batch; the compiled one after each level:
    # tests/verify/test_verify_kernel.py)
    opts = Options(max_memory=4e9, kernel="off")
    report = verify(team_of(tmp_path, COUNTERS), opts, replay=False)
    g = report.graph
    assert (
        g.bound == "this process reached the memory limit of 4 GB after 3 states "
        "(5.000 GB resident; --max-memory GB raises it)"
    )
    assert len(g.states) == 3 and not g.exhaustive
    assert g.cut == {0, 1, 2}  # the first level and its successors: none is a dead end
    assert not g.terminal().any()


def test_bad_bounds_are_usage_errors(tmp_path, capsys):
    (tmp_path / "team.yaml").write_text(BOUNDED)
    for flag, value, words in (
        ("--max-values", "0", "--max-values must be at least 1"),
        ("--max-memory", "nan", "--max-memory must be a finite number > 0, got nan"),
    ):
        assert (
            main(["verify", str(tmp_path / "team.yaml"), "-o", str(tmp_path / "o"), flag, value])
            == 2
        )
        assert words in capsys.readouterr().err


def test_the_300_robot_team_runs_within_the_memory_limit(tmp_path, monkeypatch):
    # each instance's inboxes alone: 301 agents x 301 senders x 8 numbers x 8 bytes = 5.8 MB;
    # the default batch of 2048 would take 11.9 GB (an allocation error, before the bound).
    # The resident-memory watch reads the whole process, here pytest's with every module an
    # earlier test loaded (over 1 GB in the full suite): it is tested on its own below, and
    # left out here, where the batch's size is the point
    monkeypatch.setattr(sys.modules["hybridteam.verify.explore"], "resident_bytes", lambda: None)
    team = team_of(tmp_path, roles(300))
    report = verify(team, Options(max_memory=1e9, max_states=2), replay=False)
    g = report.graph
    assert g.batch * 8 * 301 * 301 * 8 <= 0.5e9
    assert len(g.states) == 2 and g.bound == "--max-states 2 reached"
