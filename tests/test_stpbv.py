"""STP-BV support: unique region ownership, agreement of the three searches, and independent oracles
(containment, convexity, brute force over the admissible-centre set Q), on files and on builds."""

from __future__ import annotations

import numpy as np
import pytest

import spq
from harness.references.stp_oracle import brute_force_support_many
from spq.shapes.stpbv import STPBV

SAMPLE_FILES = [
    ("sch-samples", "sample_stpbv1.txt"),
    ("sch-samples", "sample_stpbv2.txt"),
    ("sch-samples", "sample_stp_p.txt"),
    ("sch-creator-examples/stp", "cube2x2.txt"),
    ("sch-creator-examples/stp", "s2x2.txt"),
]


def directions(n, seed):
    d = np.random.default_rng(seed).normal(size=(n, 3))
    k = n // 20
    d[np.arange(k), np.random.default_rng(seed + 1).integers(0, 3, k)] = 0.0  # directions with a zero component
    return d


def unit(d):
    return d / np.linalg.norm(d, axis=1)[:, None]


def check_support_oracles(stp: STPBV, n=20000, seed=0, tol=1e-12):
    """Unique ownership, agreement of the three methods (both exact), containment and convexity
    (to tol, relative to the body's scale for the latter)."""
    d = directions(n, seed)
    counts = stp.owner_counts(d)
    assert (counts == 1).all(), np.bincount(counts)
    naive = stp.support(d, method="naive")
    for method in ("march", "hull"):
        np.testing.assert_allclose(stp.support(d, method=method), naive, rtol=0, atol=1e-12)
        np.testing.assert_allclose(stp.support(d, method=method, coherent=True), naive, rtol=0, atol=1e-12)
    u = unit(d)
    x = stp.topology.vertices
    # (a) containment: the STP-BV holds every small sphere
    assert (np.einsum("ij,ij->i", u, naive) - ((u @ x.T).max(axis=1) + stp.r)).min() >= -tol
    # (b) convexity consistency: u.s(u) >= u.s(v)
    v = unit(directions(n, seed + 7))
    sv = stp.support(v)
    assert (np.einsum("ij,ij->i", u, naive) - np.einsum("ij,ij->i", u, sv)).min() >= -tol * (1 + stp.R)


@pytest.mark.parametrize("folder, name", SAMPLE_FILES)
def test_loaded_sample_files_have_unique_owners_and_agreeing_methods(shared_datasets, folder, name):
    stp = STPBV.from_sch_file(shared_datasets / folder / name)
    # the sch-core samples print 6 significant digits: their small and big spheres agree with each
    # other only to 6.4e-7 m (R = 1) and 5.9e-5 m (R = 20) (tests/test_sch_io.py); the sch-creator
    # files print full precision
    tol = 1e-12 if folder.startswith("sch-creator") else 1e-4
    check_support_oracles(stp, n=100_000, tol=tol)


@pytest.mark.parametrize("name", ["cube2x2.txt", "s2x2.txt"])
def test_file_support_matches_the_brute_force_over_q(shared_datasets, name):
    stp = STPBV.from_sch_file(shared_datasets / "sch-creator-examples" / "stp" / name)
    d = directions(300, 5)
    brute = brute_force_support_many(stp.topology.vertices, stp.r, stp.R, d)
    np.testing.assert_allclose(stp.support(d), brute, rtol=0, atol=1e-9)


def test_write_then_read_gives_the_same_object(shared_datasets, tmp_path):
    stp = STPBV.from_sch_file(shared_datasets / "sch-samples" / "sample_stp_p.txt")
    stp.to_sch_file(tmp_path / "copy.txt")
    back = STPBV.from_sch_file(tmp_path / "copy.txt")
    assert back.counts() == stp.counts()
    for field in ("vertices", "faces", "face_centres", "edges", "edge_faces", "edge_real"):
        np.testing.assert_array_equal(getattr(back.topology, field), getattr(stp.topology, field))
    d = directions(2000, 3)
    np.testing.assert_array_equal(back.support(d), stp.support(d))


def test_warm_search_along_a_smooth_path_takes_about_zero_steps(shared_datasets):
    from harness.suites.support.stp_scaling import smooth_directions

    stp = STPBV.from_sch_file(shared_datasets / "sch-samples" / "sample_stp_p.txt")
    d = smooth_directions(20000, 0)
    _, _, cold = stp.support_patches(d, method="march", coherent=False)
    _, _, warm = stp.support_patches(d, method="march", coherent=True)
    _, _, warm_hull = stp.support_patches(d, method="hull", coherent=True)
    assert warm.mean() < 0.1 < cold.mean()
    assert warm_hull.mean() < 0.1


def test_unknown_method_raises_value_error(shared_datasets):
    stp = STPBV.from_sch_file(shared_datasets / "sch-creator-examples" / "stp" / "cube2x2.txt")
    with pytest.raises(ValueError, match="unknown support method"):
        stp.method = "fast"
    with pytest.raises(ValueError, match="unknown support method"):
        stp.support([1.0, 0, 0], method="fast")


def test_stp_distance_never_exceeds_the_pch_distance_minus_r(shared_datasets):
    """The STP-BV holds the hull grown by r, so d_STP <= max(0, d_PCH - r) (coal gives d_PCH)."""
    from scipy.spatial.transform import Rotation

    from harness.engines.coal_engine import CoalEngine

    # s2x2 is printed at full precision; the sch-core samples round to 6 digits, which leaves a few of
    # their faces slightly off the ball hull of the rounded points (see tests/test_sch_io.py)
    stp = STPBV.from_sch_file(shared_datasets / "sch-creator-examples" / "stp" / "s2x2.txt")
    pch = spq.Polyhedron.from_points(stp.topology.vertices)
    coal_pair = CoalEngine().prepare(pch, pch)
    rng = np.random.default_rng(2)
    size = pch.bounding_radius()
    for _ in range(200):
        pa, pb = np.eye(4), np.eye(4)
        pa[:3, :3] = Rotation.random(random_state=rng).as_matrix()
        pb[:3, :3] = Rotation.random(random_state=rng).as_matrix()
        pb[:3, 3] = rng.normal(size=3) * size
        d_pch = coal_pair.query(pa, pb).distance
        for a, b, shrink in ((stp, pch, stp.r), (stp, stp, 2 * stp.r), (pch, stp, stp.r)):
            r = spq.distance(a, b, pa, pb)
            assert r.status != "failed"
            assert r.distance <= max(0.0, d_pch - shrink) + 1e-9


# --- built STP-BVs ---------------------------------------------------------------------------
BUILT = [("kuka_link_4", 0.005, 2.0), ("kuka_link_4", 0.01, 0.3), ("kuka_link_2", 0.005, 1.0),
         ("kuka_link_6", 0.002, 5.0), ("panda_link_2", 0.005, 0.5), ("panda_hand", 0.01, 0.2),
         ("panda_link_5", 0.001, 20.0)]


@pytest.mark.parametrize("name, r, R", BUILT)
def test_built_links_have_unique_owners_agreeing_methods_and_pass_the_oracles(name, r, R):
    from datasets import load_object

    stp = STPBV.from_points(load_object(name).vertices, r, R)
    check_support_oracles(stp, n=100_000, tol=1e-12)


@pytest.mark.parametrize("seed, R", [(0, 0.15), (1, 0.5), (2, 3.0)])
def test_built_support_matches_the_brute_force_over_q(seed, R):
    from datasets import load_object

    pts = load_object("kuka_link_4").vertices
    sub = pts[np.random.default_rng(seed).choice(len(pts), 40, replace=False)]
    stp = STPBV.from_points(sub, 0.004, R)
    d = directions(400, seed)
    np.testing.assert_allclose(stp.support(d), brute_force_support_many(sub, 0.004, R, d), rtol=0, atol=1e-9)


@pytest.mark.parametrize("dense", [True, False])
@pytest.mark.parametrize("seed, R", [(0, 0.15), (2, 3.0)])
def test_the_core_support_is_the_brute_force_support_less_r_along_the_unit_direction(seed, R, dense):
    """The signed query's EPA continues on STP_CORE, the ball hull at R - r that the STP-BV grows by r:
    its support must be the STP-BV's (brute force over Q) less r u, at any direction's length."""
    from datasets import load_object
    from spq.kernels.dispatch import support_many
    from spq.kernels.kinds import STP_CORE

    pts = load_object("kuka_link_4").vertices
    sub = pts[np.random.default_rng(seed).choice(len(pts), 40, replace=False)]
    r = 0.004
    stp = STPBV.from_points(sub, r, R)
    kd = stp.kernel_data(dense)  # a standalone STP-BV's embedded cube map, or a scene's sparse one
    d = directions(400, seed) * np.random.default_rng(seed + 3).uniform(0.01, 100.0, (400, 1))
    core = support_many(STP_CORE, kd.fdata, kd.idata, d)
    np.testing.assert_allclose(core, brute_force_support_many(sub, r, R, d) - r * unit(d), rtol=0, atol=1e-9)


@pytest.mark.parametrize("name", ["cube2x2", "s2x2"])
def test_the_reference_generator_is_reproduced_from_its_cloud(shared_datasets, name):
    root = shared_datasets / "sch-creator-examples"
    lines = (root / "cloud" / f"{name}.cloud").read_text().split()
    cloud = np.array(lines[2:], dtype=float).reshape(int(lines[1]), 3)
    from_file = STPBV.from_sch_file(root / "stp" / f"{name}.txt")
    built = STPBV.from_points(cloud, from_file.r, from_file.R)
    assert built.counts() == from_file.counts()
    d = directions(100_000, 9)
    np.testing.assert_allclose(built.support(d), from_file.support(d), rtol=0, atol=1e-9)


@pytest.mark.parametrize("kwargs, what", [
    (dict(points=np.random.default_rng(0).normal(size=(20, 3)), r=0.01, R=0.5), r"need R >= "),
    (dict(points=np.random.default_rng(0).normal(size=(20, 3)), r=0.0, R=5.0), "r"),
    (dict(points=np.random.default_rng(0).normal(size=(20, 3)), r=0.1, R=0.1), "R"),
    (dict(points=np.array([[0.0, 0, 0], [np.nan, 0, 0], [1, 1, 1]]), r=0.01, R=5.0), "NaN"),
    (dict(points=np.zeros((5, 3)), r=0.01, R=5.0), "distinct"),
])
def test_bad_construction_input_raises_value_error(kwargs, what):
    with pytest.raises(ValueError, match=what):
        STPBV.from_points(**kwargs)


def test_malformed_sch_file_raises_value_error(tmp_path):
    bad = tmp_path / "bad.txt"
    bad.write_text("0.1 1\n 2\n0.1 0 0 x\n")
    with pytest.raises(ValueError):
        STPBV.from_sch_file(bad)


def test_the_smallest_admissible_r_in_the_message_is_accepted():
    import re

    pts = np.random.default_rng(0).normal(size=(20, 3))
    with pytest.raises(ValueError) as info:
        STPBV.from_points(pts, 0.01, 0.5)
    bound = float(re.search(r"R >= ([0-9.eE+-]+) \(with", str(info.value)).group(1))
    assert STPBV.from_points(pts, 0.01, bound).n_small >= 2


def test_from_mesh_builds_the_same_stp_bv_as_the_mesh_vertices():
    import trimesh

    from datasets.paths import pybullet_data_dir
    from datasets.robot_links import ROBOT_LINKS

    path = pybullet_data_dir() / ROBOT_LINKS["kuka_link_4"]
    from_mesh = STPBV.from_mesh(path, 0.005, 2.0)
    from_points = STPBV.from_points(trimesh.load(path, force="mesh", process=False).vertices, 0.005, 2.0)
    assert from_mesh.counts() == from_points.counts()
    d = directions(2000, 11)
    np.testing.assert_array_equal(from_mesh.support(d), from_points.support(d))


@pytest.mark.parametrize("name, r, R, seed", [("kuka_link_4", 0.005, 2.0, 0), ("kuka_link_4", 0.004, 0.15, 1),
                                                ("panda_hand", 0.01, 0.2, 2)])
def test_the_hull_vertex_table_answers_as_the_small_spheres_own_records_and_the_brute_force(name, r, R, seed):
    """The table the certificates read from a hull vertex: ownership as the naive scan's owner, the
    march step towards a neighbour across a boundary, and where the sphere owns a direction the
    support is the vertex plus r times it, by the brute force over Q (on 40 points of the link: the
    brute force is cubic in them)."""
    from datasets import load_object
    from spq.kernels.stp_batch import hull_vertex_table_answers

    pts = load_object(name).vertices
    pts = pts[np.random.default_rng(seed).choice(len(pts), 40, replace=False)]
    stp = STPBV.from_points(pts, r, R)
    kd = stp.kernel_data()
    d = directions(2000, seed)
    u = unit(d)
    owns, steps = hull_vertex_table_answers(kd.fdata, kd.idata, np.ascontiguousarray(d))
    patches = stp.support_patches(d, method="naive")[1]
    small = stp.hull_to_small
    np.testing.assert_array_equal(owns, patches[:, None] == small[None, :])
    assert owns.any(axis=1).sum() >= 20  # enough owned directions for the brute force to check
    k, h = np.nonzero(owns)
    expected = brute_force_support_many(stp.topology.vertices, r, R, d[k])
    np.testing.assert_allclose(stp.hull.vertices[h] + r * u[k], expected, rtol=0, atol=1e-9)
    # a step leads to a neighbour of the sphere across a boundary it violates, or nowhere where it owns
    assert ((steps < 0) == owns).all()
    off, rec = stp.patch_offsets, stp.records
    for j in range(0, len(small), max(1, len(small) // 25)):
        nb = rec[off[small[j]]:off[small[j] + 1], 2]
        assert np.isin(steps[~owns[:, j], j], nb).all()
