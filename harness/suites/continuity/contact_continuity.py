"""Continuity through contact: signed distance and its gradient along paths that enter and leave contact.

Body A (a link's PCH, STP-BV or CSE-BV) is fixed at the identity; B moves along s in [0, 1]: it turns
about a seeded axis by ``turn`` rad in all while its origin crosses A along a line, from ``gap`` metres
of separation (s = 0) to about ``depth`` metres of penetration (s = 0.5) and out again (s = 1):

    t(s) = [(1 - s) (t_0 + gap) + s (t_1 + gap)] (1 - sin(pi s)) u + (t_half - depth) sin(pi s) u,

where u is the seeded direction from A to B and t_0, t_half, t_1 the distances along u where the
bodies touch at the rotations of s = 0, 0.5 and 1, found by bisection on spq's signed distance
(placement only): the path starts and ends apart and is in contact at s = 0.5.

Metrics per pair and path, on spq's ``signed=True`` queries (spq's default tolerances):

- ``crossings``: sign changes of the signed distance on the grid; each is bisected ``BISECTIONS``
  times in s and ``max_crossing_jump_m`` is the largest |sd(s1) - sd(s0)| left on the final
  interval (a jump at zero would stay; a continuous signed distance leaves ~ its slope times the
  interval, far below 1e-9 m);
- ``lipschitz``: max |sd(s + h) - sd(s)| / h on the grid (m per unit s);
- gradient jumps: B's 6-vector gradient (spq.distance_gradients) along the path; the
  ``JUMP_CANDIDATES`` steps with the largest relative change are bisected ``BISECTIONS`` times
  (as in the robot suite); a jump keeps over ``JUMP_RESIDUAL`` of its change. Counted over the
  whole path, over the part in contact (sd < 0), and over the part deeper than the STP-BV's small
  radius r apart: down to depth r the boundary point nearest the origin inside the Minkowski
  difference is unique for an STP-BV (a ball of radius r rolls inside it), so its gradient must not
  jump; deeper, that point can switch across the difference's medial axis, for any pair of bodies,
  and the gradient of the penetration depth jumps there by nature.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.spatial.transform import Rotation

import spq
from harness.report.charts import save_figure
from harness.suites.continuity.witness_continuity import PAIRS, Body, build_bodies

TOL = dict(tol=spq.DEFAULT_TOL_ABS, rel_tol=spq.DEFAULT_TOL_REL)
BISECTIONS = 40  # halvings of a crossing interval; of a gradient-jump candidate
JUMP_CANDIDATES = 6
JUMP_RESIDUAL = 0.5


@dataclass
class ContactConfig:
    object_name: str = "kuka_link_4"
    r: float = 0.005  # m: STP small radius
    R: float = 2.0  # m: STP big radius
    seed: int = 0
    paths: int = 3  # seeded paths per pair
    grid: int = 401
    gap: float = 0.02  # m: separation at both ends
    depth: float = 0.003  # m: about the deepest penetration, at s = 0.5
    turn: float = 0.6  # rad: total rotation of B along the path
    gradient_bisections: int = 20  # halvings of a gradient-jump candidate


class ContactPath:
    """B's poses along one path (see the module docstring)."""

    def __init__(self, A: Body, B: Body, config: ContactConfig, seed: int):
        rng = np.random.default_rng(seed)
        u = rng.normal(size=3)
        self.u = u / np.linalg.norm(u)
        axis = rng.normal(size=3)
        self.axis = axis / np.linalg.norm(axis)
        self.R0 = Rotation.random(random_state=seed).as_matrix()
        self.A, self.B, self.config = A, B, config
        self.touch = [self._touch(self.rotation(np.array([s]))[0]) for s in (0.0, 0.5, 1.0)]

    def rotation(self, s: np.ndarray) -> np.ndarray:
        angles = (np.asarray(s) - 0.5) * self.config.turn
        return Rotation.from_rotvec(angles[:, None] * self.axis).as_matrix() @ self.R0

    def _sd(self, rotation: np.ndarray, t_along: float) -> float:
        pose = np.eye(4)
        pose[:3, :3] = rotation
        pose[:3, 3] = t_along * self.u
        return spq.distance(self.A.shape, self.B.shape, self.A.offset, pose @ self.B.offset, signed=True).distance

    def _touch(self, rotation: np.ndarray) -> float:
        lo, hi = -1.0, 1.0
        while self._sd(rotation, lo) > 0.0:  # into contact first (the signed distance is convex along
            lo *= 0.5  # the line, so it is negative on an interval and positive beyond)
        while self._sd(rotation, hi) <= 0.0:
            hi *= 2.0
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if self._sd(rotation, mid) <= 0.0 else (lo, mid)
        return hi

    def poses(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        s = np.atleast_1d(np.asarray(s, dtype=float))
        c = self.config
        t0, half, t1 = self.touch
        w = np.sin(np.pi * s)
        along = ((1 - s) * t0 + s * t1 + c.gap) * (1 - w) + (half - c.depth) * w
        pb = np.repeat(np.eye(4)[None], len(s), 0)
        pb[:, :3, :3] = self.rotation(s)
        pb[:, :3, 3] = along[:, None] * self.u
        pa = np.repeat(self.A.offset[None], len(s), 0)
        return np.ascontiguousarray(pa), np.ascontiguousarray(pb @ self.B.offset)

    def query(self, s):
        pa, pb = self.poses(s)
        r = spq.distances(self.A.shape, self.B.shape, pa, pb, signed=True, **TOL)
        _, grad_b = spq.distance_gradients(r, pa, pb)
        return r, grad_b


def crossing_jump(path: ContactPath, s0: float, s1: float, levels: int = BISECTIONS) -> float:
    """|sd(s1) - sd(s0)| after ``levels`` bisections of a sign change of sd on [s0, s1]."""
    d0 = path.query([s0])[0].distance[0]
    d1 = path.query([s1])[0].distance[0]
    for _ in range(levels):
        sm = 0.5 * (s0 + s1)
        dm = path.query([sm])[0].distance[0]
        if (dm < 0.0) == (d0 < 0.0):
            s0, d0 = sm, dm
        else:
            s1, d1 = sm, dm
    return float(abs(d1 - d0))


def gradient_residual(path: ContactPath, s0: float, s1: float, levels: int) -> float:
    """The part of B's gradient change on [s0, s1] left on a 2^-levels sub-interval, following the
    larger half each time: ~1 for a jump, ~2^-levels for a continuous gradient."""
    g0, g1 = path.query([s0])[1][0], path.query([s1])[1][0]
    total = np.linalg.norm(g1 - g0)
    if not total > 0.0:
        return 0.0
    for _ in range(levels):
        sm = 0.5 * (s0 + s1)
        gm = path.query([sm])[1][0]
        if np.linalg.norm(gm - g0) >= np.linalg.norm(g1 - gm):
            s1, g1 = sm, gm
        else:
            s0, g0 = sm, gm
    return float(np.linalg.norm(g1 - g0) / total)


def measure(path: ContactPath, config: ContactConfig) -> tuple[dict, dict]:
    """(metrics row, curves for the chart) of one path."""
    s = np.linspace(0.0, 1.0, config.grid)
    r, grad = path.query(s)
    d = r.distance
    h = s[1] - s[0]
    sign = d < 0.0
    crossings = np.flatnonzero(sign[1:] != sign[:-1])
    jumps = [crossing_jump(path, s[k], s[k + 1]) for k in crossings]
    change = np.linalg.norm(np.diff(grad, axis=0), axis=1)
    scale = np.maximum(np.maximum(np.linalg.norm(grad[1:], axis=1), np.linalg.norm(grad[:-1], axis=1)), 1e-12)
    relative = change / scale
    candidates = np.argsort(-np.nan_to_num(relative, nan=np.inf))[:JUMP_CANDIDATES]
    residual = np.array([gradient_residual(path, s[k], s[k + 1], config.gradient_bisections) for k in candidates])
    jump_steps = candidates[residual > JUMP_RESIDUAL]
    in_contact = sign[jump_steps] | sign[jump_steps + 1]
    deep = np.minimum(d[jump_steps], d[jump_steps + 1]) < -config.r
    row = {"min_signed_m": float(d.min()), "failed": int((r.status == "failed").sum()),
           "crossings": int(len(crossings)),
           "max_crossing_jump_m": float(max(jumps)) if jumps else np.nan,
           "lipschitz_m_per_s": float(np.abs(np.diff(d)).max() / h),
           "gradient_jumps": int(len(jump_steps)), "gradient_jumps_in_contact": int(in_contact.sum()),
           "gradient_jumps_deeper_than_r": int(deep.sum()),
           "largest_gradient_residual": float(residual.max()) if residual.size else np.nan}
    return row, {"s": s, "distance": d, "gradient_norm": np.linalg.norm(grad[:, 3:], axis=1), "jumps": s[jump_steps]}


def run(config: ContactConfig, load_object, progress: bool = False) -> tuple[pd.DataFrame, dict]:
    """One row per (pair, path); curves of the first path of each pair for the chart."""
    from tqdm import tqdm

    bodies = build_bodies(config, load_object)
    rows, curves = [], {}
    jobs = [(a, b, k) for a, b in PAIRS for k in range(config.paths)]
    for a, b, k in tqdm(jobs, desc="contact continuity", unit="path", disable=not progress):
        path = ContactPath(bodies[a], bodies[b], config, config.seed * 1000 + k)
        row, curve = measure(path, config)
        rows.append({"pair": f"{a}-{b}", "path": k, **row})
        if k == 0:
            curves[f"{a}-{b}"] = curve
    return pd.DataFrame(rows), curves


def summary(table: pd.DataFrame) -> pd.DataFrame:
    """Per pair: paths, crossings, the largest crossing jump, gradient jumps (all, in contact, deeper
    than r)."""
    return table.groupby("pair", sort=False).agg(
        paths=("path", "count"), deepest_m=("min_signed_m", "min"), failed=("failed", "sum"),
        crossings=("crossings", "sum"), max_crossing_jump_m=("max_crossing_jump_m", "max"),
        max_lipschitz_m_per_s=("lipschitz_m_per_s", "max"), gradient_jumps=("gradient_jumps", "sum"),
        gradient_jumps_in_contact=("gradient_jumps_in_contact", "sum"),
        gradient_jumps_deeper_than_r=("gradient_jumps_deeper_than_r", "sum")).reset_index()


def plot(curves: dict, path, title: str = "") -> None:
    """Signed distance and the norm of its gradient in B's rotation (where witness jumps show) along
    each pair's first path; gradient jumps marked."""
    from harness.report.charts import pyplot

    plt = pyplot()
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    for name, c in curves.items():
        (line,) = top.plot(c["s"], c["distance"], label=name)
        bottom.plot(c["s"], c["gradient_norm"], color=line.get_color(), label=name)
        for s in c["jumps"]:
            bottom.axvline(s, color=line.get_color(), lw=0.8, ls=":")
    top.axhline(0.0, color="k", lw=0.6)
    top.set_ylabel("signed distance (m)")
    bottom.set_ylabel("|dd/d omega_B| (m/rad)")
    bottom.set_xlabel("s (path parameter)")
    top.legend(fontsize=8, ncol=3)
    save_figure(fig, path, title)
