"""The fuzz campaign's families: seeded draws of a shape pair and of poses from far apart to deep overlap.

A shape is a *spec*, a plain dict that JSON holds (so a failing case can be saved, shrunk and replayed):

- ``{"kind": "pch", "points": [[x, y, z], ...]}``: the convex hull of the points;
- ``{"kind": "stp", "points": [...], "r": r, "R": R}``: the STP-BV of the points;
- ``{"kind": "cse", "a", "b", "c", "e1", "e2"}``: a superellipsoid (semi-axes in m, exponents);
- ``{"kind": "box", "half": [hx, hy, hz]}``, ``{"kind": "sphere", "r"}``, ``{"kind": "capsule", "r", "hl"}``.

A *case* is two specs and N pose pairs (N, 4, 4 each). Poses are placed with the oracle's support
functions (harness.suites.fuzz.oracle, no spq code): B's origin along a random unit u from A's such that the
separation of the two bodies along u (a lower bound of their signed distance, equal to it when u is the
optimal normal) is the regime's target: far, near, touching, shallow or deep overlap, or B's origin at
A's (containment). Every draw comes from one ``np.random.default_rng`` so a case is a pure function of
its family, seed and index.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

# regime -> (probability, signed target in units of the pair's size L along u); see _targets
REGIMES = {
    "far": 0.15,
    "near": 0.25,
    "touching": 0.15,
    "shallow": 0.2,
    "deep": 0.2,
    "contained": 0.05,
}


# --- point clouds -------------------------------------------------------------------------------
def _log_uniform(rng, lo: float, hi: float) -> float:
    return float(np.exp(rng.uniform(np.log(lo), np.log(hi))))


def _count(rng, lo: int = 4, hi: int = 10_000) -> int:
    """Point counts log-uniform in [lo, hi]: as many small clouds (where degeneracies live) as big ones."""
    return int(round(_log_uniform(rng, lo, hi)))


def cloud_ball(rng, n: int) -> np.ndarray:
    """n points uniform in the unit ball."""
    x = rng.normal(size=(n, 3))
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    return x * rng.uniform(size=(n, 1)) ** (1 / 3)


def cloud_random(rng, n: int) -> np.ndarray:
    """Unit-size clouds of one of several kinds: in a ball, on a sphere (every point a hull vertex, kept
    to a few hundred), in a cube, anisotropic Gaussian."""
    kind = rng.integers(4)
    if kind == 0:
        return cloud_ball(rng, n)
    if kind == 1:
        x = rng.normal(size=(min(n, 400), 3))
        return x / np.linalg.norm(x, axis=1, keepdims=True)
    if kind == 2:
        return rng.uniform(-1, 1, (n, 3))
    return rng.normal(size=(n, 3)) * rng.uniform(0.2, 1.0, 3)


def cloud_sliver(rng, n: int) -> np.ndarray:
    """A flat cloud: unit extent in two axes, 1e-6 .. 1e-2 in the third."""
    x = rng.uniform(-1, 1, (n, 3))
    x[:, 2] *= _log_uniform(rng, 1e-6, 1e-2)
    return x


def cloud_needle(rng, n: int) -> np.ndarray:
    """A needle: unit length, 1e-6 .. 1e-2 across."""
    x = rng.uniform(-1, 1, (n, 3))
    x[:, 1:] *= _log_uniform(rng, 1e-6, 1e-2)
    return x


def cloud_coplanar(rng, n: int) -> np.ndarray:
    """Points on the faces of a box (many coplanar points per face), jittered by 1e-13 .. 1e-8 off their
    planes: near-coplanar faces that a hull triangulates in many near-equivalent ways."""
    half = rng.uniform(0.3, 1.0, 3)
    n = max(n, 8)
    x = rng.uniform(-1, 1, (n, 3)) * half
    axis = rng.integers(3, size=n)
    side = rng.choice([-1.0, 1.0], size=n)
    x[np.arange(n), axis] = side * half[axis]
    x[:8] = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * half
    x += rng.normal(size=x.shape) * _log_uniform(rng, 1e-13, 1e-8)
    return x


def cloud_duplicates(rng, n: int) -> np.ndarray:
    """A small cloud with near-duplicates of its points (1e-12 .. 1e-6 apart)."""
    base = cloud_ball(rng, max(4, n // 3))
    copies = base[rng.integers(len(base), size=n - len(base))]
    copies = copies + rng.normal(size=copies.shape) * _log_uniform(rng, 1e-12, 1e-6)
    return np.concatenate([base, copies])


def _full_dimensional(x: np.ndarray) -> bool:
    c = x - x.mean(axis=0)
    s = np.linalg.svd(c, compute_uv=False)
    return len(x) >= 4 and s[-1] > 1e-9 * s[0]


# --- shape specs --------------------------------------------------------------------------------
def pch(points) -> dict:
    return {"kind": "pch", "points": np.asarray(points, float).tolist()}


def _hull_spec(rng, cloud, scale: float = 1.0, n=None) -> dict:
    for _ in range(20):
        x = cloud(rng, n or _count(rng)) * scale
        if _full_dimensional(x):
            return pch(x)
    raise RuntimeError("could not draw a full-dimensional cloud")  # a family bug, not a judged case


def stp_spec(rng, scale: float, min_r_factor: float | None) -> dict:
    """An STP-BV of 4 .. 24 points (the oracle's brute force is O(n^3)): r 1e-3 .. 0.1 of the size; R
    just above its minimum r + enclosing radius (factor 1 + 1e-6 .. 1e-2) or far above it (10 .. 1e4)."""
    from spq.stp.construction import enclosing_radius

    n = int(rng.integers(4, 25))
    x = cloud_random(rng, n)[:n] * scale
    r = scale * _log_uniform(rng, 1e-3, 0.1)
    rho = enclosing_radius(x)
    if min_r_factor is None:
        R = r + rho * _log_uniform(rng, 10.0, 1e4)
    else:
        R = r + rho * (1.0 + min_r_factor)
    return {"kind": "stp", "points": x.tolist(), "r": r, "R": R}


def cse_spec(rng, scale: float) -> dict:
    """A superellipsoid: exponents 0.1 .. 1.9 (boxy to pinched), axis ratios up to 100."""
    axes = scale * np.exp(rng.uniform(np.log(0.01), 0.0, 3))
    axes *= scale / axes.max()
    e1, e2 = rng.uniform(0.1, 1.9, 2)
    return {"kind": "cse", "a": float(axes[0]), "b": float(axes[1]), "c": float(axes[2]), "e1": float(e1),
            "e2": float(e2)}


def primitive_spec(rng, scale: float) -> dict:
    kind = ("box", "sphere", "capsule")[rng.integers(3)]
    if kind == "box":
        half = scale * np.exp(rng.uniform(np.log(1e-3), 0.0, 3))
        return {"kind": "box", "half": half.tolist()}
    if kind == "sphere":
        return {"kind": "sphere", "r": scale * rng.uniform(0.05, 1.0)}
    return {"kind": "capsule", "r": scale * _log_uniform(rng, 1e-3, 0.5), "hl": scale * rng.uniform(0.05, 1.0)}


# family -> function (rng) -> (spec A, spec B, far offset in m): see FAMILY_NOTES
def _hull_pair(cloud_a, cloud_b=None):
    def draw(rng):
        return _hull_spec(rng, cloud_a), _hull_spec(rng, cloud_b or cloud_random), 0.0
    return draw


def _scaled(rng):
    s = _log_uniform(rng, 1e-4, 1e3)
    return _hull_spec(rng, cloud_random, s), _hull_spec(rng, cloud_random, s * _log_uniform(rng, 0.1, 10)), 0.0


def _far(rng):
    a, b, _ = _hull_pair(cloud_random)(rng)
    return a, b, _log_uniform(rng, 1e2, 1e5)


def _stp(min_r: bool):
    def draw(rng):
        factor = _log_uniform(rng, 1e-6, 1e-2) if min_r else None
        a = stp_spec(rng, 1.0, factor)
        other = rng.integers(3)
        if other == 0:
            b = stp_spec(rng, _log_uniform(rng, 0.2, 5.0), factor)
        elif other == 1:
            b = _hull_spec(rng, cloud_random, _log_uniform(rng, 0.2, 5.0), n=int(rng.integers(4, 60)))
        else:
            b = cse_spec(rng, _log_uniform(rng, 0.2, 5.0))
        return a, b, 0.0
    return draw


def _cse(rng):
    a = cse_spec(rng, 1.0)
    other = rng.integers(3)
    s = _log_uniform(rng, 0.2, 5.0)
    b = cse_spec(rng, s) if other == 0 else (_hull_spec(rng, cloud_random, s, n=int(rng.integers(4, 200)))
                                              if other == 1 else stp_spec(rng, s, _log_uniform(rng, 1e-4, 1.0)))
    return a, b, 0.0


def _primitives(rng):
    a = primitive_spec(rng, 1.0)
    b = primitive_spec(rng, _log_uniform(rng, 0.2, 5.0)) if rng.integers(2) else \
        _hull_spec(rng, cloud_random, _log_uniform(rng, 0.2, 5.0), n=int(rng.integers(4, 200)))
    return a, b, 0.0


FAMILIES = {
    "hull-random": _hull_pair(cloud_random),
    "hull-sliver": _hull_pair(cloud_sliver),
    "hull-needle": _hull_pair(cloud_needle, cloud_needle),
    "hull-coplanar": _hull_pair(cloud_coplanar, cloud_coplanar),
    "hull-duplicates": _hull_pair(cloud_duplicates),
    "hull-scale": _scaled,
    "hull-far": _far,
    "primitives": _primitives,
    "stp-min-R": _stp(True),
    "stp-big-R": _stp(False),
    "cse": _cse,
}
FAMILY_NOTES = {
    "hull-random": "hulls of 4 .. 10 000 points (in a ball, on a sphere, in a cube, Gaussian) vs random hulls",
    "hull-sliver": "flat hulls (1e-6 .. 1e-2 thick) vs random hulls",
    "hull-needle": "needles (1e-6 .. 1e-2 across) vs needles",
    "hull-coplanar": "box-face clouds jittered 1e-13 .. 1e-8 off their planes, both sides",
    "hull-duplicates": "clouds with near-duplicate points (1e-12 .. 1e-6 apart) vs random hulls",
    "hull-scale": "random hulls of size 1e-4 .. 1e3 m (the pair's sizes within 10x)",
    "hull-far": "random hulls 1e2 .. 1e5 m from the origin",
    "primitives": "boxes (aspect to 1000), spheres, capsules vs primitives or hulls",
    "stp-min-R": "STP-BVs with R = r + enclosing radius x (1 + 1e-6 .. 1e-2) vs STP, PCH, CSE",
    "stp-big-R": "STP-BVs with R = r + enclosing radius x 10 .. 1e4 vs STP, PCH, CSE",
    "cse": "superellipsoids, exponents 0.1 .. 1.9, axis ratios to 100, vs CSE, PCH, STP",
}


def check_family(name: str) -> str:
    if name not in FAMILIES:
        raise ValueError(f"unknown fuzz family {name!r}; choose from {sorted(FAMILIES)}")
    return name


def draw_case(family: str, rng, n_poses: int):
    """(spec A, spec B, poses_a (n, 4, 4), poses_b, regimes (n,) str) of one case of ``family``."""
    from harness.suites.fuzz.oracle import oracle_shape

    a, b, offset = FAMILIES[check_family(family)](rng)
    oa, ob = oracle_shape(a), oracle_shape(b)
    poses_a, poses_b, regimes = place(rng, oa, ob, n_poses, offset)
    return a, b, poses_a, poses_b, regimes


def place(rng, oa, ob, n: int, offset: float = 0.0):
    """n pose pairs for oracle shapes oa, ob (module docstring); offset: distance (m) of A's origin from
    the world origin."""
    names = list(REGIMES)
    regimes = rng.choice(names, size=n, p=np.array(list(REGIMES.values())) / sum(REGIMES.values()))
    Ra = Rotation.random(n, random_state=rng).as_matrix()
    Rb = Rotation.random(n, random_state=rng).as_matrix()
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    ta = np.zeros((n, 3))
    if offset > 0:
        v = rng.normal(size=3)
        ta[:] = offset * v / np.linalg.norm(v)
    ta += rng.uniform(-1, 1, (n, 3)) * oa.size
    ha = oa.support_values(np.einsum("nji,nj->ni", Ra, u))  # h_A(u) in A's frame
    hb = ob.support_values(np.einsum("nji,nj->ni", Rb, -u))
    L = 0.5 * (ha + hb)
    target = np.empty(n)
    for name in names:
        k = regimes == name
        m = int(k.sum())
        if name == "far":
            target[k] = L[k] * rng.uniform(1.0, 10.0, m)
        elif name == "near":
            target[k] = L[k] * np.exp(rng.uniform(np.log(1e-7), 0.0, m))
        elif name == "touching":
            target[k] = L[k] * rng.uniform(-1, 1, m) * np.exp(rng.uniform(np.log(1e-13), np.log(1e-8), m))
        elif name == "shallow":
            target[k] = -L[k] * np.exp(rng.uniform(np.log(1e-7), np.log(1e-2), m))
        elif name == "deep":
            target[k] = -L[k] * rng.uniform(0.05, 0.9, m)
        else:  # containment: B's origin near A's
            target[k] = -(ha[k] + hb[k]) * rng.uniform(0.9, 1.0, m)
    tb = ta + u * (target + ha + hb)[:, None]
    return _poses(Ra, ta), _poses(Rb, tb), regimes.astype(str)


def _poses(R, t) -> np.ndarray:
    out = np.zeros((len(R), 4, 4))
    out[:, :3, :3] = R
    out[:, :3, 3] = t
    out[:, 3, 3] = 1.0
    return out
