"""Brute-force support function of an STP-BV from its generating points only (an oracle for tests and
for the depth oracle, harness.references.depth_oracle).

NOTES section 1: with rho = R - r, Q = intersection of the balls B(x_i, rho) is the set of admissible
big-sphere centres, and the support point of the STP-BV in direction v is s(v) = c*(v) + R v/|v|,
c*(v) = argmin over Q of v.c. No topology is used: c*(v) is the best feasible point among

(a) the minimiser of v.c over one sphere |c - x_i| = rho: x_i - rho u (u = v/|v|);
(b) the minimiser over the circle where two spheres meet (centre m = (x_i + x_j)/2, axis
    e = (x_i - x_j)/l, radius a = sqrt(rho^2 - l^2/4)): m - a w/|w|, w = u - (u.e) e;
(c) the points where three spheres meet (0 or 2 per triple);

feasible meaning |c - x_k| <= rho + 2^-46 (1 + rho) for every k. The optimum of a linear function over
Q lies in the relative interior of a face, an edge arc or at a vertex of Q, which are exactly these.
O(n^3) in the number of points: meant for clouds up to ~40 points. Everything is in the points'
frame (metres); directions need not be unit.
"""

from __future__ import annotations

import numpy as np

FEAS_REL = 2.0 ** -46  # feasibility slack, relative to 1 + rho: 64 ulps, the rounding of |c - x_i|.
# A wider slack admits centres outside Q and lowers the support: 1e-12 (4500 ulps) put the support of an
# STP-BV with R = 8881 m 1.6e-10 m low (fuzz stp-big-R-unsigned-wrong-1)
_CHUNK = 2_000_000  # candidate-point x point distance evaluations per feasibility block


def _check(points, r, R) -> tuple[np.ndarray, float]:
    x = np.asarray(points, dtype=float).reshape(-1, 3)
    if len(x) == 0 or not np.isfinite(x).all():
        raise ValueError("points must be a non-empty finite (n, 3) array")
    if not (0.0 < r < R):
        raise ValueError(f"need 0 < r < R, got r = {r}, R = {R}")
    return x, float(R - r)


def _feasible(c: np.ndarray, x: np.ndarray, rho: float) -> np.ndarray:
    """Mask of the candidate centres c (k, 3) that lie in every ball B(x_i, rho) (with slack)."""
    lim = (rho + FEAS_REL * (1.0 + rho)) ** 2
    ok = np.empty(len(c), dtype=bool)
    step = max(1, _CHUNK // len(x))
    for s in range(0, len(c), step):
        d2 = ((c[s:s + step, None, :] - x[None, :, :]) ** 2).sum(axis=-1)
        ok[s:s + step] = d2.max(axis=1) <= lim
    return ok


def _pair_circles(x: np.ndarray, rho: float):
    """Circles where two spheres of radius rho meet: centres m (P, 3), axes e (P, 3), radii a (P,)."""
    i, j = np.triu_indices(len(x), k=1)
    d = x[i] - x[j]
    l = np.linalg.norm(d, axis=1)
    if len(l) and l.max() > 2 * rho * (1 + FEAS_REL):
        raise ValueError(f"two points are {l.max():.6g} apart, more than 2 rho = {2 * rho:.6g}: Q is empty")
    keep = l > 0  # duplicate points: the same ball, no circle
    d, l, m = d[keep], l[keep], (x[i[keep]] + x[j[keep]]) / 2
    return m, d / l[:, None], np.sqrt(np.maximum(rho ** 2 - l ** 2 / 4, 0.0))


def _triple_points(x: np.ndarray, rho: float) -> np.ndarray:
    """Points where three spheres of radius rho meet, over all triples (up to 2 per triple), (k, 3)."""
    n = len(x)
    if n < 3:
        return np.zeros((0, 3))
    i, j, k = np.array([(i, j, k) for i in range(n) for j in range(i + 1, n) for k in range(j + 1, n)]).T
    a, b = x[j] - x[i], x[k] - x[i]
    nrm = np.cross(a, b)
    nn = (nrm ** 2).sum(axis=1)
    aa, bb = (a ** 2).sum(axis=1), (b ** 2).sum(axis=1)
    ok = nn > (1e-14 ** 2) * aa * bb  # not collinear
    a, b, nrm, nn, aa, bb, xi = a[ok], b[ok], nrm[ok], nn[ok], aa[ok], bb[ok], x[i[ok]]
    rel = np.cross(aa[:, None] * b - bb[:, None] * a, nrm) / (2 * nn[:, None])  # circumcentre - x_i
    h2 = rho ** 2 - (rel ** 2).sum(axis=1)
    ok = h2 >= 0
    cc = xi[ok] + rel[ok]
    off = np.sqrt(h2[ok])[:, None] * nrm[ok] / np.sqrt(nn[ok])[:, None]
    return np.concatenate([cc + off, cc - off])


def _circle_minimisers(m, e, a, U) -> np.ndarray:
    """For unit directions U (q, 3): argmin of u.c over each circle, (q, P, 3)."""
    w = U[:, None, :] - (U @ e.T)[:, :, None] * e[None, :, :]
    wn = np.linalg.norm(w, axis=-1)
    par = wn <= 1e-12  # u along the axis: every circle point ties; take any
    if par.any():
        helper = np.where(np.abs(e[:, :1]) < 0.9, [[1.0, 0, 0]], [[0.0, 1, 0]])
        perp = np.cross(e, helper)
        perp /= np.linalg.norm(perp, axis=1, keepdims=True)
        w = np.where(par[:, :, None], np.broadcast_to(perp, w.shape), w)
        wn = np.where(par, 1.0, wn)
    return m[None] - a[None, :, None] * w / wn[:, :, None]


def brute_force_centres_many(points, rho: float, V) -> np.ndarray:
    """c*(v) = argmin over Q = intersection of B(x_i, rho) of v.c, for each row of V (m, 3); (m, 3) metres.

    Raises ValueError if Q is empty (rho below the radius of the smallest ball enclosing the points)
    or a direction is zero.
    """
    x = np.asarray(points, dtype=float).reshape(-1, 3)
    V = np.asarray(V, dtype=float).reshape(-1, 3)
    nv = np.linalg.norm(V, axis=1)
    if not (nv > 0).all() or not np.isfinite(V).all():
        raise ValueError("directions must be finite and non-zero")
    U = V / nv[:, None]
    m, e, a = _pair_circles(x, rho)
    tri = _triple_points(x, rho)
    tri = tri[_feasible(tri, x, rho)] if len(tri) else tri
    best = np.empty((len(U), 3))
    for q, u in enumerate(U):
        c = x - rho * u  # (a)
        if len(m):
            c = np.concatenate([c, _circle_minimisers(m, e, a, u[None])[0]])  # (b)
        c = np.concatenate([c[_feasible(c, x, rho)], tri])  # (c) already filtered
        if len(c) == 0:
            raise ValueError("no feasible candidate: Q is empty (rho below the enclosing-ball radius)")
        best[q] = c[np.argmin(c @ u)]
    return best


class BruteForceSTP:
    """The brute-force support of one STP-BV with the direction-free candidates (the circles where two
    spheres meet, the feasible points where three meet) computed once, and every direction of a call
    handled in one vectorised pass: the same candidates and choice as brute_force_centres_many."""

    def __init__(self, points, r: float, R: float):
        self.x, self.rho = _check(points, r, R)
        self.R = float(R)
        self.m, self.e, self.a = _pair_circles(self.x, self.rho)
        tri = _triple_points(self.x, self.rho)
        self.tri = tri[_feasible(tri, self.x, self.rho)] if len(tri) else tri
        self.lim = (self.rho + FEAS_REL * (1.0 + self.rho)) ** 2

    def support_many(self, V) -> np.ndarray:
        """Support points (m, 3) along the rows of V (m, 3; non-zero)."""
        V = np.asarray(V, dtype=float).reshape(-1, 3)
        nv = np.linalg.norm(V, axis=1)
        if not (nv > 0).all() or not np.isfinite(V).all():
            raise ValueError("directions must be finite and non-zero")
        U = V / nv[:, None]
        cand = self.x[None] - self.rho * U[:, None, :]  # (a): (q, n, 3)
        if len(self.m):
            cand = np.concatenate([cand, _circle_minimisers(self.m, self.e, self.a, U)], axis=1)  # (b)
        d2 = ((cand[:, :, None, :] - self.x[None, None]) ** 2).sum(axis=-1).max(axis=-1)
        score = np.where(d2 <= self.lim, np.einsum("qkc,qc->qk", cand, U), np.inf)
        best = cand[np.arange(len(U)), np.argmin(score, axis=1)]
        best_score = score.min(axis=1)
        if len(self.tri):  # (c), feasible already
            ts = U @ self.tri.T
            j = np.argmin(ts, axis=1)
            better = ts[np.arange(len(U)), j] < best_score
            best = np.where(better[:, None], self.tri[j], best)
            best_score = np.minimum(best_score, ts[np.arange(len(U)), j])
        if not np.isfinite(best_score).all():
            raise ValueError("no feasible candidate: Q is empty (rho below the enclosing-ball radius)")
        return best + self.R * U


def brute_force_support_many(points, r: float, R: float, V) -> np.ndarray:
    """Support points s(v) = c*(v) + R v/|v| of the STP-BV of ``points`` for each row of V (m, 3); (m, 3)."""
    x, rho = _check(points, r, R)
    V = np.asarray(V, dtype=float).reshape(-1, 3)
    c = brute_force_centres_many(x, rho, V)
    return c + R * V / np.linalg.norm(V, axis=1, keepdims=True)


def brute_force_support(points, r: float, R: float, v) -> np.ndarray:
    """Support point (3,) of the STP-BV of ``points`` (n, 3) with radii r < R in direction v (3,)."""
    return brute_force_support_many(points, r, R, np.asarray(v, dtype=float).reshape(1, 3))[0]


def containment_lower_bound(points, r: float, v) -> float:
    """max_i v.x_i + r |v|: a lower bound of v.s(v), since the STP-BV contains every B(x_i, r)."""
    x = np.asarray(points, dtype=float).reshape(-1, 3)
    v = np.asarray(v, dtype=float).reshape(3)
    return float((x @ v).max() + r * np.linalg.norm(v))
