"""The robots of the pip package ``example-robot-data`` (Gepetto's benchmark set), read in place.

Every ``*.urdf`` file under the package's ``robots/`` folder is a robot, named after its file stem;
where two files share a stem (two ``anymal.urdf``), each is named ``<package folder>/<stem>``. The
package is found with ``importlib.metadata`` (it installs its data under
``site-packages/cmeel.prefix/share/example-robot-data``); nothing is copied into this project.

A robot loads as a :class:`spq.kinematics.RobotModel` (:func:`load_model`) whose mesh filenames are
resolved to absolute paths, and as a :class:`spq.Scene` (:func:`load_scene`) in which:

- each collision mesh (a link without collision elements: its visual ones, as in
  ``Scene.from_urdf``) becomes the convex hull of its vertices (trimesh reads it, qhull hulls it);
- boxes, spheres and capsules become spq's exact ``Box``, ``Sphere`` and ``Capsule``; a cylinder,
  which spq has no shape for, becomes the hull of a 64-sided prism circumscribing it
  (``spq.scene.PRIMITIVE_SEGMENTS``: at most 0.12% of its radius too large). URDF has no capsule;
  pinocchio's ``<collision_checking><capsule name=.../>`` extension, which turns the named collision
  cylinder into a capsule of the same radius and length, is honoured as pinocchio honours it;
- pairs of bodies on adjacent links (a link and its nearest ancestor with a body) and on the same
  link are skipped, as for JVRC-1;
- the root link is fixed in the world: legged robots, humanoids and drones have a floating base,
  which does not move their links relative to each other, so self-distances do not depend on it
  (pinocchio's peer is read the same way, without a free-flyer root joint). A URDF whose own joints
  include a ``floating`` or ``planar`` joint is refused by the reader (none of this set has one).

MoveIt SRDFs ship for many robots (``robots/<folder>/srdf/*.srdf``); :func:`robot_srdf` names the one
that goes with a robot, for its ``<disable_collisions>`` pairs (spq.io.srdf, spq.collision_pairs).

Mesh filenames take the forms ``package://example-robot-data/robots/...`` (also with three
slashes), ``package://<folder>/...`` for a folder of ``robots/``, a path relative to the URDF, or
``file:///...``; a mesh that is not shipped raises ValueError naming it.
"""

from __future__ import annotations

import dataclasses
import xml.etree.ElementTree as ElementTree
from functools import lru_cache
from pathlib import Path

from spq.kinematics import MeshGeometry, PrimitiveGeometry, RobotModel

DISTRIBUTION = "example-robot-data"
SHARE = "cmeel.prefix/share/example-robot-data"  # the package's data folder inside site-packages
PACKAGE_PREFIX = "package://"
FILE_PREFIX = "file://"


def package_root() -> Path:
    """The installed package's data folder (``.../share/example-robot-data``, holding ``robots/``).

    ValueError naming the fix when the package is not installed."""
    from importlib import metadata

    try:
        dist = metadata.distribution(DISTRIBUTION)
    except metadata.PackageNotFoundError:
        raise ValueError(f"the robots of {DISTRIBUTION} need its pip package: pip install {DISTRIBUTION}") from None
    root = Path(dist.locate_file(SHARE))
    if not (root / "robots").is_dir():
        raise ValueError(f"{DISTRIBUTION} {dist.version} is installed but {root / 'robots'} is missing")
    return root


@lru_cache(maxsize=1)
def _catalogue() -> dict[str, Path]:
    robots = package_root() / "robots"
    files = sorted(robots.rglob("*.urdf"), key=lambda p: p.relative_to(robots).as_posix())
    stems = [p.stem for p in files]
    out = {}
    for path in files:
        rel = path.relative_to(robots)
        name = path.stem if stems.count(path.stem) == 1 else f"{rel.parts[0]}/{path.stem}"
        out[name] = path
    return out


def robot_names() -> list[str]:
    """Every robot of the package (one per URDF file), sorted by the URDF's path in the package."""
    return list(_catalogue())


def robot_urdf(name: str) -> Path:
    """Path of robot ``name``'s URDF inside the installed package; ValueError for an unknown name."""
    catalogue = _catalogue()
    if name not in catalogue:
        raise ValueError(f"unknown robot {name!r} of {DISTRIBUTION}; known: {', '.join(catalogue)}")
    return catalogue[name]


SRDF_OF = {  # URDF stem -> SRDF file of its folder, as example-robot-data's own loaders pair them
    "baxter": "baxter_manipulation.srdf", "hyq_no_sensors": "hyq.srdf", "icub_reduced": "icub.srdf",
    "solo12": "solo.srdf", "ur5_robot": "ur5.srdf", "talos_full_v2": "talos.srdf", "talos_full_v2_box": "talos.srdf",
    "talos_left_arm": "talos.srdf", "talos_reduced": "talos.srdf", "talos_reduced_box": "talos.srdf",
    "talos_reduced_corrected": "talos.srdf",
}


def robot_srdf(name: str) -> Path | None:
    """The SRDF shipped for robot ``name``, or None: ``srdf/<URDF stem>.srdf`` in the robot's folder of
    ``robots/`` if it exists, else the file example-robot-data's loaders pair the URDF with
    (SRDF_OF: every Talos variant with talos.srdf, solo12 with solo.srdf, ...). Some shipped SRDFs
    have no ``<disable_collisions>`` (kinova, z1, icub's are commented out), and some name links a
    variant does not have (talos_left_arm); pinocchio passes such links over. ValueError for an
    unknown robot."""
    urdf = robot_urdf(name)
    robots = package_root() / "robots"
    folder = robots / urdf.relative_to(robots).parts[0] / "srdf"
    for candidate in (f"{urdf.stem}.srdf", SRDF_OF.get(urdf.stem)):
        if candidate and (folder / candidate).is_file():
            return folder / candidate
    return None


def resolve_mesh(filename: str, urdf: Path) -> Path:
    """The file a URDF mesh filename names, for a URDF of this package (forms in the module
    docstring); ValueError naming the filename and where it was looked for when it is absent."""
    root = package_root()
    if filename.startswith(PACKAGE_PREFIX):
        rest = filename[len(PACKAGE_PREFIX):].lstrip("/")  # package:///x is package://x (talos, romeo)
        package, _, inner = rest.partition("/")
        if package == DISTRIBUTION:
            candidates = [root / inner]
        else:  # package://b1_description/meshes/trunk.dae: a folder of robots/
            candidates = [root / "robots" / package / inner, root / package / inner]
    elif filename.startswith(FILE_PREFIX):
        candidates = [Path(filename[len(FILE_PREFIX):])]
    else:
        candidates = [Path(urdf).parent / filename]
    for path in candidates:
        if path.is_file():
            return path.resolve()
    raise ValueError(f"mesh {filename!r} not found (looked at {', '.join(str(c) for c in candidates)})")


def load_model(name: str) -> RobotModel:
    """Robot ``name`` as a RobotModel: read by spq.io.urdf.read_urdf, every mesh filename made an
    absolute path (:func:`resolve_mesh`), pinocchio's collision capsules applied. ValueError for an
    unknown robot, a URDF the reader refuses, or a mesh that is not shipped (naming its link)."""
    from spq.io.urdf import read_urdf

    urdf = robot_urdf(name)
    model = read_urdf(urdf)
    capsules = _collision_capsules(urdf)
    geometry = []
    for link, geoms in zip(model.link_names, model.link_geometry):
        out = []
        for k, g in enumerate(geoms):
            if isinstance(g, MeshGeometry):
                try:
                    g = g._replace(filename=str(resolve_mesh(g.filename, urdf)))
                except ValueError as exc:
                    raise ValueError(f"{name}: link {link!r}: {exc}") from None
            elif isinstance(g, PrimitiveGeometry) and g.kind == "cylinder" and k in capsules.get(link, ()):
                g = g._replace(kind="capsule")
            out.append(g)
        geometry.append(tuple(out))
    return dataclasses.replace(model, link_geometry=tuple(geometry))


def _collision_capsules(urdf: Path) -> dict[str, set[int]]:
    """{link name: indices among its collision elements} of the cylinders pinocchio reads as capsules:
    those a ``<collision_checking><capsule name="..."/>`` of the link names. Empty if none (or if
    the file is not plain XML, which read_urdf then reports)."""
    try:
        tree = ElementTree.parse(urdf)
    except ElementTree.ParseError:
        return {}
    out = {}
    for link in tree.getroot().iter("link"):
        checking = link.find("collision_checking")
        if checking is None:
            continue
        names = {c.get("name") for c in checking.findall("capsule")}
        indices = {k for k, c in enumerate(link.findall("collision")) if c.get("name") in names}
        if indices:
            out[link.get("name")] = indices
    return out


def load_scene(name: str, policy: str = "pch", hull_cache: dict | None = None, **options):
    """Robot ``name`` as a :class:`spq.Scene` (bodies and pairs as in the module docstring) under the
    scene ``policy``. hull_cache: a dict kept across calls so that robots sharing meshes (the
    package's variants of one robot) read and hull each once. options: as for spq.Scene (r, R, tol...).
    ValueError as in :func:`load_model`, or from the scene (no bodies, a hull that cannot be built)."""
    from spq.scene import Scene

    model = load_model(name)
    return Scene.from_model(model, robot_urdf(name).parent, policy=policy, primitives="exact",
                            hull_cache=hull_cache, **options)
