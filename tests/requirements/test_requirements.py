"""Requirements on runs: verdicts against closed-form answers, and located errors.

The thermostat heats as x' = K (30 - x) from 19 and cools as x' = -K x, switching at 22
and 18: the first switch is at ln(11/8)/K, the temperature stays in [18, 22], and a band
tightened to 21.9 is first left at ln(11/8.1)/K.
"""

from __future__ import annotations

import json
import math
import textwrap

import numpy as np
import pytest

from hybridteam import simulate
from hybridteam.cli import main
from hybridteam.io.filekind import InputErrors
from tests.conftest import EXAMPLES, THERMOSTAT

K = 0.1
FIRST_SWITCH = math.log(11 / 8) / K


def thermostat(team_from_yaml, requirements: str):
    lines = textwrap.dedent(requirements).strip().splitlines()
    return team_from_yaml(THERMOSTAT + "".join(f"  {line}\n" for line in lines))


def verdicts(run, i: int = 0) -> dict:
    return run.diagnostics[i]["requirements"]


def test_band_holds_with_the_margin_to_the_switching_points(team_from_yaml):
    run = simulate(thermostat(team_from_yaml, "band: always(x >= 17.9 and x <= 22.1)"))
    v = verdicts(run)["band"]
    assert v["satisfied"] is True
    # the extremes are the switching points 18 and 22 (exact states at the transitions)
    assert v["robustness"] == pytest.approx(0.1, abs=1e-9)


def test_tightened_band_fails_at_the_closed_form_crossing(team_from_yaml):
    run = simulate(
        thermostat(
            team_from_yaml,
            """
        upper: always(x <= 21.9)
        lower: always(x >= 18.1)
    """,
        )
    )
    up, low = verdicts(run)["upper"], verdicts(run)["lower"]
    assert up["satisfied"] is False and up["failed"] == "x <= 21.9"
    assert up["violated_at"] == pytest.approx(math.log(11 / 8.1) / K, abs=1e-8)
    assert up["robustness"] == pytest.approx(-0.1, abs=1e-9)
    # cooling from 22 reaches 18.1 after ln(22/18.1)/K
    assert low["violated_at"] == pytest.approx(FIRST_SWITCH + math.log(22 / 18.1) / K, abs=1e-8)
    assert low["robustness"] == pytest.approx(-0.1, abs=1e-9)


def test_each_instance_of_an_ensemble_has_its_own_crossing(team_from_yaml):
    team = thermostat(team_from_yaml, "upper: always(x <= 21.9)")
    ks = [0.08, 0.1, 0.125]
    run = simulate(team, n=3, overrides={"thermostat.K": ks})
    for i, k in enumerate(ks):
        assert verdicts(run, i)["upper"]["violated_at"] == pytest.approx(
            math.log(11 / 8.1) / k, abs=1e-8
        )


def test_windows_read_the_state_at_known_points(team_from_yaml):
    # on [0, 2] the heater alone acts: x(t) = 30 - 11 exp(-K t), increasing
    run = simulate(
        thermostat(
            team_from_yaml,
            """
        soon: eventually[0, 2](x >= 20.5)
        early: always[0, 2](x <= 20)
        late: eventually[1, 2](x <= 19.5)
    """,
        )
    )
    v = verdicts(run)
    x2 = 30 - 11 * math.exp(-K * 2)
    assert v["soon"]["robustness"] == pytest.approx(x2 - 20.5, abs=1e-9)
    assert v["early"]["robustness"] == pytest.approx(20 - x2, abs=1e-9)
    assert v["early"]["violated_at"] == pytest.approx(-math.log(10 / 11) / K, abs=1e-8)
    x1 = 30 - 11 * math.exp(-K * 1)
    assert v["late"]["robustness"] == pytest.approx(19.5 - x1, abs=1e-9)
    assert v["late"]["satisfied"] is False
    assert v["late"]["violated_at"] == pytest.approx(2.0)  # never happened by the window's end


def test_modes_are_boolean_signals_that_switch_at_transitions(team_from_yaml):
    run = simulate(
        thermostat(
            team_from_yaml,
            """
        heating: always(in_mode(Heat))
        cools: eventually[0, 5](in_mode(thermostat, Cool))
        one: always(count_in_mode(Heat) + count_in_mode(Cool) == 1)
        until_hot: until(in_mode(Heat), x >= 21.99)
    """,
        )
    )
    v = verdicts(run)
    assert v["heating"]["satisfied"] is False
    assert v["heating"]["violated_at"] == pytest.approx(FIRST_SWITCH, abs=1e-9)
    assert v["heating"]["robustness"] == "-inf"
    assert v["cools"] == {"satisfied": True, "robustness": "inf"}
    assert v["one"]["satisfied"] is True
    assert v["until_hot"]["satisfied"] is True
    assert run.transitions["t"][1] == pytest.approx(FIRST_SWITCH, abs=1e-9)


def test_parameters_follow_the_overrides(team_from_yaml):
    team = thermostat(team_from_yaml, "band: always(x <= high + 0.1)")
    run = simulate(team, n=2, overrides={"thermostat.high": [22.0, 21.0]})
    for i in range(2):
        assert verdicts(run, i)["band"]["robustness"] == pytest.approx(0.1, abs=1e-9)


def test_a_team_without_requirements_is_simulated_exactly_as_before(team_from_yaml):
    plain = team_from_yaml(THERMOSTAT.replace("requirements:\n", ""))
    watched = thermostat(team_from_yaml, "band: always(x >= 17.9 and x <= 22.1)")
    a, b = simulate(plain), simulate(watched)
    assert "requirements" not in a.diagnostics[0]
    # a band never crossed adds no stop: the same transitions and samples, bit for bit
    assert np.array_equal(a.transitions["t"], b.transitions["t"])
    assert np.array_equal(a.samples["thermostat"], b.samples["thermostat"])


def test_messages_and_roles_on_the_handover(tmp_path):
    """The Labmate asks to lead at t = 3 s; messages take 30 ms: the request arrives at
    3.03, the grant is sent then and arrives at 3.06. One robot leads at any time."""
    from hybridteam import load

    path = tmp_path / "handover.yaml"
    path.write_text(
        (EXAMPLES / "protocols" / "handover.yaml").read_text()
        + """
requirements:
  one_leader: always(count_in_role(lead) <= 1)
  answered: always(implies(sent(labmate, request), eventually[0, 0.1](received(labmate, grant))))
  quick: always(implies(sent(labmate, request), eventually[0, 0.05](received(grant))))
  leads_later: eventually[3, 4](in_role(labmate, lead))
"""
    )
    v = verdicts(simulate(load(path)))
    assert v["one_leader"] == {"satisfied": True, "robustness": 0.0}  # 1 - 1 leader
    assert v["answered"]["satisfied"] is True
    assert v["quick"]["satisfied"] is False
    assert v["quick"]["violated_at"] == pytest.approx(3.05, abs=1e-9)
    assert v["leads_later"]["satisfied"] is True


BAD = [
    ("typo: always(y <= 1)", "unknown name 'y'"),
    ("window: always[3, 1](x <= 22.1)", "bad window [3, 1]: its start is after its end"),
    ("number: x + 1", "must be a condition"),
    ("mode: always(in_mode(Hot))", "has no mode 'Hot'"),
    ("unary: always(in_mode(x + 1))", "takes names, not expressions"),
    ("message: eventually(received(pong))", "unknown message type 'pong'"),
    ("arity: until[0, 1](x > 1)", "wrong number of arguments (1) in call to until"),
]


@pytest.mark.parametrize(("line", "words"), BAD)
def test_bad_requirements_are_located_errors(tmp_path, capsys, line, words):
    path = tmp_path / "team.yaml"
    path.write_text(THERMOSTAT + f"  {line}\n")
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    lineno = (THERMOSTAT + line).count("\n") + 1
    assert f"team.yaml:{lineno}:" in err and words in err and "Traceback" not in err


def test_a_temporal_operator_in_a_guard_is_a_located_error(tmp_path, capsys):
    path = tmp_path / "team.yaml"
    path.write_text(
        THERMOSTAT.replace("guard: x >= high", "guard: always(x >= high)").replace(
            "requirements:\n", ""
        )
    )
    with pytest.raises(InputErrors) as info:
        from hybridteam import load

        load(path)
    text = str(info.value)
    assert "team.yaml:11:" in text and "belongs to requirement formulas" in text


def test_run_prints_a_verdict_per_requirement_and_writes_it(tmp_path, capsys):
    path = tmp_path / "team.yaml"
    path.write_text(THERMOSTAT + "  upper: always(x <= 21.9)\n  band: always(x >= 17.9)\n")
    assert main(["run", str(path), "-o", str(tmp_path / "out"), "--no-views"]) == 0
    out = capsys.readouterr().out
    assert "requirement band: holds (robustness 0.1)" in out
    assert "requirement upper: VIOLATED at t=3.06031211 by x <= 21.9" in out
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["instances"][0]["requirements"]["upper"]["satisfied"] is False


def test_a_discrete_variable_is_read_after_each_instant():
    """The bouncing ball counts its impacts in ``bounces``; ``bounces <= 3`` first fails at
    the fourth impact: t1 = sqrt(2 h0 / g), then each flight 2 e^j v1 / g longer."""
    import dataclasses

    from hybridteam import load
    from hybridteam.model import Requirement

    ball = load(EXAMPLES / "automata" / "bouncing_ball.yaml")
    reqs = (
        Requirement("few", "always(bounces <= 3)", None, ("requirements", "few")),
        Requirement("counted", "eventually(ball.bounces >= 10)", None, ("requirements", "counted")),
    )
    run = simulate(dataclasses.replace(ball, requirements=reqs), duration=2.0)
    g, e, v1 = 9.81, 0.7, math.sqrt(2 * 9.81)
    impacts = [math.sqrt(2 / g)]
    for j in range(1, 12):
        impacts.append(impacts[-1] + 2 * e**j * v1 / g)
    few = verdicts(run)["few"]
    assert few["satisfied"] is False and few["robustness"] == -1.0
    assert few["violated_at"] == pytest.approx(impacts[3], abs=1e-8)
    assert few["failed"] == "bounces <= 3"
    counted = verdicts(run)["counted"]  # the most bounces by t = 2, minus 10
    assert sum(t < 2.0 for t in impacts) == 4
    assert counted["satisfied"] is False and counted["robustness"] == 4 - 10


def test_a_study_tables_satisfaction_and_minimum_robustness(tmp_path):
    """A study of the thermostat over ``high``: ``always(x <= 22.1)`` has robustness
    22.1 - high in every run (the heater stops exactly at high), so each setting's
    satisfaction rate is 1 or 0 and its minimum robustness is 22.1 - high."""
    import csv

    from hybridteam.sweep.run import run_study
    from hybridteam.sweep.study import load_study

    (tmp_path / "thermostat.yaml").write_text(THERMOSTAT + "  upper: always(x <= 22.1)\n")
    (tmp_path / "study.yaml").write_text(
        textwrap.dedent("""\
        kind: study
        team: thermostat.yaml
        duration: 10.0
        population: {size: 2}
        factors:
          thermostat.high: [21.0, 22.05, 22.3]
        repetitions: 2
        """)
    )
    result = run_study(load_study(tmp_path / "study.yaml"), tmp_path / "out")
    rows = {float(r["value"]): r for r in result.table.rows}
    for high, want_ok in ((21.0, 1.0), (22.05, 1.0), (22.3, 0.0)):
        row = rows[high]
        assert row["runs"] == 4 and row["upper_satisfied"] == want_ok
        assert row["upper_min_robustness"] == pytest.approx(22.1 - high, abs=1e-9)
    with open(tmp_path / "out" / "runs.csv") as f:
        runs = list(csv.DictReader(f))
    assert len(runs) == 12 and {"req_upper_ok", "req_upper_rho"} <= set(runs[0])
    for r in runs:
        rho = float(r["req_upper_rho"])
        assert r["factor"] == "thermostat.high"
        assert rho == pytest.approx(22.1 - float(r["value"]), abs=1e-9)
        assert float(r["req_upper_ok"]) == (rho >= 0)


def test_the_timeline_marks_a_violation_at_its_time(team_from_yaml, tmp_path):
    """The tightened band fails first at ln(11/8.1)/K: the timeline draws a dashed line
    there, labelled with the requirement, and lists it in the legend."""
    from hybridteam.export.timeline import timeline_figure

    run = simulate(thermostat(team_from_yaml, "tight: always(x <= 21.9)"))
    fig, _data = timeline_figure(run)
    ax = fig.axes[0]
    marks = [line for line in ax.lines if line.get_linestyle() == "--"]
    assert len(marks) == 1
    assert marks[0].get_xdata()[0] == pytest.approx(math.log(11 / 8.1) / K, abs=1e-8)
    assert any(t.get_text().strip() == "tight" for t in ax.texts)
    legend = ax.get_legend()
    assert legend is not None and "requirement violated" in [
        t.get_text() for t in legend.get_texts()
    ]
