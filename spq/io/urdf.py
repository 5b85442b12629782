"""Reader for URDF robot descriptions: :func:`read_urdf` gives a :class:`spq.kinematics.RobotModel`.

Parsing is yourdfpy's (no meshes are loaded: mesh files named ``package://...`` often do not exist
locally, and kinematics does not need them); this module turns its tree into the model's flat
arrays in topological order and checks what the kinematics relies on. Supported joints: fixed,
revolute, continuous, prismatic; floating and planar joints are refused. Units: metres, radians.
"""

from __future__ import annotations

import contextlib
import logging
from pathlib import Path

import numpy as np

from spq.kinematics import (
    CONTINUOUS,
    CONTINUOUS_LIMIT,
    FIXED,
    PRISMATIC,
    REVOLUTE,
    MeshGeometry,
    PrimitiveGeometry,
    RobotModel,
)

JOINT_TYPES = {"fixed": FIXED, "revolute": REVOLUTE, "continuous": CONTINUOUS, "prismatic": PRISMATIC}
DEFAULT_AXIS = np.array([1.0, 0.0, 0.0])  # the URDF default; also stored for fixed joints, where it is unused
AXIS_MIN_NORM = 1e-12  # an axis shorter than this has no direction to normalise


def read_urdf(path, follow_mimic: bool = True) -> RobotModel:
    """Read the URDF file ``path`` into a :class:`RobotModel`.

    Links are ordered depth-first from the root, children in the order of their joints in the file;
    q follows the same order. With ``follow_mimic`` (default) a joint with a ``<mimic>`` element has
    no entry in q: its value is multiplier * (its master's value) + offset, as in ROS. Without it,
    every movable joint has its own entry in q (what pybullet does, which ignores ``<mimic>``).

    Raises ValueError naming the file and the problem: missing or unreadable file, not a URDF, a
    joint type other than fixed/revolute/continuous/prismatic, a revolute or prismatic joint
    without ``<limit>``, lower > upper, a zero axis, links that do not form one tree, a mimic of an
    unknown or fixed joint, or a geometry other than mesh/box/sphere/cylinder.
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"cannot read URDF {path}: no such file")
    robot = _parse(path)
    return _build_model(robot, path, follow_mimic)


def _parse(path: Path):
    """yourdfpy's Robot for ``path``, or ValueError with yourdfpy's complaint."""
    import yourdfpy  # imported here: only URDF reading needs it

    with _quiet_logger("yourdfpy") as messages:
        try:
            urdf = yourdfpy.URDF.load(
                str(path),
                build_scene_graph=False,
                build_collision_scene_graph=False,
                load_meshes=False,
                load_collision_meshes=False,
            )
        except Exception as exc:  # yourdfpy raises whatever its XML walk hits (TypeError, KeyError, lxml errors)
            # the first logged message is lxml's (line and column); the exception is where yourdfpy gave up
            detail = "; ".join([*messages[:1], f"{type(exc).__name__}: {exc}"])
            raise ValueError(f"{path} is not a readable URDF file: {detail}") from None
    robot = urdf.robot
    if robot is None or not robot.links:
        raise ValueError(f"{path} is not a URDF file: no <robot> with <link> elements")
    return robot


@contextlib.contextmanager
def _quiet_logger(name: str):
    """Collect the messages of logger ``name`` instead of printing them (yourdfpy logs parse errors
    before falling back to a recovering parser; they belong in our ValueError, not on stderr)."""
    logger = logging.getLogger(name)
    messages: list[str] = []

    class Collect(logging.Handler):
        def emit(self, record):
            messages.append(record.getMessage())

    handler = Collect(level=logging.WARNING)
    saved = logger.propagate
    logger.addHandler(handler)
    logger.propagate = False
    try:
        yield messages
    finally:
        logger.removeHandler(handler)
        logger.propagate = saved


def _build_model(robot, path: Path, follow_mimic: bool) -> RobotModel:
    def fail(what: str):
        raise ValueError(f"{path}: {what}")

    link_by_name = {}
    for link in robot.links:
        if link.name in link_by_name:
            fail(f"two links are called {link.name!r}")
        link_by_name[link.name] = link
    joint_by_name, joint_by_child, children = {}, {}, {name: [] for name in link_by_name}
    for joint in robot.joints:
        if joint.name in joint_by_name:
            fail(f"two joints are called {joint.name!r}")
        joint_by_name[joint.name] = joint
        if joint.type not in JOINT_TYPES:
            fail(f"joint {joint.name!r} has type {joint.type!r}; supported: {', '.join(JOINT_TYPES)}")
        for end in (joint.parent, joint.child):
            if end not in link_by_name:
                fail(f"joint {joint.name!r} names link {end!r}, which is not defined")
        if joint.child in joint_by_child:
            first = joint_by_child[joint.child].name
            fail(f"link {joint.child!r} is the child of two joints ({first!r}, {joint.name!r})")
        joint_by_child[joint.child] = joint
        children[joint.parent].append(joint.child)

    roots = [name for name in link_by_name if name not in joint_by_child]
    if len(roots) != 1:
        fail(f"links must form one tree with one root; roots found: {roots}")
    order = _depth_first(roots[0], children)
    if len(order) != len(link_by_name):
        unreachable = sorted(set(link_by_name) - set(order))
        fail(f"links not reachable from root {roots[0]!r} (a joint cycle?): {unreachable}")

    n = len(order)
    parent = np.full(n, -1, dtype=np.int64)
    joint_type = np.zeros(n, dtype=np.int64)
    joint_origin = np.tile(np.eye(4), (n, 1, 1))
    joint_axis = np.tile(DEFAULT_AXIS, (n, 1))
    link_joint_names = [""] * n
    index = {name: i for i, name in enumerate(order)}
    for i, name in enumerate(order[1:], start=1):
        joint = joint_by_child[name]
        parent[i] = index[joint.parent]
        joint_type[i] = JOINT_TYPES[joint.type]
        link_joint_names[i] = joint.name
        if joint.origin is not None:
            origin = np.asarray(joint.origin, dtype=np.float64)
            if origin.shape != (4, 4) or not np.isfinite(origin).all():
                fail(f"joint {joint.name!r} has an origin that is not a finite pose")
            joint_origin[i] = origin
        if joint_type[i] != FIXED:
            axis = np.asarray(joint.axis if joint.axis is not None else DEFAULT_AXIS, dtype=np.float64)
            norm = float(np.linalg.norm(axis)) if axis.shape == (3,) else np.nan
            if not (np.isfinite(norm) and norm > AXIS_MIN_NORM):
                fail(f"joint {joint.name!r} has axis {axis}; a movable joint needs a nonzero direction")
            joint_axis[i] = axis / norm  # URDF asks for a unit axis; normalise what is nearly one

    q_index, q_multiplier, q_offset, joint_names, lower, upper = _assign_dofs(
        order, joint_by_child, joint_type, follow_mimic, fail
    )
    geometry = tuple(_link_geometry(link_by_name[name], fail) for name in order)
    return RobotModel(
        name=robot.name or path.stem,
        link_names=tuple(order),
        link_joint_names=tuple(link_joint_names),
        parent=parent,
        joint_type=joint_type,
        joint_origin=joint_origin,
        joint_axis=joint_axis,
        q_index=q_index,
        q_multiplier=q_multiplier,
        q_offset=q_offset,
        joint_names=tuple(joint_names),
        lower=lower,
        upper=upper,
        link_geometry=geometry,
        source=str(path),
    )


def _depth_first(root: str, children: dict) -> list:
    """Link names depth-first from ``root``, children in file order (each link after its parent)."""
    order, stack, seen = [], [root], set()
    while stack:
        name = stack.pop()
        if name in seen:  # only reachable through a cycle, which the caller reports
            continue
        seen.add(name)
        order.append(name)
        stack.extend(reversed(children[name]))
    return order


def _assign_dofs(order, joint_by_child, joint_type, follow_mimic, fail):
    """Entries of q: one per movable joint that does not mimic another (all of them without
    ``follow_mimic``); each link's q index and mimic factors; the limits of each entry."""
    n = len(order)
    q_index = np.full(n, -1, dtype=np.int64)
    q_multiplier = np.ones(n)
    q_offset = np.zeros(n)
    joint_names, lower, upper = [], [], []
    movable = {joint_by_child[name].name: i for i, name in enumerate(order) if joint_type[i] != FIXED}

    def is_mimic(i):
        return follow_mimic and joint_by_child[order[i]].mimic is not None

    for i in range(1, n):
        if joint_type[i] == FIXED or is_mimic(i):
            continue
        joint = joint_by_child[order[i]]
        q_index[i] = len(joint_names)
        joint_names.append(joint.name)
        lo, hi = _limits(joint, joint_type[i], fail)
        lower.append(lo)
        upper.append(hi)
    for i in range(1, n):
        if joint_type[i] == FIXED or not is_mimic(i):
            continue
        # follow the chain of masters (a mimic may mimic a mimic), composing the affine maps
        multiplier, offset, k, seen = 1.0, 0.0, i, []
        while is_mimic(k):
            joint = joint_by_child[order[k]]
            seen.append(joint.name)
            mimic = joint.mimic
            master = mimic.joint
            if master not in movable:
                fail(f"joint {joint.name!r} mimics {master!r}, which is not a movable joint")
            m = 1.0 if mimic.multiplier is None else float(mimic.multiplier)
            o = 0.0 if mimic.offset is None else float(mimic.offset)
            if not (np.isfinite(m) and np.isfinite(o)):
                fail(f"joint {joint.name!r} has a mimic multiplier/offset that is not finite")
            multiplier, offset = multiplier * m, multiplier * o + offset
            k = movable[master]
            if joint_by_child[order[k]].name in seen:
                fail(f"mimic joints form a cycle: {seen}")
        q_index[i], q_multiplier[i], q_offset[i] = q_index[k], multiplier, offset
    return (
        q_index, q_multiplier, q_offset, joint_names,
        np.array(lower, dtype=np.float64), np.array(upper, dtype=np.float64),
    )


def _limits(joint, jtype, fail) -> tuple[float, float]:
    """[lower, upper] of a movable joint: from ``<limit>`` (required by URDF for revolute and
    prismatic, missing attributes are 0 as the spec says), [-pi, pi] for continuous joints."""
    if jtype == CONTINUOUS:
        return -CONTINUOUS_LIMIT, CONTINUOUS_LIMIT
    if joint.limit is None:
        fail(f"joint {joint.name!r} ({joint.type}) has no <limit>, which URDF requires")
    lo = 0.0 if joint.limit.lower is None else float(joint.limit.lower)
    hi = 0.0 if joint.limit.upper is None else float(joint.limit.upper)
    if not (np.isfinite(lo) and np.isfinite(hi) and lo <= hi):
        fail(f"joint {joint.name!r} has limits [{lo}, {hi}]; need finite lower <= upper")
    return lo, hi


def _link_geometry(link, fail) -> tuple:
    """The link's collision geometry, or its visual geometry when it has no collision element."""
    elements = link.collisions or link.visuals
    out = []
    for element in elements:
        origin = np.eye(4) if element.origin is None else np.array(element.origin, dtype=np.float64)
        origin.setflags(write=False)  # the model is immutable, its geometry too
        g = element.geometry
        if g is not None and g.mesh is not None:
            scale = np.broadcast_to(np.asarray(1.0 if g.mesh.scale is None else g.mesh.scale, dtype=np.float64), (3,))
            if not g.mesh.filename or not np.isfinite(scale).all() or (scale == 0.0).any():
                fail(f"link {link.name!r} has a mesh without filename or with scale {scale}")
            scale = scale.copy()
            scale.setflags(write=False)
            out.append(MeshGeometry(g.mesh.filename, origin, scale))
            continue
        if g is not None and g.box is not None:
            kind, size = "box", g.box.size
        elif g is not None and g.sphere is not None:
            kind, size = "sphere", [g.sphere.radius]
        elif g is not None and g.cylinder is not None:
            kind, size = "cylinder", [g.cylinder.radius, g.cylinder.length]
        else:
            fail(f"link {link.name!r} has a geometry that is not a mesh, box, sphere or cylinder")
        try:
            size = np.array(size, dtype=np.float64)
        except (TypeError, ValueError):
            size = np.array([np.nan])
        if not (np.isfinite(size).all() and (size > 0.0).all()):
            fail(f"link {link.name!r} has a {kind} with size {size}; sizes must be finite and > 0")
        size.setflags(write=False)
        out.append(PrimitiveGeometry(kind, size, origin))
    return tuple(out)
