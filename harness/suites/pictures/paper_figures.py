"""The report's pictures of bounding volumes and scenes (paper Fig. 2, 9, 10), computed here and drawn
by harness.report.scene3d.

- :func:`link_covers`: one link's PCH, STP-BV (patches coloured by kind) and CSE cover.
- :func:`r_tradeoff`: the same link's STP-BV for R from just above its smallest admissible value to
  large (a lemon-like ball hull grows into the hull grown by r).
- :func:`closest_posture`: a robot at the configuration (of a smooth trajectory) where its bodies come
  closest without touching, every body's bounding volume, the closest pairs' witness segments.
- :func:`penetration`: two covers overlapping, with spq's penetration vector (signed distance).

Each returns a picture object holding its meshes and numbers; ``draw(path)`` writes the PNG. Meshes
come from the shapes' ``to_mesh`` (vertices on the true surfaces; error bounded by ``tolerance``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from harness.report import scene3d as s3

STP_LEGEND = [("STP small sphere (r)", s3.COLOURS["small_sphere"]), ("STP big sphere (R)", s3.COLOURS["big_sphere"]),
              ("STP torus", s3.COLOURS["torus"])]
COVER_LEGEND = [("PCH", s3.COLOURS["pch"]), *STP_LEGEND, ("CSE", s3.COLOURS["cse"])]
SEGMENT_COLOUR = "#d62728"


def legend_for(kinds) -> list:
    """Legend entries of the bounding-volume kinds shown ('pch' | 'stp' | 'cse')."""
    return [entry for kind, entries in (("pch", COVER_LEGEND[:1]), ("stp", STP_LEGEND), ("cse", COVER_LEGEND[-1:]))
            if kind in kinds for entry in entries]


def _mesh(shape, tolerance: float):
    """A shape's mesh with the tolerance clipped into its admissible range (tiny bodies)."""
    from spq import tessellation as ts
    from spq.shapes.polyhedron import Polyhedron

    if isinstance(shape, Polyhedron):
        return shape.to_mesh()
    radius = shape.bounding_radius()
    return shape.to_mesh(float(np.clip(tolerance, ts.MIN_REL_TOLERANCE * radius, 0.1 * radius)))


def _world(mesh, pose) -> np.ndarray:
    return mesh.vertices @ pose[:3, :3].T + pose[:3, 3]


def _view_across(direction: np.ndarray, centre, half_width: float, elev_bias: float = 15.0) -> s3.View:
    """A camera looking across ``direction`` (perpendicular to it, tilted up by elev_bias degrees)."""
    d = direction / np.linalg.norm(direction)
    side = np.cross(d, [0.0, 0.0, 1.0])
    side = side / np.linalg.norm(side) if np.linalg.norm(side) > 1e-6 else np.array([1.0, 0.0, 0.0])
    azim = float(np.degrees(np.arctan2(side[1], side[0])))
    return s3.View(elev_bias, azim, np.asarray(centre, dtype=float), half_width)


# --- one link's covers ------------------------------------------------------------------------------
@dataclass
class LinkCovers:
    name: str
    meshes: dict  # 'PCH' | 'STP' | 'CSE' -> trimesh (link frame)
    titles: dict
    facts: dict = field(default_factory=dict)

    def draw(self, path: Path) -> None:
        fig, axes = s3.figure(3, size=3.6, height=3.0)
        points = np.concatenate([m.vertices for m in self.meshes.values()])
        view = s3.fit_view(points, elev=18, azim=-55)
        for ax, (key, mesh) in zip(axes, self.meshes.items()):
            colour = None if key == "STP" else s3.COLOURS[key.lower()]
            s3.draw(ax, [s3.MeshItem.of(mesh, colour=colour, edges=key == "PCH")], [], view)
            ax.set_title(self.titles[key], fontsize=9)
        s3.legend(fig, COVER_LEGEND, ncol=5, fontsize=8)
        fig.subplots_adjust(left=0, right=1, top=0.8, bottom=0.08, wspace=0)
        save_figure_loose(fig, path, f"{self.name}: its hull (PCH), STP-BV and superellipsoid cover (CSE)")


def save_figure_loose(fig, path: Path, title: str) -> None:
    """Save a 3-D figure without tight_layout (which crops 3-D axes badly)."""
    from harness.report.charts import pyplot

    fig.suptitle(title, fontsize=11, y=0.995)
    fig.savefig(path, dpi=110)
    pyplot().close(fig)


def link_covers(name: str, r: float, R: float, tolerance: float) -> LinkCovers:
    from datasets import load_object
    from spq.shapes.stpbv import STPBV
    from spq.shapes.superellipsoid import Superellipsoid

    hull = load_object(name)
    stp = STPBV.from_points(hull.vertices, r, R)
    fit = Superellipsoid.fit(hull.vertices)
    cse = _mesh(fit.shape, tolerance)
    cse.apply_transform(fit.pose)
    meshes = {"PCH": hull.to_mesh(), "STP": _mesh(stp, tolerance), "CSE": cse}
    s = fit.shape
    hull_volume = meshes["PCH"].volume
    titles = {"PCH": f"PCH: {len(hull.vertices)} vertices, {len(hull.faces)} faces",
              "STP": (f"STP-BV r = {r:g} m, R = {R:g} m: {stp.n_small} + {stp.n_big} spheres,\n"
                      f"{stp.n_tori} tori; volume {meshes['STP'].volume / hull_volume:.2f}x the hull"),
              "CSE": (f"CSE: e1 = {s.e1:.2f}, e2 = {s.e2:.2f};\nvolume {fit.volume_ratio:.2f}x the hull")}
    facts = {"link": name, "hull_vertices": len(hull.vertices), "stp_small_spheres": stp.n_small,
             "stp_big_spheres": stp.n_big, "stp_tori": stp.n_tori,
             "stp_volume_ratio": meshes["STP"].volume / hull_volume, "cse_volume_ratio": fit.volume_ratio,
             "mesh_max_error_m": max(m.metadata["max_error"] for m in meshes.values())}
    return LinkCovers(name, meshes, titles, facts)


# --- the R trade-off as shapes ----------------------------------------------------------------------
@dataclass
class RShapes:
    name: str
    r: float
    R_min: float
    meshes: list  # (R, trimesh, features, volume ratio)

    def draw(self, path: Path) -> None:
        fig, axes = s3.figure(len(self.meshes), size=2.9, height=2.9)
        points = np.concatenate([m.vertices for _, m, _, _ in self.meshes])
        view = s3.fit_view(points, elev=18, azim=-55)
        for ax, (R, mesh, features, ratio) in zip(axes, self.meshes):
            s3.draw(ax, [s3.MeshItem.of(mesh)], [], view)
            ax.set_title(f"R = {R:.3g} m\n{features} patches, volume {ratio:.2f}x hull", fontsize=9)
        s3.legend(fig, STP_LEGEND, fontsize=8)
        fig.subplots_adjust(left=0, right=1, top=0.82, bottom=0.1, wspace=0)
        save_figure_loose(fig, path, f"{self.name}: STP-BV from small R (just above R_min = {self.R_min:.3g} m) "
                                     f"to large R, r = {self.r:g} m")


def r_tradeoff(name: str, r: float, R_values, tolerance: float) -> RShapes:
    from datasets import load_object
    from spq.shapes.stpbv import STPBV
    from spq.stp.construction import enclosing_radius

    hull = load_object(name)
    R_min = r + enclosing_radius(hull.vertices)
    if not R_values:
        R_values = [1.02 * R_min, 2.0 * R_min, 10.0 * R_min, 200.0 * R_min]
    hull_volume = hull.to_mesh().volume
    meshes = []
    for R in R_values:
        stp = STPBV.from_points(hull.vertices, r, float(R))
        mesh = _mesh(stp, tolerance)
        meshes.append((float(R), mesh, stp.n_patches, mesh.volume / hull_volume))
    return RShapes(name, r, R_min, meshes)


# --- a robot at its closest posture -----------------------------------------------------------------
@dataclass
class ClosestPosture:
    robot: str
    q: np.ndarray
    configuration: int
    configurations: int
    items: list  # s3.MeshItem per body, world frame
    kinds: dict  # body name -> BV kind drawn
    pairs: list  # (body_a, body_b, distance, point_a, point_b, bv_a, bv_b), closest first
    zoom_items: list

    def draw(self, path: Path) -> None:
        plt_fig, axes = s3.figure(2, size=4.0, height=4.6, widths=(1.35, 1.0))
        points = np.concatenate([it.vertices for it in self.items])
        view = s3.fit_view(points, elev=12, azim=25, margin=1.1)
        segments = [s3.Segment(pa, pb, SEGMENT_COLOUR, 2.0, label=str(k + 1))
                    for k, (_, _, _, pa, pb, _, _) in enumerate(self.pairs)]
        s3.draw(axes[0], self.items, segments, view)
        a, b, d, pa, pb, bva, bvb = self.pairs[0]
        axes[0].set_title(f"configuration {self.configuration} of {self.configurations}: "
                          f"{len(self.pairs)} closest pairs", fontsize=9)
        across = _view_across(pb - pa if d > 0 else np.array([1.0, 0, 0]), 0.5 * (pa + pb), 0.0)
        zview = s3.fit_view(np.concatenate([it.vertices for it in self.zoom_items]), across.elev, across.azim)
        s3.draw(axes[1], self.zoom_items, [s3.Segment(pa, pb, SEGMENT_COLOUR, 2.5, label=f"{1e3 * d:.1f} mm")], zview)
        axes[1].set_title(f"1: {a} ({bva.upper()}) - {b} ({bvb.upper()})\ndistance {1e3 * d:.2f} mm", fontsize=9)
        kinds = {k for k in self.kinds.values()} | {self.pairs[0][5], self.pairs[0][6]}
        s3.legend(plt_fig, legend_for(kinds), ncol=5, fontsize=8)
        plt_fig.subplots_adjust(left=0, right=1, top=0.87, bottom=0.08, wspace=0)
        save_figure_loose(plt_fig, path, f"{self.robot} where its bodies come closest without touching "
                                         "(witness segments in red)")


def robot_scene(robot: str):
    """(scene, skip note): the robot's scene with the auto policy; the skip pairs and radii of
    scenes/<robot>.toml when this is a source checkout that has it."""
    from datasets.robots import robot_files
    from spq.scene import Scene

    path = Path(__file__).resolve().parent.parent / "scenes" / f"{robot}.toml"
    if path.is_file():
        from harness.workloads.scene_file import build_scene, read_scene_file

        return build_scene(read_scene_file(path)), f"scenes/{robot}.toml"
    files = robot_files(robot)
    return Scene.from_urdf(files.urdf, convex_dir=files.convex_dir, mesh_root=files.mesh_root), "defaults"


def body_volume(scene, body, kind: str):
    """(shape, 4x4 pose of the shape in the body's hull frame) for kind 'pch' | 'stp' | 'cse'."""
    return scene._volume(body, kind)


def drawn_kind(body) -> str:
    """The bounding volume a picture shows for a body: its policy's, and the STP-BV for 'auto' (each of
    its pairs uses the STP-BV on the side with fewer patches, the hull on the other)."""
    return "stp" if body.policy == "auto" else body.policy


def body_item(scene, body, kind: str, body_pose, tolerance: float, cache: dict, alpha: float = 1.0) -> s3.MeshItem:
    key = (body.name, kind)
    if key not in cache:
        shape, local = body_volume(scene, body, kind)
        cache[key] = (_mesh(shape, tolerance), local)
    mesh, local = cache[key]
    colour = None if kind == "stp" else s3.COLOURS[kind]
    return s3.MeshItem.of(mesh, body_pose @ local, colour=colour, alpha=alpha)


def closest_posture(robot: str, steps: int, seed: int, closest_pairs: int, tolerance: float) -> ClosestPosture:
    from harness.workloads.robot_poses import smooth_trajectory
    from spq.kernels.gjk import OUT_DISTANCE, OUT_STATUS, SEPARATED

    scene, _ = robot_scene(robot)
    qs = smooth_trajectory(scene.model, steps, seed)
    out = scene.distances_many(qs, coherent=True)
    separated = (out[:, :, OUT_STATUS] == SEPARATED).all(axis=1)
    dist = out[:, :, OUT_DISTANCE].min(axis=1)
    pool = np.flatnonzero(separated) if separated.any() else np.arange(len(qs))
    k = int(pool[np.argmin(dist[pool])])
    q = qs[k]
    res = scene.distances(q, coherent=False)
    poses = scene.body_poses(q)
    cache: dict = {}
    items = [body_item(scene, b, drawn_kind(b), poses[i], tolerance, cache) for i, b in enumerate(scene.bodies)]
    order = np.argsort(res.distance)[:closest_pairs]
    pairs = []
    for p in order:
        ia, ib = scene.pairs[p]
        bva, bvb = scene.pair_kinds[p]
        pairs.append((scene.bodies[ia].name, scene.bodies[ib].name, float(res.distance[p]), res.point_a[p],
                      res.point_b[p], bva, bvb))
    ia, ib = scene.pairs[order[0]]
    bva, bvb = scene.pair_kinds[order[0]]
    zoom = [body_item(scene, scene.bodies[ia], bva, poses[ia], tolerance / 4, cache, alpha=1.0),
            body_item(scene, scene.bodies[ib], bvb, poses[ib], tolerance / 4, cache, alpha=1.0)]
    kinds = {b.name: drawn_kind(b) for b in scene.bodies}
    return ClosestPosture(scene.model.name, q, k, len(qs), items, kinds, pairs, zoom)


# --- an overlapping pair and its penetration vector -------------------------------------------------
@dataclass
class Penetration:
    names: tuple
    kinds: tuple
    meshes: tuple  # (mesh A, mesh B), local frames
    pose_a: np.ndarray
    pose_b: np.ndarray
    depth: float
    point_a: np.ndarray
    point_b: np.ndarray
    normal: np.ndarray
    status: str
    bounds: tuple  # (lower, upper) certified signed distance

    def draw(self, path: Path) -> None:
        fig, axes = s3.figure(2, size=4.2, height=4.0)
        moved = self.pose_b.copy()
        moved[:3, 3] += self.depth * self.normal
        colours = [None if k == "stp" else s3.COLOURS[k] for k in self.kinds]
        pts = np.concatenate([_world(self.meshes[0], self.pose_a), _world(self.meshes[1], self.pose_b),
                              _world(self.meshes[1], moved)])
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        view = _view_across(self.normal, 0.5 * (lo + hi), 0.5 * float((hi - lo).max()), elev_bias=20)
        arrow = s3.Segment(self.point_b, self.point_a, SEGMENT_COLOUR, 3.5, arrow=True,
                           label=f"{1e3 * self.depth:.1f} mm")
        for ax, pose_b, alpha, segs, title in (
                (axes[0], self.pose_b, 0.45, [arrow],
                 f"overlapping: depth {1e3 * self.depth:.2f} mm ({self.status})\npenetration vector from B's "
                 "witness point to A's"),
                (axes[1], moved, 1.0, [], "B moved by the penetration vector:\nthe bodies touch")):
            items = [s3.MeshItem.of(self.meshes[0], self.pose_a, colours[0], alpha=alpha),
                     s3.MeshItem.of(self.meshes[1], pose_b, colours[1], alpha=alpha)]
            s3.draw(ax, items, segs, view)
            ax.set_title(title, fontsize=9)
        s3.legend(fig, legend_for(set(self.kinds)), ncol=5, fontsize=8)
        fig.subplots_adjust(left=0, right=1, top=0.84, bottom=0.08, wspace=0)
        save_figure_loose(fig, path, f"A = {self.names[0]} ({self.kinds[0].upper()}), B = {self.names[1]} "
                                     f"({self.kinds[1].upper()}): spq.distance(..., signed=True)")


def penetration(name_a: str, name_b: str, r: float, R: float, depth: float, seed: int, tolerance: float) -> Penetration:
    """A = the STP-BV of name_a, B = the superellipsoid cover of name_b (in its fit pose), B placed
    (random rotation, along a random direction) so that spq's signed distance is -depth (m)."""
    import spq
    from datasets import load_object
    from harness.workloads.poses import random_rotations

    hull_a, hull_b = load_object(name_a), load_object(name_b)
    A = spq.STPBV.from_points(hull_a.vertices, r, R)
    fit = spq.Superellipsoid.fit(hull_b.vertices)
    B = fit.shape
    rng = np.random.default_rng(seed)
    rot = random_rotations(1, rng)[0]
    direction = rng.normal(size=3)
    direction /= np.linalg.norm(direction)
    pose_a = np.eye(4)

    def pose_at(s: float) -> np.ndarray:
        p = np.eye(4)
        p[:3, :3] = rot @ fit.pose[:3, :3]
        p[:3, 3] = rot @ fit.pose[:3, 3] + s * direction
        return p

    s = A.bounding_radius() + B.bounding_radius() + float(np.linalg.norm(fit.pose[:3, 3]))
    for _ in range(30):  # secant-free: move along the direction by the signed-distance error (slope ~ n.direction)
        res = spq.distance(A, B, pose_a, pose_at(s), signed=True)
        err = res.distance + depth
        if abs(err) < 1e-6 * depth:
            break
        slope = max(float(res.normal @ direction), 0.2)
        s -= err / slope
    res = spq.distance(A, B, pose_a, pose_at(s), signed=True)
    meshes = (_mesh(A, tolerance), _mesh(B, tolerance))
    return Penetration((name_a, name_b), ("stp", "cse"), meshes, pose_a, pose_at(s), -res.distance, res.point_a,
                       res.point_b, res.normal, res.status, (res.lower_bound, res.upper_bound))
