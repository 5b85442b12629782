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
1/q1 - 1, 1/q2 - 1] (F_* offsets below; q - 1 = e/(2 - e) and 1/q - 1 = -e/2 are stored exactly,
not recomputed from a rounded q); idata unused. Margin 0.
"""

from __future__ import annotations

import math

import numpy as np

from spq.kernels.jit import kernel

F_A, F_B, F_C, F_E1, F_E2 = 0, 1, 2, 3, 4
F_Q1, F_Q2, F_Q1M1, F_Q2M1, F_H1, F_H2 = 5, 6, 7, 8, 9, 10
FDATA_SIZE = 11

# rho^q below this is subnormal or near it: rho^(q-1) = rho^q / rho would lose relative precision,
# so it is taken as exp((q - 1) log rho) instead (dimensionless; rare: needs rho < ~1e-290^(1/q)).
TINY_POWER = 1e-290


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
    return f


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


@kernel
def superellipsoid_support(f, d0, d1, d2, out):
    """Write the support point of the superellipsoid fdata ``f`` along (d0, d1, d2) into out[0:3].

    The direction needs no normalisation (any positive scale gives the same point). A zero direction
    gives the pole (0, 0, c); a NaN direction gives NaN.
    """
    a0, a1, a2 = abs(d0), abs(d1), abs(d2)
    vmax = max(a0, a1, a2)
    if not (vmax > 0.0):
        if vmax == 0.0:
            out[0] = 0.0
            out[1] = 0.0
            out[2] = f[F_C]
        else:
            out[0] = out[1] = out[2] = math.nan
        return
    inv = 1.0 / vmax  # scale first: no overflow in u for any finite direction
    u0 = f[F_A] * (a0 * inv)
    u1 = f[F_B] * (a1 * inv)
    u2 = f[F_C] * (a2 * inv)
    if f[F_E1] == 1.0 and f[F_E2] == 1.0:  # ellipsoid: q = 2, s = diag(a, b, c) u / |u|
        k = 1.0 / math.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
        out[0] = math.copysign(f[F_A] * u0 * k, d0)
        out[1] = math.copysign(f[F_B] * u1 * k, d1)
        out[2] = math.copysign(f[F_C] * u2 * k, d2)
        return
    # inner norm m = ||(u0, u1)||_q2 = mx S^(1/q2), S = 1 + rho^q2, with gradient (w0, w1) in [0, 1]^2
    mx = max(u0, u1)
    if mx > 0.0:
        if u0 >= u1:
            p, pm1 = _minor_powers(u1 / mx, f[F_Q2], f[F_Q2M1])
            w0, w1 = 1.0, pm1
        else:
            p, pm1 = _minor_powers(u0 / mx, f[F_Q2], f[F_Q2M1])
            w0, w1 = pm1, 1.0
        ls = math.log1p(p)  # log S, in [0, log 2]
        if p > 0.0:
            g = math.exp(f[F_H2] * ls)  # S^(1/q2 - 1)
            w0 *= g
            w1 *= g
        # outer norm h = ||(m, u2)||_q1: the ratio of its entries in the log domain, where
        # log(u2 / m) = log(u2 / mx) - log(S) / q2 needs no power of S (and no wait for it)
        if u2 > 0.0:
            lr = math.log(u2 / mx) - ls * (f[F_H2] + 1.0)
            if lr == 0.0:  # a tie (also q1 = inf, where inf * 0 would be NaN)
                p, wm, wz = 1.0, 1.0, 1.0
            elif lr < 0.0:
                p = math.exp(f[F_Q1] * lr)
                wm, wz = 1.0, math.exp(f[F_Q1M1] * lr)
            else:
                p = math.exp(-f[F_Q1] * lr)
                wm, wz = math.exp(-f[F_Q1M1] * lr), 1.0
        else:
            p, wm, wz = 0.0, 1.0, 0.0
    else:
        p, wm, wz = 0.0, 0.0, 1.0
        w0 = w1 = 0.0
    if p > 0.0:
        g = math.exp(f[F_H1] * math.log1p(p))  # T^(1/q1 - 1), T = 1 + ratio^q1
        wm *= g
        wz *= g
    out[0] = math.copysign(f[F_A] * w0 * wm, d0)
    out[1] = math.copysign(f[F_B] * w1 * wm, d1)
    out[2] = math.copysign(f[F_C] * wz, d2)
