"""Whole robots described by URDF: JVRC-1 (shared data) and the KUKA iiwa and Franka Panda of pybullet_data.

``ROBOTS`` maps a robot name to its :class:`RobotFiles`: the URDF, the folder of ready-made convex
hulls of its links (JVRC-1: ``NAME-ch.txt`` in qhull ``o f`` format, one per link mesh ``NAME.dae``)
or None, and the folder that the URDF's mesh filenames are relative to, or None where the meshes
are not shipped (JVRC-1's ``package://jvrc_description/meshes/*.dae``). :func:`link_shape_file`
names the file to build a link's convex hull from. Paths are resolved when this module is imported
(``$SPQ_SHARED_DATASETS`` is read then); they may not exist, which :func:`robot_urdf` reports.
"""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

from datasets.paths import ENV_SHARED, REPO_ROOT, pybullet_data_dir, shared_datasets_dir
from datasets.shared import JVRC1_SUFFIX

PACKAGE_PREFIX = "package://"


class RobotFiles(NamedTuple):
    """Where a robot's files are: ``urdf`` file, ``convex_dir`` (hulls per link mesh) or None,
    ``mesh_root`` (folder the URDF mesh filenames resolve against) or None."""

    urdf: Path
    convex_dir: Path | None
    mesh_root: Path | None


def _robots() -> dict[str, RobotFiles]:
    # a missing shared folder still gets its expected path, so that errors can name it
    shared = shared_datasets_dir() or (REPO_ROOT.parent / "shared" / "datasets")
    bullet = pybullet_data_dir()
    return {
        "jvrc1": RobotFiles(shared / "jvrc1/urdf/jvrc1.urdf", shared / "jvrc1/convex", None),
        # collision meshes meshes/link_N.stl, relative to the URDF's folder
        "kuka_iiwa": RobotFiles(bullet / "kuka_iiwa/model.urdf", None, bullet / "kuka_iiwa"),
        # collision meshes package://meshes/collision/*.obj: the package is the URDF's folder
        "panda": RobotFiles(bullet / "franka_panda/panda.urdf", None, bullet / "franka_panda"),
    }


ROBOTS: dict[str, RobotFiles] = _robots()
"""Robot name -> RobotFiles."""


def robot_files(name: str) -> RobotFiles:
    """The files of robot ``name`` (a key of ROBOTS); ValueError for an unknown name."""
    if name not in ROBOTS:
        raise ValueError(f"unknown robot {name!r}; known: {sorted(ROBOTS)}")
    return ROBOTS[name]


def robot_urdf(name: str) -> Path:
    """Path of the URDF of robot ``name``. ValueError for an unknown name (listing the known ones),
    FileNotFoundError if the file is absent (for JVRC-1: the shared datasets, see ``$SPQ_SHARED_DATASETS``)."""
    path = robot_files(name).urdf
    if not path.is_file():
        raise FileNotFoundError(f"URDF of robot {name!r} not found at {path} (shared data: set ${ENV_SHARED})")
    return path


def link_shape_file(name: str, mesh_filename: str) -> Path:
    """File to build a convex hull from for a mesh of robot ``name``, given the mesh filename as
    written in its URDF (``MeshGeometry.filename``): the ready-made hull in ``convex_dir`` if the
    robot has one, else the mesh under ``mesh_root`` (a ``package://`` prefix and the package
    name are dropped when the rest is not found under the root). FileNotFoundError if absent."""
    files = robot_files(name)
    if files.convex_dir is not None:
        stem = Path(mesh_filename.removeprefix(PACKAGE_PREFIX)).stem
        path = files.convex_dir / f"{stem}{JVRC1_SUFFIX}"
        candidates = [path]
    else:
        rest = mesh_filename.removeprefix(PACKAGE_PREFIX)
        candidates = [files.mesh_root / rest]
        if mesh_filename.startswith(PACKAGE_PREFIX) and "/" in rest:
            candidates.append(files.mesh_root / rest.split("/", 1)[1])  # package://<package>/<path in package>
    for path in candidates:
        if path.is_file():
            return path
    looked = [str(p) for p in candidates]
    raise FileNotFoundError(f"no file for mesh {mesh_filename!r} of robot {name!r}; looked at {looked}")
