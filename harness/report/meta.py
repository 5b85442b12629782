"""What a report records about the run: versions, machine, seeds, tolerances, time."""

from __future__ import annotations

import datetime as _dt
import os
import platform
from importlib import metadata


def _version(dist: str) -> str:
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return "not installed"


PACKAGES = ("spq", "numpy", "scipy", "numba", "python-fcl", "coal", "pybullet", "trimesh", "pandas")


def run_metadata(**extra) -> dict:
    """Versions of the packages measured, machine, and the caller's settings (seed, tolerances...)."""
    return {
        "date": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "python": platform.python_version(),
        "machine": f"{platform.machine()} {platform.processor() or ''} {os.cpu_count()} cpus".strip(),
        "platform": platform.platform(),
        "versions": {p: _version(p) for p in PACKAGES},
        **extra,
    }
