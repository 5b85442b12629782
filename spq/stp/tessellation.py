"""Surface points of an STP-BV, patch by patch, for its mesh (spq.tessellation does the rest).

Each patch is sampled over its own region of directions (NOTES section 1) with the closed form of
its support, so every point lies on the true surface and the samples follow the patch boundaries
(a boundary point is the same surface point seen from both sides):

- big sphere of face f, centre c_f, radius R: its region is the spherical triangle whose corners are
  the directions (x_i - c_f) / rho to the face's three vertices; the triangle is subdivided
  barycentrically and each direction v gives c_f + R v.
- torus of edge (a, b): with e the unit axis from b to a, m the midpoint, a_t the circle radius, its
  directions are v = cos(t) w(psi) + sin(t) e with w(psi) turning (perpendicular to e) from the
  direction of m - c_f1 to that of m - c_f2 and |sin t| <= l / (2 rho); the point is
  m + (R cos t - a_t) w + R sin t e. On a (psi, t) grid of steps (h_psi, h_t), any direction of the
  region lies within (h_psi / 2, h_t / 2) of a grid direction whose point is at most
  R (1 - cos(h_t / 2)) + (R - a_t)(1 - cos(h_psi / 2)) below the support plane.
- small sphere of vertex i (radius r): the directions of an even lattice that the vertex's region
  owns (the support kernel's patch search decides), x_i + r v; its boundary is the tori's grid ends
  and the faces' corners.

A sphere of radius rho sampled at angular spacing alpha leaves at most rho (1 - cos alpha) between
the hull of its points and itself; the steps are chosen so that each patch meets a share of the
tolerance, and the certificate of spq.tessellation has the last word.
"""

from __future__ import annotations

import math

import numpy as np

from spq.tessellation import LATTICE_COVER, fibonacci_directions, unit

PATCH_SHARE = 0.5  # share of the tolerance the patch grids aim at (the rest: the certificate's 1/cos factor)
MAX_STEP = 0.35  # rad: largest angle between neighbouring samples of a patch, so a coarse mesh still looks round


def _step(tolerance: float, radius: float) -> float:
    """Angle (rad) whose sagitta on a sphere of ``radius`` is ``tolerance``, at most MAX_STEP."""
    if tolerance >= radius:
        return MAX_STEP
    return min(math.acos(1.0 - tolerance / radius), MAX_STEP)


def big_sphere_samples(stp, tolerance: float) -> tuple[np.ndarray, np.ndarray]:
    """(points, normals) on the big-sphere patches: each face's spherical triangle of directions
    subdivided so that no point of it is farther than the step of R from a sample."""
    topo = stp.topology
    if len(topo.faces) == 0:
        return np.zeros((0, 3)), np.zeros((0, 3))
    corners = unit(topo.vertices[topo.faces] - topo.face_centres[:, None, :])  # (F, 3, 3)
    cosines = np.stack([np.einsum("ij,ij->i", corners[:, i], corners[:, (i + 1) % 3]) for i in range(3)], axis=1)
    side = np.arccos(np.clip(cosines.min(axis=1), -1.0, 1.0))
    # a triangle's points lie within (longest side) / sqrt(3) of a corner: subdivide to that
    alpha = _step(tolerance, stp.R)
    levels = np.maximum(1, np.ceil(1.1 * side / (math.sqrt(3.0) * alpha))).astype(np.int64)
    points, normals = [], []
    for n in np.unique(levels):
        sel = np.flatnonzero(levels == n)
        i, j = np.array([(i, j) for i in range(n + 1) for j in range(n + 1 - i)]).T
        weights = np.column_stack([i, j, n - i - j]) / n  # (k, 3) barycentric
        v = unit(np.einsum("kc,fcd->fkd", weights, corners[sel]))  # (f, k, 3)
        normals.append(v.reshape(-1, 3))
        points.append((topo.face_centres[sel][:, None, :] + stp.R * v).reshape(-1, 3))
    return np.concatenate(points), np.concatenate(normals)


def torus_samples(stp, tolerance: float) -> tuple[np.ndarray, np.ndarray]:
    """(points, normals) on the torus patches, on each torus's (psi, t) grid (module docstring)."""
    T = stp.n_tori
    if T == 0:
        return np.zeros((0, 3)), np.zeros((0, 3))
    topo = stp.topology
    R, rho = stp.R, topo.rho
    m, e, a = stp.torus_centres, stp.torus_axes, stp.torus_radii
    length = np.linalg.norm(topo.vertices[topo.edges[stp.torus_edges, 0]]
                            - topo.vertices[topo.edges[stp.torus_edges, 1]], axis=1)
    t0 = np.arcsin(np.clip(length / (2.0 * rho), 0.0, 1.0))

    w1, u2, phi = stp.torus_start, stp.torus_turn, stp.torus_arc
    spindle = phi >= 2.0 * math.pi
    h_t = 2.0 * _step(0.5 * tolerance, R)
    h_psi = np.array([2.0 * _step(0.5 * tolerance, R - ai) for ai in a])
    n_t = np.maximum(2, np.ceil(2.0 * t0 / h_t).astype(np.int64) + 1)
    n_psi = np.maximum(2, np.ceil(phi / h_psi).astype(np.int64) + 1)
    count = n_t * n_psi
    torus = np.repeat(np.arange(T), count)
    local = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
    j, k = local // n_psi[torus], local % n_psi[torus]
    t = t0[torus] * (2.0 * j / (n_t[torus] - 1) - 1.0)
    psi = phi[torus] * np.where(spindle[torus], k / n_psi[torus], k / (n_psi[torus] - 1))
    w = np.cos(psi)[:, None] * w1[torus] + np.sin(psi)[:, None] * u2[torus]
    v = np.cos(t)[:, None] * w + np.sin(t)[:, None] * e[torus]
    points = m[torus] + (R * np.cos(t) - a[torus])[:, None] * w + (R * np.sin(t))[:, None] * e[torus]
    return points, v


def small_sphere_samples(stp, tolerance: float) -> tuple[np.ndarray, np.ndarray]:
    """(points, normals) inside the small-sphere patches: the directions of a Fibonacci lattice
    (covering angle three quarters of the step of r) that a small sphere owns."""
    alpha = 0.75 * _step(tolerance, stp.r)
    directions = fibonacci_directions(int(math.ceil((LATTICE_COVER / alpha) ** 2)))
    points, patches, _ = stp.support_patches(directions)
    small = patches < stp.n_small
    return points[small], directions[small]


def patch_samples(stp, tolerance: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Surface points (n, 3), their unit normals (n, 3) and patch kinds (n,) (0 small sphere, 1 big
    sphere, 2 torus) of an STP-BV, each patch sampled for a share PATCH_SHARE of ``tolerance`` (m)."""
    share = PATCH_SHARE * tolerance
    parts = [small_sphere_samples(stp, share), big_sphere_samples(stp, share), torus_samples(stp, share)]
    kinds = np.concatenate([np.full(len(p), k) for k, (p, _) in enumerate(parts)])
    return np.concatenate([p for p, _ in parts]), np.concatenate([n for _, n in parts]), kinds
