"""Where data lives: the shared reference datasets and pybullet's bundled models."""

from __future__ import annotations

import os
from pathlib import Path

ENV_SHARED = "SPQ_SHARED_DATASETS"
REPO_ROOT = Path(__file__).resolve().parent.parent


def shared_datasets_dir() -> Path | None:
    """Directory of the shared reference data, or None if it is missing.

    ``$SPQ_SHARED_DATASETS`` if set (it must then be an existing directory, else None), otherwise
    ``<repo root>/../shared/datasets`` (the repository root is the parent of this package), else
    ``../shared/datasets`` from the working directory: after ``pip install .`` this package lives
    in site-packages, and the README's commands run from the checkout, with ``shared`` beside it.
    """
    override = os.environ.get(ENV_SHARED)
    if override:
        candidates = [Path(override).expanduser()]
    else:
        candidates = [REPO_ROOT.parent / "shared" / "datasets", Path.cwd().parent / "shared" / "datasets"]
    for path in candidates:
        if path.is_dir():
            return path.resolve()
    return None


def pybullet_data_dir() -> Path:
    """Directory of the models shipped with pybullet (``pybullet_data.getDataPath()``)."""
    try:
        import pybullet_data
    except ImportError as exc:  # pragma: no cover - pybullet is a dependency
        raise ImportError(f"pybullet_data is needed for the robot-link meshes: {exc}") from None
    return Path(pybullet_data.getDataPath())
