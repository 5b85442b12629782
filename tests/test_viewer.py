"""spq view: the viewer's state against spq, and its page in a real headless browser (chromium)."""

from __future__ import annotations

import io
import os
from pathlib import Path

import numpy as np
import pytest

import spq
from harness.cli import main

REPO = Path(__file__).resolve().parent.parent
try:
    import viser  # noqa: F401
except ImportError:  # pragma: no cover - pyproject lists it; CI must have it
    if os.environ.get("CI"):
        raise
    pytest.skip("spq view needs viser (pip install viser; pyproject lists it)", allow_module_level=True)


def scene_file() -> Path:
    """scenes/jvrc1.toml where the shared data is, else the KUKA iiwa (pybullet_data)."""
    from datasets.robots import robot_files

    return REPO / "scenes" / ("jvrc1.toml" if robot_files("jvrc1").urdf.is_file() else "kuka_iiwa.toml")


@pytest.fixture(scope="module")
def viewer():
    from harness.report.viewer import serve

    v = serve([str(scene_file())], port=0)
    yield v
    v.close()


PANEL, NOTICE, GIZMO = 360, 160, 80  # px: viser's control panel (right), its notice (top left), axes (bottom left)


def robot_pixels(png: bytes) -> float:
    """Share of the 3-D canvas (the screenshot less viser's panel, notice and axes gizmo) in the bounding
    volumes' colours as lit by viser: saturated warm (STP-BV patches: gold, orange, purple) or the
    hull's steel blue. An empty scene scores 0 (witness segments alone: under 1e-4)."""
    import matplotlib.image as mpimg

    rgb = mpimg.imread(io.BytesIO(png), format="png")[..., :3]
    rgb = rgb[NOTICE:rgb.shape[0] - GIZMO, :rgb.shape[1] - PANEL]
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    saturation = rgb.max(axis=-1) - rgb.min(axis=-1)
    gold = (r > g) & (g > b) & (saturation > 0.2)
    purple = (b > g) & (r > g) & (saturation > 0.2)
    blue = (b > r) & (b > g) & (saturation > 0.2)
    return float((gold | purple | blue).mean())


def test_the_page_shows_the_robot_in_headless_chromium_with_no_network(viewer, tmp_path):
    from tests.headless_browser import Browser

    with Browser(1200, 800) as browser:
        shot, requests = browser.open(viewer.url, until=lambda png: robot_pixels(png) > 0.005, timeout=90)
    (tmp_path / "viewer.png").write_bytes(shot)
    assert robot_pixels(shot) > 0.005, f"no robot in the screenshot {tmp_path / 'viewer.png'}"
    # every asset came from the viewer's own server (viser's bundled client) or was inline
    outside = [u for u in requests if not u.startswith((viewer.url, "data:", "blob:"))]
    assert requests and outside == []


def test_the_page_lists_the_closest_pairs_of_spq(viewer):
    view = viewer.view
    state = view.state()
    res = view.scene.distances(state["q"], coherent=False, signed=True)
    order = np.argsort(res.distance)[:len(state["pairs"])]
    np.testing.assert_allclose([d for _, _, d in state["pairs"]], res.distance[order], atol=1e-9)
    assert state["pairs"][0][2] > 0  # it starts at the file's closest posture without overlap
    assert set(state["kinds"].values()) <= {"pch", "stp", "cse"}


def test_moving_a_joint_moves_the_bodies_and_the_distances(viewer):
    view = viewer.view
    q = view.q.copy()
    q[0] = 0.5 * (view.model.lower[0] + view.model.upper[0]) + 0.3 * (view.model.upper[0] - view.model.lower[0])
    view.set_configuration(q)
    poses = view.scene.body_poses(q)
    np.testing.assert_allclose([f.position for f in view.frames], poses[:, :3, 3], atol=1e-12)
    assert view.sliders[0].value == pytest.approx(q[0])
    expected = np.sort(view.scene.distances(q, coherent=False, signed=True).distance)[:len(view.state()["pairs"])]
    np.testing.assert_allclose([d for _, _, d in view.state()["pairs"]], expected, atol=1e-9)


def test_the_display_choice_swaps_every_body_to_that_volume(viewer):
    view = viewer.view
    view.show_box.value = "pch"
    view.show, _ = "pch", view.refresh_volumes()
    for (i, kind), handles in view._volumes.items():
        assert all(h.visible == (kind == "pch") for h in handles)
    view.show = "as used"
    view.refresh_volumes()


def test_the_pair_view_gives_spq_signed_distance():
    from harness.report.viewer import DEFAULT_PORT, PairView, pair_side, require_viser

    viser = require_viser()
    server = viser.ViserServer(host="127.0.0.1", port=DEFAULT_PORT + 17, verbose=False)
    try:
        a = pair_side("kuka_link_4:stp", 0.005, 2.0, 3e-3)
        b = pair_side("kuka_link_2:cse", 0.005, 2.0, 3e-3)
        view = PairView(server, a, b)
        pose = np.eye(4)
        pose[:3, 3] = [0.05, 0.02, 0.0]  # overlapping
        view.move_b(pose)
        ref = spq.distance(a.shape, b.shape, np.eye(4), pose @ b.local, signed=True)
        assert view.result.distance == pytest.approx(ref.distance, abs=1e-12) and ref.distance < 0
        assert "penetration depth" in view.status.content
    finally:
        server.stop()


def test_without_viser_the_command_says_how_to_install_it(monkeypatch, capsys):
    import builtins

    real = builtins.__import__

    def no_viser(name, *args, **kwargs):
        if name == "viser" or name.startswith("viser."):
            raise ImportError("No module named 'viser'")
        return real(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_viser)
    assert main(["view", str(scene_file())]) == 2
    assert "pip install viser" in capsys.readouterr().err


@pytest.mark.parametrize("targets, what", [(["a", "b", "c"], "one scene file"), (["missing.toml"], "no scene file"),
                                           (["kuka_link_4:bad", "kuka_link_2"], "bounding volume")])
def test_bad_targets_are_a_clear_error(targets, what, capsys):
    assert main(["view", *targets, "--port", "0"]) == 2
    assert what in capsys.readouterr().err
