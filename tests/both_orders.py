"""A query asked both ways round (A, B) and (B, A): the same statuses and distances."""

from __future__ import annotations

import numpy as np

import spq


def both_orders(a, b, poses_a, poses_b, atol=3e-10):
    """(forward, backward) batches of distances(a, b) and distances(b, a) on the same poses, after
    checking they agree (statuses equal, distances within atol m) and that the poses hold more than
    50 separated and 10 overlapping pairs."""
    forward = spq.distances(a, b, poses_a, poses_b)
    backward = spq.distances(b, a, poses_b, poses_a)
    sep = forward.status == "separated"
    assert sep.sum() > 50 and (~sep).sum() > 10
    np.testing.assert_array_equal(forward.status, backward.status)
    np.testing.assert_allclose(forward.distance, backward.distance, rtol=0, atol=atol)
    return forward, backward
