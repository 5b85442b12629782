"""The velocity damper of Faverjon and Tournassoud (as in mc_rtc / tvm) as linear rows on the joint velocities.

For a pair of bodies at distance d closer than the interaction distance ``di``, the damper asks the
distance not to shrink faster than a rate that vanishes at the safety distance ``ds``:

    ḋ >= -ξ (d - ds) / (di - ds),

and since ḋ = (∂d/∂q) q̇, each such pair gives one row of ``G q̇ <= h`` with

    G = -∂d/∂q,    h = ξ (d - ds) / (di - ds).

Units: metres, seconds; ξ in m/s (the fraction (d − ds)/(di − ds) has no unit; h in m/s, G in m per unit of each velocity column). The columns
are the scene's: the joints in q order (``scene.model.joint_names``), after the base twist's 6
columns for a floating-base scene (see :meth:`spq.scene.Scene.distances`). The rows feed a
hand-written QP directly; :mod:`spq.control.limits` turns them into pink's and mink's limits and
:mod:`spq.control.joint_map` into another model's velocity columns. For instance, with qpsolvers::

    damper = VelocityDamper(scene, di=0.05, ds=0.01, xi=0.5)
    rows = damper.rows(q)                      # G (k, nv), h (k,)
    qdot = qpsolvers.solve_qp(P, c, G=np.vstack([rows.G, G_limits]), h=np.concatenate([rows.h, h_limits]),
                              solver="daqp")
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from spq.kernels import damper as kdamper
from spq.scene import SceneDistances


@dataclass(frozen=True, eq=False)
class DamperRows:
    """The damper's rows at one configuration: ``G @ qdot <= h``, one row per pair closer than di.

    G: (k, nv) float64, -∂d/∂q of each pair (m per unit velocity of each column).
    h: (k,) float64, ξ (d - ds) / (di - ds) (m/s); negative for a pair closer than ds (the row then
    asks the pair to move apart).
    pairs: (k,) int64, indices into ``scene.pairs``, by increasing distance.
    distance: (k,) float64, their distances (m; negative for an overlap when signed).
    jacobian: (k, nv) float64, ∂d/∂q (= -G).
    failed: (f,) int64, indices into ``scene.pairs`` of the pairs whose query failed or whose
    Jacobian is undefined (an overlap queried without ``signed``): they give no row, and are listed
    here so that a caller can see the constraint it lacks.
    """

    G: np.ndarray
    h: np.ndarray
    pairs: np.ndarray
    distance: np.ndarray
    jacobian: np.ndarray
    failed: np.ndarray

    @property
    def n_failed(self) -> int:
        """How many pairs gave no row because their query failed (see ``failed``)."""
        return len(self.failed)

    def __len__(self) -> int:
        return len(self.h)

    @classmethod
    def _of(cls, G, h, pairs, distance, jacobian, failed) -> "DamperRows":
        # the fields set without the frozen dataclass's __init__ (six object.__setattr__ calls): the
        # same object for a third of the time, which a small arm's damper call pays every control step
        rows = object.__new__(cls)
        rows.__dict__.update(G=G, h=h, pairs=pairs, distance=distance, jacobian=jacobian, failed=failed)
        return rows


def _finite(value, name: str) -> float:
    try:
        out = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a finite number; got {value!r}") from None
    if not math.isfinite(out):
        raise ValueError(f"{name} must be a finite number; got {out}")
    return out


def check_damper_parameters(di, ds, xi) -> tuple[float, float, float]:
    """(di, ds, xi) as floats, or ValueError naming the admissible range: 0 <= ds < di (m), xi > 0 (m/s)."""
    di, ds, xi = _finite(di, "di"), _finite(ds, "ds"), _finite(xi, "xi")
    if not 0.0 <= ds < di:
        raise ValueError(f"the damper needs 0 <= ds < di (m); got ds={ds}, di={di}")
    if xi <= 0.0:
        raise ValueError(f"the damper gain xi must be > 0 (m/s); got {xi}")
    return di, ds, xi


def damper_rows(result, di: float, ds: float, xi: float) -> DamperRows:
    """The damper's rows from one configuration's scene result (a SceneDistances with ``jacobian``).

    A pair gives a row when it is queried (not pruned) and d < di; a pair whose status is 'failed',
    or whose Jacobian row is not finite (an overlap queried without ``signed``), gives none and is
    listed in ``failed``."""
    di, ds, xi = check_damper_parameters(di, ds, xi)
    if not isinstance(result, SceneDistances):
        raise ValueError(f"damper_rows takes a scene's result (spq.Scene.distances); got {type(result).__name__}")
    if result.jacobian is None:
        raise ValueError("the scene result has no Jacobian: query it with scene.distances(q, jacobian=True)")
    return _damper_rows(result, di, ds, xi)


def _damper_rows(result, di: float, ds: float, xi: float) -> DamperRows:
    # one compiled pass (spq.kernels.damper) over the sweep's own result rows
    return DamperRows._of(*kdamper.damper_rows(result._rows, result.jacobian, di, ds, xi))


class VelocityDamper:
    """Velocity-damper rows ``G q̇ <= h`` from an spq Scene (see the module docstring).

    Parameters
    ----------
    scene : spq.scene.Scene
        The bodies and pairs; its warm starts are used and updated (``coherent=True``) from one
        call to the next, as along a controller's trajectory.
    di : float
        Interaction distance (m): pairs closer than this get a row. Pairs whose bounding spheres
        are farther apart are not queried at all (``prune=di``).
    ds : float
        Safety distance (m), 0 <= ds < di: the distance the damper lets the pair approach, never reach.
    xi : float
        Damping gain (m/s), > 0: at distance d the pair may approach at up to xi (d - ds)/(di - ds) m/s.
    signed : bool
        Query overlaps with their penetration depth (negative d, a row pushing the pair apart);
        without it an overlapping pair has no Jacobian and is reported in ``DamperRows.failed``.
    """

    def __init__(self, scene, di: float = 0.05, ds: float = 0.01, xi: float = 0.5, signed: bool = True):
        self.di, self.ds, self.xi = check_damper_parameters(di, ds, xi)
        self.scene = scene
        self.signed = bool(signed)
        self.last_result = None  # the SceneDistances of the last call to rows()

    def rows(self, q) -> DamperRows:
        """The rows at joint configuration q (ndof,) in the scene's q order (radians / metres).
        ValueError for a q the scene rejects (shape, NaN, outside the limits)."""
        result = self.scene.distances(q, coherent=True, prune=self.di, signed=self.signed, jacobian=True)
        self.last_result = result
        return _damper_rows(result, self.di, self.ds, self.xi)

    def __repr__(self) -> str:
        return (f"VelocityDamper(di={self.di}, ds={self.ds}, xi={self.xi}, signed={self.signed}, "
                f"pairs={len(self.scene.pairs)})")
