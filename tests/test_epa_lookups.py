"""The EPA's branch-free lookups (spq.kernels.epa) against plain definitions of what they compute:
the edge of a face across from another (a linear search), and a fan face's plane (numpy's cross
product; the corner it is taken at must not depend on where the triangle's vertex list starts)."""

import itertools

import numpy as np
import pytest

from spq.kernels.epa import PLANE_OK, PLANE_SLIVER, _edge_towards, _plane_of
from spq.kernels.epa_layout import EPA_ADJ, EPA_W
from spq.kernels.gjk import EPA_IOFF, EPA_ROW, IWORK_SIZE, WORK_ROWS


def test_edge_towards_matches_a_linear_search():
    iw = np.zeros(IWORK_SIZE, dtype=np.int64)
    g, f = 5, 7
    # every adjacency of face g over {f, two other faces}: f once (at each edge), more than once, or not at all
    for adj in itertools.product((f, 3, 11), repeat=3):
        iw[EPA_IOFF + EPA_ADJ + 3 * g:EPA_IOFF + EPA_ADJ + 3 * g + 3] = adj
        expected = next((h for h in range(3) if adj[h] == f), -1)
        assert _edge_towards(iw, g, f) == expected, adj


def _plane(work, tri, interior):
    for i, p in enumerate(tri):
        work[EPA_ROW + EPA_W + i, :3] = p
    return _plane_of(work, 0, 1, 2, *interior)


def test_fan_plane_matches_numpy_and_not_the_vertex_order():
    rng = np.random.default_rng(3)
    work = np.zeros((WORK_ROWS, 4))
    shapes = 0
    for _ in range(3000):
        tri = rng.normal(size=(3, 3))
        if rng.random() < 0.3:  # needles: one side 1e-9 .. 1e-3 of the others
            tri[1] = tri[0] + 10.0 ** rng.uniform(-9, -3) * rng.normal(size=3)
        n = np.cross(tri[1] - tri[0], tri[2] - tri[0])
        n /= np.linalg.norm(n)
        interior = tri.mean(axis=0) - n  # behind the counter-clockwise face
        planes = [_plane(work, np.roll(tri, -k, axis=0), interior) for k in range(3)]
        if planes[0][0] == PLANE_SLIVER:
            continue
        shapes += 1
        code, n0, n1, n2, off = planes[0]
        assert code == PLANE_OK
        # the corner is the one opposite the longest side whichever vertex the list starts at: the same
        # normal bit for bit (the offset sums the corners in the list's order, so only to rounding)
        for other in planes[1:]:
            assert other[:4] == planes[0][:4]
            assert other[4] == pytest.approx(off, abs=1e-15 * np.abs(tri).max())
        scale = np.abs(tri).max()
        # a needle's normal is good to eps / (its short side / scale)
        sides = np.linalg.norm(tri - np.roll(tri, 1, axis=0), axis=1)
        tol = 1e-13 * sides.max() / sides.min()
        assert np.allclose((n0, n1, n2), n, atol=tol, rtol=0)
        assert off == pytest.approx(float(n @ tri.mean(axis=0)), abs=tol * scale)
    assert shapes > 2500
