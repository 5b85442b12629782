"""Robot scenes: every pair of a robot's bodies, with the bounding volume chosen per pair.

A :class:`Scene` holds a :class:`~spq.kinematics.RobotModel`, its bodies (one convex hull per link
geometry, in metres, in the link frame through the geometry's origin) and the list of pairs to
query. ``scene.distances(q)`` runs forward kinematics and every pair's GJK query in one compiled
call and returns world-frame results.

Bounding-volume policies, per body:

- ``pch``: the polyhedral convex hull; ``stp``: the STP-BV of the hull's vertices with radii r, R;
  ``cse``: the covering superellipsoid fit.
- ``auto``: the body keeps both a PCH and an STP-BV; in each pair the side with fewer STP features
  uses its STP-BV and the other its PCH (the paper's advice: one strictly convex side makes the
  distance gradient continuous, and the PCH side is cheaper). Against a ``pch`` body an ``auto`` body
  uses its STP-BV; against an ``stp`` or ``cse`` body, its PCH.
- ``stp-both`` (scene-wide only): every body uses its STP-BV, for comparison.

A body may carry an exact primitive (``Body.shape``: a Sphere, Box or Capsule, from a URDF read with
``primitives="exact"``): it is queried in place of the hull wherever the policy picks the PCH, and a
sphere also where it picks the STP-BV (a sphere is strictly convex already, so it needs none).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from spq.kernels import jacobian as kjac
from spq.kernels.kinematics import forward_kinematics
from spq.kernels import scene as kscene
from spq.kernels.batch import query_scratch
from spq.kernels.kinds import IDATA_DTYPE, POLYTOPE, STP
from spq.kernels.stp_support import IDX_H, IDX_HULL
from spq.kernels.gjk import OUT_SIZE, OUT_STATUS, STATUS_NAMES
from spq.kernels.batch import I_SIGNED
from spq.kinematics import PRISMATIC, MeshGeometry, PrimitiveGeometry, RobotModel
from spq.query import (DEFAULT_MAX_ITER, DEFAULT_TOL_ABS, DEFAULT_TOL_REL, BatchDistances, _check_tolerances,
                       check_signed)
from spq.shapes.base import box_centre
from spq.shapes.polyhedron import Polyhedron
from spq.shapes.primitives import Box, Capsule, Sphere
from spq.shapes.stpbv import STPBV
from spq.shapes.superellipsoid import Superellipsoid
from spq.validation import as_pose, as_positive
from spq.workers import MIN_SCENE_CONFIGURATIONS, check_workers, chunk_bounds, map_chunks

BODY_POLICIES = ("pch", "stp", "cse", "auto")
SCENE_POLICIES = BODY_POLICIES + ("stp-both",)
BV_KINDS = ("pch", "stp", "cse")
DEFAULT_R_SMALL = 0.005  # m: r of the STP-BVs (Table I's value)
DEFAULT_R_BIG = 2.0  # m: R of the STP-BVs
PRUNED_STATUS = "pruned"
_SCENE_STATUS = np.array(STATUS_NAMES + (PRUNED_STATUS,))  # indexed by status code; PRUNED (-1) is the last
WORLD = -1  # Body.link of a static obstacle: fixed in the world frame, not on any link
PRIMITIVE_MODES = ("hull", "exact")  # how Scene.from_urdf / from_model turn URDF boxes, spheres and capsules into bodies


def check_policy(policy: str, allowed=BODY_POLICIES, what: str = "policy") -> str:
    if policy not in allowed:
        raise ValueError(f"unknown {what} {policy!r}; choose one of {list(allowed)}")
    return policy


def choose_sides(policy_a: str, policy_b: str, features_a: int, features_b: int) -> tuple[str, str]:
    """The bounding volumes ('pch' | 'stp' | 'cse') a pair of bodies uses, from their policies.

    Explicit policies are kept. Two ``auto`` bodies: STP on the side with fewer STP features (A on a
    tie), PCH on the other. One ``auto`` body: STP against a ``pch`` body, PCH against a strictly
    convex one (``stp``, ``cse``)."""
    check_policy(policy_a)
    check_policy(policy_b)
    if policy_a == "auto" and policy_b == "auto":
        return ("stp", "pch") if features_a <= features_b else ("pch", "stp")
    if policy_a == "auto":
        return ("stp" if policy_b == "pch" else "pch"), policy_b
    if policy_b == "auto":
        return policy_a, ("stp" if policy_a == "pch" else "pch")
    return policy_a, policy_b


@dataclass(eq=False)
class Body:
    """One convex body of a scene: a hull riding on a link.

    name: unique body name (the link name, suffixed when a link has several geometries); link:
    index into ``model.link_names``; offset: 4x4 pose of the hull's frame in the link frame (m);
    hull: the PCH; policy: one of BODY_POLICIES; stp / cse: the STP-BV and the covering
    superellipsoid fit (FitResult: shape and its pose in the hull frame), built when the policy needs
    them; shape: an exact primitive (Sphere, Box or Capsule, in the hull frame) queried in place of
    the hull, whose hull then circumscribes it (for the STP-BV, the fit and other engines), or None."""

    name: str
    link: int
    offset: np.ndarray
    hull: Polyhedron
    policy: str
    stp: STPBV | None = None
    cse: object | None = None
    source: str = ""
    shape: Sphere | Box | Capsule | None = None

    @property
    def stp_features(self) -> int:
        return self.stp.n_patches if self.stp is not None else 0


@dataclass(eq=False)
class Obstacle:
    """A static obstacle fixed in the world (a table, a wall, a shelf board).

    name: unique among the scene's bodies; shape: a Polyhedron (any convex hull, e.g.
    ``Polyhedron.from_points``) or an exact Box, Sphere or Capsule (spq.shapes.primitives), in its own
    frame (m); pose: 4x4 world pose of that frame. In a scene it becomes a body with ``link == WORLD``
    under the scene's policy, paired with every robot body and with no other obstacle."""

    name: str
    shape: object
    pose: np.ndarray

    def body(self, policy: str) -> Body:
        """This obstacle as a scene body (its hull, and the exact primitive where it is one)."""
        pose = as_pose(self.pose, f"obstacle {self.name!r} pose")
        if isinstance(self.shape, Polyhedron):
            return Body(self.name, WORLD, pose, self.shape, policy, source="obstacle")
        if isinstance(self.shape, Box):
            geom = PrimitiveGeometry("box", 2.0 * self.shape.half_extents, np.eye(4))
        elif isinstance(self.shape, Sphere):
            geom = PrimitiveGeometry("sphere", np.array([self.shape.radius]), np.eye(4))
        elif isinstance(self.shape, Capsule):
            geom = PrimitiveGeometry("capsule", np.array([self.shape.radius, 2.0 * self.shape.half_length]), np.eye(4))
        else:
            raise ValueError(f"obstacle {self.name!r}: shape must be a Polyhedron, Box, Sphere or Capsule; got "
                             f"{type(self.shape).__name__}")
        return Body(self.name, WORLD, pose, _primitive_hull(geom), policy, source=f"obstacle {geom.kind}",
                    shape=self.shape)


class SceneDistances(BatchDistances):
    """Every queried pair's result for one configuration (world frame, metres).

    pairs: (npairs, 2) body indices; distance (npairs,) (inf for a pruned pair; with signed=True
    negative for an overlap, minus its penetration depth); point_a, point_b, normal (npairs, 3);
    status (npairs,) str, one of STATUS_NAMES or 'pruned'; iterations; lower_bound (the sphere gap
    for a pruned pair), upper_bound (== distance); pruned (npairs,) bool; jacobian (npairs, nv) when
    asked for, else None.

    point_a, point_b and normal are views into the sweep's result rows (OUT_SIZE floats each, so not
    C-contiguous), and every field is made on first access (see BatchDistances): a controller asks
    for a scene's distances every step, and copying these took about 30 us of JVRC-1's 561 pairs, a
    third of a pruned step's query (0.082 -> 0.055 ms)."""

    def __init__(self, pairs: np.ndarray, out: np.ndarray):
        super().__init__(out)
        self.pairs = pairs
        self.jacobian: np.ndarray | None = None

    @classmethod
    def from_out(cls, pairs: np.ndarray, out: np.ndarray) -> "SceneDistances":
        """The result of one configuration's rows out (npairs, OUT_SIZE), which it keeps (as views)."""
        return cls(pairs, out)

    @functools.cached_property
    def status(self) -> np.ndarray:
        """(npairs,) str: STATUS_NAMES entries, 'pruned' for a pruned pair."""
        return _SCENE_STATUS[self.status_code]  # PRUNED is -1: the last name

    @functools.cached_property
    def pruned(self) -> np.ndarray:
        """(npairs,) bool: the pairs skipped because their bounding spheres were far apart."""
        return self.status_code == kscene.PRUNED

    @property
    def min_index(self) -> int:
        """Index of the pair with the smallest distance."""
        return int(np.argmin(self.distance))

    @property
    def min_distance(self) -> float:
        return float(self.distance.min())


def _bounding_sphere(points: np.ndarray, grow: float) -> tuple[np.ndarray, float]:
    """Centre (box centre) and radius of a sphere around points grown by ``grow``."""
    c = box_centre(points)
    return c, float(np.sqrt(((points - c) ** 2).sum(axis=1).max()) + grow)


class Scene:
    """A robot's bodies and the pairs queried between them (see the module docstring).

    Parameters
    ----------
    model : RobotModel
        Kinematics (links, joints, limits).
    bodies : list of Body
        Convex bodies with their policies; STP-BVs and fits are built here as the policies need.
    policy : str
        'stp-both' makes every body use its STP-BV; any other value is only a default recorded for
        reporting (bodies keep their own policies).
    r, R : float
        Radii (m) of the STP-BVs (0 < r < R; R - r at least each hull's enclosing radius).
    skip_adjacent : bool
        Skip pairs of bodies on a link and its nearest ancestor link that has a body (they touch at
        the joint by design), and bodies on the same link.
    skip : iterable of (name, name)
        More body pairs to skip.
    base : 4x4
        World pose of the root link's parent frame (see :meth:`set_base`).
    tol, rel_tol, max_iter : GJK stopping rule, as in :func:`spq.distance`.
    obstacles : iterable of Obstacle
        Static obstacles fixed in the world, each paired with every robot body (not with each other).
        They join ``bodies`` (link ``WORLD``), under the scene's policy.
    floating_base : bool
        Whether distance Jacobians carry the base's six columns in front of the joints' (the base's
        twist in the world frame: the velocity v of its origin, then its angular velocity ω). The base
        pose itself stays ``base``; q holds the joints only.
    """

    def __init__(self, model: RobotModel, bodies: list[Body], policy: str = "auto", r: float = DEFAULT_R_SMALL,
                 R: float = DEFAULT_R_BIG, skip_adjacent: bool = True, skip=(), base=None,
                 tol: float = DEFAULT_TOL_ABS, rel_tol: float = DEFAULT_TOL_REL, max_iter: int = DEFAULT_MAX_ITER,
                 obstacles=(), floating_base: bool = False):
        check_policy(policy, SCENE_POLICIES, "scene policy")
        self.model = model
        default = "stp" if policy == "stp-both" else policy
        self.bodies = list(bodies) + [_as_obstacle(o).body(default) for o in obstacles]
        if not self.bodies:
            raise ValueError("a scene needs at least one body")
        for b in self.bodies:
            if b.link != WORLD and not 0 <= b.link < model.nlinks:
                raise ValueError(f"body {b.name!r}: link {b.link} is not a link of the model (0 to "
                                 f"{model.nlinks - 1}, or WORLD = {WORLD} for an obstacle)")
        self.floating_base = bool(floating_base)
        names = [b.name for b in self.bodies]
        if len(set(names)) != len(names):
            raise ValueError(f"body names must be unique; got {names}")
        self.policy = policy
        self.r, self.R = as_positive(r, "r"), as_positive(R, "R")
        if self.R <= self.r:
            raise ValueError(f"R must be larger than r; got r={self.r}, R={self.R}")
        self.base = np.eye(4) if base is None else as_pose(base, "base")
        self._tol = _check_tolerances(tol, rel_tol, max_iter)
        for b in self.bodies:
            check_policy(b.policy)
            if policy == "stp-both":
                b.policy = "stp"
        self._build_volumes()
        self._skip_adjacent, self._skip = bool(skip_adjacent), list(skip)
        self.pairs, self.pair_kinds = self._choose_pairs(skip_adjacent, self._skip)
        self._pack()

    # --- construction ---------------------------------------------------------------------------
    @classmethod
    def from_urdf(cls, urdf_path, convex_dir=None, mesh_root=None, policy: str = "auto", policies=None,
                  primitives: str = "hull", srdf=None, **options) -> "Scene":
        """A scene from a URDF: one body per geometry of each link (collision, else visual).

        convex_dir: a directory of qhull ``o f`` hulls named ``NAME-ch.txt`` after each mesh file
        ``NAME.ext`` (as in the JVRC-1 data); a mesh with no such file raises ValueError. Without
        it the hull of the mesh's vertices is used: ``package://PKG/REST`` resolves to
        ``mesh_root/REST``, else ``mesh_root/PKG/REST`` (mesh_root defaults to the URDF's directory),
        a relative path to the URDF's directory. Primitives: with ``primitives="hull"`` (the default)
        they become hulls: a box its 8 corners, a cylinder a PRIMITIVE_SEGMENTS-gon prism and a sphere
        an icosphere, both circumscribing the true shape (so the distance is never larger than the
        primitive's); with ``"exact"`` a box, a sphere and a capsule (a PrimitiveGeometry of kind
        'capsule') are queried as spq's Box, Sphere and Capsule (Body.shape), and a cylinder stays
        the circumscribing prism (spq has no cylinder). policy: scene policy (see SCENE_POLICIES) and
        every body's default; policies: {body name: policy} overrides. options: as for :class:`Scene`.
        """
        from spq.io.urdf import read_urdf

        check_policy(policy, SCENE_POLICIES, "scene policy")
        model = read_urdf(urdf_path)
        return cls.from_model(model, Path(urdf_path).resolve().parent, convex_dir, mesh_root, policy, policies,
                              primitives, srdf=srdf, **options)

    @classmethod
    def from_model(cls, model: RobotModel, urdf_dir=None, convex_dir=None, mesh_root=None, policy: str = "auto",
                   policies=None, primitives: str = "hull", hull_cache: dict | None = None, srdf=None,
                   srdf_reasons=None, **options) -> "Scene":
        """:meth:`from_urdf` for a RobotModel already read (or edited: mesh filenames made absolute,
        geometry replaced). urdf_dir: the folder relative mesh filenames resolve against (default:
        the folder of ``model.source``, else the working directory). hull_cache: a dict kept between
        calls, in which each mesh (file, scale, folders) and primitive (kind, size) gets its hull once:
        robots that share meshes then share hull objects, and their cube maps. srdf: an SRDF whose
        ``disable_collisions`` pairs are skipped; srdf_reasons: None (every element) or the reasons
        whose elements are honoured, e.g. ``("Adjacent", "Default", "Always")`` for a controller, which
        must still watch the pairs MoveIt disabled as 'Never' in collision (only over its sampled
        configurations, not along the controller's motion). The rest as in from_urdf."""
        check_policy(policy, SCENE_POLICIES, "scene policy")
        if primitives not in PRIMITIVE_MODES:
            raise ValueError(f"unknown primitives mode {primitives!r}; choose one of {list(PRIMITIVE_MODES)}")
        if urdf_dir is None:
            urdf_dir = Path(model.source).resolve().parent if model.source else Path.cwd()
        urdf_dir = Path(urdf_dir)
        default = "stp" if policy == "stp-both" else policy
        policies = dict(policies or {})
        bodies = []
        for link, geoms in enumerate(model.link_geometry):
            for k, geom in enumerate(geoms):
                name = model.link_names[link] + (f"#{k}" if len(geoms) > 1 else "")
                shape = None
                if isinstance(geom, MeshGeometry):
                    key = (geom.filename, tuple(np.asarray(geom.scale, dtype=float).ravel()), convex_dir, mesh_root,
                           urdf_dir)
                    hull, source = _cached(hull_cache, key, lambda: _load_hull(
                        geom.filename, geom.scale, convex_dir, mesh_root, urdf_dir, model.link_names[link]))
                else:
                    key = (geom.kind, tuple(np.asarray(geom.size, dtype=float)))
                    hull, source = _cached(hull_cache, key, lambda: (
                        _primitive_hull(geom), f"{geom.kind} {list(np.round(geom.size, 6))}"))
                    if primitives == "exact":
                        shape = _primitive_shape(geom)
                bodies.append(Body(name, link, np.asarray(geom.origin, dtype=np.float64), hull, default,
                                   source=source, shape=shape))
        unknown = set(policies) - {b.name for b in bodies}
        if unknown:
            raise ValueError(f"policies name unknown bodies {sorted(unknown)}; bodies: {[b.name for b in bodies]}")
        for b in bodies:
            b.policy = check_policy(policies.get(b.name, b.policy))
        if srdf is not None:
            from spq.collision_pairs import skip_pairs
            from spq.io.srdf import read_srdf

            entries = read_srdf(srdf)
            if srdf_reasons is not None:
                if isinstance(srdf_reasons, str):
                    raise ValueError(f"srdf_reasons must be a collection of reasons such as ('Adjacent', 'Default'), "
                                     f"got the string {srdf_reasons!r}")
                entries = [e for e in entries if e[2] in set(srdf_reasons)]
            disabled = [(a, b) for a, b, _ in entries]
            named = [(b.name, model.link_names[b.link]) for b in bodies]
            # links the model lacks are passed over, as pinocchio's removeCollisionPairs does: an SRDF may
            # be written for a larger variant of the robot (talos.srdf serves talos_left_arm)
            options["skip"] = list(options.get("skip", ())) + list(
                skip_pairs(named, disabled, link_names=model.link_names, unknown="ignore"))
        return cls(model, bodies, policy=policy, **options)

    def with_policy(self, policy: str) -> "Scene":
        """This scene with every body under the scene policy ``policy``: the same bodies (hulls,
        primitives, and the STP-BVs and fits already built are shared, not rebuilt), the same pairs,
        radii, base and stopping rule. Building a robot's scene once and deriving the others saves
        reading and hulling its meshes again."""
        check_policy(policy, SCENE_POLICIES, "scene policy")
        body_policy = "stp" if policy == "stp-both" else policy
        bodies = [Body(b.name, b.link, b.offset, b.hull, body_policy, stp=b.stp, cse=b.cse, source=b.source,
                       shape=b.shape) for b in self.bodies]
        tol, rel_tol, max_iter = self._tol
        return type(self)(self.model, bodies, policy=policy, r=self.r, R=self.R, skip_adjacent=self._skip_adjacent,
                          skip=self._skip, base=self.base, tol=tol, rel_tol=rel_tol, max_iter=max_iter,
                          floating_base=self.floating_base)

    def _build_volumes(self) -> None:
        built = {}  # id(hull) -> STP-BV: bodies that share a hull object (repeated meshes) share its STP-BV
        for b in self.bodies:
            if b.policy in ("stp", "auto") and b.stp is None and not isinstance(b.shape, Sphere):
                if id(b.hull) in built:
                    b.stp = built[id(b.hull)]
                    continue
                try:
                    b.stp = STPBV.from_points(b.hull.vertices, self.r, self.R)
                except ValueError as exc:
                    raise ValueError(f"body {b.name!r}: {exc}") from None
                except RuntimeError as exc:  # the construction's own consistency checks: name the body
                    raise RuntimeError(f"body {b.name!r} ({b.source}): STP-BV construction failed: {exc}") from exc
                b.stp.use_hull(b.hull)  # the hull's cube map is then built once for the PCH and the STP-BV
                built[id(b.hull)] = b.stp
            if b.policy == "cse" and b.cse is None:
                b.cse = Superellipsoid.fit(b.hull.vertices)

    def _adjacent_links(self) -> set[tuple[int, int]]:
        """(link, nearest ancestor link with a body) pairs, both orders."""
        has_body = {b.link for b in self.bodies if b.link != WORLD}
        out = set()
        for link in has_body:
            a = self.model.parent[link]
            while a >= 0 and a not in has_body:
                a = self.model.parent[a]
            if a >= 0:
                out |= {(link, int(a)), (int(a), link)}
        return out

    def _choose_pairs(self, skip_adjacent: bool, skip) -> tuple[np.ndarray, list[tuple[str, str]]]:
        index = {b.name: i for i, b in enumerate(self.bodies)}
        skipped = set()
        for pair in skip:
            try:
                na, nb = pair
            except (TypeError, ValueError):
                raise ValueError(f"skip entries must be (body, body) pairs; got {pair!r}") from None
            for n in (na, nb):
                if n not in index:
                    raise ValueError(f"skip names unknown body {n!r}; bodies: {list(index)}")
            skipped |= {(index[na], index[nb]), (index[nb], index[na])}
        adjacent = self._adjacent_links() if skip_adjacent else set()
        pairs, kinds_ = [], []
        for i, a in enumerate(self.bodies):
            for j in range(i + 1, len(self.bodies)):
                b = self.bodies[j]
                if (i, j) in skipped or (a.link == WORLD and b.link == WORLD):
                    continue
                if skip_adjacent and (a.link == b.link or (a.link, b.link) in adjacent):
                    continue
                pairs.append((i, j))
                kinds_.append(choose_sides(a.policy, b.policy, a.stp_features, b.stp_features))
        return np.array(pairs, dtype=np.int64).reshape(-1, 2), kinds_

    def _pack(self) -> None:
        """Flat slot and pair arrays for the compiled call.

        A body whose STP-BV's underlying hull is its own PCH (the same vertices, in the same order)
        stores that hull once: the STP-BV's data ends with its hull (spq.kernels.stp_support), so
        its pool ranges run on into the PCH's. For those bodies this halves the hulls' share of the
        working set, which the all-pairs loop sweeps through in a random order."""
        slot_of, keys = {}, []
        for pair, sides in zip(self.pairs, self.pair_kinds):
            for bi, bv in zip(pair, sides):
                if (bi, bv) not in slot_of:
                    slot_of[(bi, bv)] = len(keys)
                    keys.append((bi, bv))
        shapes = [self._volume(self.bodies[bi], bv) for bi, bv in keys]
        # the sparse cube maps: the all-pairs sweep's working set stays small (support.cube_map_size)
        data = [shape.kernel_data(dense=False) for shape, _ in shapes]
        fparts, iparts = [], []
        frange, irange = [None] * len(keys), [None] * len(keys)
        size = [0, 0]

        def put(fdata, idata):
            start = tuple(size)
            fparts.append(fdata)
            iparts.append(idata)
            size[0] += len(fdata)
            size[1] += len(idata)
            return start

        for s, (bi, bv) in enumerate(keys):
            if frange[s] is not None:
                continue
            twin = slot_of.get((bi, "pch" if bv == "stp" else "stp")) if bv in ("stp", "pch") else None
            stp, pch = (s, twin) if bv == "stp" else (twin, s)
            if twin is not None and _hull_is_tail(data[stp], data[pch]):
                nf, ni = len(data[pch].fdata), len(data[pch].idata)
                f0, i0 = put(data[stp].fdata[:-nf], data[stp].idata[:-ni])
                f1, i1 = put(data[pch].fdata, data[pch].idata)
                frange[stp], irange[stp] = (f0, f1 + nf), (i0, i1 + ni)
                frange[pch], irange[pch] = (f1, f1 + nf), (i1, i1 + ni)
            else:
                f0, i0 = put(data[s].fdata, data[s].idata)
                frange[s], irange[s] = (f0, f0 + len(data[s].fdata)), (i0, i0 + len(data[s].idata))
        centre, radius = [], []
        for (bi, bv), (shape, _), kd in zip(keys, shapes, data):
            if bv == "cse" or isinstance(shape, (Sphere, Box, Capsule)):
                c, rad = np.zeros(3), shape.bounding_radius()
            elif bv == "stp":
                c, rad = _bounding_sphere(shape.topology.vertices, shape.r)
            else:
                c, rad = _bounding_sphere(shape.vertices, kd.margin)
            centre.append(c)
            radius.append(rad)
        ns = len(keys)
        # an obstacle's slot rides on the world: the row after the links in the link-pose scratch (identity)
        self._slot_link = np.array([self.model.nlinks if self.bodies[bi].link == WORLD else self.bodies[bi].link
                                    for bi, _ in keys], dtype=np.int64)
        self._slot_offset = np.ascontiguousarray(
            np.array([self.bodies[bi].offset @ local for (bi, _), (_, local) in zip(keys, shapes)],
                     dtype=np.float64).reshape(ns, 4, 4))
        self._slot_kind = np.array([kd.kind for kd in data], dtype=np.int64)
        self._slot_margin = np.array([kd.margin for kd in data], dtype=np.float64)
        self._slot_frange = np.array(frange, dtype=np.int64).reshape(ns, 2)
        self._slot_irange = np.array(irange, dtype=np.int64).reshape(ns, 2)
        self._fpool = np.ascontiguousarray(np.concatenate(fparts) if fparts else np.zeros(0))
        self._ipool = np.ascontiguousarray(np.concatenate(iparts) if iparts else np.zeros(0, dtype=IDATA_DTYPE),
                                           dtype=IDATA_DTYPE)
        for kd, (f0, f1), (i0, i1) in zip(data, frange, irange):  # the shared ranges read back each slot's own data
            if not (np.array_equal(self._fpool[f0:f1], kd.fdata) and np.array_equal(self._ipool[i0:i1], kd.idata)):
                raise RuntimeError("scene packing: a slot's pool range differs from its kernel data")
        self._slot_centre = np.array(centre, dtype=np.float64).reshape(ns, 3)
        self._slot_radius = np.array(radius, dtype=np.float64)
        self._pair_slots = np.array([[slot_of[(a, sa)], slot_of[(b, sb)]]
                                     for (a, b), (sa, sb) in zip(self.pairs, self.pair_kinds)],
                                    dtype=np.int64).reshape(-1, 2)
        # one thread's scratch, kept: a control loop's call then allocates only its results
        body_link = np.array([b.link for b in self.bodies], dtype=np.int64)
        self._pair_stop = kjac.common_ancestors(self.model.parent, body_link[self.pairs[:, 0]],
                                                body_link[self.pairs[:, 1]])
        self._links, self._axes = self._link_scratch(), np.empty((self.model.nlinks, 3))
        self._slot_scratch, self._query_scratch = np.empty((ns, 4, 4)), query_scratch()
        self.reset()

    @staticmethod
    def _volume(body: Body, bv: str):
        """(shape, pose of the shape's frame in the hull frame) of a body's bounding volume."""
        if bv == "pch":
            return (body.hull if body.shape is None else body.shape), np.eye(4)
        if bv == "stp":
            return (body.shape if isinstance(body.shape, Sphere) else body.stp), np.eye(4)
        return body.cse.shape, np.asarray(body.cse.pose, dtype=np.float64)

    # --- queries --------------------------------------------------------------------------------
    def reset(self) -> None:
        """Forget every pair's warm start."""
        tol, rel_tol, max_iter = self._tol
        self._pair_ints, self._pair_floats = kscene.pack_pair_state(
            self._slot_kind, self._slot_margin, self._slot_centre, self._pair_slots, tol, rel_tol, max_iter)
        self._signed = False  # what the pairs' I_SIGNED column holds (pack_pair_state's zeros)

    @property
    def body_names(self) -> list[str]:
        return [b.name for b in self.bodies]

    @property
    def pair_names(self) -> list[tuple[str, str]]:
        return [(self.bodies[a].name, self.bodies[b].name) for a, b in self.pairs]

    def kind_counts(self) -> dict[str, int]:
        """How many queried pairs use each combination of bounding volumes, e.g. {'stp-pch': 500}."""
        out: dict[str, int] = {}
        for sa, sb in self.pair_kinds:
            key = "-".join(sorted((sa, sb), key=BV_KINDS.index, reverse=True))
            out[key] = out.get(key, 0) + 1
        return out

    def random_configuration(self, rng) -> np.ndarray:
        """Joint values drawn uniformly within the limits (numpy Generator)."""
        return self.model.random_configuration(rng)

    def _run(self, qs: np.ndarray, coherent: bool, prune: float, out: np.ndarray | None = None,
             signed: bool = False, workers: int = 1, jac: np.ndarray | None = None) -> np.ndarray:
        """Results (N, npairs, OUT_SIZE) of every configuration of qs; with jac (N, npairs, nv), the rows
        ∂d/∂q too, in the same compiled loop."""
        shape = (len(qs), len(self.pairs), OUT_SIZE)
        workers = check_workers(workers)
        signed = check_signed(signed)
        if signed != self._signed:  # a column write costs about 1 us: a control loop asks the same every step
            self._pair_ints[:, I_SIGNED] = signed
            self._signed = signed
        if out is None:
            out = np.empty(shape)
        elif (not isinstance(out, np.ndarray) or out.shape != shape or out.dtype != np.float64
              or not out.flags.c_contiguous or not out.flags.writeable):
            raise ValueError(f"out must be a writeable C-contiguous float64 array of shape {shape}")
        bounds = [(0, len(qs))] if coherent else chunk_bounds(len(qs), workers, MIN_SCENE_CONFIGURATIONS)
        if len(bounds) == 1:
            self._sweep(qs, coherent, prune, self._pair_ints, self._pair_floats, out,
                        (self._links, self._slot_scratch, self._query_scratch, self._axes), jac, signed)
            return out

        def chunk(start: int, stop: int):
            ints, floats = self._pair_ints.copy(), self._pair_floats.copy()
            scratch = (self._link_scratch(), np.empty_like(self._slot_scratch), query_scratch(),
                       np.empty_like(self._axes))  # a thread's own
            self._sweep(qs[start:stop], False, prune, ints, floats, out[start:stop], scratch,
                        None if jac is None else jac[start:stop], signed)
            return ints, floats

        states = map_chunks(chunk, bounds, workers)
        # the state one call leaves: each pair's from the last chunk that queried it (a pruned pair keeps its own)
        for (start, stop), (ints, floats) in zip(bounds, states):
            queried = (out[start:stop, :, OUT_STATUS] != kscene.PRUNED).any(axis=0) if prune > 0.0 else slice(None)
            self._pair_ints[queried], self._pair_floats[queried] = ints[queried], floats[queried]
        return out

    def _sweep(self, qs: np.ndarray, coherent: bool, prune: float, pair_ints: np.ndarray, pair_floats: np.ndarray,
               out: np.ndarray, scratch: tuple, jac: np.ndarray | None = None, signed: bool = False) -> None:
        """One compiled call over qs with the given per-pair warm-start state, into out (and the rows
        ∂d/∂q into jac, when given); scratch: (links, slot poses, query scratch, joint axes), one set per
        thread."""
        slots = (self._slot_link, self._slot_offset, self._slot_kind, self._slot_margin, self._slot_frange,
                 self._slot_irange, self._fpool, self._ipool, self._slot_centre, self._slot_radius)
        args = (self.model.kernel_chain(), self.base, qs, slots, (self._pair_slots, pair_ints, pair_floats),
                bool(coherent), float(prune), scratch[0], scratch[1], scratch[2], out)
        if jac is None:
            kscene.scene_distances(*args)
        else:
            kjac.scene_distances_jacobians(*args, (self.floating_base, self._pair_stop, bool(signed), scratch[3], jac))

    def _link_scratch(self) -> np.ndarray:
        """(nlinks + 1, 4, 4) scratch for the link poses; the last row, the world's pose, is the identity
        (forward kinematics writes the links' rows only)."""
        links = np.empty((self.model.nlinks + 1, 4, 4))
        links[-1] = np.eye(4)
        return links

    @property
    def nv(self) -> int:
        """Columns of a distance Jacobian: the joints, after the base's six with a floating base."""
        return self.model.ndof + (kjac.BASE_COLUMNS if self.floating_base else 0)

    def set_base(self, base) -> None:
        """Move the robot's base: ``base`` (4x4) is the world pose of the root link's parent frame."""
        self.base = as_pose(base, "base")

    def _jacobian_out(self, n: int, jac: np.ndarray | None) -> np.ndarray:
        """The (n, npairs, nv) array the rows go into: ``jac`` checked, or a new one."""
        shape = (n, len(self.pairs), self.nv)
        if jac is None:
            return np.empty(shape)
        if (not isinstance(jac, np.ndarray) or jac.shape != shape or jac.dtype != np.float64
                or not jac.flags.c_contiguous or not jac.flags.writeable):
            raise ValueError(f"jac_out must be a writeable C-contiguous float64 array of shape {shape}")
        return jac

    def frame_jacobians(self, q, frames) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Points fixed to links, as a controller's tasks need them every step, with one check of q.

        frames: [(link index, (3,) point in that link's frame, m)]. Returns (points (h, 3) world, m;
        rotations (h, 3, 3) of their links, world; jacobians (h, 6, nv) as :meth:`link_jacobian`)."""
        q = self.model.check_configuration(q)
        m = self.model
        links = self._links
        h = len(frames)
        points, rotations, jac = np.empty((h, 3)), np.empty((h, 3, 3)), np.empty((h, 6, self.nv))
        forward_kinematics(m.parent, m.joint_type, m.joint_origin, m.joint_axis, m.q_index, m.q_multiplier,
                           m.q_offset, q, self.base, links)
        for k, (link, local) in enumerate(frames):
            link = int(link)
            if not 0 <= link < m.nlinks:
                raise ValueError(f"frame {k}: link must be an index from 0 to {m.nlinks - 1}; got {link}")
            rotations[k] = links[link, :3, :3]
            points[k] = rotations[k] @ np.asarray(local, dtype=np.float64) + links[link, :3, 3]
            kjac.point_jacobian(m.kernel_chain(), self.base, self.floating_base, q, link, points[k], links, self._axes,
                                jac[k])
        return points, rotations, jac

    def link_jacobian(self, q, link, point) -> np.ndarray:
        """(6, nv) Jacobian at q of the world point ``point`` (3,) moving with ``link`` (an index into
        ``model.link_names``, or its name): rows 0..2 the point's linear velocity, rows 3..5 the link's
        angular velocity, both in the world frame, per unit rate of each column (the base's six first
        with a floating base, then the joints in q order)."""
        q = self.model.check_configuration(q)
        if isinstance(link, str):
            if link not in self.model.link_names:
                raise ValueError(f"unknown link {link!r}; links: {list(self.model.link_names)}")
            link = self.model.link_names.index(link)
        if not 0 <= int(link) < self.model.nlinks:
            raise ValueError(f"link must be an index from 0 to {self.model.nlinks - 1} or a link name; got {link}")
        point = np.asarray(point, dtype=np.float64)
        if point.shape != (3,) or not np.isfinite(point).all():
            raise ValueError(f"point must be a finite (3,) world point (m); got {point!r}")
        m = self.model
        out = np.empty((6, self.nv))
        kjac.point_jacobian(m.kernel_chain(), self.base, self.floating_base, q, int(link), point, self._links,
                            self._axes, out)
        return out

    def _check_prune(self, prune) -> float:
        prune = 0.0 if prune is None else float(prune)
        if not math.isfinite(prune) or prune < 0.0:
            raise ValueError(f"prune must be None or a finite distance >= 0 (m); got {prune}")
        return prune

    def distances(self, q, coherent: bool = True, prune: float | None = None, signed: bool = False,
                  jacobian: bool = False) -> SceneDistances:
        """Every queried pair's distance, witness points and status at joint configuration q.

        coherent: start each pair from its last simplex when its relative pose moved little (along a
        trajectory); False starts every pair cold. prune: skip pairs whose bounding spheres are more
        than this far apart (m); None queries every pair. signed: overlapping pairs get minus their
        penetration depth, with witness points and certified bounds (see spq.distance).

        jacobian: also every pair's row ∂d/∂q (``result.jacobian``, (npairs, nv), m per rad or m per m):
        nᵀ(J_B(p_B) − J_A(p_A)) with the pair's own unit normal n and witness points (through an
        overlap with signed=True, with the penetration normal), computed in compiled code. A pruned
        pair's row is zero; a row is NaN where the result defines no gradient (a failed query, or an
        overlap without signed=True). Columns: the joints in q order, after the base's six when the
        scene has ``floating_base`` (see :class:`Scene`). The row is the true gradient where the
        closest features are unique and one side is strictly convex (an STP-BV, a superellipsoid, a
        sphere or capsule); between two polyhedra it jumps where the closest features switch.

        Raises ValueError for a q of the wrong length, with NaN/inf, or outside the joint limits."""
        qs = self.model.check_configuration(q).reshape(1, -1)  # a fresh contiguous copy
        jac = np.empty((1, len(self.pairs), self.nv)) if jacobian else None
        out = self._run(qs, coherent, self._check_prune(prune), signed=signed, jac=jac)
        result = SceneDistances.from_out(self.pairs, out[0])
        if jacobian:
            result.jacobian = jac[0]
        return result

    def distances_many(self, qs, coherent: bool = False, prune: float | None = None,
                       out: np.ndarray | None = None, signed: bool = False, workers: int = 1, jacobian: bool = False,
                       jac_out: np.ndarray | None = None):
        """Raw results (N, npairs, OUT_SIZE; columns as spq.kernels.gjk.OUT_*) for N configurations
        (N, ndof) in one compiled call; coherent carries warm starts from one to the next; signed as
        in :meth:`distances`. With jacobian=True, returns ``(out, jac)``: jac (N, npairs, nv) each
        pair's row ∂d/∂q as in :meth:`distances` (into ``jac_out`` when given, float64 C-contiguous).

        workers: threads (1 to spq.workers.MAX_WORKERS) that share a cold sweep (coherent=False) in
        contiguous chunks of configurations, each with its own copy of the pairs' warm-start state;
        the results equal one thread's bit for bit, and the scene's state afterwards is the one a
        single call leaves. A coherent sweep depends on the order of the configurations (each pair
        starts from its last simplex) and runs on one thread whatever workers says.

        out: an array of that shape (float64, C-contiguous) to write the results into and return,
        so that a loop calling this again allocates nothing (a fresh array's first touch costs page
        faults, a few percent of a call over many configurations)."""
        qs = np.atleast_2d(np.asarray(qs, dtype=np.float64))
        checked = np.ascontiguousarray(self.model.check_configurations(qs))
        jac = self._jacobian_out(len(checked), jac_out) if jacobian else None
        out = self._run(checked, coherent, self._check_prune(prune), out, signed, workers, jac)
        return out if jac is None else (out, jac)

    def link_poses(self, q) -> np.ndarray:
        """(nlinks, 4, 4) world poses of the links at q (ValueError for a q the model rejects)."""
        m = self.model
        out = np.empty((m.nlinks, 4, 4))
        # the base was checked when it was set: a control loop calls this every step
        forward_kinematics(m.parent, m.joint_type, m.joint_origin, m.joint_axis, m.q_index, m.q_multiplier,
                           m.q_offset, m.check_configuration(q), self.base, out)
        return out

    def body_poses(self, q) -> np.ndarray:
        """(nbodies, 4, 4) world poses of the bodies' hull frames at q."""
        links = self.link_poses(q)
        return np.array([b.offset if b.link == WORLD else links[b.link] @ b.offset for b in self.bodies])

    def distance_gradient(self, q, result: SceneDistances, index: int) -> np.ndarray:
        """Gradient (ndof,) of pair ``index``'s distance with respect to the joint values, at q.

        d d / d q_j = n . (v_B - v_A), where n is the unit normal from A to B and v_X is the velocity
        of X's witness point (fixed to its body) under a unit rate of joint j. The same holds for a
        signed result's penetration depth (the envelope theorem on the support functions). Undefined
        (NaN) for a failed or pruned pair, and for an overlap queried without signed=True."""
        q = self.model.check_configuration(q)
        grad = np.zeros(len(q))
        defined = result.status[index] in ("separated", "touching", "overlapping")
        if not defined or not (np.isfinite(result.normal[index]).all() and np.isfinite(result.point_a[index]).all()
                               and np.isfinite(result.point_b[index]).all()):
            return grad * np.nan
        links = self.link_poses(q)
        n = result.normal[index]
        m = self.model
        for body, point, sign in ((self.pairs[index, 0], result.point_a[index], -1.0),
                                  (self.pairs[index, 1], result.point_b[index], 1.0)):
            link = self.bodies[body].link
            while link >= 0:
                j = m.q_index[link]
                if j >= 0:
                    par = m.parent[link]
                    frame = (links[par] if par >= 0 else self.base) @ m.joint_origin[link]
                    axis = frame[:3, :3] @ m.joint_axis[link]
                    v = axis if m.joint_type[link] == PRISMATIC else np.cross(axis, point - frame[:3, 3])
                    grad[j] += sign * m.q_multiplier[link] * float(n @ v)
                link = m.parent[link]
        return grad


def _as_obstacle(obstacle) -> Obstacle:
    if not isinstance(obstacle, Obstacle):
        raise ValueError(f"obstacles must be spq.scene.Obstacle objects; got {type(obstacle).__name__}")
    return obstacle


def _hull_is_tail(stp, pch) -> bool:
    """Whether an STP-BV's kernel data (stp) ends with exactly a polytope's (pch): its underlying
    hull is that polytope, stored last (spq.kernels.stp_support)."""
    nf, ni = len(pch.fdata), len(pch.idata)
    return (stp.kind == STP and pch.kind == POLYTOPE and 0 < nf < len(stp.fdata) and 0 < ni < len(stp.idata)
            and int(stp.idata[IDX_HULL]) == len(stp.idata) - ni and int(stp.idata[IDX_H]) * 3 == nf
            and np.array_equal(stp.fdata[-nf:], pch.fdata) and np.array_equal(stp.idata[-ni:], pch.idata))


def _cached(cache: dict | None, key, make):
    """make() once per key of cache (a dict), or every time without one."""
    if cache is None:
        return make()
    if key not in cache:
        cache[key] = make()
    return cache[key]


def _load_hull(filename: str, scale, convex_dir, mesh_root, urdf_dir: Path, link: str) -> tuple[Polyhedron, str]:
    """The convex hull of one URDF mesh geometry (scaled), from convex_dir or from the mesh."""
    stem = Path(filename.split("://", 1)[-1]).stem
    scale = np.asarray(scale if scale is not None else (1.0, 1.0, 1.0), dtype=np.float64)
    if convex_dir is not None:
        path = Path(convex_dir) / f"{stem}-ch.txt"
        if not path.is_file():
            raise ValueError(f"link {link!r} names mesh {filename!r} but {path} does not exist; convex_dir must "
                             f"hold a qhull file NAME-ch.txt for every mesh NAME.ext")
        hull = Polyhedron.from_qhull_file(path)
    else:
        if filename.startswith("package://"):
            full = filename[len("package://"):]
            root = Path(mesh_root or urdf_dir)
            # package://PKG/REST is mesh_root/REST; failing that, mesh_root/PKG/REST (pybullet's reading,
            # which pybullet_data's Franka Panda needs: package://meshes/collision/link0.obj)
            candidates = [root / full.split("/", 1)[-1], root / full]
        elif filename.startswith("file://"):
            candidates = [Path(filename[len("file://"):])]
        else:
            candidates = [urdf_dir / filename]
        path = next((c for c in candidates if c.is_file()), None)
        if path is None:
            looked = " or ".join(str(c) for c in dict.fromkeys(candidates))
            raise ValueError(f"link {link!r} names mesh {filename!r}, not found at {looked}; give mesh_root (the "
                             f"package directory) or convex_dir")
        hull = Polyhedron.from_mesh(path)
    if not np.allclose(scale, 1.0):
        hull = Polyhedron.from_points(hull.vertices * scale)
    return hull, str(path)


PRIMITIVE_SEGMENTS = 64  # sides of a cylinder's polygon; a circumscribed polygon overshoots by 1 - cos(pi/64) = 0.12%


def _primitive_hull(geom: PrimitiveGeometry) -> Polyhedron:
    """Hull of a URDF box, sphere, cylinder or capsule, circumscribing the true shape (see Scene.from_urdf)."""
    import trimesh

    size = np.asarray(geom.size, dtype=np.float64)
    if geom.kind == "box":
        return Polyhedron.from_points(trimesh.creation.box(extents=size).vertices)
    if geom.kind in ("sphere", "capsule"):
        ico = trimesh.creation.icosphere(subdivisions=3)
        inscribed = np.min(np.abs(ico.face_normals * ico.triangles_center).sum(axis=1))
        ball = ico.vertices * (size[0] / inscribed)
        if geom.kind == "sphere":
            return Polyhedron.from_points(ball)
        # a capsule is the hull of its two end balls: the hull of two circumscribing icospheres covers it
        ends = np.array([[0.0, 0.0, -0.5 * size[1]], [0.0, 0.0, 0.5 * size[1]]])
        return Polyhedron.from_points(np.concatenate([ball + ends[0], ball + ends[1]]))
    if geom.kind == "cylinder":
        grow = 1.0 / np.cos(np.pi / PRIMITIVE_SEGMENTS)
        cyl = trimesh.creation.cylinder(radius=size[0] * grow, height=size[1], sections=PRIMITIVE_SEGMENTS)
        return Polyhedron.from_points(cyl.vertices)
    raise ValueError(f"unsupported primitive geometry {geom.kind!r}; supported: box, sphere, cylinder, capsule")


def _primitive_shape(geom: PrimitiveGeometry) -> Sphere | Box | Capsule | None:
    """spq's exact shape for a URDF primitive (centred on its origin, a capsule along its z axis), or
    None for a cylinder, which keeps its circumscribing prism."""
    size = np.asarray(geom.size, dtype=np.float64)
    if geom.kind == "box":
        return Box.from_size(*size)
    if geom.kind == "sphere":
        return Sphere(size[0])
    if geom.kind == "capsule":
        return Capsule(size[0], 0.5 * size[1])
    return None
