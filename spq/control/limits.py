"""The velocity damper as a pink or mink limit: rows ``G Δq <= h`` on the displacement Δq = v dt.

pink (``pink.solve_ik``) and mink (``mink.solve_ik``) both solve for the displacement Δq in the
tangent space over one step dt and return v = Δq / dt; a limit gives rows ``G Δq <= h``. The damper's
rows ``G q̇ <= h`` (:class:`~spq.control.damper.VelocityDamper`) become ``G Δq <= dt h`` (the same
scaling as pink's and mink's own velocity limits), with G in the model's velocity columns
(:mod:`spq.control.joint_map`).

Usage (pink)::

    from spq.control import DamperLimit
    limit = DamperLimit(scene, di=0.05, ds=0.01, xi=0.5)                  # backend="pink"
    model = configuration.model
    v = pink.solve_ik(configuration, tasks, dt, solver="daqp",
                      limits=[limit, model.configuration_limit, model.velocity_limit])

(``limits=`` replaces pink's default joint limits, hence the two listed after the damper; without
a velocity limit the first-order rows can be stepped over.) mink: ``DamperLimit(scene, ...,
backend="mink")`` and ``mink.solve_ik(configuration, tasks, dt, "daqp", limits=[limit,
mink.ConfigurationLimit(model), mink.VelocityLimit(model, ...)])``. pink or mink is imported when
a limit is made, not before.
"""

from __future__ import annotations

import math

import numpy as np

from spq.control.damper import VelocityDamper

BACKENDS = ("pink", "mink")
_CLASSES: dict = {}


def _backend_base(backend: str):
    """The abstract Limit class of pink or mink, imported now, with a clear message if missing."""
    if backend == "pink":
        try:
            from pink.limits import Limit
        except ImportError as exc:
            raise ImportError(f"DamperLimit(backend='pink') needs pink: pip install pin-pink ({exc})") from None
        return Limit
    try:
        from mink.limits import Limit
    except ImportError as exc:
        raise ImportError(f"DamperLimit(backend='mink') needs mink: pip install mink ({exc})") from None
    return Limit


def _backend_class(backend: str):
    if backend not in BACKENDS:
        raise ValueError(f"unknown DamperLimit backend {backend!r}; choose one of {list(BACKENDS)}")
    if backend not in _CLASSES:
        base = _backend_base(backend)
        name = f"{backend.capitalize()}DamperLimit"
        _CLASSES[backend] = type(name, (DamperLimit, base), {"__module__": __name__, "_backend": backend, "__doc__": (
            f"DamperLimit as a {backend} Limit (see DamperLimit).")})
    return _CLASSES[backend]


class DamperLimit:
    """Velocity-damper rows from an spq Scene, as a pink or mink ``Limit``.

    ``DamperLimit(scene, ...)`` returns an instance of a subclass of both this class and the
    backend's ``Limit`` (``pink.limits.Limit`` or ``mink.limits.Limit``), created when first needed.

    Parameters
    ----------
    scene : spq.scene.Scene
        The same robot as the controller's model (joints matched by name).
    di, ds, xi, signed :
        The damper's interaction distance (m), safety distance (m), gain (m/s) and overlap handling,
        as in :class:`~spq.control.damper.VelocityDamper`.
    backend : 'pink' or 'mink'
        pink: ``compute_qp_inequalities`` reads a pink Configuration (pinocchio model) and returns
        ``(G, h)``, or None without a pair closer than di; mink: a mink Configuration (MuJoCo model)
        and a ``mink.limits.Constraint`` (inactive without a pair closer than di).

    After each call, ``last_rows`` holds the DamperRows in the scene's columns (its ``failed``: the
    pairs that gave no row because their query failed).
    """

    _backend = None  # set on the backend's subclass

    def __new__(cls, *args, backend: str = "pink", **kwargs):
        if cls is DamperLimit:
            cls = _backend_class(backend)
        return super().__new__(cls)

    def __init__(self, scene, di: float = 0.05, ds: float = 0.01, xi: float = 0.5, signed: bool = True,
                 backend: str = "pink"):
        if backend != self._backend:
            raise ValueError(f"{type(self).__name__} is the {self._backend!r} backend's class; got backend={backend!r}")
        self.damper = VelocityDamper(scene, di=di, ds=ds, xi=xi, signed=signed)
        self.scene = scene
        self.backend = backend
        self.last_rows = None
        self._maps: dict = {}

    def joint_map(self, model):
        """The JointMap between the backend's model (pinocchio Model or MuJoCo MjModel) and the scene."""
        key = id(model)
        if key not in self._maps:
            from spq.control.joint_map import mujoco_joint_map, pinocchio_joint_map

            make = pinocchio_joint_map if self.backend == "pink" else mujoco_joint_map
            self._maps[key] = (model, make(self.scene, model))
        return self._maps[key][1]

    def rows(self, configuration, dt: float):
        """(G (k, nv), h (k,)) with G Δq <= h for the backend's configuration over a step dt (s)."""
        dt = float(dt)
        if not (math.isfinite(dt) and dt > 0.0):
            raise ValueError(f"dt must be a finite time step > 0 (s); got {dt}")
        jmap = self.joint_map(configuration.model)
        q_other = np.asarray(configuration.q)
        q = jmap.update_scene(self.scene, q_other)
        rows = self.damper.rows(q)
        self.last_rows = rows
        return jmap.columns(rows.G, q_other), dt * rows.h

    def compute_qp_inequalities(self, configuration, dt: float):
        """The damper's rows G Δq <= h (Δq = v dt, the displacement pink and mink solve for)."""
        G, h = self.rows(configuration, dt)
        if self.backend == "mink":
            from mink.limits import Constraint

            return Constraint() if len(h) == 0 else Constraint(G=G, h=h)
        return None if len(h) == 0 else (G, h)

    def __repr__(self) -> str:
        d = self.damper
        return f"DamperLimit(di={d.di}, ds={d.ds}, xi={d.xi}, backend={self.backend!r})"
