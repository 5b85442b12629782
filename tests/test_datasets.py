"""The objects tests and benchmarks use load, with the expected sizes."""

from __future__ import annotations

import numpy as np
import pytest

import datasets
from datasets import DEFAULT_OBJECTS, ROBOT_LINKS, list_objects, load_object
from datasets.generated import random_hull
from datasets.paths import ENV_SHARED, pybullet_data_dir, shared_datasets_dir
from spq.shapes.polyhedron import Polyhedron


def _sane(poly: Polyhedron) -> None:
    assert isinstance(poly, Polyhedron)
    assert poly.vertices.ndim == 2 and poly.vertices.shape[1] == 3 and len(poly.vertices) >= 4
    assert np.isfinite(poly.vertices).all()
    assert 1e-3 < poly.bounding_radius() < 1.0  # metres: robot-link sized
    # every vertex lies on or inside every face plane (a convex hull)
    # face planes come from qhull, fitted to whole facets: exact to rounding even on sliver triangles
    assert poly.signed_distance_to_surface(poly.vertices).max() <= 1e-13


def test_default_objects_load():
    assert len(DEFAULT_OBJECTS) >= 7
    assert sum(n in ROBOT_LINKS for n in DEFAULT_OBJECTS) >= 5
    assert {"random_hull_50", "random_hull_200"} <= set(DEFAULT_OBJECTS)
    for name in DEFAULT_OBJECTS:
        poly = load_object(name)
        _sane(poly)
        assert poly.name == name
        assert load_object(name) is poly  # cached


def test_kuka_link_4_hull_has_315_vertices():
    assert len(load_object("kuka_link_4").vertices) == 315


@pytest.mark.parametrize("name", sorted(ROBOT_LINKS))
def test_every_robot_link_loads(name):
    _sane(datasets.load_link(name))


def test_random_hull_is_seeded_and_exact_size():
    a, b = random_hull(30, seed=7), random_hull(30, seed=7)
    np.testing.assert_array_equal(a.vertices, b.vertices)
    assert len(a.vertices) == 30
    assert not np.array_equal(a.vertices, random_hull(30, seed=8).vertices)
    assert len(load_object("random_hull_50").vertices) == 50
    assert len(load_object("random_hull_200").vertices) == 200
    assert len(random_hull(200, seed=1, noise=0.3).vertices) < 200
    for bad in (dict(n_points=3, seed=0), dict(n_points=10, seed=0, scale=-1.0), dict(n_points=10, seed=0, noise=1.0)):
        with pytest.raises(ValueError):
            random_hull(**bad)


def test_load_object_from_paths(tmp_path):
    mesh = pybullet_data_dir() / "kuka_iiwa" / "meshes" / "link_4.stl"
    poly = load_object(mesh)
    assert len(poly.vertices) == 315
    assert load_object(str(mesh)).name == "link_4"
    hull = random_hull(12, seed=3)
    pts, faces = hull.vertices, hull.faces
    qh = tmp_path / "hull-ch.txt"
    lines = ["3", f"{len(pts)} {len(faces)} 0", *(" ".join(f"{x:.17g}" for x in p) for p in pts)]
    lines += [f"3 {i} {j} {k}" for i, j, k in faces]
    qh.write_text("\n".join(lines) + "\n")
    from_file = load_object(qh)
    assert from_file.name == "hull-ch"
    np.testing.assert_array_equal(np.sort(from_file.vertices, axis=0), np.sort(pts, axis=0))


def test_load_object_errors():
    with pytest.raises(ValueError, match="neither a known object"):
        load_object("no_such_object")
    with pytest.raises(ValueError):
        load_object(42)
    with pytest.raises(ValueError, match="unknown robot link"):
        datasets.robot_links.link_path("kuka_link_99")


def test_list_objects_covers_defaults():
    names = list_objects(include_shared=False)
    assert set(DEFAULT_OBJECTS) <= set(names)


def test_shared_dir_override(monkeypatch, tmp_path):
    monkeypatch.setenv(ENV_SHARED, str(tmp_path / "missing"))
    assert shared_datasets_dir() is None
    with pytest.raises(FileNotFoundError, match=ENV_SHARED):
        datasets.jvrc1_hull_names()
    monkeypatch.setenv(ENV_SHARED, str(tmp_path))
    assert shared_datasets_dir() == tmp_path.resolve()
    with pytest.raises(FileNotFoundError, match="missing"):
        datasets.jvrc1_hull_names()


def test_shared_dir_beside_the_working_directory_when_installed(monkeypatch, tmp_path):
    """An installed package (not in a checkout) finds ../shared/datasets from the folder it runs in."""
    import datasets.paths as paths

    monkeypatch.delenv(ENV_SHARED, raising=False)
    monkeypatch.setattr(paths, "REPO_ROOT", tmp_path / "venv" / "site-packages")
    checkout = tmp_path / "work" / "main"
    checkout.mkdir(parents=True)
    monkeypatch.chdir(checkout)
    assert shared_datasets_dir() is None
    (tmp_path / "work" / "shared" / "datasets").mkdir(parents=True)
    assert shared_datasets_dir() == (tmp_path / "work" / "shared" / "datasets").resolve()


def test_sch_sample_polyhedron(shared_datasets):
    assert (shared_datasets / "sch-samples" / "sample_polyhedron.otp").is_file()
    poly = datasets.sch_sample_polyhedron()
    _sane(poly)
    assert len(poly.vertices) == 96  # 96 points, 188 facets in the file
    assert len(poly.faces) == 188
    assert load_object("sch_sample_polyhedron") is poly


def test_jvrc1_hulls(shared_datasets):
    names = datasets.jvrc1_hull_names()
    assert len(names) == 35 and "PELVIS_S" in names
    for name in ("PELVIS_S", "R_KNEE_S", "NECK_P_S", "L_UTHUMB_S"):
        _sane(datasets.jvrc1_hull(name))
    assert datasets.jvrc1_hull("PELVIS_S-ch.txt") is datasets.jvrc1_hull("PELVIS_S")
    assert load_object("jvrc1:R_KNEE_S") is datasets.jvrc1_hull("R_KNEE_S")
    assert "jvrc1:PELVIS_S" in list_objects()
    with pytest.raises(ValueError, match="unknown JVRC-1 hull"):
        datasets.jvrc1_hull("NO_SUCH_LINK")
