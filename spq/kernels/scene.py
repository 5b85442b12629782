"""All pairs of a robot scene in one compiled call: forward kinematics, then one GJK query per pair.

A *slot* is one bounding volume of one body (its PCH, its STP-BV or its superellipsoid): kind,
margin, a range of the shared float and int pools, the link it rides on and its pose in that link's
frame. A pair names two slots; its warm-start state (the ``ints`` and ``floats`` rows of
:mod:`spq.kernels.batch`) persists between calls, so a smooth trajectory re-uses each pair's last
simplex and search direction.
"""

from __future__ import annotations

import math

import numpy as np

from spq.kernels.batch import (
    FLOATS_SIZE,
    INTS_SIZE,
    F_CENTRES,
    F_MARGIN_A,
    F_MARGIN_B,
    F_TOL_ABS,
    F_TOL_REL,
    I_KIND_A,
    I_KIND_B,
    I_MAX_ITER,
    posed_query,
)
from spq.kernels.gjk import OUT_DISTANCE, OUT_LOWER, OUT_STATUS
from spq.kernels.indexing import at
from spq.kernels.jit import kernel
from spq.kernels.kinematics import forward_kinematics

PRUNED = -1  # out[OUT_STATUS] of a pair skipped because its bounding spheres are far apart


@kernel
def slot_poses(link_poses, slot_link, slot_offset, out):
    """World pose of every slot: its link's pose times its offset in the link frame."""
    for s in range(slot_link.shape[0]):
        L = link_poses[slot_link[s]]
        O = slot_offset[s]
        for r in range(4):
            for c in range(4):
                out[s, r, c] = L[r, 0] * O[0, c] + L[r, 1] * O[1, c] + L[r, 2] * O[2, c] + L[r, 3] * O[3, c]


@kernel
def _sphere_gap(TA, ca, ra, TB, cb, rb):
    """Distance between two bounding spheres (centres in their slot frames): a lower bound."""
    d2 = 0.0
    for r in range(3):
        xa = TA[r, 0] * ca[0] + TA[r, 1] * ca[1] + TA[r, 2] * ca[2] + TA[r, 3]
        xb = TB[r, 0] * cb[0] + TB[r, 1] * cb[1] + TB[r, 2] * cb[2] + TB[r, 3]
        d2 += (xa - xb) ** 2
    return math.sqrt(d2) - ra - rb


@kernel(hot=True)  # the query's large kernels inlined (spq.kernels.jit): the robot scene's hot loop
def pairs_at_poses(poses, slots, pairs, coherent, prune, scratch, out):
    """Every pair's query at the given slot world poses into out (npairs, OUT_SIZE), world frame.

    slots, pairs: the scene's packed bodies and pairs (see :func:`scene_distances`). coherent: keep
    each pair's warm start if its relative pose moved little; otherwise cold. prune > 0: skip
    (status PRUNED, distance inf, lower bound = sphere gap) the pairs whose bounding spheres are more
    than prune apart. scratch: :func:`spq.kernels.batch.query_scratch`'s."""
    _, _, slot_kind, slot_margin, slot_frange, slot_irange, fpool, ipool, slot_centre, slot_radius = slots
    pair_slots, pair_ints, pair_floats = pairs
    for p in range(pair_slots.shape[0]):
        sa = at(pair_slots[p, 0])
        sb = at(pair_slots[p, 1])
        TA = poses[sa]
        TB = poses[sb]
        row = out[p]
        if prune > 0.0:
            gap = _sphere_gap(TA, slot_centre[sa], slot_radius[sa], TB, slot_centre[sb], slot_radius[sb])
            if gap > prune:
                row[:] = 0.0
                row[OUT_DISTANCE] = np.inf
                row[OUT_LOWER] = gap
                row[OUT_STATUS] = PRUNED
                continue
        posed_query(fpool[slot_frange[sa, 0]:slot_frange[sa, 1]], ipool[slot_irange[sa, 0]:slot_irange[sa, 1]],
                    fpool[slot_frange[sb, 0]:slot_frange[sb, 1]], ipool[slot_irange[sb, 0]:slot_irange[sb, 1]],
                    pair_ints[p], pair_floats[p], TA, TB, coherent, scratch, row)


@kernel(nogil=True)  # threads run chunks of the configurations at once (spq.workers)
def scene_distances(chain, base, qs, slots, pairs, coherent, prune, links, poses, scratch, out):
    """All pairs for each of N joint configurations qs (N, ndof) into out (N, npairs, OUT_SIZE).

    chain: the kinematic tree, (parent, joint_type, joint_origin, joint_axis, q_index, q_multiplier,
    q_offset) as :func:`spq.kernels.kinematics.forward_kinematics` takes them. slots: the bodies,
    (slot_link, slot_offset, slot_kind, slot_margin, slot_frange, slot_irange, fpool, ipool,
    slot_centre, slot_radius). pairs: (pair_slots, pair_ints, pair_floats), the pairs and their
    packed queries (spq.kernels.batch).

    Forward kinematics from ``base`` (4x4 world pose of the root link), slot poses, then every pair
    (see :func:`pairs_at_poses`); with coherent the warm starts carry from one configuration to the
    next, as along a trajectory. links (nlinks, 4, 4), poses (nslots, 4, 4), scratch: scratch from the
    caller (see :func:`spq.kernels.batch.query_scratch`).
    Joint values are not checked here (the caller validates them)."""
    parent, joint_type, joint_origin, joint_axis, q_index, q_multiplier, q_offset = chain
    slot_link, slot_offset = slots[0], slots[1]
    for i in range(qs.shape[0]):
        forward_kinematics(parent, joint_type, joint_origin, joint_axis, q_index, q_multiplier, q_offset, qs[i], base,
                           links)
        slot_poses(links, slot_link, slot_offset, poses)
        pairs_at_poses(poses, slots, pairs, coherent, prune, scratch, out[i])


def pack_pair_state(slot_kind, slot_margin, slot_centre, pair_slots, tol_abs, tol_rel, max_iter):
    """Fresh per-pair ints and floats rows (kinds, margins, bounding-sphere centres that aim a cold
    start, tolerances; warm start zero)."""
    n = len(pair_slots)
    ints = np.zeros((n, INTS_SIZE), dtype=np.int64)
    floats = np.zeros((n, FLOATS_SIZE))
    a, b = pair_slots[:, 0], pair_slots[:, 1]
    ints[:, I_KIND_A], ints[:, I_KIND_B], ints[:, I_MAX_ITER] = slot_kind[a], slot_kind[b], max_iter
    floats[:, F_MARGIN_A], floats[:, F_MARGIN_B] = slot_margin[a], slot_margin[b]
    floats[:, F_TOL_ABS], floats[:, F_TOL_REL] = tol_abs, tol_rel
    floats[:, F_CENTRES:F_CENTRES + 3], floats[:, F_CENTRES + 3:F_CENTRES + 6] = slot_centre[a], slot_centre[b]
    return ints, floats
