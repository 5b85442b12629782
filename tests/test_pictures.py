"""spq pictures: the four report pictures are drawn and show what they say; their numbers hold."""

from __future__ import annotations

import numpy as np
import pytest

import spq
from harness.cli import main


@pytest.fixture(scope="module")
def pictures_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("pictures")
    assert main(["pictures", "--quick", "--robot", "kuka_iiwa", "--out", str(out), "--quiet"]) == 0
    return out


def pixels(path):
    import matplotlib.image as mpimg

    return mpimg.imread(path)[..., :3]


def share_near(image, rgb, tol=0.12) -> float:
    """Share of the pixels within tol (per channel) of a colour times some shade in [0.45, 1]."""
    rgb = np.asarray(rgb)
    best = np.clip((image * rgb).sum(axis=-1) / (rgb * rgb).sum(), 0.45, 1.0)  # the shade that fits best
    return float((np.abs(image - best[..., None] * rgb).max(axis=-1) < tol).mean())


def test_the_four_pictures_are_written_and_not_blank(pictures_dir):
    from harness.suites.pictures import FIGURES

    for name in FIGURES:
        image = pixels(pictures_dir / name)
        assert image.shape[0] > 250 and image.shape[1] > 600, name
        assert (image.min(axis=-1) < 0.9).mean() > 0.05, name  # over 5% of the picture is drawn


def test_the_covers_show_every_kind_and_the_robot_its_witness_segments(pictures_dir):
    from harness.report.scene3d import COLOURS

    covers = pixels(pictures_dir / "pictures_link_covers.png")
    for kind in ("pch", "big_sphere", "cse"):
        assert share_near(covers, COLOURS[kind]) > 0.01, kind
    robot = pixels(pictures_dir / "pictures_robot.png")
    red = (robot[..., 0] > 0.7) & (robot[..., 1] < 0.3) & (robot[..., 2] < 0.3)
    assert red.sum() > 30  # the witness segments (#d62728)


def test_the_tables_name_the_closest_pairs_in_order(pictures_dir):
    import pandas as pd

    pairs = pd.read_csv(pictures_dir / "pictures_closest_pairs.csv")
    assert len(pairs) == 5 and (np.diff(pairs.distance_m) >= 0).all() and (pairs.distance_m > 0).all()
    assert set(pd.read_csv(pictures_dir / "pictures.csv").picture) == {
        "pictures_link_covers.png", "pictures_r_tradeoff.png", "pictures_robot.png", "pictures_penetration.png"}


def test_moving_b_by_the_penetration_vector_makes_the_pair_touch():
    from datasets import load_object
    from harness.suites.pictures import paper_figures as pic

    p = pic.penetration("kuka_link_4", "kuka_link_2", 0.005, 2.0, 0.02, 0, 3e-3)
    assert p.depth == pytest.approx(0.02, rel=1e-5) and p.status == "overlapping"
    np.testing.assert_allclose(p.point_a - p.point_b, p.depth * p.normal, atol=1e-12)
    A = spq.STPBV.from_points(load_object("kuka_link_4").vertices, 0.005, 2.0)
    B = spq.Superellipsoid.fit(load_object("kuka_link_2").vertices).shape
    moved = p.pose_b.copy()
    moved[:3, 3] += p.depth * p.normal
    after = spq.distance(A, B, p.pose_a, moved, signed=True)
    assert abs(after.distance) < 1e-8


def test_the_closest_posture_is_the_least_distance_without_overlap():
    from harness.suites.pictures import paper_figures as pic
    from harness.workloads.robot_poses import smooth_trajectory

    posture = pic.closest_posture("kuka_iiwa", 60, 0, 3, 3e-3)
    scene, _ = pic.robot_scene("kuka_iiwa")
    qs = smooth_trajectory(scene.model, 60, 0)
    best = min(scene.distances(q, coherent=False).min_distance for q in qs
               if (scene.distances(q, coherent=False).status != "overlapping").all())
    assert posture.pairs[0][2] == pytest.approx(best, abs=1e-9)


@pytest.mark.parametrize("args, what", [(["--tolerance", "-1"], "tolerance"), (["--depth", "0"], "depth"),
                                        (["--steps", "1"], "steps")])
def test_bad_settings_are_a_clear_error(args, what, tmp_path, capsys):
    assert main(["pictures", *args, "--out", str(tmp_path), "--quiet"]) == 2
    assert what in capsys.readouterr().err
