"""Support function of a convex superellipsoid, in closed form from dual norms (NOTES section 4).

The superellipsoid F(x) = (|x/a|^(2/e2) + |y/b|^(2/e2))^(e2/e1) + |z/c|^(2/e1) <= 1 is, in the
scaled coordinates X = x/a, Y = y/b, Z = z/c, the unit ball of the nested norm
||(||(X, Y)||_p2, Z)||_p1 with p_i = 2/e_i. Its support point along v is a (diag(a, b, c)) times the
gradient of the dual norm h(u) = ||(||(u_x, u_y)||_q2, u_z)||_q1 at u = (a v_x, b v_y, c v_z), with
q_i = 2/(2 - e_i) (1/p + 1/q = 1). Written with ratios to the larger entry of each pair, every
factor lies in [0, 1]: no overflow, no trigonometry, and the limits are the formulas themselves:

- e -> 2 (q -> inf, the diamond / octahedral limit): rho^q -> 0 for rho < 1, ties (rho = 1) share
  the weight equally, so e = 2 exactly needs no special case (q = inf is stored as such);
- e -> 0 (q -> 1, the box-like limit): rho^(q-1) -> 1 for rho > 0, 0 for rho = 0 (the support is
  a box corner, or a point on the face when a direction component is zero);
- zero direction components (0^0 is never evaluated: a zero ratio gives zero weight).

Layout (kind SUPERELLIPSOID, see kinds.py): fdata = [a, b, c, e1, e2, q1, q2, q1 - 1, q2 - 1,
1/q1 - 1, 1/q2 - 1, then the implicit function's constants: p1 = 2/e1, p2 = 2/e2, e2/e1, 1/a, 1/b, 1/c,
p2/a, p2/b, p1/c, p2 (p2 - 1)/a^2, p2 (p2 - 1)/b^2, p1 (p1 - 1)/c^2] (F_* offsets below; q - 1 = e/(2 - e)
and 1/q - 1 = -e/2 are stored exactly, not recomputed from a rounded q), then an inscribed polytope's
vertices, which the support here does not read (nor idata, that polytope's). Margin 0.
"""

from __future__ import annotations

import math

import numpy as np

from spq.kernels.jit import kernel

F_A, F_B, F_C, F_E1, F_E2 = 0, 1, 2, 3, 4
F_Q1, F_Q2, F_Q1M1, F_Q2M1, F_H1, F_H2 = 5, 6, 7, 8, 9, 10
# the implicit function's (spq.kernels.closest_points_newton.implicit): its Newton steps multiply by
# these rather than divide (a division costs several multiplications' time, and implicit took 20 a side)
F_P1, F_P2, F_K = 11, 12, 13
F_IA, F_IB, F_IC = 14, 15, 16
F_GA, F_GB, F_GC = 17, 18, 19
F_HA, F_HB, F_HC = 20, 21, 22
FDATA_SIZE = 23

# rho^q below this is subnormal or near it: rho^(q-1) = rho^q / rho would lose relative precision,
# so it is taken as exp((q - 1) log rho) instead (dimensionless; rare: needs rho < ~1e-290^(1/q)).
TINY_POWER = 1e-290

# A direction is used unscaled where the largest entry of diag(a, b, c) |d| lies in this range: the
# norms built from it (at most 4 times that entry) stay far from overflow and underflow, so the
# ratios the powers take need no division by the direction's largest component first (that division
# sat on the support's critical path, ahead of its chain of logarithms and exponentials). Elsewhere
# (semi-axes or directions of extreme size) the direction is scaled to a largest component of 1 first.
RAW_LO, RAW_HI = 1e-150, 1e150


def pack(a: float, b: float, c: float, e1: float, e2: float) -> np.ndarray:
    """fdata (FDATA_SIZE,) float64 for semi-axes a, b, c (m) and exponents e1, e2 in (0, 2].

    The caller validates the values (spq.shapes.superellipsoid does)."""
    f = np.empty(FDATA_SIZE)
    f[F_A], f[F_B], f[F_C], f[F_E1], f[F_E2] = a, b, c, e1, e2
    for e, iq, iqm1, ih in ((e1, F_Q1, F_Q1M1, F_H1), (e2, F_Q2, F_Q2M1, F_H2)):
        if e >= 2.0:
            f[iq] = f[iqm1] = math.inf
        else:
            f[iq] = 2.0 / (2.0 - e)
            f[iqm1] = e / (2.0 - e)
        f[ih] = -0.5 * e  # 1/q - 1
    p1, p2 = 2.0 / e1, 2.0 / e2
    f[F_P1], f[F_P2], f[F_K] = p1, p2, e2 / e1
    f[F_IA], f[F_IB], f[F_IC] = 1.0 / a, 1.0 / b, 1.0 / c
    f[F_GA], f[F_GB], f[F_GC] = p2 / a, p2 / b, p1 / c
    f[F_HA], f[F_HB], f[F_HC] = _over_square(p2 * (p2 - 1.0), a), _over_square(p2 * (p2 - 1.0), b), \
        _over_square(p1 * (p1 - 1.0), c)
    return f


def _over_square(x: float, a: float) -> float:
    """x / a^2 for a > 0; where a^2 underflows to 0 (a below about 1e-154) x / a / a, which overflows to
    inf rather than raising (a Python float division by zero raises)."""
    aa = a * a
    return x / aa if aa > 0.0 else x / a / a


@kernel(inline="always")
def _minor_powers(rho, q, qm1):
    """(rho^q, rho^(q-1)) for a ratio 0 <= rho <= 1 and q in (1, inf]; 0^q = 0^(q-1) = 0."""
    if rho <= 0.0:
        return 0.0, 0.0
    if rho >= 1.0:
        return 1.0, 1.0  # a tie: also the q = inf case, where inf * log(1) would be NaN
    lr = math.log(rho)
    p = math.exp(q * lr)
    if p >= TINY_POWER:
        return p, p / rho
    return p, math.exp(qm1 * lr)


@kernel(inline="always")
def _octant_parts(f, u0, u1, u2):
    """For u = diag(a, b, c) |d| >= 0 at any scale (see _scaled_direction): the inner norm's gradient
    (w0, w1), the outer norm's gradient (wm, wz), the inner norm m and the outer norm h, i.e.
    h(u) = ||(m, u2)||_q1 with m = ||(u0, u1)||_q2, then the ratios of each norm to its entries
    (m / u0, m / u1, h / m, h / u2; inf for a zero entry). The gradients and ratios depend on u's
    direction only; m and h are at u's scale.

    The ratios are products of the factors the norms are built from, not quotients: the derivative
    (superellipsoid_support_jacobian) then waits for no division, and a larger entry's ratio is
    exactly the factor its norm took, so that where a norm reduces to its larger entry the
    derivative's terms cancel exactly."""
    # inner norm m = ||(u0, u1)||_q2 = mx S^(1/q2), S = 1 + rho^q2, with gradient (w0, w1) in [0, 1]^2
    mx = max(u0, u1)
    m = 0.0
    r0 = r1 = rm = rz = 1.0
    if mx > 0.0:
        if u0 >= u1:
            rho = u1 / mx
            p, pm1 = _minor_powers(rho, f[F_Q2], f[F_Q2M1])
            w0, w1 = 1.0, pm1
        else:
            rho = u0 / mx
            p, pm1 = _minor_powers(rho, f[F_Q2], f[F_Q2M1])
            w0, w1 = pm1, 1.0
        # log S, in [0, log 2]: log of the rounded S, not log1p(p), which is 9 ns slower on the chain's
        # critical path; its absolute error (about 1e-16) is what the powers of S below see, and m uses
        # the same rounded S
        s_ = 1.0 + p
        ls = math.log(s_)
        g = 1.0
        if p > 0.0:
            g = math.exp(f[F_H2] * ls)  # S^(1/q2 - 1)
            w0 *= g
            w1 *= g
        m = mx * g * s_  # S^(1/q2) = S^(1/q2 - 1) S
        r_major = g * s_
        r_minor = r_major * (1.0 / rho)  # rho's reciprocal is taken beside the powers
        if u0 >= u1:
            r0, r1 = r_major, r_minor
        else:
            r0, r1 = r_minor, r_major
        # outer norm h = ||(m, u2)||_q1: the ratio of its entries in the log domain, where
        # log(u2 / m) = log(u2 / mx) - log(S) / q2 needs no power of S (and no wait for it); the
        # ratio to the q1 - 1 is the ratio to the q1 over the ratio (u2 / m, m by then at hand):
        # a division instead of an exp, as in _minor_powers
        if u2 > 0.0:
            lr = math.log(u2 / mx) - ls * (f[F_H2] + 1.0)
            if lr == 0.0:  # a tie (also q1 = inf, where inf * 0 would be NaN)
                p, wm, wz = 1.0, 1.0, 1.0
            elif lr < 0.0:
                p = math.exp(f[F_Q1] * lr)
                wm = 1.0
                rz = m / u2
                wz = p * rz if p >= TINY_POWER else math.exp(f[F_Q1M1] * lr)
            else:
                p = math.exp(-f[F_Q1] * lr)
                wz = 1.0
                rm = u2 / m
                wm = p * rm if p >= TINY_POWER else math.exp(-f[F_Q1M1] * lr)
        else:
            p, wm, wz = 0.0, 1.0, 0.0
            rz = math.inf
    else:
        p, wm, wz = 0.0, 0.0, 1.0
        w0 = w1 = 0.0
        r0 = r1 = rm = math.inf
    G = 1.0
    if p > 0.0:
        G = math.exp(f[F_H1] * math.log(1.0 + p))  # T^(1/q1 - 1), T = 1 + ratio^q1 (log, not log1p: see ls)
        wm *= G
        wz *= G
    factor = G * (1.0 + p)  # T^(1/q1)
    h = max(m, u2) * factor  # the larger entry times T^(1/q1)
    return w0, w1, wm, wz, m, h, r0, r1, rm * factor, rz * factor


@kernel(inline="always")
def _scaled_direction(f, a0, a1, a2, vmax):
    """(u0, u1, u2, t, 1 / t) for the absolute direction components a (largest vmax > 0):
    u = diag(a, b, c) a / t, where t brings u's norms back to the direction's own scale: 1 for a
    direction used as it is (see RAW_LO), vmax for one scaled first."""
    u0, u1, u2 = f[F_A] * a0, f[F_B] * a1, f[F_C] * a2
    if RAW_LO < max(u0, u1, u2) < RAW_HI:
        return u0, u1, u2, 1.0, 1.0
    inv = 1.0 / vmax
    return f[F_A] * (a0 * inv), f[F_B] * (a1 * inv), f[F_C] * (a2 * inv), vmax, inv


@kernel
def superellipsoid_support(f, d0, d1, d2, out):
    """Write the support point of the superellipsoid fdata ``f`` along (d0, d1, d2) into out[0:3].

    The direction needs no normalisation (any positive scale gives the same point). A zero direction
    gives the pole (0, 0, c); a NaN direction gives NaN.
    """
    out[0], out[1], out[2] = support_point(f, d0, d1, d2)


@kernel(inline="always")
def support_point(f, d0, d1, d2):
    """superellipsoid_support's point as a tuple (inlined)."""
    a0, a1, a2 = abs(d0), abs(d1), abs(d2)
    vmax = max(a0, a1, a2)
    if not (vmax > 0.0):
        if vmax == 0.0:
            return 0.0, 0.0, f[F_C]
        return math.nan, math.nan, math.nan
    u0, u1, u2, _, _ = _scaled_direction(f, a0, a1, a2, vmax)
    if f[F_E1] == 1.0 and f[F_E2] == 1.0:  # ellipsoid: q = 2, s = diag(a, b, c) u / |u|
        k = 1.0 / math.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
        return (math.copysign(f[F_A] * u0 * k, d0), math.copysign(f[F_B] * u1 * k, d1),
                math.copysign(f[F_C] * u2 * k, d2))
    w0, w1, wm, wz, _, _, _, _, _, _ = _octant_parts(f, u0, u1, u2)
    return math.copysign(f[F_A] * w0 * wm, d0), math.copysign(f[F_B] * w1 * wm, d1), math.copysign(f[F_C] * wz, d2)


@kernel(inline="always")
def support_value(f, d0, d1, d2):
    """The support function max_x d.x of the superellipsoid fdata ``f`` (its own frame) along the
    nonzero (d0, d1, d2), at the direction's own scale: the dual norm h(u) of _octant_parts, without
    the support point's weights (a certificate's lower bound needs the value alone)."""
    a0, a1, a2 = abs(d0), abs(d1), abs(d2)
    u0, u1, u2, t, _ = _scaled_direction(f, a0, a1, a2, max(a0, a1, a2))
    if f[F_E1] == 1.0 and f[F_E2] == 1.0:
        return t * math.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
    return t * _octant_parts(f, u0, u1, u2)[5]


@kernel(inline="always")
def _power_over_ratio(value, u, q):
    """r^(q - 2) for the ratio r = u / N in [0, 1] of an entry u to its norm N: ``value`` (the caller's
    r^(q - 1) times N / u) where u > 0, q in (1, inf); at u = 0 its limit: inf for q < 2 (a flat
    point: the support point moves infinitely fast)."""
    if u > 0.0:
        return value
    if q > 2.0:
        return 0.0
    return 1.0 if q == 2.0 else math.inf


@kernel(inline="always")  # into Newton on the normal's evaluation, beside the other side's support
def superellipsoid_support_jacobian(f, d0, d1, d2, out, jac):
    """Support point along (d0, d1, d2) into out[0:3] and its derivative with respect to the
    direction into jac (3, 3), jac[i, j] = d out_i / d d_j, at the direction's own scale (unit
    directions give the derivative on the unit sphere's tangent plane plus a zero radial part).

    The derivative is the scaled Hessian of the dual norm (NOTES section 4): for a q-norm N,
    d2N/du_i du_j = (q - 1)/N (r_i^(q-2) delta_ij - r_i^(q-1) r_j^(q-1)), r = u/N, chained through
    the nested norm. Returns False where it does not exist or is unbounded: an exponent of 2 (edges
    and corners), a direction along the z axis, or a zero component on a flat (q < 2) side.
    """
    if f[F_E1] >= 2.0 or f[F_E2] >= 2.0:
        return False
    a0, a1, a2 = abs(d0), abs(d1), abs(d2)
    vmax = max(a0, a1, a2)
    if not (vmax > 0.0) or not (max(a0, a1) > 0.0):
        return False
    u0, u1, u2, t, it = _scaled_direction(f, a0, a1, a2, vmax)
    w0, w1, wm, wz, m, h, r0, r1, rm, rz = _octant_parts(f, u0, u1, u2)
    out[0] = math.copysign(f[F_A] * w0 * wm, d0)
    out[1] = math.copysign(f[F_B] * w1 * wm, d1)
    out[2] = math.copysign(f[F_C] * wz, d2)
    q1, q2 = f[F_Q1], f[F_Q2]
    # r_i^(q-2) = r_i^(q-1) / r_i with r_i = u_i / N, N the norm, from _octant_parts' ratios N / u_i:
    # two divisions side by side follow the powers, where six in a row did (the Hessian's 1/N at
    # the direction's own scale, where it is of degree -1)
    c0 = _power_over_ratio(w0 * r0, u0, q2)
    c1 = _power_over_ratio(w1 * r1, u1, q2)
    cm = _power_over_ratio(wm * rm, m, q1)
    cz = _power_over_ratio(wz * rz, u2, q1)
    if not (c0 < math.inf and c1 < math.inf and cz < math.inf):
        return False
    k2 = f[F_Q2M1] * it / m
    k1 = f[F_Q1M1] * it / h
    nmm = k1 * (cm - wm * wm)
    nmz = -k1 * wm * wz
    nzz = k1 * (cz - wz * wz)
    h00 = nmm * w0 * w0 + wm * k2 * (c0 - w0 * w0)
    h01 = nmm * w0 * w1 - wm * k2 * w0 * w1
    h11 = nmm * w1 * w1 + wm * k2 * (c1 - w1 * w1)
    # back from the octant: u = diag(a, b, c) |d| (over t), and the Hessian is of degree -1
    s0 = math.copysign(f[F_A], d0)
    s1 = math.copysign(f[F_B], d1)
    s2 = math.copysign(f[F_C], d2)
    jac[0, 0] = s0 * s0 * h00
    jac[0, 1] = jac[1, 0] = s0 * s1 * h01
    jac[1, 1] = s1 * s1 * h11
    jac[0, 2] = jac[2, 0] = s0 * s2 * nmz * w0
    jac[1, 2] = jac[2, 1] = s1 * s2 * nmz * w1
    jac[2, 2] = s2 * s2 * nzz
    return True
