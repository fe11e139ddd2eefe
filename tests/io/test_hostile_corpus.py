"""A corpus of hostile and degenerate inputs, one case per way a file, an argument or an
output folder can go wrong: each must give exit 0 with a diagnosed outcome, or exit 2 with
one clear message naming file:line and field — never a traceback, never a hang (every
case runs under a 5 s alarm), never a folder that looks complete when it is not.

Each case writes its files into a fresh folder and runs the command line in-process.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from hybridteam.cli import main

FLOW = """\
team: h
parameters: {{c: 1.0}}
agents:
  a:
    plant: {{kind: flow, state: {{x: 1.0}}}}
    initial: A
    modes:
      A:
        flow: {{x: "{flow}"}}
simulation: {{duration: {duration}{extra}}}
"""

NET = """\
team: n
parameters: {{lat: 0.05, d: 1.0, r: 10.0, k: 0.2}}
network: {{latency: "{latency}", loss: "{loss}"}}
messages:
  ping: {{ack: {{timeout: "{timeout}", retries: 2}}}}
agents:
  a:
    plant: {{kind: unicycle, state: {{x: 0, y: 0, theta: 0}}}}
    initial: A
    modes:
      A:
        transitions:
          - {{to: B, after: "{after}", do: [{{send: ping}}]}}
      B: {{}}
  b:
    plant: {{kind: unicycle, state: {{x: 0, y: 0, theta: 0}}}}
    modes: {{W: {{}}}}
simulation: {{duration: 2.0}}
"""

ROBOT = """\
team: r
agents:
  r:
    plant: {{kind: unicycle, state: {{x: 0, y: 0, theta: 0}}{limits}}}
    modes:
      Go: {{{body}}}
simulation: {{duration: {duration}{extra}}}
"""

STUDY = """\
kind: study
team: team.yaml
population: {{size: {size}{draws}}}
factors: {{c: {values}}}
repetitions: {reps}
"""

SAWTOOTH = """\
team: saw
agents:
  a:
    plant: {kind: flow, state: {x: 0.0}}
    modes:
      Up:
        flow: {x: 1}
        transitions: [{to: Up, guard: x >= 1, do: [x = 0]}]
simulation: {duration: 1e12, sample_period: 1e9}
"""

PROTOCOL = """\
kind: protocol
protocol: p
parameters: {rate: 0}
streams:
  - {message: state, rate: rate, fields: {x: x}}
region:
  roles: [go]
  initial: Going
  modes:
    Going: {role: go}
"""

USERLAWS = """\
import numpy as np
from hybridteam.library import law

@law("corpus.flat")
def flat(ctx):
    return np.zeros(ctx.size)

@law("corpus.asks")
def asks(ctx):
    return np.column_stack([ctx["no_such_name"], ctx["no_such_name"]])

@law("corpus.builds")
def builds(ctx):
    name = "no_" + "such"  # a name made at run time: only the run can tell
    return np.column_stack([ctx[name], ctx[name]])
"""


def flow(f: str, duration: float = 2.0, extra: str = "") -> str:
    return FLOW.format(flow=f, duration=duration, extra=extra)


def net(latency="lat", loss="0", timeout="k", after="d") -> str:
    return NET.format(latency=latency, loss=loss, timeout=timeout, after=after)


def robot(body="inputs: {v: 0.1, omega: 0}, period: 0.1", limits="", duration=2.0, extra="") -> str:
    return ROBOT.format(body=body, limits=limits, duration=duration, extra=extra)


def study(size=2, values="[0.5, 1.0]", reps=1, draws="") -> str:
    return STUDY.format(size=size, values=values, reps=reps, draws=draws)


@dataclass
class Case:
    files: dict[str, str]
    argv: list[str]
    code: int
    expect: list[str]  # substrings of stderr (exit 2) or stdout + summary.json (exit 0)
    outcome: str | None = None  # the run's outcome in summary.json
    absent: list[str] = field(default_factory=list)  # files that must not exist after


RUN = ["run", "team.yaml", "-o", "out", "--quiet"]

CASES: dict[str, Case] = {
    # --- numerical failure: an outcome, fast -------------------------------------------
    "flow_divides_by_zero": Case(
        {"team.yaml": flow("1/(x-c)")},
        RUN,
        0,
        ["the derivative of state 'x' is inf"],
        "numerical_error",
    ),
    "flow_sqrt_negative": Case(
        {"team.yaml": flow("sqrt(-x)")},
        RUN,
        0,
        ["the derivative of state 'x' is nan"],
        "numerical_error",
    ),
    "flow_overflows": Case(
        {"team.yaml": flow("exp(1000*x)")},
        RUN,
        0,
        ["is inf (flow x: exp(1000*x))"],
        "numerical_error",
    ),
    "flow_log_zero": Case({"team.yaml": flow("log(x-c)")}, RUN, 0, ["is -inf"], "numerical_error"),
    "flow_fast_oscillation": Case(
        {"team.yaml": flow("1e6*sin(1e6*t)")}, RUN, 0, ["step size fell to"], "stiff"
    ),
    "flow_stiff": Case({"team.yaml": flow("-1e9*x")}, RUN, 0, ["below 2e-06 s"], "stiff"),
    "flow_blows_up": Case({"team.yaml": flow("x*x")}, RUN, 0, ["step size fell to"], "stiff"),
    "input_infinite": Case(
        {"team.yaml": robot("inputs: {v: 1/(1-t), omega: 0}, period: 0.25")},
        RUN,
        0,
        ["input 'v' is inf"],
        "numerical_error",
    ),
    "input_nan": Case(
        {"team.yaml": robot("inputs: {v: sqrt(t-1), omega: 0}, period: 0.25")},
        RUN,
        0,
        ["input 'v' is nan"],
        "numerical_error",
    ),
    # --- values out of range, at their file:line ----------------------------------------
    "set_nan": Case(
        {"team.yaml": net()},
        [*RUN, "--set", "lat=nan"],
        2,
        ["override 'lat': nan (instance 0) is not a finite number"],
    ),
    "set_inf": Case({"team.yaml": net()}, [*RUN, "--set", "lat=inf"], 2, ["override 'lat': inf"]),
    "set_makes_loss_above_one": Case(
        {"team.yaml": net(loss="lat*10")},
        [*RUN, "--set", "lat=0.2"],
        2,
        [
            "team.yaml:3:33: network.loss: the link's loss 'lat*10' is "
            "2.0 in instance 0; it must be a number in [0, 1]"
        ],
    ),
    "negative_latency_expression": Case(
        {"team.yaml": net(latency="lat - 1")},
        RUN,
        2,
        [
            "team.yaml:3:20: network.latency: the link's latency "
            "'lat - 1' is -0.95; it must be a number >= 0"
        ],
    ),
    "loss_above_one": Case(
        {"team.yaml": net(loss="1.5")},
        RUN,
        2,
        ["team.yaml:3:33: network.loss: a loss probability is at most 1, got 1.5"],
    ),
    "negative_after_expression": Case(
        {"team.yaml": net(after="d - 0.5")},
        [*RUN, "--set", "d=0.25"],
        2,
        [
            "team.yaml:13:28: agents.a.modes.A.transitions[0].after: "
            "the delay 'd - 0.5' is -0.25 in instance 0; it must be a "
            "number >= 0"
        ],
    ),
    "zero_ack_timeout": Case(
        {"team.yaml": net(timeout="k - 0.2")},
        RUN,
        2,
        ["messages.ping.ack.timeout: the ack timeout 'k - 0.2' is 0.0"],
    ),
    "nan_latency_literal": Case(
        {"team.yaml": net().replace('"lat"', ".nan")},
        RUN,
        2,
        ["network.latency: expected a finite number, got nan"],
    ),
    "infinite_speed_limit": Case(
        {"team.yaml": robot(limits=", limits: {v: [-1, .inf]}")},
        RUN,
        2,
        ["agents.r.plant.limits.v[1]: expected a finite number"],
    ),
    "nan_actuator_limit": Case(
        {"team.yaml": robot(limits=", limits: {v: [.nan, 1]}")},
        RUN,
        2,
        ["agents.r.plant.limits.v[0]: expected a finite number, got nan"],
    ),
    "duration_inf": Case(
        {"team.yaml": robot(duration=".inf")},
        RUN,
        2,
        ["team.yaml:7:24: simulation.duration: expected a finite number"],
    ),
    "duration_1e999": Case(
        {"team.yaml": robot(duration="1e999")},
        RUN,
        2,
        ["simulation.duration: expected a finite number, got inf"],
    ),
    "sample_period_inf": Case(
        {"team.yaml": robot(extra=", sample_period: .inf")},
        RUN,
        2,
        ["simulation.sample_period: expected a finite number"],
    ),
    "component_setting_nan": Case(
        {
            "team.yaml": robot() + "world:\n  - {use: payload, with: {width: 0/0, grasps: "
            "[{agent: r}]}}\n"
        },
        RUN,
        2,
        ["world[0].with.width: setting 'width' '0/0' is nan in instance 0"],
    ),
    "stream_rate_zero": Case(
        {
            "team.yaml": robot(
                "protocol: p.yaml, roles: {go: {inputs: {v: 0.1, omega: 0}, period: 0.1}}"
            ),
            "p.yaml": PROTOCOL,
        },
        RUN,
        2,
        [
            "p.yaml:5:28: streams[0].rate: 1 / rate 'rate' is inf in "
            "instance 0; it must be a number > 0"
        ],
    ),
    # --- resources: refused before allocation -------------------------------------------
    "duration_1e12": Case(
        {"team.yaml": robot()}, [*RUN, "--duration", "1e12"], 2, ["of memory", "--max-memory"]
    ),
    "tiny_sample_period": Case(
        {"team.yaml": robot(extra=", sample_period: 1e-12")},
        RUN,
        2,
        ["output samples", "raise simulation.sample_period"],
    ),
    "huge_ensemble": Case(
        {"team.yaml": robot()}, [*RUN, "-n", "1000000000"], 2, ["1,000,000,000 instance(s)"]
    ),
    "law_periods": Case(
        {
            "team.yaml": robot(
                body="inputs: {v: 0.1, omega: 0}, period: 1e-6", extra=", sample_period: 100"
            )
        },
        [*RUN, "--duration", "1000"],
        2,
        ["1e+09 control periods"],
    ),
    "pace_projects_years": Case(
        {"team.yaml": SAWTOOTH}, RUN, 2, ["of wall time at its pace", "--max-wall HOURS"]
    ),
    "max_memory_negative": Case(
        {"team.yaml": robot()},
        [*RUN, "--max-memory", "-1"],
        2,
        ["--max-memory must be a finite number > 0"],
    ),
    "duration_nan_argument": Case(
        {"team.yaml": robot()},
        [*RUN, "--duration", "nan"],
        2,
        ["--duration must be a finite number >= 0, got nan"],
    ),
    "file_too_large": Case(
        {
            "team.yaml": "team: x\nparameters: {"
            + ", ".join(f"p{i}: {i}" for i in range(120000))
            + "}\n"
        },
        RUN,
        2,
        ["team.yaml: file is 1.8 MB; model files are read up to 1 MB"],
    ),
    "alias_bomb": Case(
        {
            "team.yaml": "a: &a [x, x, x, x, x, x, x, x, x]\n"
            + "".join(
                f"{c}: &{c} [*{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}]\n"
                for p, c in zip("abcdefgh", "bcdefghi", strict=True)
            )
            + "team: x\n"
        },
        RUN,
        2,
        ["alias"],
    ),
    "deep_nesting": Case(
        {"team.yaml": "team: x\nagents: " + "[" * 500 + "]" * 500 + "\n"},
        RUN,
        2,
        ["nested too deeply"],
    ),
    "study_1e9_runs": Case(
        {"team.yaml": flow("c"), "s.yaml": study(reps=500_000_000)},
        ["sweep", "s.yaml", "-o", "sout", "--quiet"],
        2,
        [
            "s.yaml:5:14: repetitions: this study asks for 2,000,000,000 runs (2 "
            "settings x 2 members x 500,000,000 repetitions), more than the "
            "10,000,000 a study may plan"
        ],
    ),
    "study_population_1e18": Case(
        {"team.yaml": flow("c"), "s.yaml": study(size=10**18)},
        ["sweep", "s.yaml", "-o", "sout", "--quiet"],
        2,
        ["population.size: this study asks for 2,000,000,000,000,000,000 runs"],
    ),
    "study_integers_1e30": Case(
        {
            "team.yaml": flow("c"),
            "s.yaml": study(draws=", draws: {c: {integers: [0, 1e30]}}").replace(
                "factors: {c: [0.5, 1.0]}", "factors: {}"
            ),
        },
        ["sweep", "s.yaml", "-o", "sout", "--quiet"],
        2,
        ["s.yaml:3:49: population.draws.c.integers[1]: Unable to parse input string as an integer"],
    ),
    "study_empty_factor": Case(
        {"team.yaml": flow("c"), "s.yaml": study(values="[]")},
        ["validate", "s.yaml"],
        2,
        ["s.yaml:4:14: factors.c"],
    ),
    # --- outputs: one line, exit 2, nothing that looks complete -------------------------
    "output_under_proc": Case(
        {"team.yaml": robot()},
        ["run", "team.yaml", "-o", "/proc/hybridteam", "--quiet"],
        2,
        ["cannot write /proc/hybridteam"],
    ),
    "output_is_a_file": Case(
        {"team.yaml": robot(), "out": "x"}, RUN, 2, ["output 'out' exists and is not a folder"]
    ),
    "trace_json_is_a_directory": Case(
        {"team.yaml": robot(), "out/trace.json/x": ""},
        RUN,
        2,
        ["cannot write out/trace.json: Is a directory; out/ is incomplete (INCOMPLETE marks it)"],
        absent=["out/summary.json"],
    ),
    "run_into_study_folder": Case(
        {"team.yaml": robot(), "out/study.json": "{}"}, RUN, 2, ["holds a study's results"]
    ),
    "study_into_run_folder": Case(
        {"team.yaml": flow("c"), "s.yaml": study(), "sout/summary.json": "{}"},
        ["sweep", "s.yaml", "-o", "sout", "--quiet"],
        2,
        ["holds the outputs of 'hybridteam run'"],
    ),
    "report_not_a_study": Case(
        {"folder/x.txt": "x"}, ["report", "folder"], 2, ["no study.json here"]
    ),
    # --- traces as input ----------------------------------------------------------------
    "trace_list": Case(
        {"t.json": "[1, 2]"},
        ["plot", "t.json", "-o", "p.png"],
        2,
        ["not a valid hybridteam trace: expected a JSON object"],
    ),
    "trace_null": Case(
        {"t.json": "null"}, ["timeline", "t.json"], 2, ["not a valid hybridteam trace"]
    ),
    "trace_deep": Case(
        {"t.json": "[" * 100000 + "]" * 100000}, ["sequence", "t.json"], 2, ["nested too deeply"]
    ),
    "trace_not_json": Case(
        {"t.json": "{nope"}, ["animate", "t.json"], 2, ["t.json:1:2: not a JSON file"]
    ),
    "trace_is_a_directory": Case(
        {"t.json/x": ""}, ["plot", "t.json"], 2, ["is a directory, not a trace file"]
    ),
    "trace_ragged_samples": Case(
        {}, ["plot", "{ragged}", "-o", "p.png"], 2, ["samples.agents.r: expected"]
    ),
    "trace_infinite_time": Case(
        {},
        ["timeline", "{inf_t}", "-o", "p.png"],
        2,
        ["samples.t[2]: Input should be a finite number"],
    ),
    "trace_bad_instance": Case(
        {},
        ["sequence", "{bad_instance}"],
        2,
        ["transitions.instance: 7 is not an instance of 0..0"],
    ),
    "trace_short_column": Case(
        {}, ["timeline", "{short}", "-o", "p.png"], 2, ["transitions: column 't'"]
    ),
    "trace_bad_collision_mark": Case(
        {},
        ["plot", "{bad_collision}", "-o", "p.png"],
        2,
        ["meta.world.collisions[0].t: Input should be a valid number"],
    ),
    "window_infinite": Case(
        {},
        ["timeline", "{good}", "--window", "0", "inf", "-o", "p.png"],
        2,
        ["times must be finite numbers"],
    ),
    # --- user code: located at the binding ----------------------------------------------
    "law_wrong_shape": Case(
        {"team.yaml": robot("law: {use: 'userlaws:flat', period: 0.1}"), "userlaws.py": USERLAWS},
        RUN,
        2,
        [
            "team.yaml:6:23: agents.r.modes.Go.law.use: law 'corpus.flat' of "
            "agent 'r' returned shape (1,), expected (1, 2) (inputs v, omega)"
        ],
    ),
    "law_unknown_name": Case(
        {"team.yaml": robot("law: {use: 'userlaws:asks', period: 0.1}"), "userlaws.py": USERLAWS},
        ["validate", "team.yaml"],
        2,
        [
            "team.yaml:6:23: agents.r.modes.Go.law.use: law 'corpus.asks' "
            "reads ctx['no_such_name'], which is no binding parameter"
        ],
    ),
    "law_unknown_name_at_run": Case(
        {"team.yaml": robot("law: {use: 'userlaws:builds', period: 0.1}"), "userlaws.py": USERLAWS},
        RUN,
        2,
        [
            "agents.r.modes.Go.law.use: law 'corpus.builds' of agent "
            "'r' failed: KeyError: law for agent 'r' asked for unknown "
            "name 'no_such'"
        ],
    ),
    "law_code_interact": Case(
        {"team.yaml": robot("law: {use: 'code:interact'}")},
        ["validate", "team.yaml"],
        2,
        ["module 'code' is not beside the team file"],
    ),
    # --- errors located where a line exists ---------------------------------------------
    "empty_document": Case(
        {"team.yaml": ""}, ["validate", "team.yaml"], 2, ["team.yaml:1:1: file is empty"]
    ),
    "team_is_a_directory": Case(
        {"team.yaml/x": ""},
        ["validate", "team.yaml"],
        2,
        ["team.yaml: cannot read file: it is a directory"],
    ),
    "missing_team": Case(
        {}, ["validate", "none.yaml"], 2, ["none.yaml: cannot read file: No such file or directory"]
    ),
    "missing_protocol": Case(
        {"team.yaml": robot("protocol: nowhere.yaml")},
        ["validate", "team.yaml"],
        2,
        ["team.yaml:6:22: agents.r.modes.Go.protocol: unknown protocol 'nowhere.yaml'"],
    ),
    # --- round two (issue 43): resources ------------------------------------------------
    "zeno_ring_1e9": Case(
        {"team.yaml": robot(extra=", zeno: {max_transitions: 1000000000}")},
        RUN,
        2,
        [
            "about 8 GB of memory (1 instance(s) of 1 agent(s) "
            "remembering their last 1,000,000,000 transition times "
            "(simulation.zeno.max_transitions))",
            "--max-memory GB",
        ],
    ),
    "sample_period_1e-7_written": Case(
        {"team.yaml": robot(extra=", sample_period: 1e-7")},
        RUN,
        2,
        [
            "about 14.5 GB of memory (20,000,002 output samples of 1 instance(s), every 1e-07 s "
            "over 2 s, written as trace.json and samples.csv)",
            "--max-memory GB",
        ],
        absent=["out"],
    ),
    "trace_is_dev_zero": Case(
        {},
        ["timeline", "/dev/zero", "-o", "p.png"],
        2,
        ["/dev/zero: cannot read file: it is a device or socket, not a regular file"],
        absent=["p.png"],
    ),
    "trace_is_dev_urandom": Case(
        {},
        ["sequence", "/dev/urandom"],
        2,
        ["/dev/urandom: cannot read file: it is a device or socket"],
    ),
    # --- round two: what validate accepts, run must accept --------------------------------
    "requirement_constant_nan": Case(
        {"team.yaml": flow("c") + "requirements:\n  r1: always(x > sqrt(-1))\n"},
        ["validate", "team.yaml"],
        2,
        [
            "team.yaml:12:18: requirements.r1: 'sqrt(-1)' is not a "
            "number (nan): a comparison with it has no margin"
        ],
    ),
    "requirement_runtime_nan": Case(
        {"team.yaml": flow("c") + "requirements:\n  r1: always(sqrt(1.5 - x) >= 0)\n"},
        RUN,
        0,
        ['"robustness": "nan"'],
        "ok",
    ),
    "window_one_over_zero": Case(
        {"team.yaml": flow("c") + "requirements:\n  r1: always[0, 1/0](x > 0)\n"},
        ["validate", "team.yaml"],
        2,
        [
            "requirements.r1: window bounds must be numbers; this one "
            "is inf; an endless window is written inf"
        ],
    ),
    "after_sqrt_negative": Case(
        {"team.yaml": net(after="sqrt(-1)")},
        ["validate", "team.yaml"],
        2,
        [
            "team.yaml:13:28: agents.a.modes.A.transitions[0].after: "
            "the delay 'sqrt(-1)' is nan; it must be a number >= 0"
        ],
    ),
    "after_negative_parameter": Case(
        {"team.yaml": net(after="d - 2")},
        ["validate", "team.yaml"],
        2,
        ["transitions[0].after: the delay 'd - 2' is -1.0; it must be a number >= 0"],
    ),
    "event_tol_1e300": Case(
        {"team.yaml": robot(extra=", event_tol: 1e300")},
        ["validate", "team.yaml"],
        2,
        ["team.yaml:7:40: simulation.event_tol: must be <= 0.001, got 1e+300"],
    ),
    "history_on_a_leaf": Case(
        {"team.yaml": robot("inputs: {v: 0.1, omega: 0}, period: 0.1, history: deep")},
        ["validate", "team.yaml"],
        2,
        ["team.yaml:6:62: agents.r.modes.Go.history: mode 'Go' has no modes to remember"],
    ),
    "diagram_mermaid_into_png": Case(
        {"team.yaml": robot()},
        ["diagram", "team.yaml", "-f", "mermaid", "-o", "x.png"],
        2,
        ["-o x.png says png but -f says mermaid; name the file .mmd or .mermaid, or drop -f"],
        absent=["x.png"],
    ),
    # --- round two: text that is no Unicode -----------------------------------------------
    "lone_surrogate_team_name": Case(
        {"team.yaml": robot().replace("team: r", 'team: "\\ud800"')},
        RUN,
        2,
        ["team.yaml:1:7: team: U+D800 (a lone surrogate escape) cannot be written as UTF-8"],
        absent=["out"],
    ),
    "trace_lone_surrogate": Case(
        {},
        ["sequence", "{surrogate}"],
        2,
        [
            "not a valid hybridteam trace: meta.agents[0].name: U+DC00 "
            "(a lone surrogate escape) is not text"
        ],
    ),
    "lone_surrogate_agent_name": Case(
        {"team.yaml": robot().replace("  r:", '  "r\\udc00":')},
        ["validate", "team.yaml"],
        2,
        ["team.yaml:3:3: agents: U+DC00 (a lone surrogate"],
    ),
}


@pytest.fixture(scope="module")
def traces(tmp_path_factory) -> dict[str, Path]:
    """A good trace and adversarial variants of it."""
    folder = tmp_path_factory.mktemp("traces")
    team = folder / "team.yaml"
    team.write_text(robot())
    assert main(["run", str(team), "-o", str(folder / "run"), "--quiet", "--no-views"]) == 0
    good = json.loads((folder / "run" / "trace.json").read_text())
    out = {"good": folder / "run" / "trace.json"}

    def variant(name: str, change) -> None:
        data = json.loads(json.dumps(good))
        change(data)
        (folder / f"{name}.json").write_text(json.dumps(data))
        out[name] = folder / f"{name}.json"

    variant("ragged", lambda d: d["samples"]["agents"]["r"][1].append([1.0, 2.0, 3.0]))
    variant("inf_t", lambda d: d["samples"]["t"].__setitem__(2, 1e999))
    variant("bad_instance", lambda d: d["transitions"]["instance"].__setitem__(0, 7))
    variant("short", lambda d: d["transitions"]["t"].pop())
    variant(
        "bad_collision",
        lambda d: d["meta"].__setitem__(
            "world", {"collisions": [{"instance": 0, "who": "r", "t": "soon", "x": 0.0, "y": 0.0}]}
        ),
    )
    variant("surrogate", lambda d: d["meta"]["agents"][0].__setitem__("name", "r\udc00"))
    return out


# --- searches: verify, falsify and Dask (issue 43) ----------------------------------------

COUNTER = """\
team: counter
agents:
  a:
    plant: {kind: flow, state: {x: 0.0}}
    variables: {n: 0}
    modes:
      A:
        transitions:
          - {to: A, after: 1, do: [n = n + 1]}
simulation: {duration: 10}
"""


def roles(k: int) -> str:
    """A role team of ``k`` robots and the operator (its stream inboxes: k² per state)."""
    robot = (
        "  r{i}:\n    plant: {{kind: unicycle, state: {{x: {i}, y: 0, theta: 0}}}}\n"
        "    modes:\n      T:\n        protocol: role_assignment\n"
        "        initial: {initial}\n        roles:\n"
        "          lead: {{inputs: {{v: 0.1, omega: 0}}}}\n"
        "          follow: {{inputs: {{v: 0.1, omega: 0}}}}\n"
    )
    return (
        "team: roles\nagents:\n"
        + "".join(robot.format(i=i, initial="Lead" if i == 0 else "Follow") for i in range(k))
        + "  operator:\n    operator: role_assignment\nsimulation: {duration: 2.0}\n"
    )


FALSIFY = [
    "falsify",
    "team.yaml",
    "-r",
    "low",
    "--vary",
    "c=0:1",
    "-o",
    "fout",
    "--progress",
    "none",
    "--no-replay",
]
REQUIRED = flow("c") + "requirements:\n  low: always(x <= 100)\n"

CASES.update(
    {
        "verify_team_too_big": Case(
            {"team.yaml": roles(60)},
            ["verify", "team.yaml", "-o", "vout", "--max-memory", "0.0002"],
            # 61² inbox rows of 8 numbers (238 kB), 61 Zeno rings
            # of 100 times (49 kB) and the agents' other arrays
            2,
            [
                "verify would need about 3",
                "more than 50% of the limit of 200 kB: raise the limit (--max-memory GB)",
            ],
            absent=["vout"],
        ),
        "verify_max_values_zero": Case(
            {"team.yaml": COUNTER},
            ["verify", "team.yaml", "-o", "vout", "--max-values", "0"],
            2,
            ["--max-values must be at least 1, got 0"],
        ),
        "falsify_population_1e9": Case(
            {"team.yaml": REQUIRED},
            [*FALSIFY, "--population", "1000000000"],
            2,
            [
                "--population 1,000,000,000: a generation runs as one "
                "ensemble, which would need about"
            ],
            absent=["fout"],
        ),
        "falsify_vary_overflows": Case(
            {"team.yaml": REQUIRED},
            [*FALSIFY[:5], "c=-1e308:1e308", *FALSIFY[6:]],
            2,
            ["the range is too wide"],
            absent=["fout"],
        ),
        "falsify_record_is_a_list": Case(
            {"team.yaml": REQUIRED, "fout/falsify.json": "[1, 2]"},
            FALSIFY,
            2,
            ["fout/falsify.json: cannot resume from it: expected a JSON object"],
        ),
        "falsify_scheduler_malformed": Case(
            {"team.yaml": REQUIRED},
            [*FALSIFY, "--scheduler", "tcp://[::nope"],
            2,
            ["the Dask scheduler at 'tcp://[::nope': not an address"],
            absent=["fout"],
        ),
        "sweep_scheduler_no_port": Case(
            {"team.yaml": flow("c"), "s.yaml": study()},
            ["sweep", "s.yaml", "-o", "sout", "--quiet", "--scheduler", "127.0.0.1"],
            2,
            ["the Dask scheduler at '127.0.0.1': not an address (missing port number"],
            absent=["sout"],
        ),
        "sweep_scheduler_port_out_of_range": Case(
            {"team.yaml": flow("c"), "s.yaml": study()},
            ["sweep", "s.yaml", "-o", "sout", "--quiet", "--scheduler", "tcp://127.0.0.1:99999"],
            2,
            ["port 99999 is not a port number"],
            absent=["sout"],
        ),
    }
)


class _Hang(Exception):
    pass


def _alarm(signum, frame):
    raise _Hang("took longer than 5 s")


@pytest.mark.parametrize("name", sorted(CASES))
def test_hostile_case(name, tmp_path, monkeypatch, capsys, traces):
    case = CASES[name]
    for rel, text in case.files.items():
        path = tmp_path / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    monkeypatch.chdir(tmp_path)
    argv = [
        str(traces[a[1:-1]]) if a.startswith("{") and a[1:-1] in traces else a for a in case.argv
    ]
    old = signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(5)
    try:
        code = main(argv)
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
    out, err = capsys.readouterr()
    assert "Traceback" not in err
    assert code == case.code, (out, err)
    if case.code == 2:
        assert len(err.strip().splitlines()) >= 1
        for words in case.expect:
            assert words in err, err
    else:
        summary = json.loads((tmp_path / "out" / "summary.json").read_text())
        assert summary["instances"][0]["outcome"] == case.outcome
        text = json.dumps(summary)
        for words in case.expect:
            assert words in text, text
    for rel in case.absent:
        assert not (tmp_path / rel).exists()


def test_a_fifo_is_refused_without_blocking(tmp_path, monkeypatch, capsys):
    os.mkfifo(tmp_path / "team.yaml")
    monkeypatch.chdir(tmp_path)
    signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(5)
    try:
        assert main(["validate", "team.yaml"]) == 2
    finally:
        signal.alarm(0)
    assert (
        "team.yaml: cannot read file: it is a FIFO, not a regular file" in capsys.readouterr().err
    )


def test_a_full_standard_output_is_one_line(tmp_path):
    (tmp_path / "team.yaml").write_text(robot())
    with open("/dev/full", "w") as full:
        proc = subprocess.run(
            [
                sys.executable,
                "-m",
                "hybridteam.cli",
                "run",
                "team.yaml",
                "-o",
                "out",
                "--no-views",
                "--progress",
                "none",
            ],
            cwd=tmp_path,
            stdout=full,
            stderr=subprocess.PIPE,
            text=True,
            timeout=60,
        )
    assert proc.returncode == 2
    assert proc.stderr.strip() == "hybridteam: error: cannot write: No space left on device"
    assert (tmp_path / "out" / "summary.json").exists()  # the run itself is complete


def test_an_interrupted_write_leaves_a_folder_that_says_so(tmp_path, monkeypatch, capsys):
    (tmp_path / "team.yaml").write_text(robot())
    monkeypatch.chdir(tmp_path)

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr("hybridteam.export.runviews.write_run_views", interrupted)
    with pytest.raises(SystemExit) as stop:
        main(["run", "team.yaml", "-o", "out", "--quiet"])
    assert stop.value.code == 130
    err = capsys.readouterr().err
    assert (
        "interrupted while writing out/: it is incomplete (no summary.json; INCOMPLETE "
        "marks it)" in err
    )
    assert (tmp_path / "out" / "INCOMPLETE").exists()
    assert (tmp_path / "out" / "trace.json").exists()
    assert not (tmp_path / "out" / "summary.json").exists()
    # run again: the folder is completed and says so
    monkeypatch.undo()
    monkeypatch.chdir(tmp_path)
    assert main(["run", "team.yaml", "-o", "out", "--quiet", "--no-views"]) == 0
    assert not (tmp_path / "out" / "INCOMPLETE").exists()


def test_a_failing_view_still_writes_the_summary(tmp_path, monkeypatch, capsys):
    (tmp_path / "team.yaml").write_text(robot())
    monkeypatch.chdir(tmp_path)

    def broken(*args, **kwargs):
        raise ValueError("cannot draw this")

    monkeypatch.setattr("hybridteam.export.runviews.write_run_views", broken)
    assert main(["run", "team.yaml", "-o", "out", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "drawing the views failed (ValueError: cannot draw this); out/ has the trace" in err
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["views_error"] == "ValueError: cannot draw this"
    # the data stands, the views do not: the folder says it is incomplete (issue 43)
    assert (
        "drawing the views failed (ValueError: cannot draw this)"
        in (tmp_path / "out" / "INCOMPLETE").read_text()
    )


# --- round two (issue 43): a team of thousands, bounded files, broken libraries ----------


def _crowd(agents: int, links: str = "", acked: bool = False) -> str:
    """A team of ``agents`` unicycles; with ``acked`` the first one sends an acknowledged
    'ping' (ack timeout 0.3 s) on entering its second mode."""
    lines = ["team: crowd", f"network: {{latency: 0.1{links}}}"]
    if acked:
        lines.append("messages: {ping: {ack: {timeout: 0.3, retries: 1}}}")
    lines.append("agents:")
    for i in range(agents):
        body = (
            "{A: {transitions: [{to: B, after: 1, do: [{send: ping}]}]}, B: {}}"
            if acked and i == 0
            else "{Go: {inputs: {v: 0.1, omega: 0}, period: 0.5}}"
        )
        lines += [
            f"  r{i}:",
            "    plant: {kind: unicycle, state: {x: 0, y: 0, theta: 0}}",
            *(["    initial: A"] if acked and i == 0 else []),
            f"    modes: {body}",
        ]
    return "\n".join([*lines, "simulation: {duration: 1.0}", ""])


def test_round_trips_are_not_evaluated_per_pair_of_agents(tmp_path, monkeypatch):
    """A 5,000-agent team took minutes to validate: the ack-timeout warning evaluated the
    round trip of every pair of agents (25 million link settings), senders or not. Now
    only senders of acknowledged messages are looked at, and a link's settings once."""
    import hybridteam as ht
    from hybridteam.io import timing

    calls = []
    real = timing.evaluate_setting

    def counted(*args):
        calls.append(args)
        return real(*args)

    monkeypatch.setattr(timing, "evaluate_setting", counted)
    (tmp_path / "crowd.yaml").write_text(_crowd(60))
    ht.load(tmp_path / "crowd.yaml")
    assert calls == []  # nobody sends an acknowledged message (before: 4 * 60 * 59)
    # r0 sends ping; its link to r2 is slow one way (0.3 s), the others 0.1 s each way:
    # the worst round trip is r0 -> r2 -> r0, 0.3 + 0.1 = 0.4 s, longer than the 0.3 s
    # ack timeout; the default link and the one link are evaluated once each
    (tmp_path / "crowd.yaml").write_text(
        _crowd(60, ", links: {r0->r2: {latency: 0.3}}", acked=True)
    )
    ht.load(tmp_path / "crowd.yaml")
    assert len(calls) == 4  # latency and jitter of two links
    from hybridteam.io.loader import load_team_file

    warnings = [str(w) for w in load_team_file(tmp_path / "crowd.yaml").warnings]
    assert any(
        "agent 'r0' resends ping after 0.3 s without an acknowledgement, but a "
        "round trip to 'r2' takes up to 0.4 s" in w
        for w in warnings
    ), warnings


def test_agents_share_the_team_symbol_table(tmp_path):
    """Every agent can read ``id_<agent>`` of every other: one name per agent. Copying that
    table into each agent's own made compiling a team of thousands quadratic; each agent's
    table now chains its own names to the one team table."""
    import hybridteam as ht
    from hybridteam.engine.compile.compiler import compile_team

    (tmp_path / "crowd.yaml").write_text(_crowd(30))
    cteam = compile_team(ht.load(tmp_path / "crowd.yaml"))
    tables = [ca.symbols.maps[-1] for ca in cteam.agents]  # type: ignore[attr-defined]
    assert all(t is tables[0] for t in tables)
    assert len(tables[0]) == 30 and "id_r29" in cteam.agents[0].symbols
    assert "x" in cteam.agents[0].symbols and "x" not in tables[0]


def test_a_crowd_is_run_without_views_and_says_so(tmp_path, monkeypatch, capsys):
    """Drawing a timeline of a thousand lanes took 45 s of CPU, and of 5,000 failed to
    allocate the image: beyond 100 agents ``run`` writes the data, says why there are no
    views, and the folder is complete."""
    from hybridteam.export.runviews import MAX_VIEW_AGENTS

    (tmp_path / "crowd.yaml").write_text(_crowd(MAX_VIEW_AGENTS + 1))
    monkeypatch.chdir(tmp_path)
    assert main(["run", "crowd.yaml", "-o", "out", "--quiet"]) == 0
    err = capsys.readouterr().err
    assert (
        "hybridteam: note: no views drawn: the team has 101 agents and views are drawn "
        "for up to 100; draw some of them with 'hybridteam timeline TRACE --agents A,B'" in err
    )
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["views_skipped"].startswith("no views drawn: the team has 101 agents")
    assert not (tmp_path / "out" / "timeline.png").exists()
    assert not (tmp_path / "out" / "INCOMPLETE").exists()
    # the timeline command draws as many lanes at most, and chosen ones
    assert main(["timeline", "out/trace.json", "-o", "t.png"]) == 2
    assert capsys.readouterr().err.strip() == (
        "hybridteam: error: out/trace.json: a timeline draws up to 100 agents' lanes, and "
        "this trace has 101; choose some with --agents A,B"
    )
    assert main(["timeline", "out/trace.json", "-o", "t.png", "--agents", "r0,r100"]) == 0
    # nor a report, which draws the same views (with or without the run's own views)
    for extra in ([], ["--no-views"]):
        assert main(["run", "crowd.yaml", "-o", "rep", "--quiet", "--report", *extra]) == 0
        assert (
            "hybridteam: note: no report.html: the team has 101 agents and a report "
            "draws its views for up to 100" in capsys.readouterr().err
        )
        assert not (tmp_path / "rep" / "report.html").exists()
        assert (tmp_path / "rep" / "summary.json").exists()


def test_a_trace_larger_than_the_limit_is_refused(traces, monkeypatch, capsys):
    size = traces["good"].stat().st_size
    monkeypatch.setenv("HYBRIDTEAM_MAX_TRACE_MB", str(size / 2e6))
    assert main(["sequence", str(traces["good"])]) == 2
    assert (
        capsys.readouterr()
        .err.strip()
        .endswith(
            f"trace.json: file is {size / 1e6:.1f} MB; traces are read up to {size / 2e6:g} MB "
            "(set HYBRIDTEAM_MAX_TRACE_MB to read larger ones)"
        )
    )
    monkeypatch.setenv("HYBRIDTEAM_MAX_TRACE_MB", str(size / 1e6))
    assert main(["sequence", str(traces["good"])]) == 0


def test_a_library_that_exits_at_import_ends_no_unrelated_command(tmp_path, monkeypatch, capsys):
    """A library calling sys.exit(7) at import made ``run`` of a team that does not use it,
    and ``laws``, exit 7 without a word. It is a broken library like any other: named,
    with its error, where one of its names is used."""
    from importlib import metadata

    from hybridteam import discovery

    class Exits:
        name, value = "quitter", "quitter.laws"

        def load(self):
            raise SystemExit(7)

    monkeypatch.setattr(metadata, "entry_points", lambda group: [Exits()])
    with discovery.isolated():
        monkeypatch.chdir(tmp_path)
        (tmp_path / "team.yaml").write_text(robot())
        assert main(["run", "team.yaml", "-o", "out", "--quiet", "--no-views"]) == 0
        assert main(["laws"]) == 0
        assert (
            "mode library 'quitter' failed to import (quitter.laws: SystemExit: 7)"
            in capsys.readouterr().err
        )
        (tmp_path / "team.yaml").write_text(robot("law: {use: quit.law}"))
        assert main(["validate", "team.yaml"]) == 2
        assert (
            "team.yaml:6:23: agents.r.modes.Go.law.use: unknown law 'quit.law' (mode library "
            "'quitter' failed to import (quitter.laws: SystemExit: 7))" in capsys.readouterr().err
        )


@pytest.mark.parametrize("value", ["lots", "nan", "-1"])
def test_a_bad_file_size_limit_is_one_line(value, traces, monkeypatch, capsys):
    monkeypatch.setenv("HYBRIDTEAM_MAX_TRACE_MB", value)
    assert main(["sequence", str(traces["good"])]) == 2
    assert (
        capsys.readouterr()
        .err.strip()
        .endswith(
            f"trace.json: cannot read file: HYBRIDTEAM_MAX_TRACE_MB={value!r} must be a number of "
            "megabytes > 0"
        )
    )


@pytest.mark.parametrize("command", ["run", "verify", "falsify"])
@pytest.mark.parametrize("value", ["lots", "nan", "-1", "inf"])
def test_a_bad_memory_limit_in_the_environment_is_one_line(
    command, value, tmp_path, monkeypatch, capsys
):
    """``HYBRIDTEAM_MAX_MEMORY_GB=lots`` was a ValueError traceback in falsify and a raw
    'could not convert' elsewhere; infinity would have been no limit at all."""
    (tmp_path / "team.yaml").write_text(REQUIRED)
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("HYBRIDTEAM_MAX_MEMORY_GB", value)
    argv = {
        "run": ["run", "team.yaml", "-o", "fout", "--quiet"],
        "verify": ["verify", "team.yaml", "-o", "fout"],
        "falsify": FALSIFY,
    }[command]
    assert main(argv) == 2
    assert capsys.readouterr().err == (
        f"hybridteam: error: HYBRIDTEAM_MAX_MEMORY_GB={value!r} must be a number of gigabytes > 0\n"
    )
    assert not (tmp_path / "fout").exists()


def test_running_out_of_memory_is_one_line(tmp_path, monkeypatch, capsys):
    """Within --max-memory by the estimate but beyond what the machine has: one line, not an
    ArrayMemoryError traceback; while writing, the folder keeps its INCOMPLETE marker."""
    (tmp_path / "team.yaml").write_text(robot())
    monkeypatch.chdir(tmp_path)

    def no_memory(*args, **kwargs):  # numpy's ArrayMemoryError is a MemoryError
        raise MemoryError("Unable to allocate 7.28 TiB for an array")

    with monkeypatch.context() as m:
        m.setattr("hybridteam.engine.run.simulator.Simulator.run", no_memory)
        assert main(["run", "team.yaml", "-o", "out", "--quiet"]) == 2
    assert capsys.readouterr().err.strip() == (
        "hybridteam: error: the run ran out of memory (the machine has less than the memory "
        "limit the estimate was checked against): lower --max-memory GB, shorten the run or "
        "the ensemble"
    )
    monkeypatch.setattr("hybridteam.trace.Trace.write_csv", no_memory)
    assert main(["run", "team.yaml", "-o", "out", "--quiet"]) == 2
    assert capsys.readouterr().err.strip() == (
        "hybridteam: error: ran out of memory writing out/: it is incomplete (INCOMPLETE marks "
        "it); raise simulation.sample_period or shorten the run"
    )
    assert (tmp_path / "out" / "INCOMPLETE").exists()
    assert not (tmp_path / "out" / "summary.json").exists()


def test_verify_of_an_unbounded_counter_ends_naming_the_variable(tmp_path, monkeypatch, capsys):
    (tmp_path / "team.yaml").write_text(COUNTER)
    monkeypatch.chdir(tmp_path)
    old = signal.signal(signal.SIGALRM, _alarm)
    # without the bound: one new state per level, about 40 minutes. A minute, not less:
    # with numba installed the compiled loop's first compilation on a fresh machine
    # (about 16 s, more under load) can fall in this test, the first to verify
    signal.alarm(60)
    try:
        code = main(["verify", "team.yaml", "-o", "vout", "--progress", "none"])
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
    out = capsys.readouterr().out
    assert code == 0
    assert "stopped: variable 'n' of agent 'a' took more than 256 different values" in out


@pytest.fixture
def loopback_server():
    """Start a TCP server on 127.0.0.1 that answers every connection with ``reply`` (None:
    accepts and says nothing); returns its address. Closed at the end of the test."""
    import socket
    import threading

    servers: list = []

    def start(reply: bytes | None) -> str:
        sock = socket.socket()
        sock.bind(("127.0.0.1", 0))
        sock.listen(8)
        held: list = []

        def serve():
            while True:
                try:
                    conn, _ = sock.accept()
                except OSError:
                    return
                held.append(conn)
                if reply is not None:
                    conn.sendall(reply)

        threading.Thread(target=serve, daemon=True).start()
        servers.append((sock, held))
        return f"tcp://127.0.0.1:{sock.getsockname()[1]}"

    yield start
    for sock, held in servers:
        sock.close()
        for conn in held:
            conn.close()


def _closed_port() -> str:
    import socket

    with socket.socket() as sock:  # a port just freed: nothing listens there
        sock.bind(("127.0.0.1", 0))
        return f"tcp://127.0.0.1:{sock.getsockname()[1]}"


@pytest.mark.parametrize("command", ["falsify", "sweep"])
@pytest.mark.parametrize(
    ("server", "words"),
    [
        (
            "http",
            "answers, but not as a Dask scheduler (its first bytes b'HTTP/1.1' are no Dask "
            "message)",
        ),
        ("silent", "did not answer as a Dask scheduler within 1 s (--connect-timeout S)"),
        ("closed", "Connection refused"),
    ],
)
def test_a_scheduler_that_is_not_one_is_one_line_in_bounded_time(
    command, server, words, tmp_path, monkeypatch, capsys, loopback_server
):
    pytest.importorskip("dask.distributed")
    address = {
        "http": lambda: loopback_server(b"HTTP/1.1 200 OK\r\nContent-Length: 0\r\n\r\n"),
        "silent": lambda: loopback_server(None),
        "closed": _closed_port,
    }[server]()
    (tmp_path / "team.yaml").write_text(REQUIRED if command == "falsify" else flow("c"))
    (tmp_path / "s.yaml").write_text(study())
    monkeypatch.chdir(tmp_path)
    argv = FALSIFY if command == "falsify" else ["sweep", "s.yaml", "-o", "fout", "--quiet"]
    old = signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(5)
    try:
        code = main([*argv, "--scheduler", address, "--connect-timeout", "1"])
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
    err = capsys.readouterr().err
    assert code == 2
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert f"the Dask scheduler at '{address}'" in err and words in err
    assert not (tmp_path / "fout").exists()  # nothing written


def test_an_unroutable_scheduler_is_one_line_after_the_timeout(tmp_path, monkeypatch, capsys):
    # the connection attempt times out as an unroutable address's does; the address is
    # loopback all the same, so that nothing could leave the machine if it were tried
    import socket

    pytest.importorskip("dask.distributed")
    asked = []

    def unroutable(address, timeout=None):
        asked.append((address, timeout))
        raise TimeoutError("timed out")

    monkeypatch.setattr(socket, "create_connection", unroutable)
    (tmp_path / "team.yaml").write_text(REQUIRED)
    monkeypatch.chdir(tmp_path)
    assert main([*FALSIFY, "--scheduler", "tcp://127.0.0.1:8786"]) == 2
    err = capsys.readouterr().err
    assert (
        err == "hybridteam: error: the Dask scheduler at 'tcp://127.0.0.1:8786' did not "
        "answer as a Dask scheduler within 10 s (--connect-timeout S)\n"
    )
    assert asked == [(("127.0.0.1", 8786), 10.0)]  # the documented default
    assert not (tmp_path / "fout").exists()
