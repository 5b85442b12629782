"""Forward kinematics of a tree of rigid links, over the flat arrays of :class:`spq.kinematics.RobotModel`.

Links come in topological order (every link after its parent), so one pass from the root fills
every world pose. Link ``i`` is connected to ``parent[i]`` by a joint of type ``joint_type[i]`` whose
frame sits at ``joint_origin[i]`` in the parent link frame; the joint's motion, about or along the
unit ``joint_axis[i]`` (joint frame), is applied after the origin:

    T_i = T_parent @ joint_origin[i] @ Rot(axis, value)     revolute, continuous
    T_i = T_parent @ joint_origin[i] @ Trans(axis * value)  prismatic
    T_i = T_parent @ joint_origin[i]                        fixed

The joint value is ``q_multiplier[i] * q[q_index[i]] + q_offset[i]`` (radians or metres): 1 and 0
for an ordinary joint, the URDF ``<mimic>`` factors for a joint that follows another. The root's
pose is ``base @ joint_origin[0]``. Poses are 4x4 homogeneous, link frame -> world, metres.
"""

from __future__ import annotations

import math

from spq.kernels.jit import kernel

FIXED = 0
REVOLUTE = 1
CONTINUOUS = 2
PRISMATIC = 3


@kernel(inline="always")
def _compose_rigid(A, B, out):
    """out = A @ B for rigid 4x4 transforms (bottom row 0 0 0 1 assumed and written, not computed)."""
    for r in range(3):
        a0 = A[r, 0]
        a1 = A[r, 1]
        a2 = A[r, 2]
        for c in range(3):
            out[r, c] = a0 * B[0, c] + a1 * B[1, c] + a2 * B[2, c]
        out[r, 3] = a0 * B[0, 3] + a1 * B[1, 3] + a2 * B[2, 3] + A[r, 3]
    out[3, 0] = 0.0
    out[3, 1] = 0.0
    out[3, 2] = 0.0
    out[3, 3] = 1.0


@kernel(inline="always")
def _apply_rotation(T, axis, angle, out):
    """out[:3, :3] = T[:3, :3] @ Rot(axis, angle) (Rodrigues, unit axis); out[:3, 3] = T[:3, 3].

    Row r of out depends only on row r of T, so out may be T itself."""
    x = axis[0]
    y = axis[1]
    z = axis[2]
    c = math.cos(angle)
    s = math.sin(angle)
    t = 1.0 - c
    # Rodrigues: R = c I + s [k]x + (1 - c) k k^T
    r00 = c + t * x * x
    r01 = t * x * y - s * z
    r02 = t * x * z + s * y
    r10 = t * x * y + s * z
    r11 = c + t * y * y
    r12 = t * y * z - s * x
    r20 = t * x * z - s * y
    r21 = t * y * z + s * x
    r22 = c + t * z * z
    for r in range(3):
        a0 = T[r, 0]
        a1 = T[r, 1]
        a2 = T[r, 2]
        out[r, 0] = a0 * r00 + a1 * r10 + a2 * r20
        out[r, 1] = a0 * r01 + a1 * r11 + a2 * r21
        out[r, 2] = a0 * r02 + a1 * r12 + a2 * r22
        out[r, 3] = T[r, 3]


@kernel
def forward_kinematics(parent, joint_type, joint_origin, joint_axis, q_index, q_multiplier, q_offset, q, base, out):
    """World pose of every link for the joint values ``q``.

    parent (n,) int64, -1 for the root (link 0); joint_type (n,) int64 (FIXED, REVOLUTE, CONTINUOUS,
    PRISMATIC); joint_origin (n, 4, 4) joint frame in parent link frame; joint_axis (n, 3) unit, in
    the joint frame; q_index (n,) int64 index into q (-1 for fixed joints); q_multiplier, q_offset
    (n,) float64 (mimic factors); q (ndof,) radians / metres; base (4, 4) pose of the root's parent
    frame in the world (identity for a robot at the origin); out (n, 4, 4) written: link -> world.
    Nothing is checked here: :meth:`spq.kinematics.RobotModel.link_poses` validates first.
    """
    n = parent.shape[0]
    for i in range(n):
        p = parent[i]
        # out[i] first holds T_parent @ origin; a moving joint then writes its motion in place
        if p < 0:
            _compose_rigid(base, joint_origin[i], out[i])
        else:
            _compose_rigid(out[p], joint_origin[i], out[i])
        jt = joint_type[i]
        if jt == FIXED:
            continue
        value = q_multiplier[i] * q[q_index[i]] + q_offset[i]
        if jt == PRISMATIC:
            # translation along the axis, expressed in the joint frame: rotate it into the world
            for r in range(3):
                out[i, r, 3] += value * (
                    out[i, r, 0] * joint_axis[i, 0] + out[i, r, 1] * joint_axis[i, 1] + out[i, r, 2] * joint_axis[i, 2]
                )
        else:
            # in place is safe: _apply_rotation reads each row of T into locals before writing it
            _apply_rotation(out[i], joint_axis[i], value, out[i])


@kernel
def forward_kinematics_many(
    parent, joint_type, joint_origin, joint_axis, q_index, q_multiplier, q_offset, qs, bases, out
):
    """:func:`forward_kinematics` for each row of qs (N, ndof) with bases (N, 4, 4); out (N, n, 4, 4)."""
    for k in range(qs.shape[0]):
        forward_kinematics(
            parent, joint_type, joint_origin, joint_axis, q_index, q_multiplier, q_offset, qs[k], bases[k], out[k]
        )


@kernel
def within_limits(qs, lower, upper, slack):
    """Whether every value of qs (N, ndof) is finite and within [lower - slack, upper + slack]
    (lower, upper: (ndof,)). One pass over the values: the numpy checks it stands in front of
    (isfinite, two comparisons, their any) cost about 9 us a call, a fifth of a controller's
    per-step scene call on a small robot."""
    for i in range(qs.shape[0]):
        for k in range(qs.shape[1]):
            v = qs[i, k]
            if not (math.isfinite(v) and v >= lower[k] - slack and v <= upper[k] + slack):
                return False
    return True
