"""What a robot description must satisfy before anything simulates it (docs/robots.md).

Checked once per robot and process, when its models are first built
(:class:`ffsr_gym.sim.setup.RobotAssets`): the URDF's joints (names, count, type, the chain of each
arm), the end-effector frames, the base frame at the base's centre of mass, every body's mass and
rotational inertia (positive definite, triangle inequality), and the collision file's primitives
(named after links of their arm, with positive sizes). Every error names the file and the element.
"""

from __future__ import annotations

import math
from functools import lru_cache
from pathlib import Path

import numpy as np
import pinocchio as pin

from ffsr_gym.exceptions import RobotFileError
from ffsr_gym.model.resources import robot_files
from ffsr_gym.model.robot import ARMS, JOINTS_PER_ARM, Robot, files_stamp, load_robot

#: Joint types the closed loop integrates: revolute about any fixed axis.
REVOLUTE = ("JointModelRX", "JointModelRY", "JointModelRZ", "JointModelRevoluteUnaligned")
#: How far the base's centre of mass may sit from its link frame [m] (the free-flyer position is the base CoM).
BASE_COM_TOLERANCE_M = 1e-9


def link_of_joint(robot: Robot, joint_id: int) -> str:
    """The URDF link a joint moves (its child body)."""
    for frame in robot.model.frames:
        if frame.type == pin.FrameType.BODY and int(frame.parentJoint) == joint_id:
            return frame.name
    return robot.model.names[joint_id]


def check_robot(robot: Robot) -> None:
    """Raise :class:`RobotFileError`, naming the URDF and the element, if ``robot`` is not a dual-arm FFSR.

    The loader has already found ``<arm>_joint1..6`` and ``<arm>_ee`` (it names a missing one).
    """
    model, where = robot.model, robot.urdf_path
    expected = {f"{arm}_joint{k}" for arm in ARMS for k in range(1, JOINTS_PER_ARM + 1)}
    extra = [name for name in list(model.names)[2:] if name not in expected]
    if extra or model.nv != 6 + 2 * JOINTS_PER_ARM:
        raise RobotFileError(f"{where}: joints {extra}: a robot has exactly 12 movable joints, "
                             "mission_joint1..6 and balance_joint1..6 (fixed joints are allowed)")
    for arm, ids in zip(ARMS, robot.joint_ids):
        parent = 1  # the free-flyer: the base
        for k, joint_id in enumerate(int(j) for j in ids):
            name, kind = model.names[joint_id], model.joints[joint_id].shortname()
            if kind not in REVOLUTE:
                raise RobotFileError(f"{where}: joint {name!r} is of type {kind}; allowed: revolute (or continuous)")
            if int(model.parents[joint_id]) != parent:
                raise RobotFileError(f"{where}: joint {name!r} hangs from {model.names[int(model.parents[joint_id])]!r}; "
                                     f"the {arm} arm is a chain: {arm}_joint1 on the base link, {arm}_joint{k + 1} on "
                                     f"{arm}_joint{k}'s link")
            parent = joint_id
        ee = model.frames[int(robot.ee_frame_ids[ARMS.index(arm)])]
        if int(ee.parentJoint) != parent:
            raise RobotFileError(f"{where}: frame '{arm}_ee' is attached to {model.names[int(ee.parentJoint)]!r}; "
                                 f"allowed: the link of {arm}_joint6")
    base = model.inertias[1]
    if np.linalg.norm(base.lever) > BASE_COM_TOLERANCE_M:
        raise RobotFileError(f"{where}: the root link's centre of mass is at {np.round(base.lever, 6).tolist()} m in "
                             "its frame; allowed: [0, 0, 0] (the base frame is the base's centre of mass)")
    for joint_id in [1, *(int(j) for j in robot.joint_ids.ravel())]:
        _check_inertia(where, link_of_joint(robot, joint_id), model.inertias[joint_id])


def check_robot_folder(ref: str) -> None:
    """Load the robot ``ref`` (a shipped name or a folder) and check its URDF and its collision file.

    Done once per robot and version of its files (a scenario naming it may load many times, e.g. a
    seeded family at every reset); a robot that fails is checked again, and fails again, each time.

    Raises:
        RobotFileError: what :func:`check_robot` or the collision file's reader finds, file and element named.
    """
    urdf = robot_files(ref)[0]
    _check_folder(str(urdf), files_stamp(urdf.parent))


@lru_cache(maxsize=8)
def _check_folder(urdf: str, stamp: tuple) -> None:
    from ffsr_gym.model.collision import CollisionModel

    robot = load_robot(urdf)
    check_robot(robot)
    CollisionModel(robot)


def _check_inertia(where: Path, link: str, inertia: pin.Inertia) -> None:
    mass = float(inertia.mass)
    if not (math.isfinite(mass) and mass > 0.0):
        raise RobotFileError(f"{where}: link {link!r} has mass {mass!r} kg; allowed: a finite number > 0")
    matrix = np.asarray(inertia.inertia, dtype=float)
    moments = np.linalg.eigvalsh(0.5 * (matrix + matrix.T)) if np.all(np.isfinite(matrix)) else np.array([np.nan])
    if not np.all(moments > 0.0):
        raise RobotFileError(f"{where}: link {link!r} has a rotational inertia with principal moments "
                             f"{np.round(moments, 9).tolist()} kg m²; allowed: positive definite")
    a, b, c = np.sort(moments)
    if a + b < c * (1.0 - 1e-9):
        raise RobotFileError(f"{where}: link {link!r}: principal moments {np.round(moments, 9).tolist()} kg m² break "
                             "the triangle inequality (no body has them)")
