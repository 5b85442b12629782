"""The common face of every shape: the flat data the compiled kernels read."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class KernelData:
    """What the kernels see of a shape: kind code, margin (m) and two flat arrays (see kernels.kinds)."""

    kind: int
    margin: float
    fdata: np.ndarray  # float64, C-contiguous
    idata: np.ndarray  # kinds.IDATA_DTYPE (int32), C-contiguous


class Shape:
    """Base class of convex shapes. A shape is data in its own local frame (metres); the solver
    sees only its :class:`KernelData`."""

    def kernel_data(self) -> KernelData:  # pragma: no cover - abstract
        raise NotImplementedError

    def bounding_radius(self) -> float:
        """Radius (m) of a ball centred at the local origin that contains the shape."""
        raise NotImplementedError  # pragma: no cover - abstract
