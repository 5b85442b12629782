"""Pinocchio as the robot-scene peer: the scene's bodies as ``coal.Convex`` hulls in a
``pinocchio.GeometryModel`` on the same links, the same pairs, and ``pinocchio.computeDistances``
(forward kinematics, geometry placements and every pair's coal distance in one C++ call).

The kinematic model is pinocchio's own URDF parser (``buildModelFromUrdf``, fixed base), so the
body poses it computes are an independent check of spq's kinematics. A configuration q in spq's
order (``RobotModel.joint_names``) is mapped onto pinocchio's by joint name (a continuous joint
takes cos and sin in pinocchio; a mimic joint gets its master's value through spq's multiplier and
offset). Each pair's coal DistanceRequest can be tuned: GJK tolerance, variant (Default or
Nesterov acceleration) and initial guess (the default, or the previous result's cached guess).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

VARIANTS = {  # name -> (gjk_variant, gjk_initial_guess) names in coal
    "default": ("DefaultGJK", "DefaultGuess"),
    "cached-guess": ("DefaultGJK", "CachedGuess"),
    "nesterov": ("NesterovAcceleration", "DefaultGuess"),
    "nesterov-cached": ("NesterovAcceleration", "CachedGuess"),
}


def _import():
    try:
        import coal
        import pinocchio as pin
    except ImportError as exc:
        raise ImportError(f"the pinocchio peer needs the 'pin' package (pip install pin): {exc}") from None
    return pin, coal


@dataclass
class PinocchioScene:
    model: object
    data: object
    geometry: object
    geometry_data: object
    q_index: np.ndarray  # (n,) pinocchio q index of each driven joint
    q_source: np.ndarray  # (n,) spq q index driving it
    q_multiplier: np.ndarray
    q_offset: np.ndarray
    continuous: np.ndarray  # (n,) bool: cos/sin pair in pinocchio's q
    variant: str = "default"

    def configuration(self, q: np.ndarray) -> np.ndarray:
        """pinocchio's q for spq's q (radians / metres)."""
        pin, _ = _import()
        out = pin.neutral(self.model)
        values = self.q_multiplier * np.asarray(q, dtype=np.float64)[self.q_source] + self.q_offset
        plain = ~self.continuous
        out[self.q_index[plain]] = values[plain]
        out[self.q_index[self.continuous]] = np.cos(values[self.continuous])
        out[self.q_index[self.continuous] + 1] = np.sin(values[self.continuous])
        return out

    def distances(self, q_pin: np.ndarray) -> np.ndarray:
        """Every pair's coal distance (m; negative: penetration when signed distance is on) at a
        configuration already in pinocchio's order."""
        pin, _ = _import()
        pin.computeDistances(self.model, self.data, self.geometry, self.geometry_data, q_pin)
        return np.array([r.min_distance for r in self.geometry_data.distanceResults])

    def run(self, qs_pin) -> None:
        """One computeDistances call per configuration (rows of qs_pin, pinocchio's order), in order:
        what the benchmarks time."""
        pin, _ = _import()
        model, data, geometry, gdata = self.model, self.data, self.geometry, self.geometry_data
        compute = pin.computeDistances
        for q in qs_pin:
            compute(model, data, geometry, gdata, q)

    def seconds(self, qs_pin: list, repeats: int) -> float:
        """Best of ``repeats`` runs of :meth:`run`."""
        best = np.inf
        for _ in range(repeats):
            start = time.perf_counter()
            self.run(qs_pin)
            best = min(best, time.perf_counter() - start)
        return best


def build(scene, urdf, variant: str = "default", tolerance: float = 1e-6,
          stp_shapes: dict | None = None) -> PinocchioScene:
    """The pinocchio peer of an spq Scene read from ``urdf``: its bodies' hulls (PCH; exact primitives
    where the scene has them, see coal_geometry) on the same links and offsets, its pairs.
    ``variant``: a key of VARIANTS; ``tolerance``: coal's gjk_tolerance (m).

    stp_shapes: None, or {body index: coal shape} from :func:`stp_mesh_shapes`: then where a pair's side
    is an STP-BV (Scene.pair_kinds), pinocchio gets that body's STP-BV mesh as a second geometry object
    on the same link, so that each pair compares what spq's pair compares, up to the mesh's error."""
    pin, coal = _import()
    if variant not in VARIANTS:
        raise ValueError(f"unknown pinocchio variant {variant!r}; choose one of {sorted(VARIANTS)}")
    model = pin.buildModelFromUrdf(str(urdf))
    geometry = pin.GeometryModel()
    placements = []
    for body in scene.bodies:
        link = scene.model.link_names[body.link]
        # a link's frame is a BODY frame: a joint of the same name has a frame too (anymal's LF_HAA)
        if not model.existFrame(link, pin.FrameType.BODY):
            raise ValueError(f"pinocchio's model of {urdf} has no link frame {link!r}")
        fid = model.getFrameId(link, pin.FrameType.BODY)
        frame = model.frames[fid]
        placement = frame.placement * pin.SE3(body.offset[:3, :3].copy(), body.offset[:3, 3].copy())
        geometry.addGeometryObject(pin.GeometryObject(body.name, frame.parentJoint, fid, placement,
                                                      coal_geometry(body)))
        placements.append((frame.parentJoint, fid, placement))
    objects = {i: geometry.addGeometryObject(pin.GeometryObject(f"{scene.bodies[i].name}#stp", *placements[i], shape))
               for i, shape in (stp_shapes or {}).items()}
    for (a, b), sides in zip(np.asarray(scene.pairs).tolist(), scene.pair_kinds):
        a, b = (objects.get(i, i) if side == "stp" else i for i, side in zip((a, b), sides))
        geometry.addCollisionPair(pin.CollisionPair(int(a), int(b)))
    gdata = pin.GeometryData(geometry)
    gjk_variant, guess = VARIANTS[variant]
    for request in gdata.distanceRequests:
        request.gjk_tolerance = tolerance
        request.gjk_variant = getattr(coal.GJKVariant, gjk_variant)
        request.gjk_initial_guess = getattr(coal.GJKInitialGuess, guess)
    rm = scene.model
    rows = []
    for li in range(rm.nlinks):
        if rm.q_index[li] < 0:
            continue
        name = rm.link_joint_names[li]
        if not model.existJointName(name):
            raise ValueError(f"pinocchio's model of {urdf} has no joint {name!r}")
        joint = model.joints[model.getJointId(name)]
        rows.append((joint.idx_q, rm.q_index[li], rm.q_multiplier[li], rm.q_offset[li], joint.nq == 2))
    idx, src, mult, off, cont = (np.array(c) for c in zip(*rows))
    return PinocchioScene(model, model.createData(), geometry, gdata, idx.astype(np.int64), src.astype(np.int64),
                          mult.astype(np.float64), off.astype(np.float64), cont.astype(bool), variant)


def stp_mesh_shapes(scene, rel_tolerance: float) -> tuple[dict, dict]:
    """({body index: coal.Convex}, {body index: certified error in m}) for the bodies that are an STP
    side of some pair of ``scene``: their STP-BVs' certified meshes (STPBV.to_mesh: inside the STP-BV,
    within rel_tolerance times its bounding radius of it, in the hull's frame). A body without an
    STP-BV (an exact sphere) is left out and keeps its own shape. The first dict is :func:`build`'s
    stp_shapes."""
    from harness.engines.coal_engine import convex_from_mesh

    stp_sides = {i for pair, sides in zip(np.asarray(scene.pairs).tolist(), scene.pair_kinds)
                 for i, side in zip(pair, sides) if side == "stp"}
    shapes, errors = {}, {}
    for i in sorted(stp_sides):
        stp = scene.bodies[i].stp
        if stp is None:
            continue
        mesh = stp.to_mesh(rel_tolerance * stp.bounding_radius())
        shapes[i] = convex_from_mesh(np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces))
        errors[i] = float(mesh.metadata["max_error"])
    return shapes, errors


def coal_geometry(body):
    """coal's shape for a scene body, in the body's hull frame: its exact primitive where it has one
    (coal.Sphere, coal.Box, coal.Capsule: what spq queries in place of the hull), else its hull as a
    coal.Convex."""
    _, coal = _import()
    from spq.shapes.primitives import Box, Capsule, Sphere

    shape = body.shape
    if isinstance(shape, Sphere):
        return coal.Sphere(shape.radius)
    if isinstance(shape, Box):
        return coal.Box(*(2.0 * shape.half_extents))  # coal takes the full edge lengths
    if isinstance(shape, Capsule):
        return coal.Capsule(shape.radius, 2.0 * shape.half_length)  # coal takes the segment's full length
    from harness.engines.coal_engine import convex_from_mesh

    return convex_from_mesh(np.asarray(body.hull.vertices, dtype=np.float64), np.asarray(body.hull.faces))


def version() -> str:
    pin, coal = _import()
    return f"pin {pin.__version__}, coal {coal.__version__}"
