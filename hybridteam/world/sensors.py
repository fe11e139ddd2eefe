"""Range sensors: rings of infrared or sonar beams, what they read and what they detect.

A :class:`RangeRing` places a robot's beams; its readings are rays cast against the walls
and disks around it by :mod:`hybridteam.world.raycast` (re-exported here: :func:`cast`),
clipped to the sensor's range. :func:`detect` turns readings into "something is near";
:func:`clearance` is a robot disk's gap to the nearest obstacle.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from hybridteam.arrays import filled
from hybridteam.world.geometry import as_segments, point_segment_distance, polygon_edges
from hybridteam.world.raycast import Targets, as_circles, cast, cast_at

__all__ = ["RangeRing", "Targets", "cast", "cast_at", "clearance", "detect", "polygon_edges"]


@dataclass(frozen=True)
class RangeRing:
    """A ring of ``count`` range sensors evenly spaced around a robot.

    Sensor ``i`` sits on a circle of radius ``mount_radius`` around the robot's centre at
    angle ``offset + 2 pi i / count`` from the robot's heading and looks radially outward
    (sensors are mounted on the hull, so they read the distance from the hull, not from the
    centre). A sonar is a cone rather than a line: with ``half_angle > 0`` each beam is
    ``rays_per_beam`` rays spread evenly over ``[-half_angle, half_angle]`` and reads the
    nearest echo among them. Readings are clipped to ``[min_range, max_range]``: a real
    sonar cannot hear echoes closer than its blanking distance and reports its minimum.
    """

    count: int
    max_range: float
    min_range: float = 0.0
    mount_radius: float = 0.0
    offset: float = 0.0
    half_angle: float = 0.0
    rays_per_beam: int = 1
    name: str = "range"

    def __post_init__(self) -> None:
        if self.count < 1:
            raise ValueError(f"{self.name}: a ring needs at least one beam, got {self.count}")
        if not 0.0 <= self.min_range < self.max_range:
            raise ValueError(
                f"{self.name}: need 0 <= min_range < max_range, got "
                f"{self.min_range} and {self.max_range}"
            )
        if self.mount_radius < 0.0:
            raise ValueError(f"{self.name}: mount_radius must be >= 0")
        if not 0.0 <= self.half_angle < math.pi / 2:
            raise ValueError(f"{self.name}: half_angle must be in [0, pi/2) radians")
        if self.rays_per_beam < 1 or (self.half_angle > 0.0) != (self.rays_per_beam > 1):
            raise ValueError(
                f"{self.name}: a cone (half_angle > 0) needs rays_per_beam >= 2, "
                "a single line rays_per_beam = 1"
            )

    @property
    def angles(self) -> np.ndarray:
        """Beam centre angles in the robot frame (radians, 0 = straight ahead): ``(count,)``."""
        return self.offset + 2.0 * math.pi * np.arange(self.count) / self.count

    @property
    def ray_angles(self) -> np.ndarray:
        """Directions of every sub-ray in the robot frame: ``(count, rays_per_beam)``."""
        spread = np.linspace(-self.half_angle, self.half_angle, self.rays_per_beam)
        return self.angles[:, None] + spread[None, :]

    @functools.cached_property
    def _local(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Every sub-ray's mount point and direction in the robot frame, ``(1, R)`` each:
        fixed for the ring, so computed once, not at every reading."""
        ray = self.ray_angles
        lx = np.repeat(self.mount_radius * np.cos(self.angles), self.rays_per_beam)[None, :]
        ly = np.repeat(self.mount_radius * np.sin(self.angles), self.rays_per_beam)[None, :]
        return lx, ly, np.cos(ray).ravel()[None, :], np.sin(ray).ravel()[None, :]

    def sector(self, center: float, half_width: float) -> np.ndarray:
        """Indices of the beams pointing within ``half_width`` of ``center`` (robot frame).

        ``ring.sector(0, pi / 4)`` are the front beams: what "the front IR sees something"
        checks with :func:`detect`.
        """
        diff = (self.angles - center + math.pi) % (2.0 * math.pi) - math.pi
        return np.flatnonzero(np.abs(diff) <= half_width + 1e-12)

    @functools.cached_property
    def _beam_subsets(self) -> dict[bytes, tuple[np.ndarray, ...]]:
        return {}

    def _local_of(self, beams: np.ndarray) -> tuple[np.ndarray, ...]:
        """:attr:`_local`'s columns of the sub-rays of ``beams`` (kept per set of beams)."""
        key = beams.tobytes()
        got = self._beam_subsets.get(key)
        if got is None:
            rays = (beams[:, None] * self.rays_per_beam + np.arange(self.rays_per_beam)).ravel()
            got = self._beam_subsets[key] = tuple(c[:, rays] for c in self._local)
        return got

    def local_rays(self, beams: np.ndarray | None = None) -> tuple[np.ndarray, ...]:
        """Every sub-ray's mount point and unit direction in the robot frame (of ``beams``
        only, if given): ``lx, ly, dx, dy``, ``(1, R)`` each, kept by the ring (not to be
        written)."""
        return self._local if beams is None else self._local_of(beams)

    def rays(
        self, poses: np.ndarray, beams: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """World origins and unit directions of every sub-ray: two ``(m, count * rays, 2)``;
        of the sub-rays of ``beams`` (beam indices, in that order) only, if given.

        The rotation into the world uses one cosine and one sine per pose and only ``+ *``
        per ray, so a ray does not depend on the other poses in the batch, nor on the
        other beams cast with it.
        """
        p = np.asarray(poses, dtype=float)
        if p.ndim != 2 or p.shape[1] < 3:
            raise ValueError(f"poses must have shape (m, 3) [x, y, theta], got {p.shape}")
        cos, sin = np.cos(p[:, 2])[:, None], np.sin(p[:, 2])[:, None]
        lx, ly, dx, dy = self._local if beams is None else self._local_of(beams)
        shape = (p.shape[0], lx.shape[1], 2)
        origins, directions = np.empty(shape), np.empty(shape)
        origins[..., 0] = p[:, 0:1] + (cos * lx - sin * ly)
        origins[..., 1] = p[:, 1:2] + (sin * lx + cos * ly)
        directions[..., 0] = cos * dx - sin * dy
        directions[..., 1] = sin * dx + cos * dy
        return origins, directions

    def read(
        self,
        poses: np.ndarray,
        segments: np.ndarray | list | None,
        circles: np.ndarray | list | None = None,
    ) -> np.ndarray:
        """Readings of the ring on robots at ``poses`` ``(m, 3)``: ``(m, count)``.

        ``segments`` are the world's walls and polygon edges, ``circles`` the round
        obstacles, shared ``(c, 3)`` or per instance ``(m, c, 3)``; leave the robot's own
        disk out, or its sensors read 0.
        """
        origins, directions = self.rays(poses)
        dist = cast(origins, directions, segments, circles, self.max_range)
        dist = dist.reshape(dist.shape[0], self.count, self.rays_per_beam).min(axis=2)
        return np.maximum(dist, self.min_range)


def detect(
    readings: np.ndarray,
    threshold: float | np.ndarray,
    beams: slice | np.ndarray | list[int] | None = None,
) -> np.ndarray:
    """Whether any of ``beams`` reads closer than ``threshold``: ``(m,)`` bool.

    ``threshold`` is a scalar or one value per instance ``(m,)`` (parameter studies vary
    it). This is the test behind a local event such as ``obstacle_detected``; keep the
    threshold below the ring's ``max_range``, or "nothing seen" counts as a detection.
    """
    r = np.asarray(readings, dtype=float)
    if r.ndim != 2:
        raise ValueError(f"readings must have shape (m, count), got {r.shape}")
    if beams is not None:
        r = r[:, beams]
    thr = np.asarray(threshold, dtype=float)
    return np.any(r < (thr[:, None] if thr.ndim == 1 else thr), axis=1)


def clearance(
    poses: np.ndarray,
    radius: float | np.ndarray,
    segments: np.ndarray | list | None,
    circles: np.ndarray | list | None = None,
) -> np.ndarray:
    """Gap between each robot's disk and the nearest obstacle: ``(m,)``, negative if overlapping.

    ``poses`` is ``(m, 2)`` or ``(m, 3)`` (the heading does not matter for a disk),
    ``radius`` a scalar or ``(m,)``; obstacles as in :func:`cast`. With no obstacles at
    all the clearance is +inf. This is what "positive clearance from every obstacle" is
    checked against.
    """
    p = np.asarray(poses, dtype=float)
    if p.ndim != 2 or p.shape[1] < 2:
        raise ValueError(f"poses must have shape (m, 2) or (m, 3), got {p.shape}")
    m = p.shape[0]
    gap = filled(m, np.inf)
    seg = np.zeros((0, 4)) if segments is None else as_segments(segments)
    if seg.shape[0]:
        gap, _ = point_segment_distance(p[:, :2], seg)
    circ = as_circles(circles, m)
    if circ.shape[-2]:
        c = circ if circ.ndim == 3 else circ[None]
        dx = p[:, 0:1] - c[..., 0]
        dy = p[:, 1:2] - c[..., 1]
        d = np.sqrt(dx * dx + dy * dy) - c[..., 2]
        gap = np.minimum(gap, np.minimum.reduce(np.where(np.isnan(d), np.inf, d), axis=1))
    return gap - np.asarray(radius, dtype=float)
