"""Robot kinematics: a tree of rigid links as flat arrays, joint limits, and compiled forward kinematics.

A :class:`RobotModel` is data (read one from a URDF with :func:`spq.io.urdf.read_urdf`); its world
link poses come from the kernel :func:`spq.kernels.kinematics.forward_kinematics`, which the same
arrays feed for one configuration, a batch, or a robot scene. Units: metres and radians. Frames:
link poses are 4x4 homogeneous transforms, link frame -> world (the URDF link frame, not the
inertial frame); geometry origins are in the link frame.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from spq.kernels.kinematics import (CONTINUOUS, FIXED, PRISMATIC, REVOLUTE, forward_kinematics, forward_kinematics_many,
                                    within_limits)
from spq.validation import as_pose, as_poses

JOINT_TYPE_NAMES = {FIXED: "fixed", REVOLUTE: "revolute", CONTINUOUS: "continuous", PRISMATIC: "prismatic"}
LIMIT_SLACK = 1e-12  # rad or m: a value this far outside [lower, upper] still passes (rounding of limits)
CONTINUOUS_LIMIT = np.pi  # rad: continuous joints get [-pi, pi], which reaches every rotation once
AXIS_TOL = 1e-9  # max | |axis| - 1 | for a joint axis held by a RobotModel (URDF axes are normalised on reading)


class MeshGeometry(NamedTuple):
    """A mesh attached to a link: ``filename`` as written in the URDF (``package://...`` or relative
    to the URDF's folder), ``origin`` (4, 4) mesh frame in the link frame, ``scale`` (3,) applied to
    the mesh vertices before ``origin``."""

    filename: str
    origin: np.ndarray
    scale: np.ndarray


class PrimitiveGeometry(NamedTuple):
    """A URDF primitive attached to a link, centred at ``origin`` (4, 4, in the link frame).

    ``kind`` and ``size`` (metres): 'box' (3,) full edge lengths; 'sphere' (1,) radius; 'cylinder'
    (2,) radius and length, axis along z of ``origin``; 'capsule' (2,) radius and the length of its
    segment (the cylinder between the two half balls, as in coal and pinocchio), axis along z. URDF
    has no capsule: read_urdf never makes one, a caller may (pinocchio's ``<collision_checking>``)."""

    kind: str
    size: np.ndarray
    origin: np.ndarray


@dataclass(frozen=True, eq=False)
class RobotModel:
    """A robot as a tree of links in topological order (every link after its parent; link 0 is the root).

    Per link (n = nlinks), the joint connecting it to its parent (for the root: none, FIXED,
    identity origin):

    - ``link_names`` (n,), ``link_joint_names`` (n,): the link's name and its joint's name ('' for the root).
    - ``parent`` int64 (n,): index of the parent link, -1 for the root.
    - ``joint_type`` int64 (n,): FIXED, REVOLUTE, CONTINUOUS or PRISMATIC.
    - ``joint_origin`` float64 (n, 4, 4): joint frame in the parent link frame (URDF origin xyz/rpy).
    - ``joint_axis`` float64 (n, 3): unit axis in the joint frame (x for fixed joints).
    - ``q_index`` int64 (n,): index into q of the value that drives the joint, -1 if fixed.
    - ``q_multiplier``, ``q_offset`` float64 (n,): joint value = q_multiplier * q[q_index] + q_offset;
      1 and 0 except for joints that mimic another (URDF ``<mimic>``), which share its q entry.

    Per degree of freedom (ndof, the order of q): ``joint_names``, and ``lower``, ``upper`` float64
    (radians or metres) from the URDF limits; continuous joints get [-pi, pi]. The limits of
    mimicking joints are not checked (the URDF's limits are expected to agree with the master's).

    ``link_geometry`` (n,): per link, a tuple of :class:`MeshGeometry` / :class:`PrimitiveGeometry`
    from the link's collision elements if it has any, else its visual elements.
    ``source``: the file the model was read from ('' if built in memory).

    Arrays are read-only; the model is immutable.
    """

    name: str
    link_names: tuple
    link_joint_names: tuple
    parent: np.ndarray
    joint_type: np.ndarray
    joint_origin: np.ndarray
    joint_axis: np.ndarray
    q_index: np.ndarray
    q_multiplier: np.ndarray
    q_offset: np.ndarray
    joint_names: tuple
    lower: np.ndarray
    upper: np.ndarray
    link_geometry: tuple
    source: str = ""

    def __post_init__(self):
        n = len(self.link_names)
        ndof = len(self.joint_names)
        fields = {
            "parent": (np.int64, (n,)),
            "joint_type": (np.int64, (n,)),
            "joint_origin": (np.float64, (n, 4, 4)),
            "joint_axis": (np.float64, (n, 3)),
            "q_index": (np.int64, (n,)),
            "q_multiplier": (np.float64, (n,)),
            "q_offset": (np.float64, (n,)),
            "lower": (np.float64, (ndof,)),
            "upper": (np.float64, (ndof,)),
        }
        for field, (dtype, shape) in fields.items():
            arr = np.array(getattr(self, field), dtype=dtype)  # a private copy: the caller's array may change
            if arr.shape != shape:
                raise ValueError(f"RobotModel.{field} must have shape {shape}; got {arr.shape}")
            arr.setflags(write=False)
            object.__setattr__(self, field, arr)
        for field in ("link_names", "link_joint_names", "joint_names", "link_geometry"):
            object.__setattr__(self, field, tuple(getattr(self, field)))
        if n < 1:
            raise ValueError("RobotModel needs at least one link")
        if len(self.link_joint_names) != n or len(self.link_geometry) != n:
            raise ValueError(f"RobotModel.link_joint_names and link_geometry need one entry per link ({n})")
        if self.parent[0] != -1 or self.joint_type[0] != FIXED or (self.parent[1:] < 0).any():
            raise ValueError("RobotModel link 0 must be the only root (parent -1, FIXED joint)")
        if (self.parent[1:] >= np.arange(1, n)).any():
            bad = int(np.argmax(self.parent[1:] >= np.arange(1, n))) + 1
            raise ValueError(f"RobotModel links must come after their parent; link {self.link_names[bad]!r} does not")
        if not set(np.unique(self.joint_type)) <= set(JOINT_TYPE_NAMES):
            raise ValueError(f"RobotModel.joint_type entries must be in {sorted(JOINT_TYPE_NAMES)}")
        moving = self.joint_type != FIXED
        if (self.q_index[~moving] != -1).any() or (self.q_index[moving] < 0).any() or (self.q_index >= ndof).any():
            raise ValueError(f"RobotModel.q_index must be -1 for fixed joints and in 0..{ndof - 1} otherwise")
        if not (np.isfinite(self.joint_origin).all() and np.isfinite(self.joint_axis).all()):
            raise ValueError("RobotModel joint origins and axes must be finite")
        if (np.abs(np.linalg.norm(self.joint_axis, axis=1) - 1.0) > AXIS_TOL).any():
            raise ValueError("RobotModel.joint_axis rows must be unit vectors")
        as_poses(self.joint_origin, "RobotModel.joint_origin")  # each must be a rigid transform
        if np.isnan(self.lower).any() or np.isnan(self.upper).any() or (self.lower > self.upper).any():
            raise ValueError("RobotModel limits must satisfy lower <= upper")

    @property
    def nlinks(self) -> int:
        return len(self.link_names)

    @property
    def ndof(self) -> int:
        """Length of q: the movable joints that do not mimic another."""
        return len(self.joint_names)

    def link_index(self, name: str) -> int:
        """Index of the link called ``name`` (ValueError if there is none)."""
        try:
            return self.link_names.index(name)
        except ValueError:
            raise ValueError(f"robot {self.name!r} has no link {name!r}") from None

    def check_configuration(self, q) -> np.ndarray:
        """Return q as a fresh float64 (ndof,) array, or raise ValueError for a wrong shape, NaN/inf,
        or a value outside [lower, upper] (by more than LIMIT_SLACK), naming the joint."""
        try:
            arr = np.array(q, dtype=np.float64, copy=True)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"configuration must be an array of {self.ndof} numbers: {exc}") from None
        if arr.shape != (self.ndof,):
            raise ValueError(f"configuration of robot {self.name!r} must have shape ({self.ndof},); got {arr.shape}")
        self._check_values(arr[None], "configuration")
        return arr

    def check_configurations(self, qs) -> np.ndarray:
        """:meth:`check_configuration` for a batch: a fresh float64 (N, ndof) array, or ValueError
        naming the first bad configuration and joint."""
        try:
            arr = np.array(qs, dtype=np.float64, copy=True)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"configurations must be an (N, {self.ndof}) array of numbers: {exc}") from None
        if arr.ndim != 2 or arr.shape[1] != self.ndof:
            raise ValueError(f"configurations of robot {self.name!r} must have shape (N, {self.ndof}); got {arr.shape}")
        self._check_values(arr, "configurations")
        return arr

    def _check_values(self, qs: np.ndarray, what: str) -> None:
        if within_limits(qs, self.lower, self.upper, LIMIT_SLACK):
            return
        # name the first bad value
        bad = ~np.isfinite(qs)
        if bad.any():
            n, k = np.argwhere(bad)[0]
            at = f" {n}" if len(qs) > 1 else ""
            raise ValueError(f"{what}{at}: value of joint {self.joint_names[k]!r} is {float(qs[n, k])}; must be finite")
        out = (qs < self.lower - LIMIT_SLACK) | (qs > self.upper + LIMIT_SLACK)
        if out.any():
            n, k = np.argwhere(out)[0]
            at = f" {n}" if len(qs) > 1 else ""
            raise ValueError(
                f"{what}{at}: value {float(qs[n, k])!r} of joint {self.joint_names[k]!r} is outside its limits "
                f"[{float(self.lower[k])!r}, {float(self.upper[k])!r}]"
            )

    def random_configuration(self, rng: np.random.Generator, n: int | None = None) -> np.ndarray:
        """A configuration (ndof,) drawn uniformly within [lower, upper] from the numpy Generator
        ``rng``; with ``n``, n of them as an (n, ndof) array."""
        if not isinstance(rng, np.random.Generator):
            raise ValueError(
                f"rng must be a numpy.random.Generator (np.random.default_rng(seed)); got {type(rng).__name__}"
            )
        size = None if n is None else (int(n), self.ndof)
        return rng.uniform(self.lower, self.upper, size=size)

    def joint_values(self, q) -> np.ndarray:
        """Value of each link's joint (nlinks,) for configuration q: radians or metres, 0 for fixed
        joints, mimic factors applied. Useful to set a simulator joint by joint."""
        q = self.check_configuration(q)
        moving = self.joint_type != FIXED
        values = np.zeros(self.nlinks)
        values[moving] = self.q_multiplier[moving] * q[self.q_index[moving]] + self.q_offset[moving]
        return values

    def link_poses(self, q, base=None) -> np.ndarray:
        """World pose of every link (nlinks, 4, 4), link frame -> world, for configuration q (ndof,).

        ``base`` (4, 4): pose of the root link frame in the world (identity if None). ValueError for a q
        that :meth:`check_configuration` rejects or a base that is not a rigid transform."""
        q = self.check_configuration(q)
        base = np.eye(4) if base is None else as_pose(base, "base")
        out = np.empty((self.nlinks, 4, 4))
        forward_kinematics(*self.kernel_chain(), q, base, out)
        return out

    def link_poses_many(self, qs, base=None) -> np.ndarray:
        """World link poses (N, nlinks, 4, 4) for configurations qs (N, ndof); one compiled loop.

        ``base``: None (identity), one 4x4 pose for every configuration, or (N, 4, 4)."""
        qs = self.check_configurations(qs)
        if base is None:
            bases = np.broadcast_to(np.eye(4), (len(qs), 4, 4))
        else:
            bases = as_poses(base, "base")
            if len(bases) == 1:
                bases = np.broadcast_to(bases[0], (len(qs), 4, 4))
            elif len(bases) != len(qs):
                raise ValueError(f"base must be one pose or one per configuration ({len(qs)}); got {len(bases)}")
        out = np.empty((len(qs), self.nlinks, 4, 4))
        forward_kinematics_many(*self.kernel_chain(), np.ascontiguousarray(qs), np.ascontiguousarray(bases), out)
        return out

    def kernel_chain(self) -> tuple:
        """(parent, joint_type, joint_origin, joint_axis, q_index, q_multiplier, q_offset): the tree as
        the compiled kernels take it (spq.kernels.kinematics, spq.kernels.scene)."""
        return (
            self.parent, self.joint_type, self.joint_origin, self.joint_axis,
            self.q_index, self.q_multiplier, self.q_offset,
        )
