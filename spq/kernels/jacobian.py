"""Distance Jacobians of a robot scene's pairs, over the flat arrays of :class:`spq.kinematics.RobotModel`.

For a pair with witness points p_A on body A, p_B on body B and the unit normal n (from A to B),

    ∂d/∂q = nᵀ (J_B(p_B) − J_A(p_A)),

J_X(p) the 3×nv linear Jacobian of the point p fixed to X's link. Joint j of link l moves a point p
of l or of any of its descendants with velocity ``a × (p − o)`` per unit rate (revolute: a the joint's
world axis, o its world origin) or ``a`` (prismatic), times the joint's mimic multiplier; so the
joint's column gets ``m · a·((p − o) × n)`` (revolute) or ``m · a·n`` (prismatic) from the B side, and
minus that from the A side. A floating base adds six leading columns, the base's twist (v, ω) in the
world frame (v the velocity of the base frame's origin b): the point moves with v + ω × (p − b).

A link index ``>= parent.shape[0]`` stands for the world (static obstacles): its points do not move.

A joint that moves both bodies (one above their lowest common ancestor link, the base too) adds
a·((p_B − o) × n) − a·((p_A − o) × n) = a·((p_B − p_A) × n) = 0, since p_B − p_A = d n: moving a pair
rigidly leaves its distance alone. So each side's walk stops at the pair's common ancestor (``stop``),
which halves the work on a humanoid's arm pairs; a pair with an obstacle walks to the root, base included.
Each moving joint's world axis and origin come from the link poses after forward kinematics: link i's
pose is T_parent · origin_i · motion(q), and a joint's motion leaves its own axis and (for a rotation)
its origin in place, so the axis is R_i · axis_i and the origin is T_i's translation.
"""

from __future__ import annotations

import math

from spq.kernels.gjk import OUT_NORMAL, OUT_POINT_A, OUT_POINT_B, OUT_STATUS
from spq.kernels.jit import kernel
from spq.kernels.kinematics import PRISMATIC, forward_kinematics
from spq.kernels.scene import pairs_at_poses, slot_poses

BASE_COLUMNS = 6  # columns a floating base adds in front of the joints: v (3, m/s), ω (3, rad/s), world frame
STATUS_SEPARATED = 0
STATUS_TOUCHING = 1
STATUS_OVERLAPPING = 2
PRUNED = -1  # spq.kernels.scene.PRUNED
TO_ROOT = -1  # a pair's stop link when it has a side in the world: walk to the root, the base's columns included


@kernel
def joint_axes(links, joint_axis, out):
    """World axis of every link's joint: out[i] = R_i · joint_axis[i] (links (n, 4, 4) from forward
    kinematics; out (n, 3))."""
    for i in range(joint_axis.shape[0]):
        for r in range(3):
            out[i, r] = links[i, r, 0] * joint_axis[i, 0] + links[i, r, 1] * joint_axis[i, 1] + \
                links[i, r, 2] * joint_axis[i, 2]


@kernel
def add_point_row(links, axes, chain, base, floating, link, stop, p, n, sign, row):
    """row += sign · nᵀ J(p) for the world point p (3,) fixed to ``link``, along the world direction n (3,),
    over the joints from ``link`` up to, not including, link ``stop`` (TO_ROOT: every joint and the base).

    row (nv,): the base's six columns first when ``floating``, then the joints'. A link index outside
    the model (the world) adds nothing. chain: as :func:`spq.kernels.scene.scene_distances` takes it."""
    parent, joint_type, _, _, q_index, q_multiplier, _ = chain
    nlinks = parent.shape[0]
    if link < 0 or link >= nlinks:
        return
    first = 6 if floating else 0
    if floating and stop == TO_ROOT:
        b0 = p[0] - base[0, 3]
        b1 = p[1] - base[1, 3]
        b2 = p[2] - base[2, 3]
        row[0] += sign * n[0]
        row[1] += sign * n[1]
        row[2] += sign * n[2]
        # ω·((p − b) × n)
        row[3] += sign * (b1 * n[2] - b2 * n[1])
        row[4] += sign * (b2 * n[0] - b0 * n[2])
        row[5] += sign * (b0 * n[1] - b1 * n[0])
    l = link
    while l >= 0 and l != stop:
        j = q_index[l]
        if j >= 0:
            a0 = axes[l, 0]
            a1 = axes[l, 1]
            a2 = axes[l, 2]
            if joint_type[l] == PRISMATIC:
                value = a0 * n[0] + a1 * n[1] + a2 * n[2]
            else:
                r0 = p[0] - links[l, 0, 3]
                r1 = p[1] - links[l, 1, 3]
                r2 = p[2] - links[l, 2, 3]
                value = a0 * (r1 * n[2] - r2 * n[1]) + a1 * (r2 * n[0] - r0 * n[2]) + a2 * (r0 * n[1] - r1 * n[0])
            row[first + j] += sign * q_multiplier[l] * value
        l = parent[l]


@kernel
def pair_jacobians(links, axes, chain, base, floating, slot_link, pair_slots, pair_stop, signed, out, jac):
    """Every pair's row ∂d/∂q into jac (npairs, nv) from its query result out (npairs, OUT_SIZE);
    pair_stop (npairs,): each pair's lowest common ancestor link, or TO_ROOT.

    A pruned pair gets a zero row; a pair whose result defines no gradient (failed, an overlap of an
    unsigned query, or a non-finite normal or witness point) gets a row of NaN."""
    nan = math.nan
    for p in range(pair_slots.shape[0]):
        row = jac[p]
        row[:] = 0.0
        res = out[p]
        code = int(res[OUT_STATUS])
        if code == PRUNED:
            continue
        ok = code == STATUS_SEPARATED or code == STATUS_TOUCHING or (code == STATUS_OVERLAPPING and signed)
        for k in range(3):
            if not (math.isfinite(res[OUT_NORMAL + k]) and math.isfinite(res[OUT_POINT_A + k])
                    and math.isfinite(res[OUT_POINT_B + k])):
                ok = False
        if not ok:
            row[:] = nan
            continue
        n = res[OUT_NORMAL:OUT_NORMAL + 3]
        add_point_row(links, axes, chain, base, floating, slot_link[pair_slots[p, 0]], pair_stop[p],
                      res[OUT_POINT_A:OUT_POINT_A + 3], n, -1.0, row)
        add_point_row(links, axes, chain, base, floating, slot_link[pair_slots[p, 1]], pair_stop[p],
                      res[OUT_POINT_B:OUT_POINT_B + 3], n, 1.0, row)


@kernel(nogil=True)  # threads run chunks of the configurations at once (spq.workers)
def scene_distances_jacobians(chain, base, qs, slots, pairs, coherent, prune, links, poses, scratch, out, gradient):
    """:func:`spq.kernels.scene.scene_distances` and every pair's row ∂d/∂q in one compiled loop: per
    configuration, forward kinematics, the slot poses, every pair's query into out[i], then the rows
    into jac[i] (N, npairs, nv) from the same link poses. The arguments up to ``out`` are
    scene_distances'; gradient: (floating, pair_stop, signed, axes, jac), the first three as in
    :func:`pair_jacobians`, axes (nlinks, 3) scratch."""
    parent, joint_type, joint_origin, joint_axis, q_index, q_multiplier, q_offset = chain
    slot_link, slot_offset = slots[0], slots[1]
    pair_slots = pairs[0]
    floating, pair_stop, signed, axes, jac = gradient
    for i in range(qs.shape[0]):
        forward_kinematics(parent, joint_type, joint_origin, joint_axis, q_index, q_multiplier, q_offset, qs[i], base,
                           links)
        slot_poses(links, slot_link, slot_offset, poses)
        pairs_at_poses(poses, slots, pairs, coherent, prune, scratch, out[i])
        joint_axes(links, joint_axis, axes)
        pair_jacobians(links, axes, chain, base, floating, slot_link, pair_slots, pair_stop, signed, out[i], jac[i])


@kernel
def point_jacobian(chain, base, floating, q, link, p, links, axes, out):
    """out (6, nv) = the Jacobian of the world point p (3,) fixed to ``link``: rows 0..2 its linear
    velocity, rows 3..5 the link's angular velocity (world frame), per unit rate of each column.
    chain: as :func:`spq.kernels.scene.scene_distances` takes it. links (>= nlinks, 4, 4),
    axes (nlinks, 3): scratch."""
    parent, joint_type, joint_origin, joint_axis, q_index, q_multiplier, q_offset = chain
    forward_kinematics(parent, joint_type, joint_origin, joint_axis, q_index, q_multiplier, q_offset, q, base, links)
    joint_axes(links, joint_axis, axes)
    out[:, :] = 0.0
    if link < 0 or link >= parent.shape[0]:
        return
    first = 0
    if floating:
        first = 6
        b0 = p[0] - base[0, 3]
        b1 = p[1] - base[1, 3]
        b2 = p[2] - base[2, 3]
        for k in range(3):
            out[k, k] = 1.0
            out[3 + k, 3 + k] = 1.0
        # v + ω × (p − b): the ω columns of the linear rows are −[p − b]×
        out[0, 4] = b2
        out[0, 5] = -b1
        out[1, 3] = -b2
        out[1, 5] = b0
        out[2, 3] = b1
        out[2, 4] = -b0
    l = link
    while l >= 0:
        j = q_index[l]
        if j >= 0:
            m = q_multiplier[l]
            a0 = m * axes[l, 0]
            a1 = m * axes[l, 1]
            a2 = m * axes[l, 2]
            c = first + j
            if joint_type[l] == PRISMATIC:
                out[0, c] += a0
                out[1, c] += a1
                out[2, c] += a2
            else:
                r0 = p[0] - links[l, 0, 3]
                r1 = p[1] - links[l, 1, 3]
                r2 = p[2] - links[l, 2, 3]
                out[0, c] += a1 * r2 - a2 * r1
                out[1, c] += a2 * r0 - a0 * r2
                out[2, c] += a0 * r1 - a1 * r0
                out[3, c] += a0
                out[4, c] += a1
                out[5, c] += a2
        l = parent[l]


def common_ancestors(parent, link_a, link_b):
    """(npairs,) int64: the lowest common ancestor link of each pair of links (link_a, link_b: (npairs,),
    -1 for a body in the world, whose pair gets TO_ROOT). Python: once per scene."""
    import numpy as np

    out = np.empty(len(link_a), dtype=np.int64)
    for k, (a, b) in enumerate(zip(link_a, link_b)):
        if a < 0 or b < 0:
            out[k] = TO_ROOT
            continue
        above_a = set()
        while a >= 0:
            above_a.add(int(a))
            a = parent[a]
        while b >= 0 and int(b) not in above_a:
            b = parent[b]
        out[k] = b if b >= 0 else TO_ROOT
    return out
