"""SRDFs made here, by sampling, for robots that ship none (MoveIt's setup-assistant rules,
spq.collision_pairs.disabled_pairs_by_sampling). Each file says in its opening comment how it was made;
regenerate it with the command in GENERATED.

- ``jvrc1.srdf``: JVRC-1 (shared data), its PCH bodies (the qhull hulls of ``jvrc1/convex``),
  100000 random configurations (the top of the setup assistant's sampling-density range), seed 0:
  of 595 link pairs, 34 Adjacent (the pairs Scene's skip_adjacent skips), 1 Default (PELVIS_S -
  WAIST_R_S, in collision at nearly every configuration), 0 Always, 218 Never; 342 left. Pairs in
  collision at a third of the configurations (PELVIS_S - R_HIP_Y_S and L_HIP_Y_S, a wrist and its
  lower finger segments) are not disabled by MoveIt's rules and stay. The Never pairs include the
  two hands' and a hand against the other arm's: see spq.collision_pairs on keeping them.
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
