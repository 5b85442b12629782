"""An independent penetration-depth oracle for pairs with an STP-BV or a superellipsoid (CSE).

The signed distance of convex bodies A and B is sd = -min over unit n of g(n), g(n) = h_B(n) + h_A(-n)
(the support function of the Minkowski difference B - A): for overlapping bodies, min g is the
penetration depth, and B separates by moving along minus its minimiser (the normal, A to B). This module
evaluates g from the bodies' plain data only, with code that shares nothing with spq's kernels:

- a polytope (PCH): h(n) = max over its vertices of n.v;
- an STP-BV: the brute-force support of :mod:`harness.references.stp_oracle` (from the generating points and the
  radii r, R only; no topology, no patches);
- a superellipsoid (|x/a|^p + |y/b|^p)^(q/p) + |z/c|^q <= 1, p = 2/e2, q = 2/e1: its gauge is the
  nested norm ||(||(x/a, y/b)||_p, z/c)||_q, so its support function is the dual nested norm
  h(n) = ||(||(a n_x, b n_y)||_p*, c n_z)||_q* (1/p + 1/p* = 1), and the support point is the
  gradient of h, in closed form (:func:`superellipsoid_support`).

g is minimised over the unit sphere from many starts: the best of ``STARTS`` Fibonacci directions,
then SLSQP (a sequential quadratic programme) from the ``POLISH`` best, on the constraint |n|^2 = 1
with the support point as the gradient. A polytope side makes g piecewise smooth; it enters in
epigraph form (t >= -n.v for each vertex v, the objective t + the other side's h), which SLSQP
solves with smooth functions only. Any unit n gives g(n) >= depth, so the oracle's value is an
upper bound on the depth (a lower bound on sd) whatever the optimiser did; its uncertainty is the
spread of the values the polishes reach from different starts (``spread``) when several land on the
same minimum.

Pose suites (:func:`depth_suite`): random rotations, B's origin near A's (a deep overlap); the
oracle's depth d and normal n there; B moved along n by d - target, which lowers the depth by exactly
that (the largest ball about the origin inside B - A shrinks towards the same boundary point), so
the final depth is the bucket's target; recomputed at the final pose and kept if the two agree.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.optimize import minimize
from scipy.spatial.transform import Rotation

from harness.references.stp_oracle import BruteForceSTP

STARTS = 400  # Fibonacci directions searched before polishing
POLISH = 4  # SLSQP runs from the best distinct starts
SAME_MINIMUM = 1e-6  # rad: polishes ending within this of each other found the same minimum
OVERLAP_BUCKETS = {"overlap-1e-4": 1e-4, "overlap-1e-3": 1e-3, "overlap-1e-2": 1e-2, "overlap-1e-1": 1e-1}
"""Bucket -> depth in units of the body size L = (r_A + r_B) / 2 (as harness.workloads.poses.BUCKETS)."""
AGREE = 1e-9  # m: a suite pose is kept if the oracle's depth there is its target within this


# ------------------------------------------------------------------------------------------
# support functions in the body's own frame: (support points (m, 3), values (m,)) for unit rows of U
# ------------------------------------------------------------------------------------------
def superellipsoid_support(a, b, c, e1, e2, U):
    """Support points (m, 3) and values (m,) of the superellipsoid of semi-axes a, b, c (m) and
    exponents e1, e2 in (0, 2] along the rows of U (its own frame), from the dual nested norm."""
    U = np.atleast_2d(np.asarray(U, dtype=float))
    p, q = 2.0 / e2, 2.0 / e1
    ps, qs = p / (p - 1.0) if p > 1 else np.inf, q / (q - 1.0) if q > 1 else np.inf
    if not (np.isfinite(ps) and np.isfinite(qs)):
        raise ValueError(f"exponents must be below 2 for a smooth support (got e1 = {e1}, e2 = {e2})")
    ux, uy, uz = a * U[:, 0], b * U[:, 1], c * U[:, 2]
    P = (np.abs(ux) ** ps + np.abs(uy) ** ps) ** (1.0 / ps)
    H = (P ** qs + np.abs(uz) ** qs) ** (1.0 / qs)
    safe_P = np.where(P > 0, P, 1.0)
    dP = np.where(P > 0, (P / H) ** (qs - 1.0), 0.0)  # dH/dP
    x = a * dP * np.sign(ux) * (np.abs(ux) / safe_P) ** (ps - 1.0)
    y = b * dP * np.sign(uy) * (np.abs(uy) / safe_P) ** (ps - 1.0)
    z = c * np.sign(uz) * (np.abs(uz) / H) ** (qs - 1.0)
    return np.stack([x, y, z], axis=1), H


def superellipsoid_implicit(a, b, c, e1, e2, X):
    """F(x) = (|x/a|^p + |y/b|^p)^(q/p) + |z/c|^q, p = 2/e2, q = 2/e1 (1 on the surface)."""
    X = np.atleast_2d(X)
    p, q = 2.0 / e2, 2.0 / e1
    return (np.abs(X[:, 0] / a) ** p + np.abs(X[:, 1] / b) ** p) ** (q / p) + np.abs(X[:, 2] / c) ** q


@dataclass
class Body:
    """A body for the oracle: kind 'PCH' (vertices), 'STP' (points, r, R) or 'CSE' (a, b, c, e1, e2),
    with a fixed 4x4 offset from its own frame to the frame its poses move (a fitted CSE's)."""

    kind: str
    data: tuple
    offset: np.ndarray
    _stp: object = None  # an STP-BV's brute-force support, built on first use

    def local_support(self, U):
        if self.kind == "PCH":
            (v,) = self.data
            proj = U @ v.T
            i = np.argmax(proj, axis=1)
            return v[i], proj[np.arange(len(U)), i]
        if self.kind == "STP":
            if self._stp is None:
                self._stp = BruteForceSTP(*self.data)
            s = self._stp.support_many(U)
            return s, np.einsum("ij,ij->i", s, U)
        if self.kind == "CSE":
            return superellipsoid_support(*self.data, U)
        raise ValueError(f"unknown body kind {self.kind!r}; expected PCH, STP or CSE")

    def world_support(self, pose, U):
        """Support points (m, 3, world) and values of the body at world pose (4x4) along unit rows U."""
        T = pose @ self.offset
        s, _ = self.local_support(U @ T[:3, :3])
        s = s @ T[:3, :3].T + T[:3, 3]
        return s, np.einsum("ij,ij->i", s, U)


def body_of(name: str, shape, offset=None) -> Body:
    """An oracle body from an spq shape's plain data (Polyhedron, STPBV from its points, Superellipsoid)."""
    off = np.eye(4) if offset is None else np.asarray(offset, dtype=float)
    if name == "PCH":
        return Body("PCH", (np.asarray(shape.vertices, dtype=float),), off)
    if name == "STP":
        return Body("STP", (np.asarray(shape.topology.vertices, dtype=float), float(shape.r), float(shape.R)), off)
    if name == "CSE":
        return Body("CSE", (shape.a, shape.b, shape.c, shape.e1, shape.e2), off)
    raise ValueError(f"unknown body kind {name!r}; expected PCH, STP or CSE")


def fibonacci_sphere(n: int) -> np.ndarray:
    """n roughly uniform unit vectors (n, 3)."""
    k = np.arange(n) + 0.5
    z = 1.0 - 2.0 * k / n
    phi = np.pi * (1.0 + 5 ** 0.5) * k
    rr = np.sqrt(1.0 - z * z)
    return np.stack([rr * np.cos(phi), rr * np.sin(phi), z], axis=1)


@dataclass
class OracleResult:
    signed_distance: float  # m: -min g found (a lower bound on the true sd)
    normal: np.ndarray  # unit, A to B
    spread: float  # m: spread of the values of the polishes that found the same minimum
    agreeing: int  # how many polishes found it


def signed_distance(A: Body, pose_a, B: Body, pose_b, starts: int = STARTS, polish: int = POLISH) -> OracleResult:
    """The oracle's signed distance of A at pose_a and B at pose_b (overlapping bodies: minus the
    depth), with the normal and the spread between independent polishes."""

    def g_many(U):
        _, hb = B.world_support(pose_b, U)
        _, ha = A.world_support(pose_a, -U)
        return hb + ha

    U0 = fibonacci_sphere(starts)
    g0 = g_many(U0)
    order = np.argsort(g0)
    picks = []
    for i in order:  # the best starts, not too close to one another
        if all(U0[i] @ U0[j] < np.cos(0.2) for j in picks):
            picks.append(i)
        if len(picks) == polish:
            break
    poly_a, poly_b = A.kind == "PCH", B.kind == "PCH"
    results = []
    for i in picks:
        n, val = _polish(A, pose_a, B, pose_b, U0[i], poly_a, poly_b)
        results.append((g_many(n[None])[0], n))  # re-evaluated exactly at the unit normal
    results.sort(key=lambda x: x[0])
    best, nbest = results[0]
    same = [v for v, n in results if n @ nbest > np.cos(SAME_MINIMUM) or abs(v - best) < 1e-12]
    return OracleResult(-float(best), -nbest, float(max(same) - best), len(same))


def _polish(A: Body, pose_a, B: Body, pose_b, n0, poly_a: bool, poly_b: bool):
    """SLSQP from unit n0; a polytope side in epigraph form (variable t >= its support). Returns (unit
    n, value)."""
    smooth = [(B, pose_b, 1.0)] if not poly_b else []
    smooth += [(A, pose_a, -1.0)] if not poly_a else []
    polys = []
    if poly_b:
        polys.append(((pose_b @ B.offset), B.data[0], 1.0))
    if poly_a:
        polys.append(((pose_a @ A.offset), A.data[0], -1.0))
    verts = [v @ T[:3, :3].T + T[:3, 3] for T, v, _ in polys]
    sgn = [s for _, _, s in polys]
    nt = len(polys)

    def smooth_part(n):
        val, grad = 0.0, np.zeros(3)
        for body, pose, s in smooth:
            pt, h = body.world_support(pose, (s * n)[None])
            val += h[0]
            grad += s * pt[0]
        return val, grad

    def f(x):
        return smooth_part(x[:3])[0] + x[3:].sum()

    def df(x):
        return np.concatenate([smooth_part(x[:3])[1], np.ones(nt)])

    cons = [{"type": "eq", "fun": lambda x: x[:3] @ x[:3] - 1.0, "jac": lambda x: np.concatenate([2 * x[:3],
                                                                                                 np.zeros(nt)])}]
    for k in range(nt):
        W, s = verts[k], sgn[k]

        def fun(x, W=W, s=s, k=k):
            return x[3 + k] - W @ (s * x[:3])

        def jac(x, W=W, s=s, k=k):
            J = np.zeros((len(W), 3 + nt))
            J[:, :3] = -s * W
            J[:, 3 + k] = 1.0
            return J

        cons.append({"type": "ineq", "fun": fun, "jac": jac})
    x0 = np.concatenate([n0, [float((W @ (s * n0)).max()) for W, s in zip(verts, sgn)]])
    res = minimize(f, x0, jac=df, constraints=cons, method="SLSQP", options={"ftol": 1e-16, "maxiter": 200})
    n = res.x[:3] / np.linalg.norm(res.x[:3])
    return n, res.fun


# ------------------------------------------------------------------------------------------
# pose suites and the comparison with spq
# ------------------------------------------------------------------------------------------
@dataclass
class DepthSuite:
    pair: str
    bucket: list
    target: np.ndarray
    pose_a: np.ndarray
    pose_b: np.ndarray
    oracle: np.ndarray  # sd by the oracle at the final pose
    spread: np.ndarray


def depth_suite(A: Body, B: Body, size: float, per_bucket: int, seed: int, pair: str,
                buckets: dict = OVERLAP_BUCKETS, progress=None) -> DepthSuite:
    """``per_bucket`` overlapping poses per bucket (depth = bucket * size metres), seeded."""
    if per_bucket < 1:
        raise ValueError(f"per_bucket must be >= 1, got {per_bucket}")
    rng = np.random.default_rng(seed)
    rows = []
    for name, rel in buckets.items():
        target = rel * size
        kept = 0
        while kept < per_bucket:
            rot = Rotation.random(2, random_state=rng).as_matrix()
            pa, pb = np.eye(4), np.eye(4)
            pa[:3, :3], pb[:3, :3] = rot[0], rot[1]
            pa[:3, 3] = rng.uniform(-size, size, 3)
            pb[:3, 3] = pa[:3, 3] + rng.normal(size=3) * 0.1 * size
            start = signed_distance(A, pa, B, pb)
            if not start.signed_distance < -target:
                continue
            pb[:3, 3] += (-start.signed_distance - target) * start.normal
            final = signed_distance(A, pa, B, pb)
            if abs(final.signed_distance + target) > AGREE:
                continue  # the oracle missed a minimum at one of the two poses: redraw
            rows.append((name, target, pa, pb, final.signed_distance, final.spread))
            kept += 1
            if progress is not None:
                progress.update(1)
    return DepthSuite(pair, [r[0] for r in rows], np.array([r[1] for r in rows]), np.array([r[2] for r in rows]),
                      np.array([r[3] for r in rows]), np.array([r[4] for r in rows]), np.array([r[5] for r in rows]))


def compare(suite: DepthSuite, result) -> pd.DataFrame:
    """Per pose: spq's signed result (a spq.BatchDistances) against the oracle."""
    sd = np.asarray(result.distance)
    slack = np.maximum(suite.spread, 1e-12)
    return pd.DataFrame({
        "pair": suite.pair, "bucket": suite.bucket, "target_depth_m": suite.target, "oracle_sd_m": suite.oracle,
        "oracle_spread_m": suite.spread, "spq_sd_m": sd, "spq_lower_m": result.lower_bound,
        "spq_upper_m": result.upper_bound, "spq_status": np.asarray(result.status),
        "abs_error_m": np.abs(sd - suite.oracle),
        "contains": (result.lower_bound <= suite.oracle + slack) & (suite.oracle - slack <= result.upper_bound),
    })


def summarize(table: pd.DataFrame) -> pd.DataFrame:
    """Per pair and bucket: poses, max and median |spq - oracle|, containment, spq failures, oracle spread."""
    order = {b: i for i, b in enumerate(OVERLAP_BUCKETS)}
    out = table.groupby(["pair", "bucket"], sort=False).agg(
        poses=("abs_error_m", "size"), max_abs_error_m=("abs_error_m", "max"),
        median_abs_error_m=("abs_error_m", "median"), contained_pct=("contains", lambda c: 100.0 * c.mean()),
        spq_failed=("spq_status", lambda s: int((s == "failed").sum())),
        max_oracle_spread_m=("oracle_spread_m", "max")).reset_index()
    out["_o"] = out.bucket.map(order)
    return out.sort_values(["pair", "_o"], kind="stable").drop(columns="_o").reset_index(drop=True)


PAIRS = ("STP-STP", "STP-PCH", "CSE-CSE", "CSE-PCH")
STP_POINTS = 16  # generating points of the suite's STP-BV: the brute-force support is O(n^3) per direction


@dataclass
class DepthConfig:
    object_name: str = "kuka_link_4"
    r: float = 0.005  # m: STP-BV radii, as in Table I
    R: float = 2.0
    per_bucket: int = 300  # poses per overlap bucket, pairs with a superellipsoid and a polytope
    stp_per_bucket: int = 300  # poses per overlap bucket, pairs with an STP-BV (its oracle costs ~1 s a pose)
    seed: int = 0
    pairs: tuple = PAIRS


def shapes(config: DepthConfig, load_object) -> dict:
    """kind -> (spq shape, offset 4x4): the link's hull, the STP-BV of STP_POINTS of its vertices
    (evenly spread over the hull's vertex list) and its fitted superellipsoid."""
    import spq

    pch = load_object(config.object_name)
    idx = np.linspace(0, len(pch.vertices) - 1, min(STP_POINTS, len(pch.vertices))).astype(int)
    fit = spq.Superellipsoid.fit(pch.vertices)
    return {"PCH": (pch, np.eye(4)), "STP": (spq.STPBV.from_points(pch.vertices[idx], config.r, config.R), np.eye(4)),
            "CSE": (fit.shape, fit.pose)}


def run(config: DepthConfig, load_object, progress: bool = True) -> pd.DataFrame:
    """spq's signed distances (batched, spq's default tolerances) against the oracle on each pair's
    overlap suite; one row per pose (see :func:`compare`)."""
    import spq
    from tqdm import tqdm

    unknown = [p for p in config.pairs if p not in PAIRS]
    if unknown:
        raise ValueError(f"unknown pairs {unknown}; expected some of {list(PAIRS)}")
    bodies = shapes(config, load_object)
    frames = []
    for k, pair in enumerate(config.pairs):
        an, bn = pair.split("-")
        (sa, oa), (sb, ob) = bodies[an], bodies[bn]
        per = config.stp_per_bucket if "STP" in pair else config.per_bucket
        size = 0.5 * (sa.bounding_radius() + sb.bounding_radius())
        with tqdm(total=per * len(OVERLAP_BUCKETS), desc=f"depth oracle {pair}", unit="pose",
                  disable=not progress) as bar:
            suite = depth_suite(body_of(an, sa, oa), body_of(bn, sb, ob), size, per, config.seed + k, pair,
                                progress=bar)
        result = spq.distances(sa, sb, suite.pose_a @ oa, suite.pose_b @ ob, signed=True)
        frames.append(compare(suite, result))
    return pd.concat(frames, ignore_index=True)
