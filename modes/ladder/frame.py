"""The corner frame: coordinates in which a corridor's turn is a pair of axes.

The law runs in this frame because every wall test becomes a comparison on one
coordinate. The origin is the inner vertex (where the inner walls meet); the first axis
points across the incoming leg into its inner wall, the second across the outgoing leg
into its inner wall. Then

- the inside of the turn, bounded by the inner walls, is the quadrant ``x >= 0, y >= 0``;
- the outer walls are the lines ``x = -width_in`` and ``y = -width_out``;
- the corner square is ``[-width_in, 0] x [-width_out, 0]``;
- the incoming leg is ``y > 0`` (travel toward smaller y), the outgoing leg ``x > 0``.

The frame is orthonormal (a reflection for a right turn, a rotation for a left turn), so
lengths, distances and the law's vectors carry over unchanged. The corridor's open ends
are not walls, and within the corridor its finite walls coincide with these lines.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from hybridteam.world.geometry import Corridor


@dataclass(frozen=True, eq=False)
class CornerFrame:
    """Origin, axes and leg widths of a corridor's corner frame."""

    origin: np.ndarray  # (2,) the inner vertex, world coordinates
    axes: np.ndarray  # (2, 2) rows: unit x and y axes of the frame, world coordinates
    width_in: float
    width_out: float

    @classmethod
    def of(cls, corridor: Corridor) -> CornerFrame:
        axes = np.asarray(corridor.inner_normals, dtype=float)
        return cls(
            np.asarray(corridor.inner_vertex, dtype=float).copy(),
            axes.copy(),
            float(corridor.width_in),
            float(corridor.width_out),
        )

    @cached_property
    def floats(self) -> tuple[float, float, float, float, float, float]:
        """``(o0, o1, a0, a1, b0, b1)``: the origin and the x and y axes as Python floats,
        for the law's one-row twin (:mod:`.law_one`), which would otherwise convert them
        at every period."""
        (a0, a1), (b0, b1) = self.axes.tolist()
        o0, o1 = self.origin.tolist()
        return o0, o1, a0, a1, b0, b1

    def to_frame(self, points: np.ndarray) -> np.ndarray:
        """World points ``(..., 2)`` in frame coordinates."""
        return self.vectors_to_frame(np.asarray(points, dtype=float) - self.origin)

    def vectors_to_frame(self, vectors: np.ndarray) -> np.ndarray:
        """World vectors ``(..., 2)`` (directions, displacements) in frame coordinates."""
        v = np.asarray(vectors, dtype=float)
        ax, ay = self.axes
        out = np.empty((*v.shape[:-1], 2))  # np.stack's values, without its checks
        out[..., 0] = v[..., 0] * ax[0] + v[..., 1] * ax[1]
        out[..., 1] = v[..., 0] * ay[0] + v[..., 1] * ay[1]
        return out

    def vectors_to_world(self, vectors: np.ndarray) -> np.ndarray:
        """Frame vectors ``(..., 2)`` (displacements) in world coordinates."""
        v = np.asarray(vectors, dtype=float)
        ax, ay = self.axes
        out = np.empty((*v.shape[:-1], 2))
        out[..., 0] = v[..., 0] * ax[0] + v[..., 1] * ay[0]
        out[..., 1] = v[..., 0] * ax[1] + v[..., 1] * ay[1]
        return out

    def to_world(self, points: np.ndarray) -> np.ndarray:
        """Frame points ``(..., 2)`` in world coordinates."""
        return self.vectors_to_world(points) + self.origin
