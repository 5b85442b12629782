"""Distances in a controller: velocity-damper rows from an spq Scene, and adapters for pink and mink.

- :class:`VelocityDamper` / :class:`DamperRows`: rows ``G q̇ <= h`` for every pair closer than the
  interaction distance (Faverjon and Tournassoud's damper, as in mc_rtc), for a hand-written QP.
- :class:`DamperLimit`: the same rows as a pink or mink ``Limit`` (``G Δq <= dt h``).
- :class:`SceneBarrier`: a pink ``Barrier`` (pink's SelfCollisionBarrier with spq distances).
- :mod:`spq.control.joint_map`: between pinocchio's or MuJoCo's (q, v) and the scene's q and columns.

pink (``pip install pin-pink``) and mink (``pip install mink``) are optional: they are imported
when SceneBarrier is first named, or a DamperLimit made.
"""

from spq.control.damper import DamperRows, VelocityDamper
from spq.control.joint_map import JointMap, mujoco_joint_map, pinocchio_joint_map
from spq.control.limits import DamperLimit

__all__ = ["DamperLimit", "DamperRows", "JointMap", "SceneBarrier", "VelocityDamper", "mujoco_joint_map",
           "pinocchio_joint_map"]


def __getattr__(name):
    if name == "SceneBarrier":
        from spq.control.pink_barrier import SceneBarrier

        return SceneBarrier
    raise AttributeError(f"module 'spq.control' has no attribute {name!r}")
