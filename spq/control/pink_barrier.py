"""A pink barrier whose distances and Jacobians come from an spq Scene: pink's SelfCollisionBarrier,
with spq as the geometry source.

A pink user swaps the geometry source in two lines::

    # barrier = pink.barriers.SelfCollisionBarrier(n_collision_pairs=10, d_min=0.02)
    scene = spq.Scene.from_urdf(urdf_path, policy="auto", srdf=srdf_path)  # the same URDF as pink's model
    barrier = spq.control.SceneBarrier(scene, n_collision_pairs=10, d_min=0.02)

and the rest of the pink loop stays (``pink.solve_ik(configuration, tasks, dt, solver, barriers=[barrier])``);
the pink Configuration then needs no collision model, which also saves its coal computeDistances
in every ``configuration.update``. Importing this module needs pink (``pip install pin-pink``).
"""

from __future__ import annotations

import math

import numpy as np

try:
    from pink.barriers import Barrier
except ImportError as exc:  # pragma: no cover - exercised by a test that hides pink
    raise ImportError(f"spq.control.SceneBarrier is a pink barrier and needs pink: pip install pin-pink ({exc})") \
        from None

from spq.control.joint_map import pinocchio_joint_map
from spq.kernels.gjk import FAILED

INACTIVE_VALUE = 1.0  # m: barrier value of an inactive row, whose constraint 0 . dq <= gain * 1 m holds for any motion
JACOBIAN_NORM_FLOOR = 1e-12  # (m/rad)^2: below this |J|^2, pink's safe-displacement weight gain/|J|^2 is skipped


class SceneBarrier(Barrier):
    r"""Self-collision (and static obstacle) barrier on an spq Scene, in pink's Barrier interface.

    Barrier values h(q) = d_p(q) - d_min (m) for the ``n_collision_pairs`` closest pairs p of the
    scene, by increasing distance, and their Jacobian rows ∂d_p/∂q in pinocchio's velocity columns
    (``configuration.model.nv``; see :mod:`spq.control.joint_map` for the column order and the
    floating base). pink turns them into the rows -J Δq / dt <= gain h, i.e. ḣ >= -gain h, as for
    its own SelfCollisionBarrier, whose values (d - d_min of the closest pairs, from coal through
    pinocchio) and Jacobians (nᵀ(J_1(p_1) - J_2(p_2))) these are.

    Parameters
    ----------
    scene : spq.scene.Scene
        The robot's bodies and the pairs to watch; the same robot as pink's model (joints matched by
        name). Its warm starts carry from one call to the next (``coherent=True``).
    n_collision_pairs : int
        Rows of the barrier (pink's barriers have a fixed dimension), 1 <= n <= len(scene.pairs).
    gain : float or (n,) array
        Barrier gain (1/s in ḣ >= -gain h), > 0.
    safe_displacement_gain : float
        pink's safe-displacement cost weight (>= 0); 0 leaves the cost out.
    d_min : float
        Distance the barrier keeps between bodies (m), >= 0.
    detection_distance : float or None
        Pairs whose bounding spheres are farther apart than this (m) are not queried and give no row.
        None (default) queries every pair, as pink's barrier does. Must be > d_min.
    signed : bool
        Query overlaps with their penetration depth (value < -d_min, a row that pushes apart).

    Pairs whose query failed (or, unsigned, overlap) give no row; they are listed in ``failed``
    after each evaluation. Rows short of n (fewer pairs queried than rows) are inactive: zero Jacobian,
    value INACTIVE_VALUE. After each
    evaluation ``pairs`` holds the scene pair index of each row (-1 for an inactive one) and
    ``distance`` their distances (m).
    """

    def __init__(self, scene, n_collision_pairs: int, gain=1.0, safe_displacement_gain: float = 1.0,
                 d_min: float = 0.02, detection_distance: float | None = None, signed: bool = True):
        npairs = len(scene.pairs)
        if isinstance(n_collision_pairs, bool) or not isinstance(n_collision_pairs, (int, np.integer)) or not (
                1 <= n_collision_pairs <= npairs):
            raise ValueError(f"n_collision_pairs must be an integer in 1..{npairs} (the scene's pairs); "
                             f"got {n_collision_pairs!r}")
        d_min = float(d_min)
        if not (math.isfinite(d_min) and d_min >= 0.0):
            raise ValueError(f"d_min must be a finite distance >= 0 (m); got {d_min}")
        gains = np.asarray(gain, dtype=np.float64)
        if gains.shape not in ((), (int(n_collision_pairs),)) or not (np.isfinite(gains).all() and (gains > 0).all()):
            raise ValueError(f"gain must be a finite number > 0 or {n_collision_pairs} of them; got {gain!r}")
        sdg = float(safe_displacement_gain)
        if not (math.isfinite(sdg) and sdg >= 0.0):
            raise ValueError(f"safe_displacement_gain must be a finite number >= 0; got {safe_displacement_gain}")
        if detection_distance is not None:
            detection_distance = float(detection_distance)
            if not (math.isfinite(detection_distance) and detection_distance > d_min):
                raise ValueError(f"detection_distance must be None or a finite distance > d_min = {d_min} (m); "
                                 f"got {detection_distance}")
        super().__init__(dim=int(n_collision_pairs), gain=gains.copy() if gains.shape else float(gains),
                         safe_displacement_gain=sdg)
        self.scene = scene
        self.d_min = d_min
        self.detection_distance = detection_distance
        self.signed = bool(signed)
        self.pairs = np.full(self.dim, -1, dtype=np.int64)
        self.distance = np.full(self.dim, np.nan)
        self.failed = np.zeros(0, dtype=np.int64)
        self._maps: dict = {}
        self._cached = None  # (model, q copy, values, jacobian)

    def joint_map(self, model):
        """The JointMap between pinocchio model ``model`` and the scene (built once per model)."""
        key = id(model)
        if key not in self._maps:
            self._maps[key] = (model, pinocchio_joint_map(self.scene, model))
        return self._maps[key][1]

    def _evaluate(self, configuration):
        model, q_pin = configuration.model, np.asarray(configuration.q)
        c = self._cached
        if c is not None and c[0] is model and np.array_equal(c[1], q_pin):
            return c[2], c[3]
        jmap = self.joint_map(model)
        q = jmap.update_scene(self.scene, q_pin)
        prune = self.detection_distance
        result = self.scene.distances(q, coherent=True, prune=prune, signed=self.signed, jacobian=True)
        d, jac = result.distance, result.jacobian
        failed = (result.status_code == FAILED) | ~np.isfinite(jac).all(axis=1)  # a pruned pair's row is 0
        self.failed = np.flatnonzero(failed).astype(np.int64)
        valid = np.flatnonzero(~failed & ~result.pruned)
        chosen = valid[np.argsort(d[valid], kind="stable")[:self.dim]]
        k = len(chosen)
        values = np.empty(self.dim)
        jacobian = np.zeros((self.dim, model.nv))
        values[:k] = d[chosen] - self.d_min
        if k:
            jacobian[:k] = jmap.columns(jac[chosen], q_pin)
        self.pairs = np.full(self.dim, -1, dtype=np.int64)
        self.pairs[:k] = chosen
        self.distance = np.full(self.dim, np.nan)
        self.distance[:k] = d[chosen]
        values[k:] = INACTIVE_VALUE
        self._cached = (model, q_pin.copy(), values, jacobian)
        return values, jacobian

    def compute_barrier(self, configuration) -> np.ndarray:
        """h(q) (n,) = d - d_min (m) of the n closest pairs, by increasing distance."""
        return self._evaluate(configuration)[0].copy()

    def compute_jacobian(self, configuration) -> np.ndarray:
        """∂h/∂q (n, nv) in pinocchio's velocity columns, rows as :meth:`compute_barrier`'s."""
        return self._evaluate(configuration)[1].copy()

    def compute_qp_objective(self, configuration):
        """pink's safe-displacement cost; left out (zeros) when every row is inactive, where pink's
        weight gain / |J|^2 would divide by zero."""
        jacobian = self._evaluate(configuration)[1]
        if self.safe_displacement_gain > 0.0 and float((jacobian ** 2).sum()) < JACOBIAN_NORM_FLOOR:
            nv = configuration.model.nv
            return np.zeros((nv, nv)), np.zeros(nv)
        return super().compute_qp_objective(configuration)

    def __repr__(self) -> str:
        return (f"SceneBarrier(n_collision_pairs={self.dim}, d_min={self.d_min}, "
                f"detection_distance={self.detection_distance}, scene pairs={len(self.scene.pairs)})")
