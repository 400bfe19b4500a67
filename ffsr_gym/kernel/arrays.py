"""Arrays for the native kernel, extracted from the Pinocchio model and the collision file.

The URDF (through Pinocchio) stays the single source of truth: the kernel receives the joint
placements, axes, inertias, end-effector frames and collision primitives read here, never numbers
of its own. Joints are stored in the paper's order (mission arm first); index maps convert to
Pinocchio's ``q``/``v`` layout.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ffsr_gym.exceptions import RobotFileError
from ffsr_gym.model.collision import CollisionModel
from ffsr_gym.model.robot import Robot

_AXES = {"JointModelRX": (1.0, 0.0, 0.0), "JointModelRY": (0.0, 1.0, 0.0), "JointModelRZ": (0.0, 0.0, 1.0)}


@dataclass(frozen=True)
class KernelModel:
    """Robot and collision arrays in kernel order (joint k = paper joint k, mission arm first).

    Attributes:
        parent: (12,) kernel index of the parent joint, -1 for the base.
        placement_R, placement_p: (12, 3, 3), (12, 3) joint placement in the parent joint frame.
        axis: (12, 3) joint axis in the joint frame.
        mass: (13,) body masses [kg], 0 = base.
        lever: (13, 3) body CoM in its joint frame [m].
        inertia: (13, 3, 3) rotational inertia about the CoM in the joint frame [kg m²].
        ee_parent, ee_R, ee_p: end-effector frames (mission, balance).
        cap_parent, cap_a, cap_b, cap_radius, cap_arm, cap_vs_base: capsules (axis end points in the
            parent joint frame [m], radius [m], arm 0/1, whether checked against the base).
        box_half: (3,) base box half extents [m], centred on the base frame.
        q_index, v_index: (12,) Pinocchio ``q`` / ``v`` index of each kernel joint.
        axis_code: (12,) 0, 1, 2 for a joint about the frame's x, y, z axis (a cheaper rotation in
            the kernel), -1 for any other axis.

    Joints are in tree order within each arm: a parent has a smaller index than its children and
    lies on the same arm (joints 0-5 mission, 6-11 balance), as the kernel's passes assume.
    """

    parent: np.ndarray
    placement_R: np.ndarray
    placement_p: np.ndarray
    axis: np.ndarray
    mass: np.ndarray
    lever: np.ndarray
    inertia: np.ndarray
    ee_parent: np.ndarray
    ee_R: np.ndarray
    ee_p: np.ndarray
    cap_parent: np.ndarray
    cap_a: np.ndarray
    cap_b: np.ndarray
    cap_radius: np.ndarray
    cap_arm: np.ndarray
    cap_vs_base: np.ndarray
    box_half: np.ndarray
    q_index: np.ndarray
    v_index: np.ndarray
    axis_code: np.ndarray


def extract(robot: Robot, collision: CollisionModel) -> KernelModel:
    """Read the kernel arrays from a Pinocchio robot and its collision model.

    Raises:
        RobotFileError: a joint type the kernel does not support, or a base whose frame is not at
            its centre of mass.
    """
    model = robot.model
    pin_ids = [int(j) for j in robot.joint_ids.ravel()]
    kernel_of = {pin_id: k for k, pin_id in enumerate(pin_ids)}
    if np.linalg.norm(model.inertias[1].lever) > 0.0:
        raise RobotFileError("the kernel needs the base link frame at the base centre of mass")
    parent, R, p, axis = [], [], [], []
    for pin_id in pin_ids:
        joint = model.joints[pin_id]
        name = joint.shortname()
        if name in _AXES:
            axis.append(_AXES[name])
        elif name == "JointModelRevoluteUnaligned":
            axis.append(tuple(joint.extract().axis))
        else:
            raise RobotFileError(f"joint {model.names[pin_id]!r} of type {name} is not supported by the kernel")
        parent.append(kernel_of.get(int(model.parents[pin_id]), -1))
        k = len(parent) - 1
        if parent[k] >= k or (parent[k] >= 0 and parent[k] // 6 != k // 6):
            raise RobotFileError(f"joint {model.names[pin_id]!r}: the kernel needs each arm's joints in chain order "
                                 f"from its base (joint {k} has parent {parent[k]})")
        R.append(model.jointPlacements[pin_id].rotation)
        p.append(model.jointPlacements[pin_id].translation)
    bodies = [1, *pin_ids]
    ee = [model.frames[int(f)] for f in robot.ee_frame_ids]
    parts = collision._parts[1:]
    frames = [model.frames[part.frame_id] for part in parts]
    placements = [frame.placement * part.local for frame, part in zip(frames, parts)]
    half_lengths = [part.shape.halfLength for part in parts]
    ignored = collision._ignored
    return KernelModel(
        parent=np.array(parent, dtype=np.int64), placement_R=np.array(R), placement_p=np.array(p),
        axis=np.array(axis, dtype=float),
        mass=np.array([model.inertias[b].mass for b in bodies]),
        lever=np.array([model.inertias[b].lever for b in bodies]),
        inertia=np.array([model.inertias[b].inertia for b in bodies]),
        ee_parent=np.array([kernel_of[int(f.parentJoint)] for f in ee], dtype=np.int64),
        ee_R=np.array([f.placement.rotation for f in ee]), ee_p=np.array([f.placement.translation for f in ee]),
        cap_parent=np.array([kernel_of.get(int(f.parentJoint), -1) for f in frames], dtype=np.int64),
        cap_a=np.array([pl.act(np.array([0.0, 0.0, -h])) for pl, h in zip(placements, half_lengths)]),
        cap_b=np.array([pl.act(np.array([0.0, 0.0, h])) for pl, h in zip(placements, half_lengths)]),
        cap_radius=np.array([part.shape.radius for part in parts]),
        cap_arm=np.array([0 if part.arm == "mission" else 1 for part in parts], dtype=np.int64),
        cap_vs_base=np.array([frozenset(("base", part.name)) not in ignored for part in parts]),
        box_half=np.array(collision._parts[0].shape.halfSide),
        q_index=robot.joint_q_index.astype(np.int64), v_index=robot.joint_v_index.astype(np.int64),
        axis_code=np.array([_axis_code(a) for a in axis], dtype=np.int64),
    )


def _axis_code(axis: tuple[float, ...]) -> int:
    """0, 1, 2 when ``axis`` is the unit x, y or z axis, else -1."""
    for code in range(3):
        if tuple(axis) == tuple(1.0 if i == code else 0.0 for i in range(3)):
            return code
    return -1
