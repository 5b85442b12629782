"""Convex superellipsoids (CSE-BV) and ellipsoids: data, accessors and a covering fit (NOTES section 4).

A superellipsoid with semi-axes a, b, c (m) and exponents e1, e2 in (0, 2] is the set

    F(x, y, z) = (|x/a|^(2/e2) + |y/b|^(2/e2))^(e2/e1) + |z/c|^(2/e1) <= 1

centred at its local origin with its axes along the local axes. e = 1 gives an ellipsoid, e -> 0 a
box (the support jumps to a corner), e = 2 a diamond / octahedron. The compiled support is in
``spq.kernels.superellipsoid_support``.

The fit (:meth:`Superellipsoid.fit`) covers a point cloud: the minimum-volume enclosing ellipsoid
(Khachiyan's algorithm with away steps, on the convex hull vertices) gives a frame and semi-axes;
SLSQP then minimises the volume over (a, b, c, e1, e2) and a small refinement of the frame,
subject to the gauge G = F^(e1/2) <= 1 at every hull vertex; a final scaling of (a, b, c) by
max G repairs any violation left (G is homogeneous of degree 1 in the point).
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize
from scipy.spatial import ConvexHull, QhullError
from scipy.spatial.transform import Rotation
from scipy.special import betaln, digamma

from spq.kernels import kinds
from spq.kernels.superellipsoid_support import pack
from spq.shapes.base import KernelData, Shape
from spq.shapes.polyhedron import Polyhedron
from spq.validation import as_points, as_positive

E_MAX = 2.0  # largest exponent of a convex superellipsoid (the diamond / octahedral limit)
FIT_E_BOUNDS = (0.1, 2.0)  # exponents the fit searches: below 0.1, F has powers > 20 and is ill-conditioned
MVEE_TOL = 1e-7  # Khachiyan stop: max_i q_i^T X^-1 q_i <= (d + 1)(1 + tol), dimensionless
MVEE_MAX_ITER = 100_000
MVEE_REFRESH = 200  # Khachiyan steps between exact recomputations of X^-1 (rank-one updates drift)
FLAT_VOLUME = 1e-9  # hull volume / extent^3 below which a cloud is treated as flat (dimensionless)
REPAIR_SLACK = 1e-13  # relative inflation added to the repair scale so rounding leaves max F <= 1
FIT_MAX_F = 1.0 + 1e-12  # what the fit guarantees for every input point: F(R^T (x - t)) <= FIT_MAX_F
POSE_SHIFT_BOUND = 0.25  # fit: max centre shift per axis, in units of the mean MVEE semi-axis
POSE_TURN_BOUND = 0.5  # fit: max rotation-vector component of the frame refinement (rad)
LOG_FLOAT_MAX = math.log(sys.float_info.max)  # the largest log a float's exp can return
AXIS_RANGE = (1e-2, 1e2)  # fit: semi-axes searched within these multiples of the MVEE's smallest / largest
INNER_DIRECTIONS = 200  # support points spanning the inner polytope, GJK's first phase between two of them
_NO_IDATA = np.zeros(1, dtype=kinds.IDATA_DTYPE)  # the closed-form support reads no integer data
MESH_START_DIRECTIONS = (400, 20_000)  # fewest and most lattice directions a mesh starts from before refining
INNER_SHRINK = 1e-9  # relative pull of the inner polytope's vertices towards the centre: inside despite rounding


def as_exponent(value, name: str) -> float:
    """Return ``value`` as a float in (0, 2] (a convex superellipsoid's exponent), or raise ValueError."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number in (0, 2]; got {value!r}") from None
    if not (0.0 < x <= E_MAX):  # also rejects NaN
        raise ValueError(f"{name} must be in (0, 2] for a convex superellipsoid; got {x}")
    return x


class Superellipsoid(Shape):
    """Convex superellipsoid with semi-axes a, b, c (m) and exponents e1 (z against xy), e2 (in xy).

    Raises ValueError for a, b, c that are not finite and > 0 or exponents outside (0, 2].
    """

    n_features = 1  # a smooth shape: one "feature" (for tables next to vertex / patch counts)

    def __init__(self, a: float, b: float, c: float, e1: float, e2: float):
        self.a = as_positive(a, "a")
        self.b = as_positive(b, "b")
        self.c = as_positive(c, "c")
        self.e1 = as_exponent(e1, "e1")
        self.e2 = as_exponent(e2, "e2")
        self._core = pack(self.a, self.b, self.c, self.e1, self.e2)  # what the closed-form support reads
        self._kernel = {}  # dense -> KernelData

    # ---------------------------------------------------------------------------------- data
    @property
    def semi_axes(self) -> np.ndarray:
        """(a, b, c) in metres."""
        return np.array([self.a, self.b, self.c])

    @property
    def exponents(self) -> tuple[float, float]:
        """(e1, e2)."""
        return self.e1, self.e2

    def kernel_data(self, dense: bool = True) -> KernelData:
        """fdata: the closed-form parameters, then the inner polytope's vertices; idata: the inner
        polytope's (see kernels.kinds), with the dense or the sparse cube map as ``dense`` says
        (Polyhedron.kernel_data). The dense map's supports run the inner polytopes' search faster
        (Table I's CSE-CSE 1.03x with each side timed on warm caches, rows bit-identical;
        docs/notes/speed-45.md, stop 121)."""
        if dense not in self._kernel:
            inner = self.inner_polytope().kernel_data(dense=dense)
            fdata = np.concatenate([self._core, inner.fdata])
            self._kernel[dense] = KernelData(kinds.SUPERELLIPSOID, 0.0, fdata, inner.idata)
        return self._kernel[dense]

    def inner_polytope(self, n: int = INNER_DIRECTIONS) -> Polyhedron:
        """A polytope inside the shape: the hull of its support points along n directions spread
        evenly over the sphere (a Fibonacci lattice), pulled towards the centre by a relative 1e-9
        so that rounding cannot put a vertex outside. Two of them overlap only if the shapes do, and
        their closest points give the normal that Newton's finish starts from."""
        from spq.kernels.dispatch import support_many

        k = np.arange(n) + 0.5
        z = 1.0 - 2.0 * k / n
        phi = math.pi * (3.0 - math.sqrt(5.0)) * k
        rho = np.sqrt(1.0 - z * z)
        directions = np.column_stack([rho * np.cos(phi), rho * np.sin(phi), z])
        points = support_many(kinds.SUPERELLIPSOID, self._core, _NO_IDATA, directions) * (1.0 - INNER_SHRINK)
        try:
            return Polyhedron.from_points(points)
        except ValueError:
            # exponents near 2 (a diamond's tips) or near 0 (a box's flat sides) send many directions
            # to nearly one point, and qhull's precision check can refuse such a cloud (fuzz campaign,
            # seed 0, case 1108): drop the points within 1e-7 of the body's size of one kept. A flat
            # diamond (e1 near 2, c << a, b) sends every direction of the lattice to its rim, a flat
            # cloud (seed 79, case 593): its tips, the supports along +-z, and those along +-x and
            # +-y, are taken too, so the hull spans the body's three extents
            axes = np.vstack([np.eye(3), -np.eye(3)])
            points = np.vstack([points, support_many(kinds.SUPERELLIPSOID, self._core, _NO_IDATA, axes)
                                * (1.0 - INNER_SHRINK)])
            scale = float(np.abs(points).max())
            _, keep = np.unique(np.round(points / scale, 7), axis=0, return_index=True)
            return Polyhedron.from_points(points[np.sort(keep)])

    def __repr__(self) -> str:
        return f"Superellipsoid(a={self.a}, b={self.b}, c={self.c}, e1={self.e1}, e2={self.e2})"

    # ---------------------------------------------------------------------------------- accessors
    def volume(self) -> float:
        """Volume (m^3): 2 abc e1 e2 B(e1/2 + 1, e1) B(e2/2, e2/2)."""
        log_v = _log_volume(self.a, self.b, self.c, self.e1, self.e2)
        return math.exp(log_v) if log_v < LOG_FLOAT_MAX else math.inf  # math.exp raises beyond range

    def inside(self, points) -> np.ndarray:
        """F at (n, 3) local points (m): <= 1 inside or on the surface, > 1 outside. Returns (n,)."""
        p = as_points(points, "points")
        return _gauge(p, self.a, self.b, self.c, self.e1, self.e2) ** (2.0 / self.e1)

    def bounding_radius(self) -> float:
        """Radius (m) of the smallest ball centred at the local origin that contains the shape.

        Closed form: max over the surface of |x|^2 is ||(||(a^2, b^2)||_k2, c^2)||_k1 with
        k = 1/(1 - e) for e < 1 and the max-norm for e >= 1."""
        r2 = _power_mean_max(_power_mean_max(self.a ** 2, self.b ** 2, self.e2), self.c ** 2, self.e1)
        return math.sqrt(r2)

    def support(self, directions) -> np.ndarray:
        """Support points (m, 3) (local frame) of (m, 3) or (3,) local directions."""
        from spq.kernels.dispatch import support_many

        d = np.asarray(directions, dtype=np.float64)
        single = d.ndim == 1
        d = as_points(d.reshape(1, 3) if single else d, "directions")
        s = support_many(kinds.SUPERELLIPSOID, self._core, _NO_IDATA, d)
        return s[0] if single else s

    def to_mesh(self, tolerance: float | None = None):
        """Triangle mesh of this superellipsoid, a ``trimesh.Trimesh`` in its local frame (metres).

        The vertices are support points (closed form) of an even lattice of directions plus the six
        axis directions, refined where needed: each lies on the true surface (F = 1 to rounding) with
        its direction as the exact outward normal (``mesh.vertex_normals``). The mesh is their convex
        hull: watertight, convex, inside the body, triangles counter-clockwise seen from outside; its
        error is certified (spq.tessellation.hausdorff_bound) and refined until the Hausdorff
        distance between mesh and body is at most ``tolerance``. tolerance: metres, default 1e-3 x
        the bounding radius; ValueError outside [1e-6, 0.5] x the bounding radius.
        ``mesh.metadata``: max_error (certified, m), tolerance (m). Pose it with a fit's pose
        (``mesh.apply_transform(fit.pose)``); export with ``mesh.export("cover.glb")``.
        """
        from spq import tessellation as ts

        radius = self.bounding_radius()
        tol = ts.check_tolerance(tolerance, radius)
        axes = np.vstack([np.eye(3), -np.eye(3)])
        start = ts.lattice_size(math.sqrt(2.0 * tol / radius), MESH_START_DIRECTIONS)  # sagitta tol on a ball of the radius
        directions = np.vstack([axes, ts.fibonacci_directions(start)])
        surface = ts.support_mesh(self.support, self.support(directions), directions, tol, radius)
        return surface.to_trimesh(tolerance=tol)

    def surface_points(self, n: int, seed: int = 0) -> np.ndarray:
        """(n, 3) points on the surface (m), from uniform random parameters (eta, omega) of the
        parametric form x = a C(eta)^e1 C(omega)^e2, y = b C(eta)^e1 S(omega)^e2, z = c S(eta)^e1
        (C, S: signed powers of cos, sin). Seeded: the same n and seed give the same points."""
        n = int(n)
        if n < 1:
            raise ValueError(f"n must be >= 1; got {n}")
        rng = np.random.default_rng(seed)
        eta = rng.uniform(-0.5 * math.pi, 0.5 * math.pi, n)
        omega = rng.uniform(-math.pi, math.pi, n)
        ce = _signed_power(np.cos(eta), self.e1)
        out = np.empty((n, 3))
        out[:, 0] = self.a * ce * _signed_power(np.cos(omega), self.e2)
        out[:, 1] = self.b * ce * _signed_power(np.sin(omega), self.e2)
        out[:, 2] = self.c * _signed_power(np.sin(eta), self.e1)
        return out

    # ---------------------------------------------------------------------------------- fit
    @classmethod
    def fit(cls, points, e_bounds: tuple[float, float] = FIT_E_BOUNDS, refine_pose: bool = True) -> "FitResult":
        """Smallest-volume convex superellipsoid containing every point of an (n, 3) cloud (m).

        Returns a :class:`FitResult` (which also unpacks as ``shape, pose``): pose is the 4x4
        transform from the shape's frame to the points' frame, and every point x satisfies
        F(R^T (x - t)) <= 1 + 1e-12. Deterministic. ``e_bounds``: the exponent range searched
        (within (0, 2]); ``refine_pose``: also move the MVEE frame a little.
        Raises ValueError for fewer than 4 points, NaN/inf, or a flat (degenerate) cloud.
        """
        lo, hi = (as_exponent(e, "e_bounds") for e in e_bounds)
        if lo > hi:
            raise ValueError(f"e_bounds must be (low, high) with low <= high; got {e_bounds}")
        return fit_superellipsoid(points, (lo, hi), refine_pose, cls=cls)


class Ellipsoid(Superellipsoid):
    """Ellipsoid with semi-axes a, b, c (m): the superellipsoid with e1 = e2 = 1."""

    def __init__(self, a: float, b: float, c: float):
        super().__init__(a, b, c, 1.0, 1.0)

    def __repr__(self) -> str:
        return f"Ellipsoid(a={self.a}, b={self.b}, c={self.c})"

    @classmethod
    def fit(cls, points, e_bounds=None, refine_pose: bool = False) -> "FitResult":
        """The minimum-volume enclosing ellipsoid of an (n, 3) cloud (m), as in Superellipsoid.fit
        (exponents fixed at 1, MVEE frame kept: ``e_bounds`` and ``refine_pose`` are ignored)."""
        return fit_superellipsoid(points, (1.0, 1.0), False, cls=cls)


@dataclass(frozen=True, eq=False)
class FitResult:
    """A covering fit: shape (local frame), pose (4x4, shape frame -> points frame), volume (m^3),
    hull_volume (m^3, of the points' convex hull), volume_ratio = volume / hull_volume (>= 1), and
    max_f = max F over the input points (<= 1 + 1e-12). Unpacks as ``shape, pose``."""

    shape: Superellipsoid
    pose: np.ndarray
    volume: float
    hull_volume: float
    volume_ratio: float
    max_f: float

    def __iter__(self):
        return iter((self.shape, self.pose))


# ------------------------------------------------------------------------------------------
# closed forms
# ------------------------------------------------------------------------------------------
def _log_volume(a, b, c, e1, e2):
    scale = 2.0 * a * b * c * e1 * e2
    if not (0.0 < scale < math.inf):  # semi-axes whose product underflows or overflows: a sum of logs
        scale_log = math.log(2.0 * e1 * e2) + math.log(a) + math.log(b) + math.log(c)
    else:
        scale_log = math.log(scale)
    return scale_log + betaln(0.5 * e1 + 1.0, e1) + betaln(0.5 * e2, 0.5 * e2)


def _d_log_volume_de(e1, e2):
    """(d/de1, d/de2) of the log volume."""
    d1 = 1.0 / e1 + 0.5 * digamma(0.5 * e1 + 1.0) + digamma(e1) - 1.5 * digamma(1.5 * e1 + 1.0)
    d2 = 1.0 / e2 + digamma(0.5 * e2) - digamma(e2)
    return d1, d2


def _power_mean_max(A: float, B: float, e: float) -> float:
    """max over t of A cos(t)^(2e) + B sin(t)^(2e) (A, B >= 0): ||(A, B)||_k, k = 1/(1 - e) (e < 1),
    max(A, B) for e >= 1 (the function is then convex in cos^2)."""
    hi, lo = max(A, B), min(A, B)
    if e >= 1.0 or lo == 0.0:
        return hi
    k = 1.0 / (1.0 - e)
    return hi * math.exp(math.log1p((lo / hi) ** k) / k)


def _signed_power(x: np.ndarray, e: float) -> np.ndarray:
    return np.sign(x) * np.abs(x) ** e


def _pnorm2(w1, w2, p):
    """p-norm (p >= 1) of nonnegative pairs (w1, w2) (arrays) and its derivatives.

    Returns (N, dN/dw1, dN/dw2, dN/dp), computed with ratios to the larger entry (no overflow)."""
    hi = np.maximum(w1, w2)
    lo = np.minimum(w1, w2)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(hi > 0.0, lo / hi, 0.0)
        rp = r ** p
        log_s = np.log1p(rp)
        g = np.exp((1.0 / p - 1.0) * log_s)  # S^(1/p - 1), S = 1 + r^p
        n = hi * (1.0 + rp) * g
        g_lo = np.where(r > 0.0, r ** (p - 1.0), 0.0 if p > 1.0 else 1.0) * g
        rlogr = np.where(r > 0.0, rp * np.log(np.where(r > 0.0, r, 1.0)), 0.0)
    dn_dp = n / p * (-log_s / p + rlogr / (1.0 + rp))
    first_is_hi = w1 >= w2
    d1 = np.where(first_is_hi, g, g_lo)
    d2 = np.where(first_is_hi, g_lo, g)
    return n, d1, d2, dn_dp


def _gauge(p: np.ndarray, a, b, c, e1, e2) -> np.ndarray:
    """G = F^(e1/2) at (n, 3) local points: the nested norm ||(||(X, Y)||_(2/e2), Z)||_(2/e1)."""
    X, Y, Z = np.abs(p[:, 0]) / a, np.abs(p[:, 1]) / b, np.abs(p[:, 2]) / c
    inner = _pnorm2(X, Y, 2.0 / e2)[0]
    return _pnorm2(inner, Z, 2.0 / e1)[0]


def _gauge_and_gradient(p: np.ndarray, a, b, c, e1, e2):
    """G at (n, 3) local points, its gradient (n, 5) over (log a, log b, log c, e1, e2) and its
    gradient (n, 3) over the local coordinates."""
    s = np.array([a, b, c])
    U = np.abs(p) / s
    p1, p2 = 2.0 / e1, 2.0 / e2
    inner, dX, dY, dp2 = _pnorm2(U[:, 0], U[:, 1], p2)
    G, dI, dZ, dp1 = _pnorm2(inner, U[:, 2], p1)
    dU = np.column_stack([dI * dX, dI * dY, dZ])
    grad = np.empty((len(p), 5))
    grad[:, 0:3] = -dU * U
    grad[:, 3] = dp1 * (-2.0 / e1 ** 2)
    grad[:, 4] = dI * dp2 * (-2.0 / e2 ** 2)
    dp = dU * np.sign(p) / s
    return G, grad, dp


# ------------------------------------------------------------------------------------------
# minimum-volume enclosing ellipsoid
# ------------------------------------------------------------------------------------------
def minimum_volume_ellipsoid(points: np.ndarray, tol: float = MVEE_TOL, max_iter: int = MVEE_MAX_ITER):
    """Minimum-volume enclosing ellipsoid of (n, 3) points (m), n >= 4 affinely independent.

    Khachiyan's barycentric coordinate ascent with Todd-Yildirim away steps (linear convergence),
    vectorised, with rank-one (Sherman-Morrison) updates of X^-1 and of M_i = q_i^T X^-1 q_i,
    refreshed exactly every MVEE_REFRESH steps. Stops when max M <= (d + 1)(1 + tol) and
    min M over the support >= (d + 1)(1 - tol). Returns (centre (3,), A (3, 3)) with
    (x - centre)^T A (x - centre) <= 1 + O(tol) for every point; the caller repairs the excess."""
    P = np.asarray(points, dtype=np.float64)
    n, d = P.shape
    Q = np.vstack([P.T, np.ones(n)])  # (d + 1, n)
    u = np.full(n, 1.0 / n)
    target = d + 1.0
    for it in range(max_iter):
        if it % MVEE_REFRESH == 0:
            Xi = np.linalg.inv((Q * u) @ Q.T)
            M = np.einsum("ij,ij->j", Q, Xi @ Q)
        j = int(np.argmax(M))
        k = int(np.argmin(np.where(u > 0.0, M, np.inf)))
        up = M[j] / target - 1.0
        down = 1.0 - M[k] / target
        if up <= tol and down <= tol:
            break
        if up >= down:
            i = j
            tau = (M[j] - target) / (target * (M[j] - 1.0))
        else:  # away step: move weight off the point deepest inside, at most all of it
            i = k
            tau = max((M[k] - target) / (target * (M[k] - 1.0)), -u[k] / (1.0 - u[k]))
        # X <- (1 - tau) X + tau q_i q_i^T
        xq = Xi @ Q[:, i]
        y = xq @ Q  # q_l^T X^-1 q_i for every l
        den = 1.0 - tau + tau * M[i]
        Xi = (Xi - (tau / den) * np.outer(xq, xq)) / (1.0 - tau)
        M = (M - (tau / den) * y * y) / (1.0 - tau)
        u *= 1.0 - tau
        u[i] += tau
        if u[i] < 1e-15:
            u[i] = 0.0
    centre = P.T @ u
    cov = (P.T * u) @ P - np.outer(centre, centre)
    A = np.linalg.inv(cov) / d
    return centre, 0.5 * (A + A.T)


# ------------------------------------------------------------------------------------------
# the covering fit
# ------------------------------------------------------------------------------------------
def _hull(points: np.ndarray):
    try:
        hull = ConvexHull(points)
    except QhullError as exc:
        raise ValueError(f"points are degenerate (flat, collinear or coincident): no 3-D convex hull ({exc})"
                         .splitlines()[0]) from None
    extent = float(np.ptp(points, axis=0).max())
    if not hull.volume > FLAT_VOLUME * extent ** 3:
        raise ValueError(f"points are nearly flat: hull volume {hull.volume:.3g} m^3 for an extent of "
                         f"{extent:.3g} m; need a 3-D cloud")
    return hull


class _Problem:
    """SLSQP problem for one frame and one starting point. Variables:
    theta = (log a, log b, log c, e1, e2, shift (3, units of L), rotation vector (3, rad));
    local points p = (x - t0 - L shift) R0 Rot(w), i.e. the rows of R^T (x - t) with R = R0 Rot(w)."""

    def __init__(self, V, t0, R0, L, refine_pose):
        self.V, self.t0, self.R0, self.L = V, t0, R0, L
        self.refine_pose = refine_pose
        self._key = None

    def frame(self, theta):
        if not self.refine_pose:
            return self.t0, self.R0
        t = self.t0 + self.L * theta[5:8]
        R = self.R0 @ Rotation.from_rotvec(theta[8:11]).as_matrix()
        return t, R

    def _evaluate(self, theta):
        if self._key is not None and np.array_equal(theta, self._key):
            return
        a, b, c = np.exp(theta[0:3])
        e1, e2 = theta[3], theta[4]
        t, R = self.frame(theta)
        D = self.V - t
        p = D @ R
        G, grad, dp = _gauge_and_gradient(p, a, b, c, e1, e2)
        jac = np.zeros((len(p), len(theta)))
        jac[:, 0:5] = grad
        if self.refine_pose:
            jac[:, 5:8] = -self.L * (dp @ R.T)
            h = 1e-6
            for k in range(3):  # d Rot / d w_k by central differences on the 3x3 matrix (error O(h^2))
                w_plus, w_minus = theta[8:11].copy(), theta[8:11].copy()
                w_plus[k] += h
                w_minus[k] -= h
                dRot = (Rotation.from_rotvec(w_plus).as_matrix() - Rotation.from_rotvec(w_minus).as_matrix()) / (2 * h)
                jac[:, 8 + k] = np.einsum("ij,ij->i", dp, D @ (self.R0 @ dRot))
        self._key = theta.copy()
        self._G, self._jac = G, jac

    def objective(self, theta):
        return float(theta[0] + theta[1] + theta[2] + _log_volume(1.0, 1.0, 1.0, theta[3], theta[4]))

    def objective_gradient(self, theta):
        g = np.zeros(len(theta))
        g[0:3] = 1.0
        g[3], g[4] = _d_log_volume_de(theta[3], theta[4])
        return g

    def constraint(self, theta):
        self._evaluate(theta)
        return 1.0 - self._G

    def constraint_jacobian(self, theta):
        self._evaluate(theta)
        return -self._jac


def _repair(points, t, R, axes, e1, e2):
    """Scale the semi-axes so that every point has F <= 1 (G homogeneous of degree 1)."""
    p = (points - t) @ R
    for _ in range(4):
        G = _gauge(p, *axes, e1, e2).max()
        axes = axes * (G * (1.0 + REPAIR_SLACK))
        if (_gauge(p, *axes, e1, e2).max()) ** (2.0 / e1) <= 1.0:
            break
    return axes


def _solve_frame(V, t0, R0, axes0, e_start, e_bounds, refine_pose):
    """One SLSQP run from a feasible start; returns (t, R, axes, e1, e2) after repair."""
    e1, e2 = e_start
    axes = _repair(V, t0, R0, axes0, e1, e2)
    if e_bounds[0] == e_bounds[1] and not refine_pose:
        return t0, R0, axes, e1, e2
    L = float(np.mean(axes0))
    prob = _Problem(V, t0, R0, L, refine_pose)
    nvar = 11 if refine_pose else 5
    theta0 = np.zeros(nvar)
    theta0[0:3] = np.log(axes)
    theta0[3:5] = e1, e2
    log_lo, log_hi = math.log(AXIS_RANGE[0] * min(axes0)), math.log(AXIS_RANGE[1] * max(axes0))
    bounds = [(log_lo, log_hi)] * 3 + [e_bounds] * 2
    if refine_pose:
        bounds += [(-POSE_SHIFT_BOUND, POSE_SHIFT_BOUND)] * 3 + [(-POSE_TURN_BOUND, POSE_TURN_BOUND)] * 3
    res = minimize(prob.objective, theta0, jac=prob.objective_gradient, method="SLSQP", bounds=bounds,
                   constraints=[{"type": "ineq", "fun": prob.constraint, "jac": prob.constraint_jacobian}],
                   options={"maxiter": 300, "ftol": 1e-12})
    theta = res.x if np.all(np.isfinite(res.x)) and np.isfinite(res.fun) else theta0
    theta[3:5] = np.clip(theta[3:5], *e_bounds)
    theta[0:3] = np.clip(theta[0:3], log_lo, log_hi)
    t, R = prob.frame(theta)
    return t, R, np.exp(theta[0:3]), float(theta[3]), float(theta[4])


def _proper_rotation(R: np.ndarray) -> np.ndarray:
    R = np.array(R, dtype=np.float64)
    if np.linalg.det(R) < 0.0:
        R[:, 0] = -R[:, 0]  # the shape is symmetric in each axis: a flipped axis is the same shape
    return R


def fit_superellipsoid(points, e_bounds=FIT_E_BOUNDS, refine_pose: bool = True, cls=Superellipsoid) -> FitResult:
    """See :meth:`Superellipsoid.fit`. ``cls`` is the shape class returned (Ellipsoid: e fixed at 1)."""
    pts = as_points(points, "points", min_count=4)
    hull = _hull(pts)
    V = pts[hull.vertices]
    origin = V.mean(axis=0)  # work near the cloud: the lifted (x, 1) system stays well conditioned
    centre, A = minimum_volume_ellipsoid(V - origin)
    centre = centre + origin
    lam, vecs = np.linalg.eigh(A)
    mvee_axes = 1.0 / np.sqrt(lam)
    fixed = e_bounds[0] == e_bounds[1]
    starts = [(e_bounds[0], e_bounds[0])] if fixed else sorted({
        tuple(float(np.clip(e, *e_bounds)) for e in start) for start in ((1.0, 1.0), (0.5, 0.5))})
    best = None
    for z_axis in ((2,) if fixed else (0, 1, 2)):  # which MVEE axis becomes the shape's z (e1's axis)
        order = [i for i in range(3) if i != z_axis] + [z_axis]
        R0 = _proper_rotation(vecs[:, order])
        for start in starts:
            t, R, axes, e1, e2 = _solve_frame(V, centre, R0, mvee_axes[order], start, e_bounds, refine_pose)
            R = _proper_rotation(Rotation.from_matrix(R).as_matrix())  # re-orthonormalised
            axes = _repair(pts, t, R, axes, e1, e2)
            logv = _log_volume(*axes, e1, e2)
            if not (np.all(np.isfinite(axes)) and np.all(np.isfinite(t)) and math.isfinite(logv)):
                continue  # a diverged run: the other starts remain
            if best is None or logv < best[0]:
                best = (logv, t, R, axes, e1, e2)
    if best is None:  # pragma: no cover - every run diverged: the repaired MVEE frame, exponents at 1 if allowed
        e1 = e2 = float(np.clip(1.0, *e_bounds))
        R = _proper_rotation(vecs)
        best = (0.0, centre, R, _repair(pts, centre, R, mvee_axes, e1, e2), e1, e2)
    _, t, R, axes, e1, e2 = best
    shape = cls(*axes) if cls is Ellipsoid else cls(*axes, e1, e2)
    pose = np.eye(4)
    pose[:3, :3] = R
    pose[:3, 3] = t
    max_f = float(shape.inside((pts - t) @ R).max())
    if not max_f <= FIT_MAX_F:  # pragma: no cover - the repair guarantees it
        raise RuntimeError(f"fit left a point outside: max F = {max_f!r}")
    volume = shape.volume()
    return FitResult(shape, pose, volume, float(hull.volume), volume / float(hull.volume), max_f)
