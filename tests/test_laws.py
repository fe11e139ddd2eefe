"""Laws and plants against closed forms: user laws, continuous laws, holonomic, limits."""

from __future__ import annotations

import math
import shutil
from importlib import metadata
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import hybridteam as ht
from hybridteam import discovery, laws
from hybridteam.dynamics.plants import FEW_ARCS, Holonomic, Unicycle
from hybridteam.engine.run.drivers import next_ticks
from hybridteam.errors import ModelError
from hybridteam.floatpaths import FLOAT_PATHS
from hybridteam.io.filekind import InputErrors


def test_unicycle_arc_is_exact_for_any_step():
    p = Unicycle()
    x0 = np.array([[1.0, 2.0, 0.3], [0.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    u = np.array([[2.0, 0.5], [1.0, 0.0], [1.0, 1e-12]])
    h = np.array([1.7, 2.0, 3.0])
    got = p.propagate(x0, u, h)
    th = 0.3 + 0.5 * 1.7
    np.testing.assert_allclose(
        got[0],
        [1 + 4 * (math.sin(th) - math.sin(0.3)), 2 - 4 * (math.cos(th) - math.cos(0.3)), th],
        atol=1e-14,
    )
    np.testing.assert_allclose(got[1], [2.0, 0.0, 0.0], atol=0)
    np.testing.assert_allclose(
        got[2], [3 * math.cos(1.0), 3 * math.sin(1.0), 1.0 + 3e-12], atol=1e-12
    )
    # two half steps equal one full step (the flow property of an exact solution)
    half = p.propagate(p.propagate(x0, u, h / 2), u, h / 2)
    np.testing.assert_allclose(half, got, atol=1e-13)


@settings(max_examples=300, deadline=None)
@given(
    st.lists(
        st.lists(st.floats(allow_nan=True, allow_infinity=True, width=64), min_size=6, max_size=6),
        min_size=1,
        max_size=FEW_ARCS,
    )
)
def test_a_few_rows_arcs_on_floats_have_the_array_versions_bits(rows):
    """A few rows (a single run's step) are moved on Python floats; with the float paths
    off they take the array path. Both must give the same bits, also for zero turn rates,
    zero steps, inf and NaN."""
    p = Unicycle()
    vals = np.array(rows)
    x, u, h = vals[:, :3], vals[:, 3:5], np.abs(vals[:, 5])
    with np.errstate(all="ignore"):
        few = p.propagate(x, u, h)
        with FLOAT_PATHS.off():
            arrays = p.propagate(x, u, h)
    assert few.shape == x.shape
    assert few.tobytes() == arrays.tobytes()
    # one step for every row (a number, as callers may pass it) moves them alike
    with np.errstate(all="ignore"):
        one_h = p.propagate(x, u, float(h[0]))
        each = p.propagate(x, u, np.full(len(rows), h[0]))
    assert one_h.tobytes() == each.tobytes()


def test_holonomic_moves_in_world_frame():
    got = Holonomic().propagate(
        np.array([[1.0, 1.0, 0.5]]), np.array([[0.2, -0.1, 0.3]]), np.array([2.0])
    )
    np.testing.assert_allclose(got, [[1.4, 0.8, 1.1]], atol=1e-15)


UNICYCLE = """
team: laws
agents:
  r:
    plant:
      kind: {kind}
      state: {state}
      limits: {limits}
    parameters: {{k: 0.5}}
    modes:
      Go:
        {body}
simulation: {{duration: 4.0, sample_period: 1.0}}
"""


def make(team_from_yaml, body, kind="unicycle", state="{x: 0, y: 0, theta: 0}", limits="{}"):
    return team_from_yaml(UNICYCLE.format(kind=kind, state=state, limits=limits, body=body))


@pytest.fixture
def userlaws(tmp_path):
    """The user-law module beside the team file (where a model may name Python)."""
    shutil.copy(Path(__file__).parent / "fixtures" / "userlaws.py", tmp_path / "userlaws.py")


def test_user_law_by_module_function_reference(team_from_yaml, userlaws):
    team = make(
        team_from_yaml, "law: {use: 'userlaws:circle', period: 0.1, with: {v: 2.0, w: 0.5}}"
    )
    run = ht.simulate(team)
    final = run.samples["r"][-1, 0]
    th = 0.5 * 4.0
    np.testing.assert_allclose(final, [4 * math.sin(th), 4 * (1 - math.cos(th)), th], atol=1e-12)


def test_continuous_law_is_integrated_accurately(team_from_yaml, userlaws):
    team = make(
        team_from_yaml, "law: {use: 'userlaws:heading_decay'}", state="{x: 0, y: 0, theta: 1.0}"
    )
    run = ht.simulate(team)
    theta = run.samples["r"][:, 0, 2]
    np.testing.assert_allclose(theta, np.exp(-0.5 * run.sample_times), rtol=1e-9)


def test_sampled_inputs_read_the_time_in_their_mode_at_each_tick(team_from_yaml):
    """``vx = 0.5 t_in_mode`` sampled every 0.5 s in Accelerate (2 s), then 1 m/s in
    Cruise (1 s), then Accelerate again from zero: held speeds 0, 0.25, 0.5, 0.75 give
    x(2) = 0.5 * 1.5 = 0.75, Cruise adds 1, and the second Accelerate starts at speed 0
    (its time in the mode restarts at t = 3)."""
    team = team_from_yaml("""
        team: ramp
        agents:
          rover:
            plant: {kind: holonomic, state: {x: 0, y: 0, theta: 0}}
            initial: Accelerate
            modes:
              Accelerate:
                inputs: {vx: 0.5 * t_in_mode, vy: 0, omega: 0}
                period: 0.5
                transitions: [{to: Cruise, after: 2}]
              Cruise:
                inputs: {vx: 1, vy: 0, omega: 0}
                period: 0.5
                transitions: [{to: Accelerate, after: 1}]
        simulation: {duration: 5, sample_period: 0.5}
        """)
    run = ht.simulate(team)
    assert run.samples["rover"][:, 0, 0].tolist() == [
        0.0,
        0.0,
        0.125,
        0.375,
        0.75,
        1.25,
        1.75,
        1.75,
        1.875,
        2.125,
        2.5,
    ]


def test_holonomic_inputs_and_limits_saturate(team_from_yaml):
    team = make(
        team_from_yaml,
        "inputs: {vx: 3.0, vy: -0.5, omega: 0.1}\n        period: 0.5",
        kind="holonomic",
        limits="{vx: [-1, 1], vy: [-1, 1]}",
    )
    run = ht.simulate(team)
    np.testing.assert_allclose(run.samples["r"][-1, 0], [4.0, -2.0, 0.4], atol=1e-12)


def test_law_with_wrong_output_shape_names_the_law(team_from_yaml, userlaws):
    team = make(team_from_yaml, "law: {use: 'userlaws:wrong_shape', period: 0.1}")
    with pytest.raises(
        ModelError,
        match=r"law 'userlaws\.wrong_shape' of agent 'r' returned "
        r"shape \(1,\), expected \(1, 2\)",
    ):
        ht.simulate(team)


def test_law_reference_errors_are_model_errors(team_from_yaml, userlaws):
    from hybridteam.io.loader import InputErrors

    with pytest.raises(InputErrors, match=r"module 'nope' is not beside the team file"):
        make(team_from_yaml, "law: {use: 'nope:f', period: 0.1}")
    with pytest.raises(InputErrors, match=r"has no function 'cirle'.*did you mean 'circle'"):
        make(team_from_yaml, "law: {use: 'userlaws:cirle', period: 0.1}")


def test_libraries_are_found_through_entry_points(monkeypatch):
    """A third-party package ships laws by registering a hybridteam.libraries entry point."""

    class FakeEntryPoint:
        name = "thirdparty"

        def load(self):
            @laws.law("thirdparty.spin", plants=("unicycle",))
            def spin(ctx):
                return np.stack([np.zeros(ctx.size), np.ones(ctx.size)], axis=1)

            return object()

    def entry_points(group):
        assert group == "hybridteam.libraries"
        return [FakeEntryPoint()]

    assert "thirdparty.spin" not in laws.registered()
    monkeypatch.setattr(metadata, "entry_points", entry_points)
    with discovery.isolated():
        assert laws.resolve("thirdparty.spin").plants == ("unicycle",)
        assert "thirdparty.spin" in laws.registered()
    assert "thirdparty.spin" not in laws.registered()  # (the process's laws as before)


def test_a_library_that_fails_to_import_is_named_with_its_error(monkeypatch, tmp_path):
    """A broken library must not break other models, but a model that needs one of its
    names is told which library failed and why, not just "unknown law"."""

    class BrokenEntryPoint:
        name = "conveyors"
        value = "conveyors.laws"

        def load(self):
            import conveyors_missing_dependency  # noqa: F401

    monkeypatch.setattr(metadata, "entry_points", lambda group: [BrokenEntryPoint()])
    path = tmp_path / "t.yaml"
    path.write_text(
        "team: t\nagents:\n  a:\n    plant: {kind: unicycle, state: {x: 0, y: 0, "
        "theta: 0}}\n    modes: {M: {}}\nworld:\n  - {use: conveyor.belt}\n"
    )
    with discovery.isolated():
        with pytest.raises(laws.LawNotFound) as exc:
            laws.resolve("conveyor.belt")
        assert str(exc.value) == (
            "unknown law 'conveyor.belt' (mode library 'conveyors' failed to import "
            "(conveyors.laws: ModuleNotFoundError: No module named "
            "'conveyors_missing_dependency'))"
        )
        with pytest.raises(
            InputErrors,
            match=r"t.yaml:7:11: world\[0\].use: unknown world component "
            r"'conveyor.belt' \(mode library 'conveyors' failed to import "
            r"\(conveyors.laws: ModuleNotFoundError",
        ):
            ht.load(path)


def test_names_a_law_reads_are_checked_at_validation(team_from_yaml, userlaws, tmp_path):
    """A law reading ctx["k_along"] that the agent does not have fails `validate`, at the
    binding — not with a KeyError a few seconds into the run."""
    (tmp_path / "reader.py").write_text(
        "import numpy as np\nfrom hybridteam.library import law\n\n"
        "@law('tests.reader', params={'gain': 1.0})\n"
        "def reader(ctx):\n"
        "    return np.column_stack([ctx['gain'] * ctx['k_along'], ctx.get('w', 0.0)])\n"
    )
    with pytest.raises(
        InputErrors,
        match=r"team.yaml:12:\d+: agents.r.modes.Go.law.use: law "
        r"'tests.reader' reads ctx\['k_along'\], which is no binding parameter",
    ):
        make(team_from_yaml, "law: {use: 'reader:reader', period: 0.1}")
    text = UNICYCLE.format(
        kind="unicycle",
        state="{x: 0, y: 0, theta: 0}",
        limits="{}",
        body="law: {use: 'reader:reader', period: 0.1}",
    )
    team = team_from_yaml(text.replace("{k: 0.5}", "{k: 0.5, k_along: 0.5}"))
    assert ht.simulate(team).samples["r"][-1, 0, 0] == pytest.approx(2.0)  # 0.5 m/s for 4 s


def test_a_law_default_named_as_a_state_is_refused_at_the_binding(team_from_yaml, tmp_path):
    """ctx['theta'] reads a binding parameter before the state: a law whose default is
    called ``theta`` would never see its robot's heading on a unicycle, so binding it there
    is an error at ``use`` (a ``with:`` key of that name is refused at the key, see
    tests/io/test_bad_input.py)."""
    (tmp_path / "steer.py").write_text(
        "import numpy as np\nfrom hybridteam.library import law\n\n"
        "@law('tests.steer', params={'theta': 0.0})\n"
        "def steer(ctx):\n"
        "    return np.column_stack([np.ones(ctx.size), -ctx['theta']])\n"
    )
    with pytest.raises(
        InputErrors,
        match=r"team.yaml:12:\d+: agents.r.modes.Go.law.use: "
        r"binding parameter 'theta' of law 'tests.steer' has the name of a "
        r"state of this agent.*cannot be bound to this plant",
    ):
        make(team_from_yaml, "law: {use: 'steer:steer', period: 0.1}")


def test_a_registered_name_of_a_module_beside_the_team_gets_a_hint(team_from_yaml, tmp_path):
    """The module beside the team is not imported for a registry name (only installed
    libraries are), so the name is unknown: the message says how to name it."""
    (tmp_path / "beside.py").write_text(
        "from hybridteam.library import law\n\n@law('beside.drive')\ndef drive(ctx):\n    pass\n"
    )
    with pytest.raises(
        InputErrors,
        match=r"unknown law 'beside.drive' \(a law in a module "
        r"beside the team file is named by module:function, e.g. "
        r"'beside:drive'\)",
    ):
        make(team_from_yaml, "law: {use: beside.drive, period: 0.1}")


def test_the_laws_command_lists_parameters_and_docs(capsys):
    from hybridteam.cli import main

    assert main(["laws", "formation"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("formation.follow  (unicycle)\n")
    assert "with: ahead=" in out and "reads from the agent:" in out
    assert main(["laws", "nosuch"]) == 2


def test_the_laws_command_shows_whole_sentences(capsys):
    """transport.match's summary runs over two source lines: both are shown, wrapped."""
    from hybridteam.cli import main

    assert main(["laws", "transport.match"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == "transport.match  (unicycle)"
    described = " ".join(
        line.strip() for line in lines[1:] if not line.startswith(("    with:", "    reads from"))
    )
    assert described == (
        "The Scout's Follow: the paper's u = (v̂_l, ω̂_l) with ``k_form`` = "
        "0; by default it also closes the loop on its place in the team."
    )


@settings(max_examples=300, deadline=None)
@given(
    st.lists(st.floats(min_value=0.0, max_value=1e9), min_size=1, max_size=4),
    st.floats(min_value=1e-6, max_value=10.0),
)
def test_a_few_next_ticks_on_floats_have_the_array_versions_bits(times, period):
    """A single run's next law tick is computed on Python floats, an ensemble's on arrays:
    the same bits, each tick strictly after its time and at most one period later."""
    t = np.array(times)
    few = next_ticks(t, period)
    many = next_ticks(np.concatenate([t, np.zeros(5)]), period)[: t.size]
    assert few.tobytes() == many.tobytes()
    assert np.all(few > t)
    assert np.all(few - t <= period * (1 + 1e-9) + 1e-9 * t)
    k = np.round(few / period)
    np.testing.assert_allclose(few, k * period, rtol=1e-15)


def test_next_ticks_on_exact_multiples_and_round_off():
    # ticks are k * 0.1 in floating point: a time on tick 2 (0.2) moves to tick 3, which is
    # 3 * 0.1 = 0.30000000000000004; 0.3 / 0.1 = 2.9999999999999996 floors to 2, so 0.3,
    # just before tick 3, also moves to it
    assert next_ticks(np.array([0.0, 0.2, 0.3]), 0.1).tolist() == [
        0.1,
        0.30000000000000004,
        0.30000000000000004,
    ]


def test_a_table_of_names_is_their_columns_with_item_precedence():
    """``ctx.table(names)`` is ``ctx[name]`` for each name, side by side: one gather when
    all are agent parameters, else name by name with the same precedence (a binding
    parameter hides an agent parameter of its name, state comes before parameters)."""
    from hybridteam.engine.compile.compiled import Ctx

    x = np.array([[1.0, 2.0], [3.0, 4.0]])
    p = np.array([[10.0, 20.0, 30.0], [11.0, 21.0, 31.0]])
    v = np.array([[7.0], [8.0]])
    ctx = Ctx(x, v, p, np.zeros(2))
    tables: dict = {}

    def law_ctx(binding):
        return laws.LawContext(
            ctx,
            binding,
            "r",
            {"x": 0, "y": 1},
            {"mode_v": 0},
            {"a": 0, "b": 1, "x": 2},
            ("v",),
            tables,
        )

    got = law_ctx({}).table(("b", "a"))
    assert got.tolist() == [[20.0, 10.0], [21.0, 11.0]]
    assert tables[("b", "a")].tolist() == [1, 0]  # kept for the binding's next call
    assert law_ctx({}).table(("b", "a")).tolist() == got.tolist()
    # "x" is a state component before it is a parameter; "a" is hidden by the binding
    mixed = law_ctx({"a": lambda c: np.full(2, -1.0)}).table(("a", "x", "mode_v", "b"))
    assert mixed.tolist() == [[-1.0, 1.0, 7.0, 20.0], [-1.0, 3.0, 8.0, 21.0]]
    assert tables[("a", "x", "mode_v", "b")] is None
    with pytest.raises(KeyError, match="unknown name 'nope'"):
        law_ctx({}).table(("a", "nope"))


def test_a_constant_binding_parameter_is_evaluated_once_per_size():
    """A binding parameter reading no name (``window: 16``) has the same values at every
    call: the binding keeps them (read-only) per size; one reading a name is evaluated at
    every call, from that call's rows."""
    from hybridteam.engine.compile.compiled import Ctx
    from hybridteam.expr.compiler import compile_expression

    calls = []
    symbols = {"a": lambda c: c.p[:, 0]}
    const = compile_expression("2 * 8", {})
    varying = compile_expression("a + 1", symbols)
    counted = {"window": lambda c: calls.append(1) or const(c)}
    tables: dict = {}
    for rows in ([[1.0]], [[2.0]], [[3.0], [4.0]]):
        p = np.array(rows)
        ctx = Ctx(np.zeros((len(rows), 2)), np.zeros((len(rows), 0)), p, np.zeros(len(rows)))
        law_ctx = laws.LawContext(
            ctx, {"window": const, "shift": varying}, "r", {}, {}, {"a": 0}, (), tables
        )
        assert law_ctx["window"].tolist() == [16.0] * len(rows)
        assert not law_ctx["window"].flags.writeable
        assert law_ctx["shift"].tolist() == [r[0] + 1 for r in rows]
    assert set(tables) == {("window", 1), ("window", 2)}
    # a callable without recorded names (a plain function) is evaluated at every call
    for _ in range(2):
        laws.LawContext(ctx, counted, "r", {}, {}, {"a": 0}, (), tables)["window"]
    assert len(calls) == 2


_FIELD = st.floats(allow_nan=True, allow_infinity=True, width=64)


@settings(max_examples=400, deadline=None)
@given(
    st.lists(_FIELD, min_size=8, max_size=8),
    st.sets(st.sampled_from(["v", "vx", "vy", "omega"])),
    st.booleans(),
)
def test_a_single_rows_dead_reckoning_on_floats_has_the_array_versions_bits(values, carried, along):
    """A single run's tick dead-reckons its one copy on Python floats (``estimate``); the
    array version is what an ensemble and the float paths off take. Same bits for every
    form of copy (arc, line, both: along the heading or not), also for NaN, inf, zero turn
    rates and copies never received (infinite age)."""
    x, y, th, v, vx, vy, omega, age = values
    if along:  # a unicycle's copy: its world velocity along its heading
        with np.errstate(all="ignore"):
            vx, vy = float(v * np.cos(th)), float(v * np.sin(th))
    given_ = {"v": v, "vx": vx, "vy": vy, "omega": omega}
    f = {"x": x, "y": y, "theta": th} | {k: given_[k] for k in carried}
    rows = {k: np.array([a]) for k, a in f.items()}
    ages = np.array([age])
    with np.errstate(all="ignore"):
        one = laws._dead_reckon_one(rows, age)
        arrays = laws._dead_reckon(rows, np.where(np.isfinite(ages), ages, 0.0))
    assert one.keys() == arrays.keys()
    for k in arrays:
        assert one[k].shape == (1,) and one[k].tobytes() == arrays[k].tobytes(), k


def test_a_single_rows_dead_reckoning_is_the_arc_and_the_line():
    """Closed forms on the float path: a quarter turn of radius 1 (v = 1, omega = pi/2 for
    one second) ends at (1, 1) heading pi/2; a holonomic copy moves on its line."""
    arc = laws._dead_reckon_one(
        {
            k: np.array([a])
            for k, a in dict(x=0.0, y=0.0, theta=0.0, v=1.0, omega=math.pi / 2).items()
        },
        1.0,  # one second: radius v / omega = 2 / pi
    )
    np.testing.assert_allclose([arc["x"][0], arc["y"][0]], [2 / math.pi, 2 / math.pi], atol=1e-15)
    assert arc["theta"][0] == pytest.approx(math.pi / 2, abs=1e-15)
    line = laws._dead_reckon_one(
        {k: np.array([a]) for k, a in dict(x=1.0, y=2.0, theta=0.3, vx=0.5, vy=-0.25).items()},
        2.0,
    )
    assert (line["x"][0], line["y"][0], line["theta"][0]) == (2.0, 1.5, 0.3)
    never = laws._dead_reckon_one({k: np.array([1.0]) for k in ("x", "y", "theta", "v")}, math.inf)
    assert (never["x"][0], never["y"][0], never["theta"][0]) == (1.0, 1.0, 1.0)  # age 0
