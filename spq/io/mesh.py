"""Mesh files (anything trimesh reads: .obj, .stl, .ply, .dae, ...) as vertex arrays."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def load_mesh_vertices(mesh) -> np.ndarray:
    """(n, 3) float64 vertices of a mesh given as a path or a trimesh object (units of the file).

    Raises ValueError for a missing or unreadable file, or a mesh without vertices."""
    if isinstance(mesh, (str, Path)):
        import trimesh

        path = Path(mesh)
        if not path.is_file():
            raise ValueError(f"mesh file not found: {path}")
        try:
            mesh = trimesh.load(path, force="mesh", process=False)
        except Exception as exc:  # trimesh raises many types for unreadable files
            raise ValueError(f"cannot read mesh {path}: {exc}") from None
    vertices = getattr(mesh, "vertices", None)
    if vertices is None or len(vertices) == 0:
        raise ValueError(f"mesh {mesh!r} has no vertices")
    return np.asarray(vertices, dtype=np.float64)
