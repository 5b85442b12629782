"""`spq view`: an interactive viewer in the browser, served by viser (a local web server that ships its
own client with the package: nothing is fetched from the network).

Two subjects:

- a robot scene file (scenes/*.toml, read with harness.workloads.scene_file): every body with its bounding volume
  (coloured by kind; STP-BV patches by kind too), a slider per joint, a slider through the file's
  configurations (starting at the one where the bodies come closest without overlapping), live
  distances of the closest pairs with their witness segments, and the bounding volume of each body;
- a pair of shapes (dataset names or mesh paths, each with its bounding volume): B under a
  translate/rotate gizmo, the live (signed) distance, witness points and segment.

viser is imported only here and only when a viewer starts: without it, :func:`require_viser` raises
MissingViewer with the command that installs it. Frames and units: world frame, metres.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from harness.report.scene3d import COLOURS

KINDS = ("pch", "stp", "cse")
KIND_NAMES = {"pch": "PCH (convex hull)", "stp": "STP-BV", "cse": "CSE (superellipsoid)"}
SHOW_CHOICES = ("as used", "pch", "stp", "cse")
SEGMENT_RGB = (214, 39, 40)  # separated pairs' witness segments
OVERLAP_RGB = (200, 0, 200)  # overlapping pairs' penetration segments (signed distances)
DEFAULT_PORT = 8080
DEFAULT_TOLERANCE = 1e-3  # m: mesh-to-surface distance of the drawn bounding volumes
SEGMENT_THICKNESS = 0.004  # m: witness segments, in world units
ENVIRONMENT_INTENSITY = 0.35  # viser's image-based light, dimmed: the colours of the kinds stay readable


class MissingViewer(RuntimeError):
    """viser is not installed."""


def require_viser():
    """The viser module, or MissingViewer naming the install command."""
    try:
        import viser
    except ImportError:  # pragma: no cover - exercised by monkeypatching in the tests
        raise MissingViewer("spq view needs the 'viser' package (a local web viewer): pip install viser "
                            "(or reinstall spq from its folder with pip install ., which lists it)") from None
    return viser


def rgb255(rgb) -> tuple[int, int, int]:
    return tuple(int(round(255 * c)) for c in rgb)


def wxyz(rotation: np.ndarray) -> np.ndarray:
    """Quaternion (w, x, y, z) of a 3x3 rotation matrix."""
    from scipy.spatial.transform import Rotation

    x, y, z, w = Rotation.from_matrix(rotation).as_quat()
    return np.array([w, x, y, z])


def add_volume(server, name: str, mesh, kind: str, visible: bool = True) -> list:
    """Add a bounding volume's mesh (local frame) under scene node ``name``: one mesh per STP-BV patch
    kind, else one mesh in the kind's colour. Returns the mesh handles."""
    handles = []
    if kind == "stp" and "face_kind" in mesh.metadata:
        for patch_kind in ("small_sphere", "big_sphere", "torus"):
            faces = mesh.faces[mesh.metadata["face_kind"] == patch_kind]
            if len(faces):
                handles.append(server.scene.add_mesh_simple(f"{name}/{patch_kind}", mesh.vertices, faces,
                                                            color=rgb255(COLOURS[patch_kind]), flat_shading=False,
                                                            visible=visible))
    else:
        handles.append(server.scene.add_mesh_simple(f"{name}/{kind}", mesh.vertices, mesh.faces,
                                                    color=rgb255(COLOURS[kind]), visible=visible))
    return handles


def segments_of(point_a: np.ndarray, point_b: np.ndarray, distance: np.ndarray):
    """(points (n, 2, 3), colours (n, 2, 3) uint8) of witness segments; overlaps in OVERLAP_RGB."""
    points = np.stack([point_a, point_b], axis=1)
    rgb = np.where((distance < 0)[:, None], OVERLAP_RGB, SEGMENT_RGB).astype(np.uint8)
    return points, np.repeat(rgb[:, None, :], 2, axis=1)


def _mesh(shape, tolerance: float):
    from harness.suites.pictures.paper_figures import _mesh as picture_mesh

    return picture_mesh(shape, tolerance)


# --- a robot scene ------------------------------------------------------------------------------------
class SceneView:
    """A robot scene file in the viewer (see the module docstring). ``state()`` gives what the page
    shows, for tests: the configuration, the closest pairs and the kinds drawn."""

    def __init__(self, server, scene_path, tolerance: float = DEFAULT_TOLERANCE, pairs_shown: int = 5):
        from harness.workloads import scene_file as sf

        self.server = server
        self.spec = sf.read_scene_file(scene_path)
        self.scene = sf.build_scene(self.spec)
        self.model = self.scene.model
        self.configurations = sf.scene_configurations(self.spec, self.model)
        self.tolerance = tolerance
        self.lock = threading.RLock()
        self.signed = True
        self.pairs_shown = pairs_shown
        self.show = "as used"
        self._volumes: dict = {}  # (body index, kind) -> mesh handles
        self.start = self.closest_configuration()
        self.q = self.configurations[self.start].copy()
        self._build_scene()
        self._build_gui()
        self.update()

    # what each body shows
    @staticmethod
    def used_kind(body) -> str:
        return "stp" if body.policy == "auto" else body.policy

    def kind_shown(self, body) -> str:
        if self.show == "as used":
            return self.used_kind(body)
        return self.show

    def closest_configuration(self) -> int:
        """Index of the file's configuration where the bodies come closest without overlapping (any
        configuration if every one overlaps)."""
        from spq.kernels.gjk import OUT_DISTANCE, OUT_STATUS, SEPARATED

        out = self.scene.distances_many(self.configurations, coherent=self.spec.poses.coherent)
        separated = (out[:, :, OUT_STATUS] == SEPARATED).all(axis=1)
        least = out[:, :, OUT_DISTANCE].min(axis=1)
        pool = np.flatnonzero(separated) if separated.any() else np.arange(len(least))
        return int(pool[np.argmin(least[pool])])

    def _volume(self, i: int, kind: str) -> list:
        """Mesh handles of body i's bounding volume ``kind``, built on first use."""
        key = (i, kind)
        if key not in self._volumes:
            body = self.scene.bodies[i]
            if kind == "stp" and body.stp is None:
                from spq.shapes.stpbv import STPBV

                body.stp = STPBV.from_points(body.hull.vertices, self.scene.r, self.scene.R)
            if kind == "cse" and body.cse is None:
                from spq.shapes.superellipsoid import Superellipsoid

                body.cse = Superellipsoid.fit(body.hull.vertices)
            shape, local = self.scene._volume(body, kind)
            mesh = _mesh(shape, self.tolerance).copy()  # the copy keeps the metadata (STP-BV patch kinds)
            mesh.apply_transform(local)
            self._volumes[key] = add_volume(self.server, f"/robot/{i}/{kind}", mesh, kind)
        return self._volumes[key]

    def _build_scene(self) -> None:
        self.frames = [self.server.scene.add_frame(f"/robot/{i}", show_axes=False)
                       for i in range(len(self.scene.bodies))]
        for i, body in enumerate(self.scene.bodies):
            self._volume(i, self.kind_shown(body))
        self.lines = None
        poses = self.scene.body_poses(self.q)
        lo = poses[:, :3, 3].min(axis=0)
        hi = poses[:, :3, 3].max(axis=0)
        centre, size = 0.5 * (lo + hi), float((hi - lo).max()) + 0.3
        self.server.initial_camera.look_at = tuple(centre)
        self.server.initial_camera.position = tuple(centre + size * np.array([1.0, 0.65, 0.25]))
        self.server.scene.configure_environment_map(environment_intensity=ENVIRONMENT_INTENSITY)

    def _build_gui(self) -> None:
        gui = self.server.gui
        spec = self.spec
        gui.add_markdown(f"**{spec.name}**: {len(self.scene.bodies)} bodies, {len(self.scene.pairs)} pairs "
                         f"({', '.join(f'{k} {v}' for k, v in self.scene.kind_counts().items())}); policy "
                         f"{spec.policy}, r = {spec.r:g} m, R = {spec.R:g} m")
        self.status = gui.add_markdown("")
        with gui.add_folder("Display"):
            self.show_box = gui.add_dropdown("Bounding volumes", SHOW_CHOICES, initial_value="as used")
            self.signed_box = gui.add_checkbox("Signed distances", initial_value=True)
            self.pairs_slider = gui.add_slider("Closest pairs drawn", 1, 20, 1, self.pairs_shown)
        with gui.add_folder("Posture"):
            self.pose_slider = gui.add_slider(f"Configuration of {spec.poses.kind}", 0, len(self.configurations) - 1,
                                              1, self.start)
            closest = gui.add_button("Closest posture of the file")
        with gui.add_folder("Joints", expand_by_default=False):
            self.sliders = []
            for j, name in enumerate(self.model.joint_names):
                lo, hi = float(self.model.lower[j]), float(self.model.upper[j])
                self.sliders.append(gui.add_slider(name, lo, hi, (hi - lo) / 1000.0, float(self.q[j])))
        with gui.add_folder("Bodies", expand_by_default=False):
            rows = "\n".join(f"| {b.name} | {b.policy} | {KIND_NAMES[self.used_kind(b)]} |" for b in self.scene.bodies)
            gui.add_markdown("| body | policy | drawn |\n|---|---|---|\n" + rows)
        self._syncing = False

        @self.show_box.on_update
        def _(_event) -> None:
            with self.lock:
                self.show = self.show_box.value
                self.refresh_volumes()

        @self.signed_box.on_update
        def _(_event) -> None:
            self.signed = bool(self.signed_box.value)
            self.update()

        @self.pairs_slider.on_update
        def _(_event) -> None:
            self.pairs_shown = int(self.pairs_slider.value)
            self.update()

        @self.pose_slider.on_update
        def _(_event) -> None:
            self.set_configuration(self.configurations[int(self.pose_slider.value)])

        @closest.on_click
        def _(_event) -> None:
            self.pose_slider.value = self.start

        for j, slider in enumerate(self.sliders):
            def moved(_event, j=j, slider=slider) -> None:
                if self._syncing:
                    return
                with self.lock:
                    self.q[j] = float(slider.value)
                self.update()
            slider.on_update(moved)

    def refresh_volumes(self) -> None:
        """Show each body's volume of the current display choice, hide the others."""
        with self.lock:
            for i, body in enumerate(self.scene.bodies):
                want = self.kind_shown(body)
                self._volume(i, want)
                for (b, kind), handles in self._volumes.items():
                    if b == i:
                        for h in handles:
                            h.visible = kind == want

    def set_configuration(self, q) -> None:
        with self.lock:
            self.q = self.model.check_configuration(q).copy()
            self._syncing = True
            try:
                for j, slider in enumerate(self.sliders):
                    slider.value = float(self.q[j])
            finally:
                self._syncing = False
        self.update()

    def update(self) -> None:
        """Move the bodies to the configuration, recompute every pair, redraw the closest pairs."""
        with self.lock:
            poses = self.scene.body_poses(self.q)
            for frame, pose in zip(self.frames, poses):
                frame.position = pose[:3, 3]
                frame.wxyz = wxyz(pose[:3, :3])
            res = self.scene.distances(self.q, coherent=True, signed=self.signed)
            order = np.argsort(res.distance)[:self.pairs_shown]
            self.result, self.order = res, order
            points, colours = segments_of(res.point_a[order], res.point_b[order], res.distance[order])
            finite = np.isfinite(points).all(axis=(1, 2))
            if self.lines is not None:
                self.lines.remove()
            self.lines = self.server.scene.add_line_segments("/witness", points[finite], colours[finite],
                                                             thickness=SEGMENT_THICKNESS)
            names = self.scene.pair_names
            kinds = self.scene.pair_kinds
            lines = [f"| {k + 1} | {names[p][0]} ({kinds[p][0]}) | {names[p][1]} ({kinds[p][1]}) | "
                     f"{1e3 * res.distance[p]:.3f} | {res.status[p]} |" for k, p in enumerate(order)]
            overlapping = int(np.count_nonzero(res.status == "overlapping"))
            self.status.content = (f"**closest**: {1e3 * res.distance[order[0]]:.3f} mm; {overlapping} overlapping "
                                   f"pair{'s' if overlapping != 1 else ''}\n\n| # | A | B | mm | status |\n"
                                   "|---|---|---|---|---|\n" + "\n".join(lines))

    def state(self) -> dict:
        """What the page shows: q, the closest pairs [(body_a, body_b, distance)], the kinds drawn."""
        with self.lock:
            names = self.scene.pair_names
            return {"q": self.q.copy(), "pairs": [(*names[p], float(self.result.distance[p])) for p in self.order],
                    "kinds": {b.name: self.kind_shown(b) for b in self.scene.bodies}}


# --- a pair of shapes ---------------------------------------------------------------------------------
@dataclass
class PairSide:
    name: str
    kind: str  # 'pch' | 'stp' | 'cse'
    shape: object
    local: np.ndarray  # 4x4 pose of the shape in the object's frame (a fit's pose; identity otherwise)
    mesh: object  # trimesh in the object's frame


def pair_side(spec: str, r: float, R: float, tolerance: float) -> PairSide:
    """'NAME[:KIND]' (a dataset name or mesh path; KIND pch | stp | cse, default pch) as a shape."""
    from datasets import load_object
    from spq.shapes.stpbv import STPBV
    from spq.shapes.superellipsoid import Superellipsoid

    name, _, kind = spec.partition(":")
    kind = kind or "pch"
    if kind not in KINDS:
        raise ValueError(f"{spec!r}: the bounding volume after ':' is one of {list(KINDS)}")
    hull = load_object(name)
    local = np.eye(4)
    if kind == "pch":
        shape = hull
    elif kind == "stp":
        shape = STPBV.from_points(hull.vertices, r, R)
    else:
        fit = Superellipsoid.fit(hull.vertices)
        shape, local = fit.shape, np.asarray(fit.pose, dtype=float)
    mesh = _mesh(shape, tolerance).copy()  # the copy keeps the metadata (STP-BV patch kinds)
    mesh.apply_transform(local)
    return PairSide(name, kind, shape, local, mesh)


class PairView:
    """Two shapes in the viewer: A fixed at the origin, B under a gizmo; live signed distance."""

    def __init__(self, server, a: PairSide, b: PairSide):
        self.server, self.a, self.b = server, a, b
        self.lock = threading.RLock()
        ra = float(np.linalg.norm(a.mesh.vertices, axis=1).max())
        rb = float(np.linalg.norm(b.mesh.vertices, axis=1).max())
        self.pose_b = np.eye(4)
        self.pose_b[:3, 3] = [1.2 * (ra + rb), 0.0, 0.0]
        add_volume(server, "/a", a.mesh, a.kind)
        self.control = server.scene.add_transform_controls("/b", scale=max(ra, rb), position=self.pose_b[:3, 3])
        add_volume(server, "/b/shape", b.mesh, b.kind)
        self.lines = None
        server.initial_camera.look_at = tuple(0.5 * self.pose_b[:3, 3])
        server.initial_camera.position = tuple(0.5 * self.pose_b[:3, 3] + 1.6 * (ra + rb) * np.array([0.3, -1.0, 0.5]))
        server.scene.configure_environment_map(environment_intensity=ENVIRONMENT_INTENSITY)
        server.gui.add_markdown(f"**A** {a.name} ({KIND_NAMES[a.kind]}), fixed; **B** {b.name} ({KIND_NAMES[b.kind]}): "
                                "drag its gizmo")
        self.status = server.gui.add_markdown("")

        @self.control.on_update
        def _(_event) -> None:
            from scipy.spatial.transform import Rotation

            w, x, y, z = self.control.wxyz
            pose = np.eye(4)
            pose[:3, :3] = Rotation.from_quat([x, y, z, w]).as_matrix()
            pose[:3, 3] = self.control.position
            self.move_b(pose)

        self.update()

    def move_b(self, pose) -> None:
        with self.lock:
            self.pose_b = np.asarray(pose, dtype=float)
        self.update()

    def update(self) -> None:
        import spq

        with self.lock:
            self.result = spq.distance(self.a.shape, self.b.shape, self.a.local, self.pose_b @ self.b.local, signed=True)
            r = self.result
            points, colours = segments_of(r.point_a[None], r.point_b[None], np.array([r.distance]))
            if self.lines is not None:
                self.lines.remove()
            self.lines = self.server.scene.add_line_segments("/witness", points, colours, thickness=SEGMENT_THICKNESS)
            what = "penetration depth" if r.distance < 0 else "distance"
            self.status.content = (f"**{what}** {1e3 * abs(r.distance):.4f} mm ({r.status}); certified in "
                                   f"[{1e3 * r.lower_bound:.4f}, {1e3 * r.upper_bound:.4f}] mm; normal "
                                   f"{np.round(r.normal, 3).tolist()}")


# --- serving --------------------------------------------------------------------------------------------
@dataclass
class Viewer:
    server: object
    view: object

    @property
    def url(self) -> str:
        return f"http://{self.server.get_host()}:{self.server.get_port()}"

    def close(self) -> None:
        self.server.stop()


def serve(targets: list[str], host: str = "127.0.0.1", port: int = DEFAULT_PORT, tolerance: float = DEFAULT_TOLERANCE,
          r: float = 0.005, R: float = 2.0) -> Viewer:
    """Start the viewer on host:port (port 0: any free port) for one scene file (.toml) or two shapes
    ('NAME[:pch|stp|cse]'); returns at once with the server running in its own threads."""
    viser = require_viser()
    if len(targets) == 1 and Path(targets[0]).suffix == ".toml":
        if not Path(targets[0]).is_file():
            raise ValueError(f"no scene file {targets[0]!r}")
        make = lambda server: SceneView(server, targets[0], tolerance)  # noqa: E731
    elif len(targets) == 2:
        sides = [pair_side(t, r, R, tolerance) for t in targets]
        make = lambda server: PairView(server, *sides)  # noqa: E731
    else:
        raise ValueError("give one scene file (scenes/*.toml) or two shapes NAME[:pch|stp|cse]; got "
                         f"{targets!r}")
    if port == 0:
        import socket

        with socket.socket() as s:
            s.bind((host, 0))
            port = s.getsockname()[1]
    server = viser.ViserServer(host=host, port=port, label="spq view", verbose=False)
    try:
        return Viewer(server, make(server))
    except BaseException:
        server.stop()
        raise
