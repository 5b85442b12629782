"""What one run did to the commands: the measures of ``spq bench control``, per run, from its RunLog.

- Smallest distance on a common geometry: every method's trajectory evaluated on the same PCH scene
  (signed), so that volumes that keep their own margin are compared on the same bodies; steps below d_s
  (by more than DS_TOL_M: a damper brings a pair to d_s asymptotically) and below 0.
- Row turn: ‖Δ(∂d/∂q)‖ between consecutive steps of a pair that stays active (its peak and 99th
  percentile; m per rad, the row's own units).
- The commands: total variation Σ‖Δq̇‖ (rad/s) and the joint acceleration ‖Δq̇‖/dt at every step
  (from rest at the start), with each step's causes: a damper row switching on or off, a row starting
  or stopping to hold the command (its slack reaching 0: the QP's active set; known for the QPs spq's
  controller solves, not inside pink's or mink's), a distance
  crossing d_s, a joint-limit damper turning on/off or starting/stopping to hold its joint, a joint
  reaching or leaving its velocity limit, a closest-feature switch (a witness point jumping in its own
  body's frame: by over FEATURE_JUMP_M in one step and over FEATURE_JUMP_RATIO times its move at the
  step before and the step after, so that a witness sliding fast on a large sphere patch is not
  counted, an isolated jump is), a QP failure; a step with none of these is 'no_event' (its acceleration comes from the continuous
  dynamics: a binding row turning, the task). A spike is a step whose acceleration
  exceeds SPIKE_RAD_S2.
- QP failures, clipped steps, final task error, time per step (distances + Jacobians, and QP).
"""

from __future__ import annotations

import numpy as np

FEATURE_JUMP_M = 0.001  # m: least witness-point move in its body's frame in one step that can be a feature switch
FEATURE_JUMP_RATIO = 3.0  # ... and it must be this many times the pair's move at the steps before and after
DS_TOL_M = 5e-4  # m: a step counts below d_s when under d_s by more than this (the damper approaches d_s itself)
SPIKE_RAD_S2 = 50.0  # rad/s²: a step's ‖Δq̇‖/dt above this is a spike (the references need a few rad/s²)
CAUSES = ("row_switch", "row_binding", "ds_reached", "joint_limit", "velocity_limit", "feature_switch", "qp_failure", "no_event")


def accelerations(qdot: np.ndarray, dt: float) -> np.ndarray:
    """(T,) ‖q̇_k − q̇_{k−1}‖/dt (rad/s²), q̇_{−1} = 0 (the run starts from rest)."""
    prev = np.vstack([np.zeros((1, qdot.shape[1])), qdot[:-1]])
    return np.linalg.norm(qdot - prev, axis=1) / dt


def step_causes(log, ds: float) -> np.ndarray:
    """(T, len(CAUSES)) bool: which events happened between step k − 1 and step k."""
    T = len(log.rows)
    out = np.zeros((T, len(CAUSES)), bool)
    c = {name: i for i, name in enumerate(CAUSES)}
    failed = np.array([s != "solved" for s in log.status])
    witness_moves = _witness_moves(log)
    for k in range(T):
        now = log.rows[k]
        prev = log.rows[k - 1] if k > 0 else None
        pn = {int(p): i for i, p in enumerate(now.pairs)}
        pp = {int(p): i for i, p in enumerate(prev.pairs)} if prev is not None else {}
        out[k, c["row_switch"]] = set(pn) != set(pp)
        out[k, c["row_binding"]] = k > 0 and _binding(now, log.qdot[k]) != _binding(prev, log.qdot[k - 1])
        crossed = False
        for p, i in pn.items():
            d = now.distance[i]
            if p in pp:
                crossed |= (prev.distance[pp[p]] - ds) * (d - ds) <= 0.0 and d != prev.distance[pp[p]]
            else:
                crossed |= d <= ds
        out[k, c["ds_reached"]] = crossed
        if k > 0:
            out[k, c["joint_limit"]] = bool((log.joint_damped[k] != log.joint_damped[k - 1]).any()
                                            or (log.joint_binding[k] != log.joint_binding[k - 1]).any())
            out[k, c["velocity_limit"]] = bool((log.speed_binding[k] != log.speed_binding[k - 1]).any())
            out[k, c["feature_switch"]] = any(_jumped(witness_moves, k, p) for p in pn if p in pp)
        out[k, c["qp_failure"]] = failed[k] or (k > 0 and failed[k - 1])
    out[:, c["no_event"]] = ~out[:, :-1].any(axis=1)
    return out


BINDING_TOL = 1e-6  # m/s: a damper row whose slack h − G q̇ is below this holds the command


def _binding(rows, qdot) -> set:
    """The pairs whose damper row holds the command (spq's QP only: rows.h is set)."""
    if rows is None or rows.h is None or not len(rows.pairs):
        return set()
    slack = rows.h + rows.jacobian @ qdot
    return {int(p) for p, s in zip(rows.pairs, slack) if s < BINDING_TOL}


def _active_at_both(log):
    """(k, pair, rows at k, its index there, rows at k − 1, its index there) for every pair active at both
    steps k − 1 and k."""
    for k in range(1, len(log.rows)):
        now, prev = log.rows[k], log.rows[k - 1]
        pp = {int(p): i for i, p in enumerate(prev.pairs)}
        for i, p in enumerate(now.pairs):
            j = pp.get(int(p))
            if j is not None:
                yield k, int(p), now, i, prev, j


def _witness_moves(log) -> dict:
    """{(step k, pair): the larger of the two witness points' moves in their body frames from k − 1 to k}."""
    return {(k, p): max(np.linalg.norm(now.witness_a[i] - prev.witness_a[j]),
                        np.linalg.norm(now.witness_b[i] - prev.witness_b[j]))
            for k, p, now, i, prev, j in _active_at_both(log)}


def _jumped(moves: dict, k: int, pair: int) -> bool:
    m = moves.get((k, pair), 0.0)
    around = max(moves.get((k - 1, pair), 0.0), moves.get((k + 1, pair), 0.0))
    return m > FEATURE_JUMP_M and m > FEATURE_JUMP_RATIO * around


def row_turns(log) -> np.ndarray:
    """‖Δ(∂d/∂q)‖ of every (step, pair) where the pair is active at both k − 1 and k."""
    return np.array([np.linalg.norm(now.jacobian[i] - prev.jacobian[j])
                     for _, _, now, i, prev, j in _active_at_both(log)])


def common_distances(pch_scene, q: np.ndarray) -> np.ndarray:
    """(N,) smallest signed distance (m) over the scene's pairs at each configuration q (N, n)."""
    from spq.kernels.gjk import OUT_DISTANCE

    q = np.clip(q, pch_scene.model.lower, pch_scene.model.upper)
    out = pch_scene.distances_many(q, coherent=True, signed=True)
    return np.nanmin(out[:, :, OUT_DISTANCE], axis=1)


def run_metrics(log, params, pch_scene) -> dict:
    """The measures of the module docstring for one run (a flat dict, SI units; ms for times)."""
    dt = params.dt
    acc = accelerations(log.qdot, dt)
    causes = step_causes(log, params.ds)
    turns = row_turns(log)
    dmin = common_distances(pch_scene, log.q)
    dq = np.diff(np.vstack([np.zeros((1, log.qdot.shape[1])), log.qdot]), axis=0)
    active = np.array([len(r.pairs) for r in log.rows])
    total = log.seconds_distance + log.seconds_qp
    row = {
        "method": log.method, "robot": log.robot, "task": log.task, "steps": len(log.rows),
        "min_distance_m": float(dmin.min()), "steps_below_ds": int((dmin < params.ds - DS_TOL_M).sum()),
        "steps_below_0": int((dmin < 0).sum()),
        "final_task_error_m": float(log.task_error[-1]), "max_reference_error_m": float(log.reference_error.max()),
        "active_rows_mean": float(active.mean()), "active_rows_max": int(active.max()),
        "row_turn_peak": float(turns.max()) if len(turns) else 0.0,
        "row_turn_p99": float(np.percentile(turns, 99)) if len(turns) else 0.0,
        "qdot_total_variation": float(np.linalg.norm(dq, axis=1).sum()),
        "acc_peak": float(acc.max()), "acc_p99": float(np.percentile(acc, 99)),
        "spikes": int((acc > SPIKE_RAD_S2).sum()),
        "qp_failures": int(log.failures), "qp_fallbacks": int(log.fallbacks), "clipped_steps": int(log.clipped),
        "ms_distance_median": 1e3 * float(np.median(log.seconds_distance)),
        "ms_qp_median": 1e3 * float(np.median(log.seconds_qp)),
        "ms_step_median": 1e3 * float(np.median(total)), "ms_step_p99": 1e3 * float(np.percentile(total, 99)),
        "note": log.note,
    }
    for i, name in enumerate(CAUSES):
        flagged = causes[:, i]
        row[f"acc_peak_{name}"] = float(acc[flagged].max()) if flagged.any() else 0.0
        row[f"spikes_{name}"] = int((flagged & (acc > SPIKE_RAD_S2)).sum())
        row[f"events_{name}"] = int(flagged.sum())
    return row


def series(log, params) -> dict:
    """Per-step arrays kept for the charts: accelerations and causes."""
    return {"acc": accelerations(log.qdot, params.dt), "causes": step_causes(log, params.ds)}
