"""The common face of every shape: the flat data the compiled kernels read."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from spq.kernels.kinds import pack_shape


@dataclass(frozen=True, eq=False)
class KernelData:
    """What the kernels see of a shape: kind code, margin (m) and two flat arrays (see kernels.kinds),
    which are views of one array, ``packed`` (kinds.pack_shape), made here from the given ones."""

    kind: int
    margin: float
    fdata: np.ndarray  # float64, C-contiguous
    idata: np.ndarray  # kinds.IDATA_DTYPE (int32), C-contiguous
    packed: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        packed, fdata, idata = pack_shape(self.fdata, self.idata)
        object.__setattr__(self, "packed", packed)
        object.__setattr__(self, "fdata", fdata)
        object.__setattr__(self, "idata", idata)


class Shape:
    """Base class of convex shapes. A shape is data in its own local frame (metres); the solver
    sees only its :class:`KernelData`."""

    def kernel_data(self, dense: bool = True) -> KernelData:  # pragma: no cover - abstract
        """What the kernels see of this shape. dense: a shape with a support cube map (a hull, or an
        STP-BV's embedded hull) gives its denser one, for a standalone query; False the sparse one,
        which a robot scene's pools take (spq.kernels.support.cube_map_size says why). Shapes
        without one ignore it."""
        raise NotImplementedError

    def bounding_radius(self) -> float:
        """Radius (m) of a ball centred at the local origin that contains the shape."""
        raise NotImplementedError  # pragma: no cover - abstract

    def aim_point(self) -> np.ndarray:
        """(3,) a point near the shape's middle (local frame, m). A query without a warm start searches
        first along the line from A's aim point to B's: only a start, which changes no result beyond
        the tolerance. Here the local origin, the middle of every shape symmetric about it; a hull's
        or an STP-BV's is the centre of the box about its points, as a mesh's origin often lies far
        from its middle (a robot link's at its joint), and an aim from there took 13% to 31% more GJK
        steps (two copies of kuka_link_4 moved 0.1 to 1 m off their origin, at random poses)."""
        return np.zeros(3)


def box_centre(points: np.ndarray) -> np.ndarray:
    """(3,) the centre of the axis-aligned box about points (n, 3)."""
    return 0.5 * (points.min(axis=0) + points.max(axis=0))
