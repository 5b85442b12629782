"""Continuity of witness points, normals and distance gradients along smooth trajectories.

Body A is fixed at the identity; body B (the same link) moves along a trajectory s in [0, 1]:

* ``parallel_faces``: B is placed so that its largest hull facet faces A's largest hull facet, parallel at
  s = 0.5 with a gap, and B rotates about an axis lying in the facet plane through that configuration
  (angle theta = (s - 0.5) * 2 * theta_max, radians). For two polyhedra the witness point jumps across the
  facet at theta = 0; with an STP-BV or CSE-BV on a side it moves continuously.
* ``edge_slide``: B, in a seeded generic orientation, translates parallel to A's longest hull edge at a small
  gap, its closest vertex sliding from 10 % to 90 % of the edge (metres).
* ``random_path``: a seeded smooth path, a few Fourier modes in translation (m) and rotation (rad) around a
  separated base pose.

For each bounding-volume pair, B is shifted along the separation direction so that the pair's own supporting
planes keep the requested gap (the STP-BV and the CSE-BV are larger than the hull). Metrics per step h (in s):
the empirical Lipschitz ratio max |p(s + h) - p(s)| / (h * scale) of the witness points (max over A and B) and
of the normal, where scale converts s to radians (parallel_faces), metres (edge_slide) or stays 1 (random_path,
ratios per unit s). Sample points: a uniform grid plus points straddling the largest witness jumps, located by
bisection, so that a jump is seen at every step size. Gradient check: the analytic rate dd/ds = grad_b . xi(s)
from :func:`spq.distance_gradients` (xi = B's world twist per unit s) against a central finite difference of the
distance in s, at solver tolerance 1e-13.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from scipy.spatial.transform import Rotation

import spq
from harness.report.charts import save_figure

TOL = dict(tol=1e-13, rel_tol=1e-13)
PAIRS = [("PCH", "PCH"), ("STP", "PCH"), ("STP", "STP"), ("CSE", "PCH"), ("CSE", "CSE")]
TRAJECTORIES = ("parallel_faces", "edge_slide", "random_path")
UNITS = {"parallel_faces": ("rad", "m/rad"), "edge_slide": ("m", "m/m"), "random_path": ("s", "m per unit s")}


@dataclass
class ContinuityConfig:
    object_name: str = "kuka_link_4"
    r: float = 0.005  # m: STP small radius (as in spq bench table1)
    R: float = 2.0  # m: STP big radius
    seed: int = 0
    steps: tuple = (1e-1, 1e-2, 1e-3, 1e-4, 1e-5)  # in s
    grid: int = 201  # uniform base points per step
    locate_grid: int = 1001  # grid to find the largest witness jumps before bisection
    jumps: int = 2  # jumps located and straddled per pair and trajectory
    gradient_samples: int = 21  # s values for the gradient check
    fd_step: float = 1e-6  # in s
    theta_max: float = 0.25  # rad: parallel_faces sweeps theta in [-theta_max, theta_max]
    gap: float = 0.01  # m: gap between the supporting planes at the closest configuration
    engines: tuple = ("coal", "fcl")
    trajectories: tuple = TRAJECTORIES
    pairs: list = field(default_factory=lambda: list(PAIRS))


@dataclass
class Body:
    name: str
    shape: object
    offset: np.ndarray  # body frame -> link frame

    def support_world(self, pose_link: np.ndarray, direction: np.ndarray) -> float:
        """Support value h(direction) of this body with its link at pose_link (world)."""
        pose = pose_link @ self.offset
        local = pose[:3, :3].T @ direction
        if isinstance(self.shape, spq.Polyhedron):
            return float(np.max(self.shape.vertices @ local) + direction @ pose[:3, 3])
        p = np.asarray(self.shape.support(local[None]), dtype=float).reshape(-1, 3)[0]
        return float(local @ p + direction @ pose[:3, 3])


def build_bodies(config: ContinuityConfig, load_object) -> dict[str, Body]:
    link = load_object(config.object_name)
    stp = spq.STPBV.from_points(link.vertices, config.r, config.R)
    fit = spq.Superellipsoid.fit(link.vertices)
    return {"PCH": Body("PCH", link, np.eye(4)), "STP": Body("STP", stp, np.eye(4)),
            "CSE": Body("CSE", fit.shape, np.asarray(fit.pose, dtype=float))}


def _pose(R: np.ndarray, t) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3] = R
    out[:3, 3] = t
    return out


def _rot(axis, angle) -> np.ndarray:
    axis = np.asarray(axis, dtype=float)
    return Rotation.from_rotvec(axis / np.linalg.norm(axis) * angle).as_matrix()


class Trajectory:
    """B's link pose as a function of s (A's link is at the identity); ``direction`` is the separation
    direction used to shift B per pair; ``scale`` converts s to the physical unit."""

    name: str
    scale: float
    direction: np.ndarray

    def poses(self, s: np.ndarray) -> np.ndarray:  # (N, 4, 4)
        raise NotImplementedError


class ParallelFaces(Trajectory):
    name = "parallel_faces"

    def __init__(self, link: spq.Polyhedron, theta_max: float, gap: float):
        normals, faces, verts = link.face_normals, link.faces, link.vertices
        tri = verts[faces]
        areas = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
        keys = np.round(normals, 6)
        best, best_area = None, -1.0
        for key in np.unique(keys, axis=0):
            sel = np.all(keys == key, axis=1)
            if areas[sel].sum() > best_area:
                best, best_area = sel, areas[sel].sum()
        n = normals[best][0]
        pts = np.unique(faces[best].ravel())
        fv = verts[pts]
        c = fv.mean(axis=0)
        # in-plane axes: rotate about the axis of smallest spread, so the sweep runs across the largest
        q = fv - c
        q -= np.outer(q @ n, n)
        w, v = np.linalg.eigh(q.T @ q)
        axes = [v[:, i] for i in range(3) if abs(v[:, i] @ n) < 0.5]
        self.axis = axes[0] / np.linalg.norm(axes[0])  # smallest in-plane spread
        self.sweep = np.cross(n, self.axis)  # witness jumps along this direction
        self.normal, self.centroid, self.facet_area = n, c, best_area
        self.half_width = float(np.max(np.abs(q @ self.sweep)))
        self.theta_max = theta_max
        self.scale = 2.0 * theta_max  # rad per unit s
        self.direction = n
        # B0: B's facet mirrored onto A's: rotation by pi about the in-plane axis through the centroid
        flip = _rot(self.axis, np.pi)
        base_gap = gap + self.half_width * np.sin(theta_max)  # the tilted facet edge must stay clear
        self.pivot = c + 0.5 * base_gap * n
        # B0 maps B's centroid c to c + base_gap n, facet normal n -> -n
        self.B0 = _pose(flip, c + base_gap * n - flip @ c)

    def poses(self, s):
        s = np.atleast_1d(np.asarray(s, dtype=float))
        out = np.empty((len(s), 4, 4))
        for i, si in enumerate(s):
            R = _rot(self.axis, (si - 0.5) * self.scale)
            rot = _pose(R, self.pivot - R @ self.pivot)
            out[i] = rot @ self.B0
        return out


class EdgeSlide(Trajectory):
    name = "edge_slide"

    def __init__(self, link: spq.Polyhedron, gap: float, seed: int):
        verts, faces, normals = link.vertices, link.faces, link.face_normals
        edges = {}
        for f, tri in enumerate(faces):
            for a, b in ((tri[0], tri[1]), (tri[1], tri[2]), (tri[2], tri[0])):
                edges.setdefault((min(a, b), max(a, b)), []).append(f)
        best, best_len = None, -1.0
        for (a, b), fs in edges.items():
            if len(fs) != 2 or abs(normals[fs[0]] @ normals[fs[1]]) > 1 - 1e-6:
                continue  # skip edges inside a coplanar facet
            length = np.linalg.norm(verts[a] - verts[b])
            if length > best_len:
                best, best_len = (a, b, fs), length
        a, b, fs = best
        m = normals[fs[0]] + normals[fs[1]]
        self.m = m / np.linalg.norm(m)
        self.v0, self.v1 = verts[a], verts[b]
        self.edge_length = best_len
        self.direction = self.m
        self.scale = 0.8 * best_len  # m per unit s
        R = Rotation.random(random_state=seed).as_matrix()
        local = R.T @ -self.m
        vb = verts[np.argmax(verts @ local)]  # B's closest vertex to A's edge (local frame)
        self.R, self.vb, self.gap = R, vb, gap

    def poses(self, s):
        s = np.atleast_1d(np.asarray(s, dtype=float))
        target = self.v0[None] + np.outer(0.1 + 0.8 * s, self.v1 - self.v0) + self.gap * self.m
        out = np.tile(np.eye(4), (len(s), 1, 1))
        out[:, :3, :3] = self.R
        out[:, :3, 3] = target - self.R @ self.vb
        return out


class RandomPath(Trajectory):
    name = "random_path"

    def __init__(self, link: spq.Polyhedron, seed: int, modes: int = 3, distance: float | None = None):
        rng = np.random.default_rng(seed)
        self.modes = modes
        self.at = rng.normal(size=(modes, 2, 3)) * 0.02 / np.arange(1, modes + 1)[:, None, None]  # m
        self.ar = rng.normal(size=(modes, 2, 3)) * 0.4 / np.arange(1, modes + 1)[:, None, None]  # rad
        u = rng.normal(size=3)
        self.direction = u / np.linalg.norm(u)
        self.R0 = Rotation.random(random_state=int(rng.integers(1 << 31))).as_matrix()
        rad = float(np.max(np.linalg.norm(link.vertices, axis=1)))
        self.distance = distance if distance is not None else 2.0 * rad
        self.scale = 1.0

    def _fourier(self, s, amp):
        k = np.arange(1, self.modes + 1)[None, :, None]
        ang = 2 * np.pi * k * s[:, None, None]
        return (np.sin(ang) * amp[None, :, 0] + np.cos(ang) * amp[None, :, 1] - amp[None, :, 1]).sum(axis=1)

    def poses(self, s):
        s = np.atleast_1d(np.asarray(s, dtype=float))
        t = self.distance * self.direction + self._fourier(s, self.at)
        w = self._fourier(s, self.ar)
        out = np.tile(np.eye(4), (len(s), 1, 1))
        out[:, :3, :3] = Rotation.from_rotvec(w).as_matrix() @ self.R0
        out[:, :3, 3] = t
        return out


def quick_config(object_name: str = "kuka_link_4", seed: int = 0, **overrides) -> ContinuityConfig:
    """Small settings (a few seconds): three steps, coarser grids, fewer gradient samples."""
    settings = dict(object_name=object_name, seed=seed, steps=(1e-1, 1e-3, 1e-5), grid=41, locate_grid=201, jumps=1,
                    gradient_samples=7)
    settings.update(overrides)
    return ContinuityConfig(**settings)


def make_trajectory(name: str, link, config: ContinuityConfig) -> Trajectory:
    if name == "parallel_faces":
        return ParallelFaces(link, config.theta_max, config.gap)
    if name == "edge_slide":
        return EdgeSlide(link, config.gap, config.seed)
    if name == "random_path":
        return RandomPath(link, config.seed)
    raise ValueError(f"unknown trajectory {name!r}; known: {TRAJECTORIES}")


class PairQuery:
    """Witness points and normals of one (pair, engine) along a trajectory, B shifted by `shift` metres."""

    def __init__(self, A: Body, B: Body, traj: Trajectory, shift: float, engine=None):
        self.A, self.B, self.traj, self.engine = A, B, traj, engine
        self.shift = shift
        self.prepared = engine.prepare(A.shape, B.shape) if engine is not None else None

    def body_poses(self, s):
        pb = self.traj.poses(s)
        pb[:, :3, 3] += self.shift * self.traj.direction
        return np.ascontiguousarray(self.A.offset[None].repeat(len(pb), 0)), np.ascontiguousarray(pb @ self.B.offset)

    def query(self, s):
        pa, pb = self.body_poses(s)
        if self.prepared is None:
            r = spq.distances(self.A.shape, self.B.shape, pa, pb, **TOL)
            return r.distance, r.point_a, r.point_b, r.normal, r.status
        r = self.prepared.query_many(pa, pb)
        d = r.point_b - r.point_a
        normal = d / np.linalg.norm(d, axis=1)[:, None]
        return r.distance, r.point_a, r.point_b, normal, r.status


def pair_shift(A: Body, B: Body, traj: Trajectory, link: spq.Polyhedron, s_ref: float = 0.5) -> float:
    """Shift (m) of B along the separation direction n so that this pair's supporting planes with normal n
    sit as far apart as the link hulls' do at s_ref (the STP-BV and CSE-BV stick out of the hull)."""
    hull = Body("hull", link, np.eye(4))
    link_a, link_b = np.eye(4), traj.poses([s_ref])[0]
    n = traj.direction
    excess_a = A.support_world(link_a, n) - hull.support_world(link_a, n)
    excess_b = B.support_world(link_b, -n) - hull.support_world(link_b, -n)
    return max(excess_a + excess_b, 0.0)


def _witness_step(q: PairQuery, s: np.ndarray, h: float):
    _, pa0, pb0, n0, st0 = q.query(s)
    _, pa1, pb1, n1, st1 = q.query(s + h)
    dp = np.maximum(np.linalg.norm(pa1 - pa0, axis=1), np.linalg.norm(pb1 - pb0, axis=1))
    dn = np.linalg.norm(n1 - n0, axis=1)
    ok = (st0 == "separated") & (st1 == "separated")
    return dp, dn, ok


def locate_jumps(q: PairQuery, count: int, grid: int, iterations: int = 40) -> list[float]:
    """s values of the `count` largest witness-point changes on a grid, each refined by bisection."""
    s = np.linspace(0.0, 1.0, grid)
    _, pa, pb, _, _ = q.query(s)
    jump = np.maximum(np.linalg.norm(np.diff(pa, axis=0), axis=1), np.linalg.norm(np.diff(pb, axis=0), axis=1))
    found = []
    for i in np.argsort(jump)[::-1][:count]:
        lo, hi = s[i], s[i + 1]
        _, plo, qlo, _, _ = q.query(np.array([lo, hi]))
        for _ in range(iterations):
            mid = 0.5 * (lo + hi)
            _, pm, qm, _, _ = q.query(np.array([mid]))
            left = max(np.linalg.norm(pm[0] - plo[0]), np.linalg.norm(qm[0] - qlo[0]))
            right = max(np.linalg.norm(plo[1] - pm[0]), np.linalg.norm(qlo[1] - qm[0]))
            if left >= right:
                hi, plo[1], qlo[1] = mid, pm[0], qm[0]
            else:
                lo, plo[0], qlo[0] = mid, pm[0], qm[0]
        found.append(0.5 * (lo + hi))
    return found


def gradient_check(q: PairQuery, config: ContinuityConfig) -> tuple[float, float, float]:
    """(max |analytic - FD| of dd/ds in m per unit s, max relative error, max |dd/ds|) over sample s."""
    s = np.linspace(0.05, 0.95, config.gradient_samples)
    e = config.fd_step
    pa, pb = q.body_poses(s)
    res = spq.distances(q.A.shape, q.B.shape, pa, pb, **TOL)
    _, grad_b = spq.distance_gradients(res, pa, pb)
    pb_plus, pb_minus = q.body_poses(s + e)[1], q.body_poses(s - e)[1]
    v = (pb_plus[:, :3, 3] - pb_minus[:, :3, 3]) / (2 * e)
    w = Rotation.from_matrix(np.einsum("nij,nkj->nik", pb_plus[:, :3, :3], pb_minus[:, :3, :3])).as_rotvec() / (2 * e)
    analytic = np.einsum("ni,ni->n", grad_b, np.concatenate([v, w], axis=1))
    d_plus = spq.distances(q.A.shape, q.B.shape, pa, pb_plus, **TOL).distance
    d_minus = spq.distances(q.A.shape, q.B.shape, pa, pb_minus, **TOL).distance
    fd = (d_plus - d_minus) / (2 * e)
    err = np.abs(analytic - fd)
    rel = err / np.maximum(np.abs(analytic), 1.0)
    return float(np.nanmax(err)), float(np.nanmax(rel)), float(np.nanmax(np.abs(analytic)))


def run(config: ContinuityConfig, load_object, progress: bool = False) -> tuple[pd.DataFrame, dict]:
    """(table with one row per pair, engine, trajectory and step; paths for the witness-path chart)."""
    from harness.engines import available_engines

    bodies = build_bodies(config, load_object)
    link = bodies["PCH"].shape
    engines = {}
    if config.engines:
        try:
            engines = available_engines(list(config.engines))
        except ImportError:
            engines = {}
    rows, paths = [], {}
    for tname in config.trajectories:
        traj = make_trajectory(tname, link, config)
        unit_step, unit_ratio = UNITS[tname]
        for a_name, b_name in config.pairs:
            A, B = bodies[a_name], bodies[b_name]
            shift = pair_shift(A, B, traj, link)
            runs = [("spq", None)]
            if (a_name, b_name) == ("PCH", "PCH"):
                runs += list(engines.items())
            for ename, engine in runs:
                q = PairQuery(A, B, traj, shift, engine)
                pair = f"{a_name}-{b_name}"
                if tname == "parallel_faces":
                    s_path = np.linspace(0.0, 1.0, 401)
                    _, _, pb_path, _, _ = q.query(s_path)
                    paths[(pair, ename)] = (s_path, (s_path - 0.5) * traj.scale, pb_path @ traj.sweep)
                jumps = locate_jumps(q, config.jumps, config.locate_grid)
                dist = q.query(np.linspace(0.0, 1.0, config.grid))[0]
                if ename == "spq":
                    g_err, g_rel, g_max = gradient_check(q, config)
                else:
                    g_err = g_rel = g_max = np.nan  # engine tolerances (~1e-8 m) are too loose for an FD check
                for h in config.steps:
                    base = np.linspace(0.0, 1.0 - h, config.grid)
                    extra = [j - h * f for j in jumps for f in (0.25, 0.5, 0.75)]
                    s = np.clip(np.concatenate([base, extra]), 0.0, 1.0 - h)
                    dp, dn, ok = _witness_step(q, s, h)
                    step = h * traj.scale
                    rows.append({"trajectory": tname, "pair": pair, "engine": ename, "step_s": h,
                                 "step": step, "step_unit": unit_step,
                                 "witness_lipschitz": float(np.max(dp[ok]) / step) if ok.any() else np.nan,
                                 "normal_lipschitz": float(np.max(dn[ok]) / step) if ok.any() else np.nan,
                                 "ratio_unit": unit_ratio, "min_distance_m": float(np.nanmin(dist)),
                                 "not_separated": int((~ok).sum()), "shift_m": shift,
                                 "grad_abs_error": g_err, "grad_rel_error": g_rel, "max_abs_dd_ds": g_max})
    return pd.DataFrame(rows), paths


def growth(table: pd.DataFrame) -> pd.DataFrame:
    """Per (trajectory, pair, engine): witness ratio at the largest and smallest steps and their quotient."""
    out = []
    for (t, p, e), g in table.groupby(["trajectory", "pair", "engine"], sort=False):
        g = g.sort_values("step_s")
        out.append({"trajectory": t, "pair": p, "engine": e, "ratio_unit": g.ratio_unit.iloc[0],
                    "ratio_largest_step": g.witness_lipschitz.iloc[-1],
                    "ratio_smallest_step": g.witness_lipschitz.iloc[0],
                    "growth": g.witness_lipschitz.iloc[0] / g.witness_lipschitz.iloc[-1],
                    "normal_ratio_smallest_step": g.normal_lipschitz.iloc[0],
                    "grad_rel_error": g.grad_rel_error.iloc[0], "min_distance_m": g.min_distance_m.iloc[0]})
    return pd.DataFrame(out)


def plot_lipschitz(table: pd.DataFrame, path, title: str = "") -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    trajs = list(dict.fromkeys(table.trajectory))
    fig, axes = plt.subplots(1, len(trajs), figsize=(5.2 * len(trajs), 4.5), squeeze=False)
    for ax, t in zip(axes[0], trajs):
        sub = table[table.trajectory == t]
        for (p, e), g in sub.groupby(["pair", "engine"], sort=False):
            g = g.sort_values("step")
            ax.plot(g.step, g.witness_lipschitz, marker="o", linestyle="-" if e == "spq" else "--",
                    label=p if e == "spq" else f"{p} ({e})")
        unit_step, unit_ratio = UNITS[t]
        steps = np.sort(sub.step.unique())
        ref = sub[(sub.pair == "PCH-PCH") & (sub.engine == "spq")].sort_values("step")
        if len(ref):
            ax.plot(steps, ref.witness_lipschitz.iloc[-1] * steps[-1] / steps, color="grey", linewidth=0.8,
                    linestyle=":", label="∝ 1/step")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(f"step ({unit_step})")
        ax.set_ylabel(f"witness-point Lipschitz ratio max|Δp|/step ({unit_ratio})")
        ax.set_title(t)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    save_figure(fig, path, title)


def plot_paths(paths: dict, path, title: str = "") -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.5))
    for (pair, engine), (_, theta, coord) in paths.items():
        ax.plot(theta, coord, linestyle="-" if engine == "spq" else "--",
                label=pair if engine == "spq" else f"{pair} ({engine})")
    ax.set_xlabel("rotation angle of B about the in-plane axis θ (rad)")
    ax.set_ylabel("witness point p_B along the sweep direction (m, world)")
    ax.set_title(title or "parallel_faces: witness point on B")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    save_figure(fig, path)
