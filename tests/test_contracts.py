"""The typed contracts between the engine and a library: what a law context reads of the
engine (``LawRows``), ``WorldAccess`` as an abstract base class, the scene description a
world component gives the views, and the ``py.typed`` marker that lets a library's type
checker read them."""

from __future__ import annotations

import inspect
import json
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

import hybridteam as ht
from hybridteam.engine.run.access import EnsembleAccess
from hybridteam.export.scene import scene_of
from hybridteam.laws import Estimate, LawContext
from hybridteam.library import (
    BarShape,
    BoxShape,
    CircleObstacle,
    CollisionMark,
    Footprint,
    GuidePath,
    PolygonObstacle,
    Region,
    SceneDescription,
    WallObstacle,
    WorldAccess,
)
from hybridteam.trace import Trace

ROOT = Path(__file__).resolve().parents[1]


# ---------------------------------------------------------------------- LawRows
@dataclass
class Inbox:
    """A StreamInbox with one stream, ``pose``, from sender 2, sent at t = 1."""

    def carries(self, message: str, /) -> bool:
        return message == "pose"

    def sender(self, message: str, sender: np.ndarray | None = None, /) -> np.ndarray:
        return np.full(2, 2) if sender is None else np.asarray(sender)

    def fields(self, message: str, who: np.ndarray, /) -> dict[str, np.ndarray]:
        return {"x": np.array([5.0, 6.0])}

    def sent(self, message: str, sender: np.ndarray | None = None, /) -> np.ndarray:
        return np.array([1.0, 1.0])


@dataclass
class Memory:
    """A LawWorld: instances 7 and 9, a sensed ``bearing``, a dict as memory."""

    kept: dict[str, np.ndarray] = field(default_factory=dict)

    def instances(self) -> np.ndarray:
        return np.array([7, 9])

    def sense(self, name: str, /) -> np.ndarray:
        return np.array([0.5, -0.5])

    def recall(self, name: str, initial: float, /) -> np.ndarray:
        return self.kept.get(name, np.full(2, initial))

    def keep(self, name: str, values: np.ndarray, /) -> None:
        self.kept[name] = values


@dataclass
class Rows:
    """A LawRows written from its documentation alone: domain names, no engine."""

    state: np.ndarray
    parameters: np.ndarray
    variables: np.ndarray
    time: np.ndarray
    time_in_mode: np.ndarray
    streams: Inbox | None
    world: Memory


def test_a_law_context_reads_the_engine_through_the_domain_names_of_law_rows():
    """Anything with LawRows' domain-named members drives a LawContext: state,
    parameters and variables by column name, time, the time in mode, stream estimates,
    sensing and memory all come from the member of that name."""
    rows = Rows(
        state=np.array([[1.0, 2.0], [3.0, 4.0]]),
        parameters=np.array([[10.0], [11.0]]),
        variables=np.array([[0.0], [1.0]]),
        time=np.array([3.0, 4.0]),
        time_in_mode=np.array([0.5, 1.5]),
        streams=Inbox(),
        world=Memory(),
    )
    ctx = LawContext(
        rows,
        {"gain": lambda r: 2.0 * r.parameters[:, 0]},
        "r",
        {"x": 0, "y": 1},
        {"busy": 0},
        {"k": 0},
        ("v",),
    )
    assert ctx.size == 2
    assert ctx["y"].tolist() == [2.0, 4.0]
    assert ctx["k"].tolist() == [10.0, 11.0]
    assert ctx["busy"].tolist() == [0.0, 1.0]
    assert ctx["gain"].tolist() == [20.0, 22.0]  # a binding parameter, evaluated on rows
    assert ctx.t.tolist() == [3.0, 4.0] and ctx.t_in_mode.tolist() == [0.5, 1.5]
    assert ctx.state is rows.state
    est = ctx.estimate("pose")
    assert isinstance(est, Estimate)
    assert est["x"].tolist() == [5.0, 6.0] and est.age.tolist() == [2.0, 3.0]
    assert est.sender.tolist() == [2, 2]
    with pytest.raises(KeyError, match="stream 'speed'"):
        ctx.estimate("speed")
    assert ctx.instances.tolist() == [7, 9]
    assert ctx.sense("bearing").tolist() == [0.5, -0.5]
    ctx.keep("integral", np.array([1.0, 2.0]))
    assert ctx.recall("integral").tolist() == [1.0, 2.0]
    assert ctx.recall("never", 4.0).tolist() == [4.0, 4.0]


def test_the_engines_context_offers_law_rows_under_the_domain_names():
    """The engine's expression context answers LawRows' names with its one-letter slots."""
    from hybridteam.engine.compile.compiled import Ctx

    x, v, p, t = np.ones((2, 3)), np.zeros((2, 1)), np.full((2, 2), 7.0), np.array([1.0, 2.0])
    ctx = Ctx(x, v, p, t, t_in=np.array([0.25, 0.5]), e="inbox", w="world")
    assert ctx.state is x and ctx.variables is v and ctx.parameters is p and ctx.time is t
    assert ctx.time_in_mode.tolist() == [0.25, 0.5]
    assert ctx.streams == "inbox" and ctx.world == "world"


# ---------------------------------------------------------------------- WorldAccess
def test_world_access_is_an_abstract_base_class():
    """Every method of WorldAccess is abstract: an implementation missing one fails when
    it is made, naming what it lacks, instead of mid-run when a component calls it."""
    assert inspect.isabstract(WorldAccess)
    with pytest.raises(TypeError, match="abstract"):
        WorldAccess()  # type: ignore[abstract]
    # every public member a component may call is among the abstract methods
    members = {name for name, _ in inspect.getmembers(WorldAccess) if not name.startswith("_")}
    assert WorldAccess.__abstractmethods__ == members

    body = {name: (lambda self, *args: None) for name in WorldAccess.__abstractmethods__ - {"pose"}}
    no_pose = type("NoPose", (WorldAccess,), body)
    with pytest.raises(TypeError, match="pose"):
        no_pose()
    type("Complete", (WorldAccess,), {**body, "pose": lambda self, *args: None})()


def test_a_subclass_leaving_out_a_method_cannot_be_instantiated():
    class Partial(WorldAccess):
        def live(self, idx: np.ndarray) -> np.ndarray:
            return idx

    with pytest.raises(TypeError, match="finish"):
        Partial()  # type: ignore[abstract]


def test_the_engines_world_access_declares_and_implements_the_contract():
    """The engine's implementation is checked by ABCMeta: nothing of the contract left
    abstract in it (so a method added to WorldAccess and not to it fails every run)."""
    assert issubclass(EnsembleAccess, WorldAccess)
    assert EnsembleAccess.__abstractmethods__ == frozenset()


# ---------------------------------------------------------------------- py.typed
def test_the_package_ships_its_py_typed_marker():
    """PEP 561: the marker sits in the package and the build includes it as package data
    (a marker left out of package-data is not installed, and type checkers then ignore
    the package's annotations)."""
    package = Path(ht.__file__).parent
    assert (package / "py.typed").is_file()
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert "py.typed" in config["tool"]["setuptools"]["package-data"]["hybridteam"]


# ---------------------------------------------------------------------- scene description
EXPERIMENT3 = ROOT / "examples" / "transport" / "experiment3.yaml"


def test_the_scene_of_experiment3_is_what_its_yaml_declares(tmp_path):
    """The world of experiment3.yaml, as its components describe it and as the views read
    it back from the trace file: the one circle of ``circles: [[-4.6, -0.2, 0.15]]``, the
    0.8 x 0.5 box of the payload, and the robots' preset footprints (presets.yaml:
    labmate 0.35, xr4000 0.33, scout 0.2); no corridor walls, regions or guide paths."""
    run = ht.simulate(ht.load(EXPERIMENT3), duration=0.5)
    expected = SceneDescription(
        obstacles=(CircleObstacle(-4.6, -0.2, 0.15),),
        payloads={"box": BoxShape(width=0.8, depth=0.5)},
        footprints={"xr4000": Footprint(0.33), "labmate": Footprint(0.35), "scout": Footprint(0.2)},
    )
    assert SceneDescription.from_meta(run.meta) == expected
    run.to_json(tmp_path / "trace.json")
    assert scene_of(Trace.load(tmp_path / "trace.json")) == expected


def test_the_trajectory_plot_draws_the_described_obstacle():
    """The views draw what the description says: one grey disk at (-4.6, -0.2) of radius
    0.15 for the obstacle, the box's outline of 0.8 x 0.5 at its start pose."""
    from matplotlib.patches import Circle

    from hybridteam.export.trajectories import trajectory_figure

    run = ht.simulate(ht.load(EXPERIMENT3), duration=0.5)
    fig = trajectory_figure(run, instance=0)
    (disk,) = [p for ax in fig.axes for p in ax.patches if p.get_gid() == "obstacle"]
    assert isinstance(disk, Circle)
    assert disk.center == pytest.approx((-4.6, -0.2)) and disk.radius == pytest.approx(0.15)
    (box,) = [c for ax in fig.axes for c in ax.collections if c.get_gid() == "payload:box"]
    corners = box.get_paths()[0].vertices[:4]  # the first outline: pose (0.85, 0, 0)
    assert sorted(map(tuple, corners.round(9).tolist())) == [
        (0.45, -0.25),
        (0.45, 0.25),
        (1.25, -0.25),
        (1.25, 0.25),
    ]


def test_a_scene_description_keeps_the_trace_keys_and_reads_back():
    """Each part serializes to the keys traces have always had (what hand-written and old
    traces hold), and the trace form reads back to the same description."""
    scene = SceneDescription(
        walls=((0.0, 0.0, 1.0, 0.0),),
        regions=(Region(((0.0, 0.0), (1.0, 0.0), (1.0, 1.0)), "corner"),),
        obstacles=(
            WallObstacle((2.0, -1.0), (2.0, 1.0)),
            CircleObstacle(3.0, 0.5, 0.1),
            PolygonObstacle(((4.0, 0.0), (5.0, 0.0), (5.0, 1.0), (4.0, 1.0))),
        ),
        units="units",
        paths=(GuidePath(0, "a", ((0.0, 0.0), (1.0, 1.0))),),
        collisions=(CollisionMark(1, "a", 2.5, 0.25, 0.75),),
        payloads={"beam": BarShape(2.0), "ladder": BarShape(3.0, 6.0)},
        footprints={"a": Footprint(0.3)},
    )
    meta = scene.to_meta()
    assert meta == {
        "world": {
            "walls": [[0.0, 0.0, 1.0, 0.0]],
            "regions": [{"points": [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]], "label": "corner"}],
            "obstacles": [
                {"kind": "wall", "points": [[2.0, -1.0], [2.0, 1.0]]},
                {"kind": "circle", "x": 3.0, "y": 0.5, "r": 0.1},
                {"kind": "box", "points": [[4.0, 0.0], [5.0, 0.0], [5.0, 1.0], [4.0, 1.0]]},
            ],
            "units": "units",
            "paths": [{"instance": 0, "agent": "a", "points": [[0.0, 0.0], [1.0, 1.0]]}],
            "collisions": [{"instance": 1, "who": "a", "t": 2.5, "x": 0.25, "y": 0.75}],
        },
        "payloads": ["beam", "ladder"],
        "payload_shapes": {
            "beam": {"kind": "bar", "length": 2.0},
            "ladder": {"kind": "bar", "length": 3.0, "width": 6.0},
        },
        "footprints": {"a": {"radius": 0.3}},
    }
    assert SceneDescription.from_meta(json.loads(json.dumps(meta))) == scene
    assert SceneDescription().to_meta() == {}  # a component that draws nothing adds nothing
    # a guide path or mark without an instance is drawn in every instance
    loose = SceneDescription.from_meta({"world": {"paths": [{"agent": "a", "points": [[0, 0]]}]}})
    assert loose.paths_of(5) == loose.paths and loose.paths[0].instance is None


def test_a_component_still_defining_meta_is_refused_at_registration():
    """The untyped ``meta()`` dict is gone; a library still defining it would have its
    drawing silently dropped, so registering it is an error that names the replacement."""
    from hybridteam.library import WorldComponent, world_component

    class Old(WorldComponent):
        def meta(self) -> dict:
            return {"world": {}}

    with pytest.raises(TypeError, match=r"defines meta\(\).*describe\(\)"):
        world_component("test.old_meta")(Old)
