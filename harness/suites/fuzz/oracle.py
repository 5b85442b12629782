"""The fuzz campaign's independent side: support functions from a spec's plain data, the spq shape and
the peers' meshes it stands for, and the exact reference or the depth oracle for one pose pair.

Nothing here calls spq's kernels: a polytope's support is the best of its vertices (numpy), an STP-BV's
the brute force of harness.references.stp_oracle (points and radii only), a superellipsoid's the closed form of
harness.references.depth_oracle; a sphere is a point and a capsule a segment, inflated by their radius (a support
value grows by r, a signed distance drops by r). The reference for one pose pair: the exact Minkowski
reference (harness.references.minkowski) when both sides are polytopes, else the depth oracle's multi-start
minimisation of the support of the Minkowski difference, with the radii subtracted.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

POLYTOPES = ("pch", "box")


def box_corners(half) -> np.ndarray:
    h = np.asarray(half, float)
    return np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], float) * h


@dataclass
class OracleShape:
    """A spec's support function, in its own frame: a core (vertices, or an STP-BV / superellipsoid
    body of harness.references.depth_oracle) swept by a ball of ``radius``."""

    spec: dict
    core: object  # depth_oracle.Body
    radius: float
    size: float  # m: largest support value over the axis directions, a length scale
    magnitude: float = 0.0  # m: largest coordinate its support computes with (an STP-BV's R), for rounding

    def support(self, U) -> tuple[np.ndarray, np.ndarray]:
        """(points (m, 3), values (m,)) along the unit rows of U (own frame)."""
        U = np.atleast_2d(np.asarray(U, float))
        s, h = self.core.local_support(U)
        if self.radius:
            s = s + self.radius * U
            h = h + self.radius
        return s, h

    def support_values(self, U) -> np.ndarray:
        return self.support(U)[1]

    def world_support(self, poses, U):
        """Support points (m, 3) and values along world unit rows U of the shape at poses (m, 4, 4)."""
        R, t = poses[:, :3, :3], poses[:, :3, 3]
        s, _ = self.support(np.einsum("mji,mj->mi", R, U))
        s = np.einsum("mij,mj->mi", R, s) + t
        return s, np.einsum("mi,mi->m", s, U)


def oracle_shape(spec: dict) -> OracleShape:
    from harness.references.depth_oracle import Body

    kind, eye = spec["kind"], np.eye(4)
    radius = 0.0
    if kind == "pch":
        core = Body("PCH", (np.asarray(spec["points"], float),), eye)
    elif kind == "box":
        core = Body("PCH", (box_corners(spec["half"]),), eye)
    elif kind == "sphere":
        core, radius = Body("PCH", (np.zeros((1, 3)),), eye), float(spec["r"])
    elif kind == "capsule":
        core, radius = Body("PCH", (np.array([[0, 0, -spec["hl"]], [0, 0, spec["hl"]]], float),), eye), float(spec["r"])
    elif kind == "stp":
        core = Body("STP", (np.asarray(spec["points"], float), float(spec["r"]), float(spec["R"])), eye)
    elif kind == "cse":
        core = Body("CSE", tuple(float(spec[k]) for k in ("a", "b", "c", "e1", "e2")), eye)
    else:
        raise ValueError(f"unknown shape kind {kind!r}; expected pch, box, sphere, capsule, stp or cse")
    shape = OracleShape(spec, core, radius, 0.0)
    axes = np.concatenate([np.eye(3), -np.eye(3)])
    shape.size = float(np.abs(shape.support_values(axes)).max())
    shape.magnitude = shape.size + (float(spec["R"]) * stp_condition(spec) if kind == "stp" else 0.0)
    return shape


STP_CONDITION_CAP = 1e4


def stp_condition(spec: dict) -> float:
    """How much an STP-BV's sphere centres amplify a rounding of its points: R' / sqrt(R'^2 - rho^2),
    with R' = R - r and rho the points' enclosing radius. At R near its minimum a big sphere's centre
    lies at sqrt(R'^2 - rho_f^2) from its face's circumcentre, a difference of nearly equal squares,
    so spq's and the oracle's bodies differ by about eps R times this (1e-13 m at R 1e-6 above its
    minimum): the judge's rounding slack grows with it. At most STP_CONDITION_CAP."""
    from spq.stp.construction import enclosing_radius

    big = float(spec["R"]) - float(spec["r"])
    rho = enclosing_radius(np.asarray(spec["points"], float))
    gap = (big - rho) * (big + rho)
    return STP_CONDITION_CAP if gap <= 0.0 else min(STP_CONDITION_CAP, max(1.0, big / np.sqrt(gap)))


def spq_shape(spec: dict):
    """The spq shape a spec stands for."""
    import spq

    kind = spec["kind"]
    if kind == "pch":
        return spq.Polyhedron.from_points(np.asarray(spec["points"], float))
    if kind == "box":
        return spq.Box(*spec["half"])
    if kind == "sphere":
        return spq.Sphere(spec["r"])
    if kind == "capsule":
        return spq.Capsule(spec["r"], spec["hl"])
    if kind == "stp":
        return spq.STPBV.from_points(np.asarray(spec["points"], float), spec["r"], spec["R"])
    if kind == "cse":
        return spq.Superellipsoid(*(spec[k] for k in ("a", "b", "c", "e1", "e2")))
    raise ValueError(f"unknown shape kind {kind!r}")


def peer_polyhedron(spec: dict):
    """The spq Polyhedron a peer is given for a polytope spec (hull vertices and faces), or None."""
    import spq

    if spec["kind"] == "pch":
        return spq.Polyhedron.from_points(np.asarray(spec["points"], float))
    if spec["kind"] == "box":
        return spq.Polyhedron.from_points(box_corners(spec["half"]))
    return None


def separation_bounds(oa: OracleShape, ob: OracleShape, poses_a, poses_b, normals):
    """(lower, upper) bounds (m, each (n,)) on the signed distance from each pose pair's normal m (A to
    B, unit): lower = the separation along m, -(h_A(m) + h_B(-m)), a lower bound for any m; upper =
    |b* - a*| for the support points a* of A along m and b* of B along -m, an upper bound when the
    bodies are apart (NaN where the lower bound is not positive). Both equal the signed distance when m
    is the optimal normal and the support points are unique."""
    a, ha = oa.world_support(poses_a, normals)
    b, hb = ob.world_support(poses_b, -normals)
    lower = -(ha + hb)
    upper = np.where(lower > 0, np.linalg.norm(b - a, axis=1), np.nan)
    return lower, upper


@dataclass
class Reference:
    signed_distance: float
    uncertainty: float  # m: 0 for the exact reference; the oracle's polish spread otherwise
    exact: bool


def reference(oa: OracleShape, ob: OracleShape, pose_a, pose_b, poly=None) -> Reference:
    """The signed distance of the pair at one pose pair (module docstring). poly: the (Polyhedron A,
    Polyhedron B) of two polytope specs, built once per case by the caller. Two polytopes whose
    Minkowski difference qhull cannot build (a precision error on near-coplanar points, about once
    in 10^6 queries) go to the depth oracle, as curved bodies do."""
    if oa.spec["kind"] in POLYTOPES and ob.spec["kind"] in POLYTOPES:
        from harness.references.minkowski import reference_distance

        pa, pb = poly if poly is not None else (peer_polyhedron(oa.spec), peer_polyhedron(ob.spec))
        try:
            r = reference_distance(pa, pb, pose_a, pose_b)
            return Reference(float(r.signed_distance), 0.0, True)
        except ValueError:
            pass  # qhull refused the Minkowski difference (near-coplanar points): the oracle judges it
    from harness.references.depth_oracle import signed_distance

    r = signed_distance(oa.core, pose_a, ob.core, pose_b)
    return Reference(float(r.signed_distance) - oa.radius - ob.radius, float(r.spread), False)
