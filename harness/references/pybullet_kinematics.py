"""pybullet as an independent oracle for forward kinematics: its link frames for given configurations.

pybullet parses the URDF itself and runs its own forward kinematics, so agreeing with it checks
both spq's URDF reading (via yourdfpy) and its compiled kinematics.
"""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from spq.kinematics import FIXED


def urdf_without_geometry(path: Path, folder: Path) -> Path:
    """A copy of the URDF without <visual>/<collision>: pybullet refuses JVRC-1, whose
    package://jvrc_description meshes are not shipped, and kinematics does not need geometry."""
    tree = ET.parse(path)
    for link in tree.getroot().iter("link"):
        for tag in ("visual", "collision"):
            for element in link.findall(tag):
                link.remove(element)
    out = Path(folder) / Path(path).name
    tree.write(out)
    return out


def quaternion_matrix(quat) -> np.ndarray:
    """Rotation matrix of an (x, y, z, w) quaternion (normalised first)."""
    x, y, z, w = np.asarray(quat, dtype=np.float64) / np.linalg.norm(quat)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def link_frame(com_position, com_orientation, inertial_position, inertial_orientation) -> np.ndarray:
    """URDF link frame = centre-of-mass frame @ inverse(local inertial frame), composed in double.

    pybullet's own worldLinkFramePosition/Orientation (getLinkState indices 4, 5) are this product
    computed by its client library in single precision (0.1575 comes back as 0.15749999880...), so
    they agree with any exact FK only to ~1e-7; indices 0-3 are the server's doubles."""
    R_com, R_in = quaternion_matrix(com_orientation), quaternion_matrix(inertial_orientation)
    T = np.eye(4)
    T[:3, :3] = R_com @ R_in.T
    T[:3, 3] = np.asarray(com_position) - T[:3, :3] @ np.asarray(inertial_position)
    return T


@contextlib.contextmanager
def c_stdout_silenced():
    """Send the process's file descriptor 1 to /dev/null: pybullet's URDF importer prints warnings
    (links without inertial data, which kinematics does not use) from C, past Python's sys.stdout."""
    sys.stdout.flush()
    saved = os.dup(1)
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 1)
        yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)


class PybulletRobot:
    """A URDF loaded in a private pybullet DIRECT client with a fixed base, its joints mapped to a
    :class:`spq.RobotModel`'s links by name. Use as a context manager (it disconnects)."""

    def __init__(self, urdf_path, model, strip_geometry: bool = False):
        import pybullet as pb

        self._pb = pb
        self.model = model
        self._tmp = tempfile.TemporaryDirectory()
        load = urdf_without_geometry(Path(urdf_path), Path(self._tmp.name)) if strip_geometry else urdf_path
        self.client = pb.connect(pb.DIRECT)
        with c_stdout_silenced():
            self.body = pb.loadURDF(str(load), useFixedBase=True, physicsClientId=self.client)
        n = pb.getNumJoints(self.body, physicsClientId=self.client)
        self.joint_info = [pb.getJointInfo(self.body, j, physicsClientId=self.client) for j in range(n)]
        # pybullet: joint j connects link j (its child) to its parent
        self.links = [model.link_index(row[12].decode()) for row in self.joint_info]

    def set_configuration(self, q) -> None:
        values = self.model.joint_values(q)  # pybullet ignores <mimic>: set every joint
        for j, (row, i) in enumerate(zip(self.joint_info, self.links)):
            if row[2] != self._pb.JOINT_FIXED:
                self._pb.resetJointState(self.body, j, values[i], physicsClientId=self.client)

    def base_frame(self) -> np.ndarray:
        pb, c = self._pb, self.client
        com = pb.getBasePositionAndOrientation(self.body, physicsClientId=c)
        inertial = pb.getDynamicsInfo(self.body, -1, physicsClientId=c)[3:5]
        return link_frame(*com, *inertial)

    def link_states(self) -> list:
        """getLinkState of every pybullet link (forward kinematics computed)."""
        return [self._pb.getLinkState(self.body, j, computeForwardKinematics=True, physicsClientId=self.client)
                for j in range(len(self.joint_info))]

    def link_frames(self, q) -> np.ndarray:
        """(nlinks, 4, 4) world frames of the model's links at q, by pybullet; the root is pybullet's base."""
        self.set_configuration(q)
        out = np.empty((self.model.nlinks, 4, 4))
        out[:] = self.base_frame()  # the root, and any link pybullet does not list
        for state, i in zip(self.link_states(), self.links):
            out[i] = link_frame(*state[:4])
        return out

    def fixed_joints_agree(self) -> bool:
        return all((row[2] == self._pb.JOINT_FIXED) == (self.model.joint_type[i] == FIXED)
                   for row, i in zip(self.joint_info, self.links))

    def close(self) -> None:
        if self.client is not None:
            self._pb.disconnect(self.client)
            self.client = None
        self._tmp.cleanup()

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def fk_errors(urdf_path, model, qs, strip_geometry: bool = False) -> tuple[float, float]:
    """Largest |position| (m) and |rotation entry| differences between model.link_poses and
    pybullet's link frames over configurations qs."""
    worst_p = worst_r = 0.0
    with PybulletRobot(urdf_path, model, strip_geometry) as robot:
        for q in qs:
            ours, theirs = model.link_poses(q), robot.link_frames(q)
            worst_p = max(worst_p, float(np.abs(ours[:, :3, 3] - theirs[:, :3, 3]).max()))
            worst_r = max(worst_r, float(np.abs(ours[:, :3, :3] - theirs[:, :3, :3]).max()))
    return worst_p, worst_r
