"""Robot-link meshes shipped with pybullet_data (KUKA LBR iiwa and Franka Panda), as convex hulls.

Each name maps to a mesh path relative to ``pybullet_data.getDataPath()``; :func:`load_link` returns
the convex hull of the mesh vertices as a :class:`~spq.shapes.polyhedron.Polyhedron` in the mesh's
own frame (metres; the link frame of the URDF). Results are cached: repeated calls return the same
object, so do not modify it.

Hull sizes (vertices): kuka_link_0 188, kuka_link_1 574, kuka_link_2 296, kuka_link_3 362,
kuka_link_4 315, kuka_link_5 253, kuka_link_6 346, kuka_link_7 327, panda_link_0 102,
panda_link_1..5 152, panda_link_6 260, panda_link_7 102, panda_hand 102, panda_finger 18.
"""

from __future__ import annotations

from functools import lru_cache

from datasets.paths import pybullet_data_dir
from spq.shapes.polyhedron import Polyhedron

ROBOT_LINKS: dict[str, str] = {
    **{f"kuka_link_{i}": f"kuka_iiwa/meshes/link_{i}.obj" for i in range(0, 8)},
    **{f"panda_link_{i}": f"franka_panda/meshes/collision/link{i}.obj" for i in range(0, 8)},
    "panda_hand": "franka_panda/meshes/collision/hand.obj",
    "panda_finger": "franka_panda/meshes/collision/finger.obj",
}
"""Link name -> mesh path relative to pybullet_data."""


def link_path(name: str):
    """Absolute path of the mesh of link ``name``."""
    if name not in ROBOT_LINKS:
        raise ValueError(f"unknown robot link {name!r}; known: {sorted(ROBOT_LINKS)}")
    path = pybullet_data_dir() / ROBOT_LINKS[name]
    if not path.is_file():
        raise FileNotFoundError(f"mesh of {name!r} not found at {path} (is pybullet_data complete?)")
    return path


@lru_cache(maxsize=None)
def load_link(name: str) -> Polyhedron:
    """Convex hull (Polyhedron, link frame, metres) of the robot link ``name`` (a key of ROBOT_LINKS)."""
    poly = Polyhedron.from_mesh(link_path(name))
    poly.name = name
    return poly
