"""datasets: where the convex objects used by tests and benchmarks come from.

- Robot links from pybullet_data (:mod:`datasets.robot_links`): 'kuka_link_0'..'kuka_link_7',
  'panda_link_0'..'panda_link_7', 'panda_hand', 'panda_finger'.
- Seeded random hulls (:mod:`datasets.generated`): 'random_hull_50', 'random_hull_200'.
- Shared reference data (:mod:`datasets.shared`, needs ``../shared/datasets``):
  'sch_sample_polyhedron' and 'jvrc1:NAME' for the JVRC-1 link hulls.

Every object is a :class:`spq.shapes.polyhedron.Polyhedron` in its own frame (metres) carrying a
``name`` attribute. ``datasets`` may import ``spq``, never ``harness``.
"""

from __future__ import annotations

from pathlib import Path

from datasets.generated import GENERATED, load_generated, random_hull
from datasets.paths import pybullet_data_dir, shared_datasets_dir
from datasets.robot_links import ROBOT_LINKS, load_link
from datasets.shared import jvrc1_hull, jvrc1_hull_names, sch_sample_polyhedron
from spq.shapes.polyhedron import Polyhedron

DEFAULT_OBJECTS: list[str] = [
    "kuka_link_2",
    "kuka_link_4",
    "kuka_link_6",
    "panda_link_2",
    "panda_link_5",
    "panda_hand",
    "random_hull_50",
    "random_hull_200",
]
"""Objects used by default in benchmarks: six robot links and two random hulls."""

SCH_SAMPLE_NAME = "sch_sample_polyhedron"
JVRC1_PREFIX = "jvrc1:"


def _is_qhull_file(path: Path) -> bool:
    """True if the file starts like qhull 'o f' output (first non-blank line is the dimension 3)."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(256)
    except OSError:
        return False
    for line in head.splitlines():
        if line.strip():
            return line.strip() == b"3"
    return False


def load_object(name_or_path) -> Polyhedron:
    """A Polyhedron from a dataset name (see :func:`list_objects`) or a file path.

    Paths: a qhull ``o f`` file (first line ``3``, e.g. the JVRC-1 ``*-ch.txt`` files) is read with
    ``Polyhedron.from_qhull_file``; anything else goes to ``Polyhedron.from_mesh`` (any mesh format
    trimesh reads: .obj, .stl, .ply, .dae ...). Raises ValueError for an unknown name that is not an
    existing file.
    """
    if isinstance(name_or_path, str):
        name = name_or_path
        if name in ROBOT_LINKS:
            return load_link(name)
        if name in GENERATED:
            return load_generated(name)
        if name == SCH_SAMPLE_NAME:
            return sch_sample_polyhedron()
        if name.startswith(JVRC1_PREFIX):
            return jvrc1_hull(name[len(JVRC1_PREFIX) :])
    elif not isinstance(name_or_path, Path):
        raise ValueError(f"expected a dataset name or a file path; got {type(name_or_path).__name__}")
    path = Path(name_or_path).expanduser()
    if not path.is_file():
        raise ValueError(
            f"{str(name_or_path)!r} is neither a known object nor an existing file; "
            f"known names: {list_objects(include_shared=False)} plus '{SCH_SAMPLE_NAME}' and "
            f"'{JVRC1_PREFIX}NAME' from the shared data"
        )
    poly = Polyhedron.from_qhull_file(path) if _is_qhull_file(path) else Polyhedron.from_mesh(path)
    poly.name = path.stem
    return poly


def list_objects(include_shared: bool = True) -> list[str]:
    """Names :func:`load_object` accepts: robot links, generated hulls and, when the shared data is
    present and ``include_shared``, the sch sample polyhedron and the JVRC-1 hulls."""
    names = list(ROBOT_LINKS) + list(GENERATED)
    if include_shared and shared_datasets_dir() is not None:
        names.append(SCH_SAMPLE_NAME)
        try:
            names += [JVRC1_PREFIX + n for n in jvrc1_hull_names()]
        except FileNotFoundError:
            pass
    return names


__all__ = [
    "DEFAULT_OBJECTS",
    "GENERATED",
    "ROBOT_LINKS",
    "jvrc1_hull",
    "jvrc1_hull_names",
    "list_objects",
    "load_generated",
    "load_link",
    "load_object",
    "pybullet_data_dir",
    "random_hull",
    "sch_sample_polyhedron",
    "shared_datasets_dir",
]
