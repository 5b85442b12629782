"""Frame changes of a pair query: B's pose in A's frame is (R, t), so a point x of B's frame is
R x + t in A's, and a point y of A's frame is R^T (y - t) in B's."""

from __future__ import annotations

from spq.kernels.jit import kernel


@kernel(inline="always")
def to_a(R, t, x0, x1, x2):
    return (R[0, 0] * x0 + R[0, 1] * x1 + R[0, 2] * x2 + t[0], R[1, 0] * x0 + R[1, 1] * x1 + R[1, 2] * x2 + t[1],
            R[2, 0] * x0 + R[2, 1] * x1 + R[2, 2] * x2 + t[2])


@kernel(inline="always")
def to_b(R, t, x0, x1, x2):
    y0, y1, y2 = x0 - t[0], x1 - t[1], x2 - t[2]
    return (R[0, 0] * y0 + R[1, 0] * y1 + R[2, 0] * y2, R[0, 1] * y0 + R[1, 1] * y1 + R[2, 1] * y2,
            R[0, 2] * y0 + R[1, 2] * y1 + R[2, 2] * y2)


@kernel(inline="always")
def rot_to_b(R, x0, x1, x2):
    return (R[0, 0] * x0 + R[1, 0] * x1 + R[2, 0] * x2, R[0, 1] * x0 + R[1, 1] * x1 + R[2, 1] * x2,
            R[0, 2] * x0 + R[1, 2] * x1 + R[2, 2] * x2)


@kernel(inline="always")
def rot_to_a(R, x0, x1, x2):
    return (R[0, 0] * x0 + R[0, 1] * x1 + R[0, 2] * x2, R[1, 0] * x0 + R[1, 1] * x1 + R[1, 2] * x2,
            R[2, 0] * x0 + R[2, 1] * x1 + R[2, 2] * x2)
