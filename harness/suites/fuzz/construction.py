"""STP-BV construction as a fuzz family: adversarial point clouds, and a judge that owes nothing to the
construction it judges.

``construction_cases(rng, n)`` draws n cases (dicts with ``family``, ``points`` (k, 3) m, ``r``, ``R``)
from the families below, each cloud then scaled to a size of 1e-4 .. 1e3 m, turned, and in a third of
the cases moved 1 .. 1e4 sizes away from the origin:

- ``random``: 4 .. 10,000 points in a ball, on a sphere, in a cube or Gaussian;
- ``duplicates``: a cloud with near-duplicates of its points 1e-9 .. 1e-6 of its size apart (and a few
  exact ones and ones 1e-13 apart, which are one point);
- ``coplanar``: points on the faces of a box, many per face and on its edges, some moved 1e-13 .. 1e-7
  off their planes;
- ``cospherical``: points on one sphere (random, a latitude-longitude grid, the corners of a cube or an
  icosahedron), exactly up to rounding or 1e-15 .. 1e-9 off it;
- ``cocircular``: rings of 3 .. 200 points: cylinders, cones, a box with round bosses (CAD parts),
  often rounded to float32 as mesh files store them;
- ``sliver`` and ``needle``: clouds 1e-13 .. 1e-2 thin or across, and exactly flat or on a line;
- ``mesh``: the convex hull vertices of boxes and cylinders put together, float32-rounded (what robot
  meshes give).

R - r is drawn from three regimes relative to the cloud's enclosing radius r_meb (computed here, see
:func:`enclosing_ball`): at or just above it (factor 1 + 0 .. 1e-2), moderate (1.01 .. 10) and very
large (1e1 .. 1e9 times the cloud's size); r is 1e-6 .. 0.1 of the size.

``check_construction(points, r, R)`` builds the STP-BV with spq and returns ``(verdict, detail)``:
'failed' when the construction raises on an admissible R (detail: the exception), 'ok' when it
refuses an R below the enclosing radius with ValueError or when every check below passes, 'wrong'
otherwise, the detail saying what is at fault:

- ``construction:`` the topology (spq.stp.construction): inconsistent or not one closed surface
  (V - E + F = 2), a face's ball of radius R - r misses a point (the definition of a face), or the
  STP-BV of its vertices is not the cloud's: for clouds of up to ORACLE_MAX_POINTS points its
  brute-force support (harness.references.stp_oracle: no topology, the best admissible centre over every
  sphere, circle and triple point) differs from that of all the points; for bigger clouds on at most
  ORACLE_MAX_VERTICES vertices it misses a point;
- ``volume:`` the STP-BV built on a topology that passed (spq.shapes.stpbv, its support function):
  along random directions and the normal cones of the convex hull's vertices its support
  h(u) = u.s(u) is less than max_i u.x_i + r (a point's small sphere is outside: the volume does not
  cover the cloud) or more than min_f u.c_f + R (it leaves a face's big sphere, which holds the
  cloud); for small clouds it differs from the brute-force support; or a direction has other than
  one owner (for up to OWNER_MAX_PATCHES patches). A bracket names what in the topology the STP-BV's
  regions of directions cannot express, when the judge finds it (_representation_limits): such
  failures belong to spq.shapes.stpbv, not to the construction.

Tolerance (m): ``CHECK_REL_TOL * size + ROUNDING_REL_TOL * (R + max|x|)``; the second term is the
rounding of a support point c_f + R u computed from centres R - r away in the input's frame.
"""

from __future__ import annotations

import itertools
import math
import time
from collections import Counter

import numpy as np
from scipy.spatial import ConvexHull, QhullError
from scipy.spatial.transform import Rotation

from harness.suites.fuzz.families import _count, _log_uniform

CHECK_REL_TOL = 1e-9  # admissible miss, relative to the cloud's size (bounding-box diagonal) (m/m)
# rounding of a support point c_f + R u, or m - a w / |w| + R u on a torus with a ~ R, relative to
# R + max|x| (m/m): ~4500 eps; a needle at R = 6e5 sizes came 600 eps short along its axis (|w| small)
ROUNDING_REL_TOL = 1e-12
MEB_REL_TOL = 1e-12  # the core set's ball is the cloud's when no point is farther out, over the size (m/m)
ORACLE_MAX_POINTS = 30  # brute-force support is O(n^3) per call
ORACLE_MAX_VERTICES = 40  # beyond ORACLE_MAX_POINTS points, the oracle on the vertices alone
N_ORACLE_DIRECTIONS = 600
OWNER_MAX_PATCHES = 20_000  # owner counts cost directions x patches
N_RANDOM_DIRECTIONS = 1000
N_OWNER_DIRECTIONS = 300
# R - r beyond this many sizes: the faces' regions, ~ size / rho across, approach the rounding of
# their planes (~ eps rho / size); a 1e-8 thin sliver at 7e6 sizes had two faces own its normal
WIDE_RHO = 1e6
AT_MINIMUM = 1e-9  # R - r within this of the enclosing radius (relative): Q is a point up to rounding
FAMILIES = ("random", "duplicates", "coplanar", "cospherical", "cocircular", "sliver", "needle", "mesh")


# ------------------------------------------------------------------------------------------ draws

def _unit_rows(rng, n: int) -> np.ndarray:
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def cloud_random(rng) -> np.ndarray:
    """4 .. 10,000 points in the unit ball, on the unit sphere (up to 3000), in a cube or Gaussian."""
    n = _count(rng)
    kind = rng.integers(4)
    if kind == 0:
        return _unit_rows(rng, n) * rng.uniform(size=(n, 1)) ** (1 / 3)
    if kind == 1:
        return _unit_rows(rng, min(n, 3000))
    if kind == 2:
        return rng.uniform(-1, 1, (n, 3))
    return rng.normal(size=(n, 3)) * rng.uniform(0.05, 1.0, 3)


def cloud_duplicates(rng) -> np.ndarray:
    """A random cloud of up to 2000 points and near-duplicates of some of them."""
    base = cloud_random(rng)[: _count(rng, 4, 2000)]
    k = int(rng.integers(1, len(base) + 1))
    pick = rng.integers(len(base), size=k)
    gap = np.array([_log_uniform(rng, 1e-9, 1e-6) for _ in range(k)])
    gap[rng.uniform(size=k) < 0.1] = 0.0  # exact duplicates
    gap[rng.uniform(size=k) < 0.1] = 1e-13  # one point to the construction (MERGE_TOL 1e-12)
    size = float(np.linalg.norm(np.ptp(base, axis=0)))
    copies = base[pick] + _unit_rows(rng, k) * (gap * size)[:, None]
    x = np.concatenate([base, copies])
    return x[rng.permutation(len(x))]


def cloud_coplanar(rng) -> np.ndarray:
    """Box faces sampled on grids (coplanar and collinear points) or at random, corners included."""
    half = rng.uniform(0.05, 1.0, 3)
    corners = np.array(list(itertools.product([-1.0, 1.0], repeat=3))) * half
    if rng.uniform() < 0.5:
        k = int(rng.integers(2, 12))
        t = np.linspace(-1.0, 1.0, k)
        grid = np.array(list(itertools.product(t, t)))
        faces = []
        for axis in range(3):
            others = [a for a in range(3) if a != axis]
            for side in (-1.0, 1.0):
                f = np.zeros((len(grid), 3))
                f[:, others] = grid
                f[:, axis] = side
                faces.append(f * half)
        x = np.unique(np.concatenate([corners] + faces), axis=0)
    else:
        n = _count(rng, 8, 5000)
        x = rng.uniform(-1, 1, (n, 3)) * half
        axis = rng.integers(3, size=n)
        x[np.arange(n), axis] = rng.choice([-1.0, 1.0], size=n) * half[axis]
        x = np.concatenate([corners, x])
    moved = rng.uniform(size=len(x)) < rng.uniform()
    x[moved] += rng.normal(size=(moved.sum(), 3)) * _log_uniform(rng, 1e-13, 1e-7)
    return x


def _icosahedron() -> np.ndarray:
    g = (1 + 5 ** 0.5) / 2
    v = [(0, s1, s2 * g) for s1 in (-1, 1) for s2 in (-1, 1)]
    v = [p for q in v for p in (q, q[1:] + q[:1], q[2:] + q[:2])]
    v = np.array(v, dtype=float)
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def cloud_cospherical(rng) -> np.ndarray:
    """Points on the unit sphere: random, a latitude-longitude grid, a cube's or an icosahedron's
    corners; half of the draws moved off it by 1e-15 .. 1e-9."""
    kind = rng.integers(4)
    if kind == 0:
        x = _unit_rows(rng, _count(rng, 5, 2000))
    elif kind == 1:
        k, m = int(rng.integers(3, 40)), int(rng.integers(2, 20))
        lat = np.linspace(-np.pi / 2, np.pi / 2, m + 2)[1:-1]
        lon = 2 * np.pi * np.arange(k) / k
        la, lo = np.meshgrid(lat, lon)
        x = np.c_[np.cos(la.ravel()) * np.cos(lo.ravel()), np.cos(la.ravel()) * np.sin(lo.ravel()),
                  np.sin(la.ravel())]
        if rng.uniform() < 0.5:
            x = np.vstack([x, [[0, 0, 1.0], [0, 0, -1.0]]])
    elif kind == 2:
        x = np.array(list(itertools.product([-1.0, 1.0], repeat=3))) / 3 ** 0.5
    else:
        x = _icosahedron()
    if rng.uniform() < 0.5:
        x = x * (1 + rng.normal(size=(len(x), 1)) * _log_uniform(rng, 1e-15, 1e-9))
    return x


def _ring(k: int, radius: float, z: float, phase: float = 0.0) -> np.ndarray:
    a = phase + 2 * np.pi * np.arange(k) / k
    return np.c_[radius * np.cos(a), radius * np.sin(a), np.full(k, z)]


def cloud_cocircular(rng) -> np.ndarray:
    """Rings of 3 .. 200 points: a stack (a turned part), a cone, or bosses on a box's top face."""
    kind = rng.integers(3)
    k = int(_log_uniform(rng, 3, 200))
    if kind == 0:  # a cylinder, or a stack of rings (a turned part)
        m = int(rng.integers(2, 6))
        zs = np.sort(rng.uniform(-1, 1, m))
        radii = rng.uniform(0.2, 1.0, m) if rng.uniform() < 0.5 else np.ones(m)
        x = np.vstack([_ring(k, a, z) for a, z in zip(radii, zs)])
    elif kind == 1:  # a cone, with or without its apex
        x = np.vstack([_ring(k, 1.0, 0.0), _ring(k, rng.uniform(0.0, 0.9), 1.0)])
    else:  # a box with round bosses on its top face
        half = rng.uniform(0.2, 1.0, 3)
        x = [np.array(list(itertools.product([-1.0, 1.0], repeat=3))) * half]
        for _ in range(int(rng.integers(1, 5))):
            a = rng.uniform(0.01, 0.3) * half[:2].min()
            centre = rng.uniform(-1, 1, 2) * (half[:2] - a)
            h = rng.uniform(0.0, 0.2) * half[2]
            ring_top = _ring(k, a, half[2] + h) + [*centre, 0]
            ring_base = _ring(k, a, half[2]) + [*centre, 0]
            x += [ring_top, ring_base]
        x = np.vstack(x)
    return x


def cloud_sliver(rng) -> np.ndarray:
    """A random cloud squashed to 1e-13 .. 1e-2 of its size, or flat."""
    x = cloud_random(rng)
    x[:, 2] *= 0.0 if rng.uniform() < 0.2 else _log_uniform(rng, 1e-13, 1e-2)
    return x


def cloud_needle(rng) -> np.ndarray:
    """A random cloud squashed to 1e-13 .. 1e-2 of its size across, or onto a line."""
    x = cloud_random(rng)
    x[:, 1:] *= 0.0 if rng.uniform() < 0.2 else _log_uniform(rng, 1e-13, 1e-2)
    return x


def cloud_mesh(rng) -> np.ndarray:
    """Boxes and cylinders, axis-aligned as CAD parts are, stored in float32: the hull's vertices."""
    parts = []
    for _ in range(int(rng.integers(1, 5))):
        centre = rng.uniform(-1, 1, 3)
        if rng.uniform() < 0.5:
            half = rng.uniform(0.05, 1.0, 3)
            parts.append(np.array(list(itertools.product([-1.0, 1.0], repeat=3))) * half + centre)
        else:
            k, a, h = int(_log_uniform(rng, 8, 128)), rng.uniform(0.02, 0.6), rng.uniform(0.02, 1.0)
            parts.append(np.vstack([_ring(k, a, -h), _ring(k, a, h)]) + centre)
    x = np.vstack(parts)
    try:
        x = x[ConvexHull(x).vertices]
    except QhullError:
        pass
    return x


CLOUDS = {"random": cloud_random, "duplicates": cloud_duplicates, "coplanar": cloud_coplanar,
          "cospherical": cloud_cospherical, "cocircular": cloud_cocircular, "sliver": cloud_sliver,
          "needle": cloud_needle, "mesh": cloud_mesh}


def _placed(rng, x: np.ndarray, float32: bool) -> np.ndarray:
    """x scaled to a size of 1e-4 .. 1e3 m, turned (or, for a CAD-like cloud, left on its axes), in a
    third of the draws moved 1 .. 1e4 sizes from the origin, and rounded to float32 if asked."""
    size = float(np.linalg.norm(np.ptp(x, axis=0))) or 1.0
    scale = _log_uniform(rng, 1e-4, 1e3)
    if not float32 or rng.uniform() < 0.5:
        x = Rotation.random(random_state=rng).apply(x)
    x = (x - x.mean(axis=0)) * (scale / size)
    if rng.uniform() < 1 / 3:
        x = x + _unit_rows(rng, 1)[0] * scale * _log_uniform(rng, 1.0, 1e4)
    if float32:
        x = x.astype(np.float32).astype(np.float64)
    return x


def _radii(rng, x: np.ndarray) -> tuple[float, float]:
    size = float(np.linalg.norm(np.ptp(x, axis=0)))
    r = size * _log_uniform(rng, 1e-6, 0.1)
    r_meb = enclosing_ball(x)[1]
    regime = rng.uniform()
    if regime < 0.4:  # at or just above the minimum: a third of these exactly at it
        rho = r_meb if rng.uniform() < 1 / 3 else r_meb * (1.0 + _log_uniform(rng, 1e-12, 1e-2))
    elif regime < 0.6:
        rho = r_meb * rng.uniform(1.01, 10.0)
    else:
        rho = max(r_meb * 1.01, size * _log_uniform(rng, 10.0, 1e9))
    return r, r + rho


def construction_cases(rng, n: int) -> list[dict]:
    """n cases drawn with ``rng`` (a numpy Generator): dicts with ``family``, ``points`` (k, 3) in
    metres, ``r`` and ``R`` (metres, R - r at least the points' enclosing radius)."""
    cases = []
    while len(cases) < n:
        family = FAMILIES[int(rng.integers(len(FAMILIES)))]
        x = CLOUDS[family](rng)
        float32 = family == "mesh" or (family in ("cocircular", "coplanar") and rng.uniform() < 0.5)
        x = _placed(rng, x, float32)
        if len(np.unique(x, axis=0)) < 2:
            continue
        r, R = _radii(rng, x)
        cases.append({"family": family, "points": x, "r": r, "R": R})
    return cases


# ---------------------------------------------------------------------------- enclosing ball

def _ball_candidates(q: np.ndarray, new: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Centres (c, 3) of the balls through the point ``new`` (3,) and 1, 2 or 3 of the points q (k, 3),
    and their radii over q and new (c,): when new lies outside the smallest ball enclosing q, the
    smallest enclosing both has new on its boundary (Welzl), so it is one of them."""
    k = len(q)
    centres = [0.5 * (q + new)]
    if k >= 2:
        i, j = np.array(list(itertools.combinations(range(k), 2))).T
        u, v = q[i] - new, q[j] - new
        w = np.cross(u, v)
        w2 = (w * w).sum(axis=1)
        ok = w2 > 0
        centres.append(new + (((u * u).sum(1)[ok, None] * np.cross(v[ok], w[ok])
                               + (v * v).sum(1)[ok, None] * np.cross(w[ok], u[ok])) / (2 * w2[ok, None])))
    if k >= 3:
        tri = np.array(list(itertools.combinations(range(k), 3)))
        m = q[tri] - new  # (T, 3, 3)
        rhs = 0.5 * (m * m).sum(axis=2)
        ok = np.abs(np.linalg.det(m)) > 0
        centres.append(new + np.linalg.solve(m[ok], rhs[ok][..., None])[..., 0])
    c = np.concatenate(centres)
    pts = np.vstack([q, new])
    radius = np.sqrt(((c[:, None, :] - pts[None]) ** 2).sum(axis=2).max(axis=1))
    return c, radius


def enclosing_ball(points, max_core: int = 80) -> tuple[np.ndarray, float]:
    """Centre (3,) and radius (m) of the smallest ball enclosing points (n, 3), independently of spq.

    A core set grows by the farthest point from the current ball, whose new ball is the best through
    that point and up to 3 of the core's (every such ball tried), until the ball holds every point
    (within MEB_REL_TOL of the size). The radius returned is measured from the returned centre to
    the farthest point: a ball of that radius holds every point (an upper bound of the true radius,
    equal to it to rounding).
    """
    x = np.asarray(points, dtype=float)
    origin = x.mean(axis=0)
    p = x - origin
    size = float(np.linalg.norm(np.ptp(p, axis=0)))
    core = [int(np.argmin(p[:, 0]))]
    centre, radius = p[core[0]].copy(), 0.0
    while True:
        far = np.sqrt(((p - centre) ** 2).sum(axis=1))
        worst = int(np.argmax(far))
        if far[worst] <= radius + MEB_REL_TOL * size or len(core) >= max_core or worst in core:
            return centre + origin, float(far[worst])
        c, r = _ball_candidates(p[core], p[worst])
        best = int(np.argmin(r))
        centre, radius = c[best], float(r[best])
        core.append(worst)


# ------------------------------------------------------------------------------------------ judge

def _directions(rng, x: np.ndarray) -> np.ndarray:
    """Random unit directions, and for each convex-hull vertex the mean of its facets' normals (inside
    its normal cone, where its small sphere is the support), and the facet normals themselves."""
    u = [_unit_rows(rng, N_RANDOM_DIRECTIONS)]
    try:
        hull = ConvexHull(x - x.mean(axis=0))
        normals = hull.equations[:, :3]
        u.append(normals)
        cone = np.zeros((len(x), 3))
        np.add.at(cone, hull.simplices.ravel(), np.repeat(normals, 3, axis=0))
        cone = cone[np.linalg.norm(cone, axis=1) > 0]
        u.append(cone / np.linalg.norm(cone, axis=1, keepdims=True))
    except (QhullError, ValueError):
        pass
    return np.concatenate(u)


def _max_dot(x: np.ndarray, u: np.ndarray, chunk: int = 4_000_000) -> np.ndarray:
    """max_i u_k.x_i for each row of u, in blocks of at most ``chunk`` products."""
    out = np.empty(len(u))
    step = max(1, chunk // max(len(x), 1))
    for s in range(0, len(u), step):
        out[s:s + step] = (u[s:s + step] @ x.T).max(axis=1)
    return out


def _farthest(x: np.ndarray, c: np.ndarray, chunk: int = 4_000_000) -> np.ndarray:
    """max_i |x_i - c_k| for each row of c, in blocks; expanded about the points' mean (BLAS), which
    rounds a distance to a centre R away by a few eps R, inside ROUNDING_REL_TOL."""
    shift = x.mean(axis=0)
    xs, cs = x - shift, c - shift
    sq = (xs * xs).sum(axis=1)
    out = np.empty(len(c))
    step = max(1, chunk // max(len(x), 1))
    for s in range(0, len(c), step):
        b = cs[s:s + step]
        d2 = sq[:, None] - 2.0 * xs @ b.T + (b * b).sum(axis=1)[None, :]
        out[s:s + step] = np.sqrt(np.maximum(d2.max(axis=0), 0.0))
    return out


def _oracle_support(points: np.ndarray, r: float, R: float, u: np.ndarray, shift: np.ndarray):
    """h(u) (m,) of the STP-BV of points (n, 3) along unit rows of u by harness.references.stp_oracle, run about
    shift (its feasibility slack is absolute); None when it finds no centre within that slack (Q a
    point: R at its minimum)."""
    from harness.references.stp_oracle import BruteForceSTP

    try:
        return np.einsum("ij,ij->i", BruteForceSTP(points - shift, r, R).support_many(u), u) + u @ shift
    except ValueError:
        return None


def _closed_surface(topo) -> str:
    """'' when the faces form one closed surface of genus 0 (each edge between two faces, V - E + F =
    2), else what is wrong; a face-less STP-BV must be a spindle (2 vertices, 1 edge)."""
    V, E, F = len(topo.vertices), len(topo.edges), len(topo.faces)
    if F == 0:
        return "" if (V, E) == (2, 1) else f"no face but {V} vertices and {E} edges"
    if (topo.edge_faces < 0).any() or 2 * E != 3 * F:
        return f"{E} edges for {F} faces (an open surface)"
    if V - E + F != 2:
        return f"V - E + F = {V - E + F}, not 2"
    return ""


def _representation_limits(topo) -> str:
    """What the topology holds that the STP-BV's regions of directions (spq.shapes.stpbv, as in the
    paper: each a cone cut by planes through the origin) cannot express, as text ('' if nothing):

    - a vertex whose edges are all zero-width tori (the points on one rho-sphere when R - r is the
      enclosing radius): it gets no boundary, so its region is every direction;
    - a reflex torus, whose arc of centres in Q spans more than 180 degrees (the rim of a thin lens,
      R just above its minimum): its region is then not the intersection of the two face planes'
      half-spaces;
    - R - r so large against the size that the faces' regions are narrower than the rounding of the
      planes that bound them.
    """
    out = []
    real = np.zeros(len(topo.vertices), dtype=bool)
    real[topo.edges[topo.edge_real].ravel()] = True
    if len(topo.faces) and not real.all():
        out.append(f"{int((~real).sum())} vertices with only zero-width tori")
    rho = topo.R - topo.r
    x = topo.vertices
    slack = CHECK_REL_TOL * float(np.linalg.norm(np.ptp(x, axis=0))) + ROUNDING_REL_TOL * rho
    keep = topo.edge_real & (topo.edge_faces[:, 0] >= 0)
    a, b = topo.edges[keep, 0], topo.edges[keep, 1]
    mid = 0.5 * (x[a] + x[b])
    radius = np.sqrt(np.maximum(rho * rho - 0.25 * ((x[a] - x[b]) ** 2).sum(axis=1), 0.0))
    w = (topo.face_centres[topo.edge_faces[keep, 0]] - mid) + (topo.face_centres[topo.edge_faces[keep, 1]] - mid)
    norm = np.linalg.norm(w, axis=1)
    ok = norm > 0
    c = mid[ok] + (radius[ok] / norm[ok])[:, None] * w[ok]  # the middle of each minor arc
    reflex = int((_farthest(x, c) > rho + slack).sum()) if len(c) else 0
    if reflex:
        out.append(f"{reflex} reflex tori")
    size = float(np.linalg.norm(np.ptp(x, axis=0)))
    if rho > WIDE_RHO * size:
        # a face's region is ~ size / rho across; its planes, from (x_a - c) x (x_b - c) with c rho
        # away, are rounded by ~ eps rho / size
        out.append(f"R - r {rho / size:.2g} times its size (face regions near their planes' rounding)")
    return "; ".join(out)


def check_construction(points, r: float, R: float, rng=None) -> tuple[str, str]:
    """Build the STP-BV of ``points`` (n, 3) m with radii r < R and judge it (module docstring).

    Returns (verdict, detail): 'ok', 'failed' (the construction raised on an admissible R; detail is
    the exception) or 'wrong'. A 'wrong' detail starts with what is at fault: 'construction:' (the
    topology: not closed, a face's ball misses a point, or, for a small cloud, its vertices span
    another STP-BV than the cloud's) or 'volume:' (the topology passes these checks but the STP-BV
    built on it, its support function, misses a point, bulges out of a face's ball, differs from the
    brute-force support or leaves directions with other than one owner).
    """
    from harness.references.stp_oracle import FEAS_REL
    from spq.shapes.stpbv import STPBV
    from spq.stp.construction import build_topology

    rng = np.random.default_rng(0) if rng is None else rng
    x = np.asarray(points, dtype=float)
    rho = R - r
    size = float(np.linalg.norm(np.ptp(x, axis=0)))
    tol = CHECK_REL_TOL * size + ROUNDING_REL_TOL * (R + float(np.abs(x).max()))
    _, r_meb = enclosing_ball(x)
    try:
        topo = build_topology(x, r, R)
    except ValueError as exc:
        if "too small" in str(exc) and rho < r_meb - tol:
            return "ok", f"refused R below the minimum: {exc}"
        return "failed", f"ValueError: {exc}"
    except Exception as exc:  # noqa: BLE001 - the verdict reports whatever the construction raised
        return "failed", f"{type(exc).__name__}: {exc}"
    if rho < r_meb * (1 - 1e-9) - tol:
        return "wrong", f"construction: built with R - r = {rho!r} below the enclosing radius {r_meb!r}"

    # the topology: consistent, closed, every face's ball holds the cloud
    try:
        topo.check()
    except ValueError as exc:
        return "wrong", f"construction: inconsistent topology: {exc}"
    problem = _closed_surface(topo)
    if problem:
        return "wrong", f"construction: {problem}"
    if not np.array_equal(topo.vertices, x[topo.source_index]):
        return "wrong", "construction: vertices are not the input rows they name"
    c = topo.face_centres
    if len(c):
        far = _farthest(x, c)
        miss = float(far.max() - rho)
        if miss > tol:
            return "wrong", (f"construction: face {int(np.argmax(far))} misses a point by {miss:.3g} m "
                             f"(tolerance {tol:.3g})")
    unique = np.unique(x, axis=0)
    small = len(unique) <= ORACLE_MAX_POINTS
    v = _unit_rows(rng, 200)
    # the oracle's feasibility slack eps is absolute: run it near the origin. It fattens Q by about
    # eps rho / (rho - r_meb), Q holding a ball of radius rho - r_meb, and by sqrt(2 rho eps) at most
    shift = unique.mean(axis=0)
    eps = FEAS_REL * (1.0 + rho)
    oracle_tol = tol + eps + min(math.sqrt(2.0 * rho * eps), eps * rho / max(rho - r_meb, 1e-300))
    n_vert = len(topo.vertices)
    h_all = _oracle_support(unique, r, R, v, shift) if small else None
    if h_all is not None:
        # the STP-BV depends on its vertices only: theirs must be the whole cloud's
        h_vert = _oracle_support(topo.vertices, r, R, v, shift)
        gap = float(np.abs(h_all - h_vert).max()) if h_vert is not None else 0.0
        if gap > oracle_tol:
            return "wrong", (f"construction: the STP-BV of its {n_vert} vertices differs from the cloud's by "
                             f"{gap:.3g} m (tolerance {oracle_tol:.3g})")
    elif not small and n_vert <= ORACLE_MAX_VERTICES:
        # a big cloud on few vertices (R near its minimum): their STP-BV must hold every point
        u = _directions(rng, x)[:N_ORACLE_DIRECTIONS]
        h_vert = _oracle_support(topo.vertices, r, R, u, shift)
        short = float((_max_dot(x, u) + r - h_vert).max()) if h_vert is not None else 0.0
        if short > oracle_tol:
            return "wrong", (f"construction: the STP-BV of its {n_vert} vertices misses a point by "
                             f"{short:.3g} m (tolerance {oracle_tol:.3g})")

    # the volume built on it
    limits = _representation_limits(topo)
    if rho <= r_meb * (1.0 + AT_MINIMUM):
        at_minimum = "R - r at the enclosing radius (Q a point up to rounding, its arcs sqrt(rounding) long)"
        limits = "; ".join(filter(None, [limits, at_minimum]))
    note = f" [topology has {limits}]" if limits else ""
    try:
        stp = STPBV(topo)
    except Exception as exc:  # noqa: BLE001
        return "failed", f"STPBV: {type(exc).__name__}: {exc}"
    u = _directions(rng, x)
    h = np.einsum("ij,ij->i", stp.support(u), u)
    need = _max_dot(x, u) + r
    short = float((need - h).max())
    if short > tol:
        k = int(np.argmax(need - h))
        return "wrong", (f"volume: a point is outside by {short:.3g} m along u = {u[k].tolist()} "
                         f"(tolerance {tol:.3g})") + note
    if len(c):
        cap = -_max_dot(-c, u) + R
        over = float((h - cap).max())
        if over > tol:
            return "wrong", (f"volume: support exceeds a face's big sphere by {over:.3g} m "
                             f"(tolerance {tol:.3g})") + note
    if h_all is not None:
        h_spq = np.einsum("ij,ij->i", stp.support(v), v)
        gap = float(np.abs(h_spq - h_all).max())
        if gap > oracle_tol:
            return "wrong", (f"volume: support differs from the brute-force oracle's by {gap:.3g} m "
                             f"(tolerance {oracle_tol:.3g})") + note
    if stp.n_patches <= OWNER_MAX_PATCHES:
        owners = stp.owner_counts(_unit_rows(rng, N_OWNER_DIRECTIONS))
        if (owners != 1).any():
            return "wrong", (f"volume: {int((owners != 1).sum())} of {N_OWNER_DIRECTIONS} directions have "
                             f"{sorted(set(owners.tolist()) - {1})} owners") + note
    return "ok", f"{stp.n_small} small spheres, {stp.n_big} big spheres, {stp.n_tori} tori"


# ------------------------------------------------------------------------------------------ run

def run(seed: int, n: int, log=print) -> Counter:
    """Draw n cases with ``np.random.default_rng(seed)`` and judge each; print every case that is not
    ok (family, index, verdict, detail) and return the counts by (family, verdict, what is at fault)."""
    rng = np.random.default_rng(seed)
    counts = Counter()
    for i, case in enumerate(construction_cases(rng, n)):
        t0 = time.perf_counter()
        verdict, detail = check_construction(case["points"], case["r"], case["R"])
        counts[(case["family"], verdict, detail.split(":")[0] if verdict == "wrong" else "")] += 1
        if verdict != "ok":
            log(f"seed {seed} case {i} {case['family']} n={len(case['points'])} r={case['r']!r} "
                f"R={case['R']!r}: {verdict}: {detail} ({time.perf_counter() - t0:.2f} s)")
    return counts


def case(seed: int, index: int) -> dict:
    """Case ``index`` of run(seed, n) for any n > index (the draws are sequential: the earlier ones
    are drawn again), to replay one."""
    return construction_cases(np.random.default_rng(seed), index + 1)[index]


if __name__ == "__main__":
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--cases", type=int, default=200)
    args = parser.parse_args()
    start = time.perf_counter()
    totals = run(args.seed, args.cases)
    for (family, verdict, where), k in sorted(totals.items()):
        print(f"{family:12s} {verdict:7s} {where:12s} {k}")
    print(f"{args.cases} cases in {time.perf_counter() - start:.0f} s")
