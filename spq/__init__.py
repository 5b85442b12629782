"""spq: Smooth Proximity Queries.

Convex shapes with support functions (polyhedral hull, STP-BV, superellipsoid, primitives) and a certified GJK
distance with witness points, single, per-pair with warm start, and batched.
"""

from spq.compile_notice import install as _install_compile_notice
from spq.gradient import distance_gradient, distance_gradients
from spq.kernels.gjk import STATUS_NAMES
from spq.query import (
    DEFAULT_MAX_ITER,
    DEFAULT_TOL_ABS,
    DEFAULT_TOL_REL,
    BatchDistances,
    DistanceResult,
    Pair,
    distance,
    distances,
)
from spq.kinematics import RobotModel
from spq.scene import Body, Obstacle, Scene, SceneDistances
from spq.shapes.base import Shape
from spq.shapes.polyhedron import Polyhedron
from spq.shapes.primitives import Box, Capsule, Sphere
from spq.shapes.stpbv import STPBV
from spq.shapes.superellipsoid import Ellipsoid, FitResult, Superellipsoid

__version__ = "0.1.0"

_install_compile_notice()  # a line on stderr while numba compiles the kernels (minutes, on first use)

__all__ = [
    "STATUS_NAMES", "DEFAULT_MAX_ITER", "DEFAULT_TOL_ABS", "DEFAULT_TOL_REL", "BatchDistances",
    "DistanceResult", "Pair", "distance", "distances", "Shape", "Polyhedron", "Box", "Capsule", "Sphere", "STPBV",
    "Superellipsoid", "Ellipsoid", "FitResult", "distance_gradient", "distance_gradients",
    "RobotModel", "Scene", "SceneDistances", "Body", "Obstacle",
]
