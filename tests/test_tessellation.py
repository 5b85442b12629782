"""Meshes of the bounding volumes (to_mesh): vertices on the true surface, watertight, certified error,
volumes converging to the body's, exports that reload."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

import spq
from harness.references.stp_oracle import brute_force_support_many
from spq import tessellation as ts


def link(name="kuka_link_4"):
    from datasets import load_object

    return load_object(name)


@pytest.fixture(scope="module")
def stp():
    return spq.STPBV.from_points(link().vertices, 0.005, 2.0)


@pytest.fixture(scope="module")
def cse():
    return spq.Superellipsoid.fit(link().vertices).shape


def unit_directions(n, seed):
    d = np.random.default_rng(seed).normal(size=(n, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def steiner_upper(mesh: trimesh.Trimesh, eps: float) -> float:
    """Volume of the mesh grown by eps (Steiner's formula for a convex polytope): V + A eps + M eps^2 +
    4/3 pi eps^3, M = half the sum over edges of length x exterior dihedral angle. A body within
    Hausdorff distance eps of the mesh (and containing it) has at most this volume."""
    lengths = np.linalg.norm(np.diff(mesh.vertices[mesh.face_adjacency_edges], axis=1)[:, 0], axis=1)
    m = 0.5 * float((lengths * mesh.face_adjacency_angles).sum())
    return mesh.volume + mesh.area * eps + m * eps ** 2 + 4.0 / 3.0 * math.pi * eps ** 3


def gap_to_support(mesh, support, n=20000, seed=0) -> float:
    """max over random unit u of h_K(u) - h_mesh(u): how far the body reaches beyond the mesh."""
    u = unit_directions(n, seed)
    return float((np.einsum("ij,ij->i", u, support(u)) - (u @ mesh.vertices.T).max(axis=1)).max())


# --- vertices on the true surface ---------------------------------------------------------------
@pytest.mark.parametrize("seed, R", [(0, 0.15), (1, 0.5), (2, 3.0)])
def test_stp_vertices_are_the_brute_force_support_points_of_their_normals(seed, R):
    pts = link().vertices
    sub = pts[np.random.default_rng(seed).choice(len(pts), 40, replace=False)]
    small = spq.STPBV.from_points(sub, 0.004, R)
    mesh = small.to_mesh(1e-4)
    pick = np.random.default_rng(seed).choice(len(mesh.vertices), 400, replace=False)  # the oracle is O(n^3)
    normals = mesh.vertex_normals[pick]
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(mesh.vertices[pick], brute_force_support_many(sub, 0.004, R, normals), rtol=0,
                               atol=1e-9)
    assert set(mesh.metadata["face_kind"]) == {"small_sphere", "big_sphere", "torus"}


def test_stp_vertices_lie_on_the_surface_by_gjk_against_a_tiny_sphere(stp):
    """A 1e-12 m sphere 1e-6 m outside a vertex along its normal is 1e-6 m away (within GJK's certified
    bounds); 1e-6 m inside, it overlaps."""
    mesh = stp.to_mesh(2e-4)
    v, n = mesh.vertices, mesh.vertex_normals
    poses = np.tile(np.eye(4), (len(v), 1, 1))
    dot = spq.Sphere(1e-12)
    poses[:, :3, 3] = v + 1e-6 * n
    out = spq.distances(stp, dot, np.eye(4), poses)
    true = 1e-6 - 1e-12
    assert (out.lower_bound <= true + 1e-14).all() and (out.distance >= true - 1e-14).all()  # rounding: centres 2 m away
    assert np.abs(out.distance - true).max() <= 2e-10  # GJK's stopping tolerance
    poses[:, :3, 3] = v - 1e-6 * n
    assert set(spq.distances(stp, dot, np.eye(4), poses).status) == {"overlapping"}


def test_stp_vertices_agree_with_the_naive_support_search(stp):
    mesh = stp.to_mesh()
    # neighbouring patches' closed forms meet to ~1e-11 m at their boundaries (rounding of the centres, 2 m away)
    np.testing.assert_allclose(mesh.vertices, stp.support(mesh.vertex_normals, method="naive"), rtol=0, atol=1e-10)


def test_superellipsoid_vertices_satisfy_the_implicit_equation_with_its_gradient_as_normal(cse):
    mesh = cse.to_mesh()
    np.testing.assert_allclose(cse.inside(mesh.vertices), 1.0, rtol=0, atol=1e-12)
    # outward normal of F = 1: the gradient of F, by central differences
    h = 1e-7
    grad = np.stack([(cse.inside(mesh.vertices + h * e) - cse.inside(mesh.vertices - h * e)) / (2 * h)
                     for e in np.eye(3)], axis=1)
    keep = np.all(np.abs(mesh.vertices) > 1e-4, axis=1)  # away from the axis planes, where |x|^p has kinks
    grad = grad[keep] / np.linalg.norm(grad[keep], axis=1, keepdims=True)
    assert np.einsum("ij,ij->i", grad, mesh.vertex_normals[keep]).min() > 1 - 1e-6


def test_polyhedron_mesh_is_its_hull(stp):
    hull = link()
    mesh = hull.to_mesh()
    np.testing.assert_array_equal(mesh.vertices, hull.vertices)
    np.testing.assert_array_equal(mesh.faces, hull.faces)
    assert mesh.metadata["max_error"] == 0.0


# --- watertight and certified -------------------------------------------------------------------
@pytest.mark.parametrize("which", ["pch", "stp", "cse", "box-like cse", "octahedron cse", "spindle stp"])
def test_meshes_are_watertight_convex_and_wound_outward(which, stp, cse):
    shape = {"pch": link(), "stp": stp, "cse": cse, "box-like cse": spq.Superellipsoid(0.1, 0.05, 0.2, 0.1, 0.1),
             "octahedron cse": spq.Superellipsoid(0.1, 0.05, 0.2, 2.0, 2.0),
             "spindle stp": spq.STPBV.from_points([[0, 0, -0.1], [0, 0, 0.1]], 0.01, 0.2)}[which]
    mesh = shape.to_mesh()
    assert mesh.is_watertight and mesh.is_winding_consistent and mesh.is_volume and mesh.is_convex
    assert mesh.volume > 0  # outward: a positive signed volume


@pytest.mark.parametrize("which, tolerance", [("stp", 1e-3), ("stp", 1e-4), ("cse", 1e-3), ("cse", 1e-4),
                                              ("box-like cse", 3e-4)])
def test_the_certified_error_holds_against_dense_support_sampling(which, tolerance, stp, cse):
    shape = {"stp": stp, "cse": cse, "box-like cse": spq.Superellipsoid(0.1, 0.05, 0.2, 0.1, 0.1)}[which]
    mesh = shape.to_mesh(tolerance)
    bound = mesh.metadata["max_error"]
    assert 0.0 <= bound <= tolerance * (1 + 1e-9)
    gap = gap_to_support(mesh, shape.support)
    assert -1e-12 <= gap <= bound + 1e-12


def test_the_certificate_brackets_the_exact_error_of_a_polytope_in_a_sphere():
    """Unit sphere, hull P of points on it: the exact Hausdorff distance is 1 - (least face offset)."""
    points = unit_directions(300, 4)
    used, faces, planes = ts.hull(points)
    bound, _ = ts.hausdorff_bound(points[used], faces, planes, lambda u: u / np.linalg.norm(u, axis=1, keepdims=True))
    exact = 1.0 - planes[:, 3].min()
    assert exact <= bound <= exact / math.cos(ts.CONE_ANGLE)


# --- volumes ------------------------------------------------------------------------------------
def test_polyhedron_mesh_volume_is_the_hull_volume():
    from scipy.spatial import ConvexHull

    hull = link("kuka_link_2")
    assert hull.to_mesh().volume == pytest.approx(ConvexHull(hull.vertices).volume, rel=1e-12)


@pytest.mark.parametrize("shape", [spq.Superellipsoid(0.08, 0.05, 0.12, 0.4, 1.0),
                                   spq.Superellipsoid(0.1, 0.1, 0.05, 1.6, 0.3), spq.Ellipsoid(0.1, 0.06, 0.03)],
                         ids=repr)
def test_superellipsoid_mesh_volume_converges_to_the_closed_form(shape):
    errors = []
    for rel in (3e-3, 1e-3, 2e-4):
        tol = rel * shape.bounding_radius()
        mesh = shape.to_mesh(tol)
        assert mesh.volume <= shape.volume() <= steiner_upper(mesh, mesh.metadata["max_error"])
        errors.append(shape.volume() - mesh.volume)
    assert errors[0] > errors[1] > errors[2] > 0 and errors[2] < 2e-3 * shape.volume()


def test_stp_mesh_volume_converges_and_agrees_with_monte_carlo(stp):
    lows, highs = [], []
    for tol in (1e-3, 3e-4, 1e-4):
        mesh = stp.to_mesh(tol)
        lows.append(mesh.volume)
        highs.append(steiner_upper(mesh, mesh.metadata["max_error"]))
    # every bracket holds the true volume: they are nested or overlapping, and they shrink
    assert max(lows) <= min(highs)
    assert lows[0] < lows[1] < lows[2] and (highs[2] - lows[2]) < 0.5 * (highs[0] - lows[0])
    # Monte Carlo inside test by GJK (a 1e-12 m sphere overlaps or touches) in the mesh's box grown by tol
    rng = np.random.default_rng(0)
    lo, hi = mesh.bounds[0] - 1e-4, mesh.bounds[1] + 1e-4
    n = 200_000
    poses = np.tile(np.eye(4), (n, 1, 1))
    poses[:, :3, 3] = rng.uniform(lo, hi, size=(n, 3))
    res = spq.distances(stp, spq.Sphere(1e-12), np.eye(4), poses)
    p = np.isin(res.status, ["overlapping", "touching"]).mean()
    box = float(np.prod(hi - lo))
    sigma = math.sqrt(p * (1 - p) / n) * box
    assert lows[2] - 4 * sigma <= p * box <= highs[2] + 4 * sigma


# --- export and bad input -----------------------------------------------------------------------
@pytest.mark.parametrize("ext", ["glb", "obj"])
def test_an_exported_mesh_reloads_in_trimesh_with_the_same_vertices(ext, stp, tmp_path):
    mesh = stp.to_mesh()
    path = tmp_path / f"stp.{ext}"
    mesh.export(path)
    back = trimesh.load(path, process=False, force="mesh")
    np.testing.assert_allclose(back.vertices, mesh.vertices, rtol=0, atol=1e-7)  # GLB stores float32
    np.testing.assert_array_equal(back.faces, mesh.faces)


@pytest.mark.parametrize("tolerance, what", [(0.0, "tolerance must lie in"), (-1e-3, "tolerance must lie in"),
                                             (float("nan"), "tolerance must lie in"), (1.0, "tolerance must lie in"),
                                             (1e-9, "tolerance must lie in"), ("fine", "distance in metres")])
def test_a_tolerance_out_of_range_raises_value_error(tolerance, what, stp, cse):
    for shape in (stp, cse):
        with pytest.raises(ValueError, match=what):
            shape.to_mesh(tolerance)


# --- patch colours and robot bodies -------------------------------------------------------------
def test_a_triangle_within_one_patch_is_given_that_patch():
    """Triangles whose three vertices' normals one patch owns lie on that patch (oracle: the support
    search's owner of each vertex normal); the face colours of the pictures come from face_patch."""
    stp = spq.STPBV.from_points(link().vertices, 0.02, 0.4)
    mesh = stp.to_mesh(1e-4)
    _, owner, _ = stp.support_patches(mesh.vertex_normals)
    tri = owner[mesh.faces]
    same = (tri[:, 0] == tri[:, 1]) & (tri[:, 1] == tri[:, 2])
    assert same.sum() > 0.25 * len(tri)  # the rest straddle a boundary
    assert (mesh.metadata["face_patch"][same] == tri[same, 0]).mean() > 0.99
    assert set(mesh.metadata["face_kind"]) == {"small_sphere", "big_sphere", "torus"}


@pytest.mark.parametrize("robot", ["kuka_iiwa", "panda"])
def test_every_body_of_a_robot_meshes_watertight_within_its_tolerance(robot):
    from harness.suites.robot.robot_bench import RobotBenchConfig, load_scene

    scene = load_scene(RobotBenchConfig(robot=robot), "stp-both")
    for body in scene.bodies:
        for tol in (1e-3, 1e-4):
            mesh = body.stp.to_mesh(tol)
            assert mesh.is_watertight and mesh.is_winding_consistent, body.name
            assert mesh.metadata["max_error"] <= tol * (1 + 1e-9)
