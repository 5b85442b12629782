"""SRDFs made here, by sampling, for robots that ship none (MoveIt's setup-assistant rules,
spq.collision_pairs.disabled_pairs_by_sampling). Each file says in its opening comment how it was made;
regenerate it with the command in GENERATED.

- ``jvrc1.srdf``: JVRC-1 (shared data), its PCH bodies (the qhull hulls of ``jvrc1/convex``).
"""

from __future__ import annotations

from pathlib import Path

FOLDER = Path(__file__).resolve().parent
GENERATED = {  # robot name (datasets.robots) -> (file, the command that writes it, run from the repository root)
    "jvrc1": ("jvrc1.srdf", "spq srdf jvrc1 --out datasets/srdf/jvrc1.srdf --samples 100000 --seed 0"),
}


def generated_srdf(name: str) -> Path | None:
    """The SRDF generated here for robot ``name`` (a key of datasets.robots.ROBOTS), or None."""
    entry = GENERATED.get(name)
    if entry is None:
        return None
    path = FOLDER / entry[0]
    return path if path.is_file() else None
