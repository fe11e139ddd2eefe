"""Plant conformance: does the robot move as its model says under what it was told?

A log of a robot holds its poses and, where its driver's topic was recorded, the commands
it was given (``Twist`` → the plant's inputs, the series ``A.cmd``; :mod:`.bag`). The
replay of :mod:`.conformance` drives the model's plant by the model's own laws; here the
plant is driven by the logged commands instead, so the two questions stay apart: did the
robot decide as its model does (the replay), and did its body move as its plant model says
under the commands it was actually given (this module)?

The trajectory is the engine's own plant (:meth:`~hybridteam.dynamics.plants.Plant.propagate`,
exact under a held input: the unicycle's arc, the holonomic base's line), started from the
first logged pose at which a command is in force and integrated under the logged commands,
each held from its sample until the next one (zero-order hold, as a robot's controller
holds a ``Twist``), saturated to the plant's ``limits:`` as the model saturates its own
inputs. Integration steps end at every command and pose time, so the trajectory is read
exactly at the logged pose times. What is left between the two is the plant's error: wheel
slip, a model speed that is not the robot's, and the command changes the log's sampling
missed (a command that changed ``Δ`` after a sample is held ``h - Δ`` too long, ``h`` the
command period).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from hybridteam.dynamics.plants import saturate
from hybridteam.engine.compile.compiled import CAgent
from hybridteam.logs.export import PLANAR
from hybridteam.trace import Trace, command_series


@dataclasses.dataclass(frozen=True)
class PoseDeviation:
    """Where a logged position is farthest from a model's: at time ``t`` the log has the
    robot at ``logged`` and the model at ``model`` (x, y), ``distance`` apart (m)."""

    distance: float
    t: float
    logged: tuple[float, float]
    model: tuple[float, float]


@dataclasses.dataclass(frozen=True)
class CommandedPath:
    """An agent's plant under its logged commands: positions ``xy`` (rows x, y) at times
    ``t`` (its start, then every later command and pose time of the log), and the logged
    position farthest from it (the first such where several are as far)."""

    t: np.ndarray
    xy: np.ndarray
    deviation: PoseDeviation


class NoPoseCheck(Exception):
    """A kinematic agent whose pose under commands cannot be checked; the message says
    why (no commands logged, or none while it has a pose). Not an error: the report says
    so on the agent's line."""


def commanded_path(run: Trace, instance: int, ca: CAgent) -> CommandedPath | None:
    """``ca``'s plant integrated under its logged commands in instance ``instance`` of
    ``run`` (module docstring); None for an agent without a kinematic plant (nothing to
    drive), :class:`NoPoseCheck` for one whose log does not allow the check."""
    info = next(a for a in run.meta["agents"] if a["name"] == ca.name)
    if ca.plant.kind not in PLANAR or info["state"][:3] != ["x", "y", "theta"]:
        return None
    series = command_series(ca.name)
    if series not in run.samples:
        raise NoPoseCheck("the log has no commands for it")
    if ca.name not in run.samples:
        raise NoPoseCheck("the log has no poses for it")
    times = run.sample_times
    pose = run.samples[ca.name][:, instance, :3]
    cmd = run.samples[series][:, instance, :]
    given_at = np.isfinite(cmd).all(axis=1)
    given = np.flatnonzero(given_at)
    placed = np.isfinite(pose[:, :2]).all(axis=1)
    if not given.size:
        raise NoPoseCheck("the log has no commands for it")
    starts = np.flatnonzero(placed & np.isfinite(pose[:, 2]) & (times >= times[given[0]]))
    if not starts.size:
        raise NoPoseCheck("the log has no pose of it once commands are given")
    first = int(starts[0])
    bounds = ca.bounds
    x = pose[first][None, :].copy()
    u = held(cmd[int(given[given <= first][-1])], bounds)
    path_t, path_xy = [float(times[first])], [x[0, :2].copy()]
    worst = PoseDeviation(
        0.0, float(times[first]), (float(x[0, 0]), float(x[0, 1])), (float(x[0, 0]), float(x[0, 1]))
    )
    t = float(times[first])
    for k in range(first, times.size):
        tk = float(times[k])
        if tk > t:  # the held command up to this sample (steps end at every sample time)
            x = ca.plant.propagate(x, u, np.array([tk - t]))
            t = tk
            path_t.append(t)
            path_xy.append(x[0, :2].copy())
        if placed[k]:
            logged = (float(pose[k, 0]), float(pose[k, 1]))
            distance = float(np.hypot(logged[0] - x[0, 0], logged[1] - x[0, 1]))
            if distance > worst.distance:
                worst = PoseDeviation(distance, tk, logged, (float(x[0, 0]), float(x[0, 1])))
        if given_at[k]:  # in force from this sample on
            u = held(cmd[k], bounds)
    return CommandedPath(np.array(path_t), np.array(path_xy), worst)


def held(command: np.ndarray, bounds: tuple[np.ndarray, np.ndarray] | None) -> np.ndarray:
    """A logged command as the plant's input row: saturated to the actuator limits, as
    the engine's drivers saturate a law's output."""
    u = command[None, :]
    return u if bounds is None else saturate(u, *bounds)
