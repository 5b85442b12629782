"""Scene files: a robot scene and the joint configurations to run it on, declared in TOML.

A scene file names only what the scene needs (examples with comments in ``scenes/``)::

    robot = "kuka_iiwa"          # a name from datasets.robots.ROBOTS; or urdf = "path" (see below)
    policy = "auto"              # pch | stp | cse | auto | stp-both
    r = 0.005                    # STP-BV radii (m)
    R = 2.0
    [policies]                   # optional: body or link name = pch | stp | cse | auto
    lbr_iiwa_link_7 = "cse"
    [skip]
    adjacent = true              # skip bodies on neighbouring links (default true)
    pairs = [["lbr_iiwa_link_5", "lbr_iiwa_link_7"]]
    [poses]
    kind = "random"              # random (count, seed) | trajectory (steps, seed) | file (path)
    count = 200
    seed = 0

Instead of ``robot``: ``urdf = "path"`` with optional ``convex_dir`` (qhull hulls ``NAME-ch.txt``
per mesh ``NAME.ext``) and ``mesh_root`` (the folder ``package://PKG/...`` mesh names resolve
against); relative paths are relative to the scene file's folder, as is the CSV ``path`` of a
``file`` pose source (header: joint names in any order, one configuration per row; see
:func:`harness.workloads.robot_poses.read_configurations`). Optional everywhere: ``tol``, ``rel_tol``,
``max_iter`` (the GJK stopping rule of :class:`spq.Scene`), and in ``[poses]`` ``coherent`` (warm
starts from one configuration to the next; default true for a trajectory, false otherwise) and
``prune`` (m: skip pairs whose bounding spheres are farther apart). Unknown keys, wrong types and
values out of range raise ValueError naming the file, the key and what is admissible.

:func:`read_scene_file` checks the file alone (no robot files are opened); :func:`build_scene`
reads the robot and builds the :class:`spq.Scene`, checking the body names the file uses;
:func:`scene_configurations` draws or reads the configurations.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from spq.kinematics import RobotModel
from spq.query import DEFAULT_MAX_ITER, DEFAULT_TOL_ABS, DEFAULT_TOL_REL
from spq.scene import BODY_POLICIES, DEFAULT_R_BIG, DEFAULT_R_SMALL, SCENE_POLICIES, Scene

TOP_KEYS = ("robot", "urdf", "convex_dir", "mesh_root", "policy", "policies", "r", "R", "tol", "rel_tol",
            "max_iter", "skip", "poses")
SKIP_KEYS = ("adjacent", "pairs")
POSE_KEYS = {
    "random": ("kind", "count", "seed", "coherent", "prune"),
    "trajectory": ("kind", "steps", "seed", "coherent", "prune"),
    "file": ("kind", "path", "coherent", "prune"),
}
COHERENT_DEFAULT = {"random": False, "trajectory": True, "file": False}


@dataclass(frozen=True)
class PoseSpec:
    """Where the configurations come from: ``kind`` 'random' (``count`` uniform draws within the
    limits), 'trajectory' (``steps`` along harness.workloads.robot_poses.smooth_trajectory) or 'file' (CSV at
    ``path``); ``seed`` of the seeded kinds; ``coherent``: warm-start each pair from the previous
    configuration; ``prune``: skip pairs whose bounding spheres are more than this far apart (m),
    None to query every pair."""

    kind: str
    count: int | None = None
    steps: int | None = None
    seed: int = 0
    path: Path | None = None
    coherent: bool = False
    prune: float | None = None

    def describe(self) -> str:
        what = {"random": f"{self.count} random configurations, seed {self.seed}",
                "trajectory": f"trajectory of {self.steps} steps, seed {self.seed}",
                "file": f"configurations from {self.path}"}[self.kind]
        prune = "no pruning" if self.prune is None else f"pruning beyond {self.prune:g} m"
        return f"{what}; {'coherent' if self.coherent else 'cold starts'}; {prune}"


@dataclass(frozen=True)
class SceneSpec:
    """A checked scene file. ``source``: the TOML file; ``robot`` (a ROBOTS name) or ``urdf`` (with
    ``convex_dir``, ``mesh_root``; paths absolute); ``policy`` and ``policies`` {body or link name:
    policy}; ``r``, ``R`` (m); ``tol`` (m), ``rel_tol``, ``max_iter``; ``skip_adjacent`` and
    ``skip_pairs`` (body or link names); ``poses``."""

    source: Path
    robot: str | None
    urdf: Path | None
    convex_dir: Path | None
    mesh_root: Path | None
    policy: str
    policies: dict
    r: float
    R: float
    tol: float
    rel_tol: float
    max_iter: int
    skip_adjacent: bool
    skip_pairs: tuple
    poses: PoseSpec

    @property
    def name(self) -> str:
        return self.robot if self.robot is not None else self.urdf.stem


# --- reading and checking the file ------------------------------------------------------------------
def read_scene_file(path) -> SceneSpec:
    """Read and check the scene file ``path`` (see the module docstring). ValueError, naming the file,
    for invalid TOML, unknown keys, wrong types or out-of-range values; FileNotFoundError if absent."""
    path = Path(path)
    with path.open("rb") as fh:
        try:
            data = tomllib.load(fh)
        except tomllib.TOMLDecodeError as exc:
            raise ValueError(f"{path}: not valid TOML: {exc}") from None
    try:
        return _scene_spec(data, path.resolve())
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None


def _scene_spec(data: dict, source: Path) -> SceneSpec:
    _check_keys(data, TOP_KEYS, "top level")
    here = source.parent
    robot = _optional(data, "robot", _string)
    urdf = _optional(data, "urdf", _string)
    if (robot is None) == (urdf is None):
        raise ValueError("give exactly one robot source: robot = NAME (one of datasets.robots.ROBOTS) or "
                         "urdf = PATH")
    if robot is not None:
        from datasets.robots import ROBOTS

        if robot not in ROBOTS:
            raise ValueError(f"unknown robot {robot!r}; known robots: {sorted(ROBOTS)}")
        for key in ("convex_dir", "mesh_root"):
            if key in data:
                raise ValueError(f"{key} goes with urdf = PATH; robot {robot!r} brings its own files")
    policy = _optional(data, "policy", _string) or "auto"
    if policy not in SCENE_POLICIES:
        raise ValueError(f"unknown policy {policy!r}; choose one of {list(SCENE_POLICIES)}")
    policies = _optional(data, "policies", _table) or {}
    for name, value in policies.items():
        if not isinstance(value, str) or value not in BODY_POLICIES:
            raise ValueError(f"policies.{name} = {value!r}: a body's policy is one of {list(BODY_POLICIES)}")
    r = _optional(data, "r", _positive) or DEFAULT_R_SMALL
    R = _optional(data, "R", _positive) or DEFAULT_R_BIG
    if R <= r:
        raise ValueError(f"R must be larger than r; got r = {r}, R = {R}")
    tol = _optional(data, "tol", _non_negative)
    rel_tol = _optional(data, "rel_tol", _non_negative)
    max_iter = _optional(data, "max_iter", _count)
    skip = _optional(data, "skip", _table) or {}
    _check_keys(skip, SKIP_KEYS, "[skip]")
    adjacent = _optional(skip, "adjacent", _boolean, "skip.")
    pairs = _optional(skip, "pairs", _name_pairs, "skip.") or ()
    if "poses" not in data:
        raise ValueError("missing [poses] table (kind = 'random' | 'trajectory' | 'file')")
    return SceneSpec(
        source=source, robot=robot, urdf=_path(here, urdf),
        convex_dir=_path(here, data.get("convex_dir"), "convex_dir"),
        mesh_root=_path(here, data.get("mesh_root"), "mesh_root"), policy=policy, policies=dict(policies), r=r, R=R,
        tol=DEFAULT_TOL_ABS if tol is None else tol, rel_tol=DEFAULT_TOL_REL if rel_tol is None else rel_tol,
        max_iter=DEFAULT_MAX_ITER if max_iter is None else max_iter,
        skip_adjacent=True if adjacent is None else adjacent, skip_pairs=pairs,
        poses=_pose_spec(_table(data["poses"], "poses"), here))


def _pose_spec(poses: dict, here: Path) -> PoseSpec:
    kind = _optional(poses, "kind", _string, "poses.")
    if kind not in POSE_KEYS:
        raise ValueError(f"poses.kind = {kind!r}; choose one of {list(POSE_KEYS)}")
    _check_keys(poses, POSE_KEYS[kind], f"[poses] of kind {kind!r}")
    needed = {"random": "count", "trajectory": "steps", "file": "path"}[kind]
    if needed not in poses:
        raise ValueError(f"[poses] of kind {kind!r} needs {needed}")
    steps = _optional(poses, "steps", _count, "poses.")
    if steps is not None and steps < 2:
        raise ValueError(f"poses.steps must be at least 2; got {steps}")
    coherent = _optional(poses, "coherent", _boolean, "poses.")
    seed = _optional(poses, "seed", _integer, "poses.")
    if seed is not None and seed < 0:
        raise ValueError(f"poses.seed must be >= 0; got {seed}")
    return PoseSpec(kind=kind, count=_optional(poses, "count", _count, "poses."), steps=steps,
                    seed=seed or 0, path=_path(here, poses.get("path"), "poses.path"),
                    coherent=COHERENT_DEFAULT[kind] if coherent is None else coherent,
                    prune=_optional(poses, "prune", _non_negative, "poses."))


def _check_keys(table: dict, allowed, where: str) -> None:
    unknown = [k for k in table if k not in allowed]
    if unknown:
        raise ValueError(f"unknown key{'s' if len(unknown) > 1 else ''} {unknown} at {where}; admissible keys: "
                         f"{list(allowed)}")


def _optional(table: dict, key: str, check, prefix: str = ""):
    return None if key not in table else check(table[key], prefix + key)


def _string(value, name: str) -> str:
    if not isinstance(value, str) or not value:
        raise ValueError(f"{name} must be a non-empty string; got {value!r}")
    return value


def _table(value, name: str) -> dict:
    if not isinstance(value, dict):
        raise ValueError(f"{name} must be a table ([{name}] or {{...}}); got {value!r}")
    return value


def _boolean(value, name: str) -> bool:
    if not isinstance(value, bool):
        raise ValueError(f"{name} must be true or false; got {value!r}")
    return value


def _integer(value, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise ValueError(f"{name} must be an integer; got {value!r}")
    return value


def _count(value, name: str) -> int:
    if _integer(value, name) < 1:
        raise ValueError(f"{name} must be at least 1; got {value}")
    return value


def _number(value, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ValueError(f"{name} must be a finite number; got {value!r}")
    return float(value)


def _positive(value, name: str) -> float:
    if _number(value, name) <= 0.0:
        raise ValueError(f"{name} must be > 0; got {value}")
    return float(value)


def _non_negative(value, name: str) -> float:
    if _number(value, name) < 0.0:
        raise ValueError(f"{name} must be >= 0; got {value}")
    return float(value)


def _name_pairs(value, name: str) -> tuple:
    if not isinstance(value, list) or not all(
            isinstance(p, list) and len(p) == 2 and all(isinstance(n, str) for n in p) for p in value):
        raise ValueError(f"{name} must be a list of name pairs [[\"A\", \"B\"], ...]; got {value!r}")
    return tuple((a, b) for a, b in value)


def _path(here: Path, value, name: str = "urdf") -> Path | None:
    if value is None:
        return None
    path = Path(_string(value, name)).expanduser()
    return path if path.is_absolute() else (here / path).resolve()


# --- building the scene -----------------------------------------------------------------------------
def robot_sources(spec: SceneSpec) -> tuple[Path, Path | None, Path | None]:
    """(urdf, convex_dir, mesh_root) of the scene's robot. FileNotFoundError if the URDF is absent."""
    if spec.robot is None:
        if not spec.urdf.is_file():
            raise FileNotFoundError(f"{spec.source}: urdf {spec.urdf} not found")
        return spec.urdf, spec.convex_dir, spec.mesh_root
    from datasets.robots import robot_files, robot_urdf

    files = robot_files(spec.robot)
    return robot_urdf(spec.robot), files.convex_dir, files.mesh_root


def body_names_by_link(model: RobotModel) -> dict[str, list[str]]:
    """{link name: names of its bodies} as :meth:`spq.Scene.from_urdf` names them (the link name,
    suffixed #k when the link has several geometries); links without geometry are left out."""
    return {link: [link + (f"#{k}" if len(geoms) > 1 else "") for k in range(len(geoms))]
            for link, geoms in zip(model.link_names, model.link_geometry) if geoms}


def _bodies_named(name: str, by_link: dict[str, list[str]]) -> list[str]:
    bodies = {b for names in by_link.values() for b in names}
    return [name] if name in bodies else by_link.get(name, [])


def _check_names(names, by_link: dict[str, list[str]], where: str) -> None:
    unknown = sorted({n for n in names if not _bodies_named(n, by_link)})
    if unknown:
        bodies = [b for names_ in by_link.values() for b in names_]
        multi = [link for link, names_ in by_link.items() if len(names_) > 1]
        also = f"; or a link name for all its bodies: {multi}" if multi else ""
        raise ValueError(f"{where} name{'s' if len(unknown) > 1 else ''} {unknown} not in the scene; bodies: "
                         f"{bodies}{also}")


def build_scene(spec: SceneSpec) -> Scene:
    """The :class:`spq.Scene` a checked scene file describes. ValueError (naming the file and listing
    the valid names) for policies or skip pairs that name no body or link; FileNotFoundError for
    missing robot files."""
    from spq.io.urdf import read_urdf

    urdf, convex_dir, mesh_root = robot_sources(spec)
    model = read_urdf(urdf)
    by_link = body_names_by_link(model)
    try:
        _check_names(spec.policies, by_link, "policies")
        _check_names([n for pair in spec.skip_pairs for n in pair], by_link, "skip.pairs")
    except ValueError as exc:
        raise ValueError(f"{spec.source}: {exc}") from None
    policies = {body: policy for name, policy in spec.policies.items() for body in _bodies_named(name, by_link)}
    skip = [(a, b) for na, nb in spec.skip_pairs
            for a in _bodies_named(na, by_link) for b in _bodies_named(nb, by_link) if a != b]
    return Scene.from_urdf(urdf, convex_dir=convex_dir, mesh_root=mesh_root, policy=spec.policy, policies=policies,
                           r=spec.r, R=spec.R, skip_adjacent=spec.skip_adjacent, skip=skip, tol=spec.tol,
                           rel_tol=spec.rel_tol, max_iter=spec.max_iter)


def scene_configurations(spec: SceneSpec, model: RobotModel) -> np.ndarray:
    """(n, ndof) configurations of the scene file's pose source, checked against the joint limits."""
    from harness.workloads.robot_poses import random_configurations, read_configurations, smooth_trajectory

    poses = spec.poses
    if poses.kind == "random":
        return random_configurations(model, poses.count, poses.seed)
    if poses.kind == "trajectory":
        return smooth_trajectory(model, poses.steps, poses.seed)
    if not poses.path.is_file():
        raise FileNotFoundError(f"{spec.source}: poses.path {poses.path} not found")
    return read_configurations(model, poses.path)
