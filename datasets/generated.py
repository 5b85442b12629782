"""Seeded random convex hulls.

:func:`random_hull` puts points on the surface of an ellipsoid (directions uniform on the sphere,
mapped onto the ellipsoid), optionally pushed inwards by up to ``noise`` (relative), and takes
their convex hull. With ``noise=0`` every point lies on a strictly convex surface, so the hull has
exactly ``n_points`` vertices.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from spq.shapes.polyhedron import Polyhedron

DEFAULT_SCALE = 0.1  # m: largest semi-axis, comparable to a robot link
DEFAULT_AXES = (1.0, 0.75, 0.5)  # semi-axes relative to ``scale``

GENERATED: dict[str, dict] = {
    "random_hull_50": dict(n_points=50, seed=50),
    "random_hull_200": dict(n_points=200, seed=200),
}
"""Named generated objects -> keyword arguments of :func:`random_hull`."""


def random_hull(
    n_points: int,
    seed: int,
    scale: float = DEFAULT_SCALE,
    axes=DEFAULT_AXES,
    noise: float = 0.0,
) -> Polyhedron:
    """Convex hull of ``n_points`` (>= 4) random points on an ellipsoid, centred at the origin.

    The ellipsoid's semi-axes are ``scale * axes`` (metres) along x, y, z. Each point is scaled
    towards the centre by a factor uniform in ``[1 - noise, 1]`` (0 <= noise < 1); with noise > 0
    some points fall inside and the hull has fewer vertices. Deterministic in ``seed``.
    """
    if isinstance(n_points, bool) or not isinstance(n_points, (int, np.integer)) or n_points < 4:
        raise ValueError(f"n_points must be an integer >= 4; got {n_points!r}")
    if not np.isfinite(scale) or scale <= 0:
        raise ValueError(f"scale must be finite and > 0 (metres); got {scale}")
    ax = np.asarray(axes, dtype=np.float64)
    if ax.shape != (3,) or not np.isfinite(ax).all() or (ax <= 0).any():
        raise ValueError(f"axes must be three finite numbers > 0; got {axes!r}")
    if not 0.0 <= noise < 1.0:
        raise ValueError(f"noise must be in [0, 1); got {noise}")
    rng = np.random.default_rng(seed)
    d = rng.normal(size=(int(n_points), 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    pts = d * (scale * ax)
    if noise > 0:
        pts *= rng.uniform(1.0 - noise, 1.0, size=(int(n_points), 1))
    return Polyhedron.from_points(pts)


@lru_cache(maxsize=None)
def load_generated(name: str) -> Polyhedron:
    """The named generated object ``name`` (a key of GENERATED); cached, do not modify it."""
    if name not in GENERATED:
        raise ValueError(f"unknown generated object {name!r}; known: {sorted(GENERATED)}")
    poly = random_hull(**GENERATED[name])
    poly.name = name
    return poly
