"""Simple primitives with analytic support: sphere, box, capsule (local frames, metres)."""

from __future__ import annotations

import numpy as np

from spq.kernels import kinds
from spq.shapes.base import KernelData, Shape
from spq.validation import as_positive


class Sphere(Shape):
    """Ball of ``radius`` centred at the local origin. The solver sees a point core plus a margin."""

    def __init__(self, radius: float):
        self.radius = as_positive(radius, "radius")
        self._kernel = KernelData(kinds.POINT, self.radius, np.zeros(1), np.zeros(1, dtype=kinds.IDATA_DTYPE))

    def kernel_data(self, dense: bool = True) -> KernelData:
        return self._kernel

    def bounding_radius(self) -> float:
        return self.radius

    def __repr__(self) -> str:
        return f"Sphere(radius={self.radius})"


class Box(Shape):
    """Axis-aligned box centred at the local origin with half extents (hx, hy, hz) in metres."""

    def __init__(self, hx: float, hy: float, hz: float):
        self.half_extents = np.array([as_positive(hx, "hx"), as_positive(hy, "hy"), as_positive(hz, "hz")])
        self._kernel = KernelData(kinds.BOX, 0.0, self.half_extents.copy(), np.zeros(1, dtype=kinds.IDATA_DTYPE))

    @classmethod
    def from_size(cls, sx: float, sy: float, sz: float) -> "Box":
        """Box from its full edge lengths (m)."""
        return cls(0.5 * as_positive(sx, "sx"), 0.5 * as_positive(sy, "sy"), 0.5 * as_positive(sz, "sz"))

    def kernel_data(self, dense: bool = True) -> KernelData:
        return self._kernel

    def bounding_radius(self) -> float:
        return float(np.linalg.norm(self.half_extents))

    def __repr__(self) -> str:
        hx, hy, hz = self.half_extents
        return f"Box(hx={hx}, hy={hy}, hz={hz})"


class Capsule(Shape):
    """Segment from (0, 0, -half_length) to (0, 0, +half_length) swept by a ball of ``radius``."""

    def __init__(self, radius: float, half_length: float):
        self.radius = as_positive(radius, "radius")
        self.half_length = as_positive(half_length, "half_length")
        self._kernel = KernelData(kinds.SEGMENT, self.radius, np.array([self.half_length]),
                                  np.zeros(1, dtype=kinds.IDATA_DTYPE))

    def kernel_data(self, dense: bool = True) -> KernelData:
        return self._kernel

    def bounding_radius(self) -> float:
        return self.radius + self.half_length

    def __repr__(self) -> str:
        return f"Capsule(radius={self.radius}, half_length={self.half_length})"
