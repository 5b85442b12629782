"""Loaders for the shared reference data (``../shared/datasets``, see its README).

- ``sch-samples/sample_polyhedron.otp``: convex polyhedron in qhull ``o f`` output (96 points).
- ``jvrc1/convex/NAME-ch.txt``: convex hulls of the 35 JVRC-1 humanoid links, same format.

All return Polyhedra in the file's frame (metres). A missing shared directory or file raises
FileNotFoundError naming the path and the ``SPQ_SHARED_DATASETS`` override; an unknown name raises
ValueError listing the known ones.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

from datasets.paths import ENV_SHARED, shared_datasets_dir
from spq.shapes.polyhedron import Polyhedron

SCH_SAMPLE_POLYHEDRON = "sch-samples/sample_polyhedron.otp"
JVRC1_CONVEX_DIR = "jvrc1/convex"
JVRC1_SUFFIX = "-ch.txt"


def _shared_path(relative: str) -> Path:
    root = shared_datasets_dir()
    if root is None:
        raise FileNotFoundError(
            "shared datasets not found: expected <repo>/../shared/datasets, or set "
            f"${ENV_SHARED} to the directory"
        )
    path = root / relative
    if not path.exists():
        raise FileNotFoundError(f"shared dataset file missing: {path}")
    return path


@lru_cache(maxsize=None)
def sch_sample_polyhedron() -> Polyhedron:
    """The sch-core sample polyhedron (``sch-samples/sample_polyhedron.otp``)."""
    poly = Polyhedron.from_qhull_file(_shared_path(SCH_SAMPLE_POLYHEDRON))
    poly.name = "sch_sample_polyhedron"
    return poly


def jvrc1_hull_names() -> list[str]:
    """Sorted names of the JVRC-1 convex hulls (e.g. 'PELVIS_S', 'R_KNEE_S')."""
    folder = _shared_path(JVRC1_CONVEX_DIR)
    return sorted(p.name[: -len(JVRC1_SUFFIX)] for p in folder.glob(f"*{JVRC1_SUFFIX}"))


def jvrc1_hull(name: str) -> Polyhedron:
    """Convex hull of the JVRC-1 link ``name`` ('PELVIS_S'; 'PELVIS_S-ch' and 'PELVIS_S-ch.txt'
    are accepted too), in the link's mesh frame (metres). Cached: do not modify it."""
    if not isinstance(name, str):
        raise ValueError(f"JVRC-1 hull name must be a string; got {name!r}")
    base = name[: -len(".txt")] if name.endswith(".txt") else name
    base = base[: -len("-ch")] if base.endswith("-ch") else base
    names = jvrc1_hull_names()
    if base not in names:
        raise ValueError(f"unknown JVRC-1 hull {name!r}; known: {names}")
    return _load_jvrc1(base)


@lru_cache(maxsize=None)
def _load_jvrc1(base: str) -> Polyhedron:
    poly = Polyhedron.from_qhull_file(_shared_path(f"{JVRC1_CONVEX_DIR}/{base}{JVRC1_SUFFIX}"))
    poly.name = f"jvrc1:{base}"
    return poly
