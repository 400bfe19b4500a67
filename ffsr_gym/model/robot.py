"""Pinocchio model of the dual-arm free-floating space robot and its momentum kinematics.

Conventions (docs/model.md §1-2):

* ``q`` (size 19) and ``v`` (size 18) are in Pinocchio order: free-flyer first (position [m],
  quaternion ``(x, y, z, w)``; linear and angular velocity [m/s, rad/s] in the **base frame**),
  then the revolute joints in the model's order.
* ``dq_joints`` (size 12) are joint rates [rad/s] in the paper's order, mission arm first.
* "World" twists ``V = [v; ω]`` are the paper's: linear part first, both in the inertial frame,
  ``v`` of the frame origin (for the base: its centre of mass).
* Momentum matrices follow docs/model.md §2 (R5): ``H_b V_0 + H_bm1 dq1 + H_bm2 dq2 = C`` with
  ``C = [P; L_0]`` and ``L_0`` the angular momentum about the base centre of mass.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np
import pinocchio as pin

from ffsr_gym.exceptions import InvalidInputError, RobotFileError
from ffsr_gym.model import portable
from ffsr_gym.model.quaternion import skew, wxyz_from_xyzw, xyzw_from_wxyz
from ffsr_gym.model.resources import robot_files
from ffsr_gym.model.urdf_check import read_urdf
from ffsr_gym.types import Array

ARMS = ("mission", "balance")
JOINTS_PER_ARM = 6
LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


@dataclass(frozen=True)
class MomentumMatrices:
    """World-frame momentum matrices about the base centre of mass (docs/model.md §2, R5).

    Attributes:
        H_b: (6, 6) base inertia matrix, maps the world base twist V_0 to [P; L_0].
        H_bm: (2, 6, 6) coupling matrices of the (mission, balance) arms, map joint rates
            [rad/s] to [P; L_0].
    """

    H_b: Array
    H_bm: Array


class Robot:
    """A dual-arm free-floating robot loaded from a URDF with a free-flyer root.

    The URDF must name its revolute joints ``<arm>_joint1..6`` and its end-effector frames
    ``<arm>_ee`` for ``arm`` in ``("mission", "balance")``; the root link is the base, with its
    frame at the base centre of mass.
    """

    def __init__(self, urdf_path: str | Path) -> None:
        path = Path(urdf_path)
        if not path.is_file():
            raise RobotFileError(f"robot file {str(path)!r} does not exist")
        text = read_urdf(path)  # checked as the file says, before Pinocchio merges its fixed links
        try:
            self.model = pin.buildModelFromXML(text, pin.JointModelFreeFlyer())
        except (RuntimeError, ValueError) as exc:
            raise RobotFileError(f"robot file {str(path)!r} could not be parsed: {exc}") from exc
        self.urdf_path = path
        self.data = self.model.createData()
        self.joint_ids = np.array([[self._joint_id(f"{arm}_joint{k}") for k in range(1, 7)] for arm in ARMS])
        self.arm_q_index = np.array([[self.model.joints[int(j)].idx_q for j in row] for row in self.joint_ids])
        self.arm_v_index = np.array([[self.model.joints[int(j)].idx_v for j in row] for row in self.joint_ids])
        self.joint_v_index = self.arm_v_index.ravel()
        self.joint_q_index = self.arm_q_index.ravel()
        self.ee_frame_ids = np.array([self._frame_id(f"{arm}_ee") for arm in ARMS])
        self.total_mass = float(sum(inertia.mass for inertia in self.model.inertias))

    def __reduce__(self) -> tuple:
        """Pickle as the URDF path (and the plant's changes); the model is rebuilt on load."""
        changes = getattr(self, "inertial_changes", None)
        if changes is not None:
            return (_changed_robot, (self.urdf_path, changes))
        return (Robot, (self.urdf_path,))

    def with_inertial_changes(self, mass_scale: Array, inertia_scale: Array, com_offset_m: Array) -> Robot:
        """A copy whose bodies' masses, rotational inertias (about the CoM) and link CoMs are changed.

        Bodies in the paper's order: 0 the base, then the mission arm's links and the balance
        arm's. ``com_offset_m`` (12, 3) moves each link's CoM in its joint frame; the base's
        frame stays its CoM. The kinematics are unchanged.
        """
        mass_scale, inertia_scale = np.asarray(mass_scale, dtype=float), np.asarray(inertia_scale, dtype=float)
        offsets = np.zeros((13, 3))
        offsets[1:] = np.asarray(com_offset_m, dtype=float).reshape(12, 3)
        copy = Robot.__new__(Robot)
        copy.__dict__.update(self.__dict__)
        copy.model = self.model.copy()
        for body, joint in enumerate([1, *(int(j) for j in self.joint_ids.ravel())]):
            nominal = self.model.inertias[joint]
            copy.model.inertias[joint] = pin.Inertia(nominal.mass * mass_scale[body],
                                                     nominal.lever + offsets[body],
                                                     nominal.inertia * inertia_scale[body])
        copy.data = copy.model.createData()
        copy.total_mass = float(sum(inertia.mass for inertia in copy.model.inertias))
        copy.inertial_changes = (tuple(mass_scale), tuple(inertia_scale), tuple(map(tuple, offsets[1:])))
        return copy

    def _joint_id(self, name: str) -> int:
        if not self.model.existJointName(name):
            raise RobotFileError(f"{self.urdf_path}: joint {name!r} is missing (need <arm>_joint1..6)")
        return self.model.getJointId(name)

    def _frame_id(self, name: str) -> int:
        if not self.model.existFrame(name):
            raise RobotFileError(f"{self.urdf_path}: frame {name!r} is missing")
        return self.model.getFrameId(name)

    # ----------------------------------------------------------------------------- state
    def configuration(self, *, base_position_m: Array, base_quaternion_wxyz: Array, joints_rad: Array) -> Array:
        """Build ``q`` from a base pose and 12 joint angles [rad] (mission arm first)."""
        q = pin.neutral(self.model)
        q[:3] = base_position_m
        quat = np.asarray(base_quaternion_wxyz, dtype=float)
        q[3:7] = xyzw_from_wxyz(quat / portable.norm(quat))
        q[self.joint_q_index] = joints_rad
        return q

    def joint_angles(self, q: Array) -> Array:
        """Return the 12 joint angles [rad], mission arm first."""
        return q[self.joint_q_index]

    def base_pose(self, q: Array) -> tuple[Array, Array]:
        """Return the base CoM position [m] and scalar-first attitude quaternion."""
        return q[:3].copy(), wxyz_from_xyzw(q[3:7])

    # ------------------------------------------------------------------------ kinematics
    def update_kinematics(self, q: Array) -> None:
        """Run forward kinematics, joint Jacobians and frame placements for ``q``."""
        pin.computeJointJacobians(self.model, self.data, q)
        pin.updateFramePlacements(self.model, self.data)

    def transform_ee_to_world(self, q: Array, arm: int) -> pin.SE3:
        """Pose of the end-effector of ``arm`` (0 mission, 1 balance) in the inertial frame."""
        pin.framesForwardKinematics(self.model, self.data, q)
        return self.data.oMf[int(self.ee_frame_ids[arm])].copy()

    def arm_jacobian(self, arm: int) -> Array:
        """Fixed-base Jacobian J_m of ``arm`` (6x6, world-aligned, at its end-effector; R4).

        Requires :meth:`update_kinematics` for the current ``q``.
        """
        J = pin.getFrameJacobian(self.model, self.data, int(self.ee_frame_ids[arm]), LWA)
        return J[:, self.arm_v_index[arm]]

    def ee_jacobian(self, arm: int) -> Array:
        """World-aligned (6, 18) Jacobian of the end-effector of ``arm``: its twist [v; ω] per generalized velocity.

        Requires :meth:`update_kinematics` for the current ``q``.
        """
        return pin.getFrameJacobian(self.model, self.data, int(self.ee_frame_ids[arm]), LWA)

    def ee_twist(self, v: Array, arm: int) -> Array:
        """World-aligned twist [v; ω] (6,) of the end-effector of ``arm`` at the generalized velocity ``v`` (18,).

        Requires :meth:`update_kinematics` for the current ``q``. Each entry is summed left to right
        (:func:`ffsr_gym.model.portable.matvec_rows`: the capture rule reads it, and ``@`` would leave the order
        to the CPU's BLAS kernel); many samples' twists are one ``matvec_rows`` over their :meth:`ee_jacobian`.
        """
        return portable.matvec_rows(self.ee_jacobian(arm)[None], v)[0]

    def joint_points(self, arm: int) -> tuple[Array, Array]:
        """Joint origins p_0..p_5 plus the end-effector p_6 [m] and joint axes z_0..z_5.

        Returns:
            ``(points, axes)`` of shapes (7, 3) and (6, 3), in the inertial frame. Requires
            :meth:`update_kinematics` (or forward kinematics and frame placements) for ``q``.
        """
        placements = [self.data.oMi[int(j)] for j in self.joint_ids[arm]]
        points = np.array([m.translation for m in placements] + [self.data.oMf[int(self.ee_frame_ids[arm])].translation])
        axes = np.array([m.rotation[:, 2] for m in placements])
        return points, axes

    # -------------------------------------------------------------------------- momentum
    def momentum_matrices(self, q: Array) -> MomentumMatrices:
        """World-frame H_b, H_bm1, H_bm2 about the base CoM (R5), from Pinocchio's centroidal map."""
        Ag = pin.computeCentroidalMap(self.model, self.data, q)
        R = self.data.oMi[1].rotation
        T = np.eye(6)
        T[3:, :3] = skew(self.data.com[0] - q[:3])
        H_b = T @ Ag[:, :6] @ np.kron(np.eye(2), R.T)
        H_bm = np.array([T @ Ag[:, idx] for idx in self.arm_v_index])
        return MomentumMatrices(H_b=H_b, H_bm=H_bm)

    def momentum_about_base(self, q: Array, centroidal_momentum: Array) -> Array:
        """Convert ``[P; L_G]`` (about the system CoM) to the paper's ``C = [P; L_0]`` (about r_0).

        Uses the CoM stored by the last :meth:`momentum_matrices` or :meth:`velocity` call.
        """
        h = np.asarray(centroidal_momentum, dtype=float)
        return np.concatenate((h[:3], h[3:] + np.cross(self.data.com[0] - q[:3], h[:3])))

    def centroidal_momentum(self, q: Array, v: Array) -> Array:
        """Total momentum ``[P; L_G]`` [kg m/s, kg m²/s] (Pinocchio's centroidal momentum)."""
        return np.array(pin.computeCentroidalMomentum(self.model, self.data, q, v).vector)

    def system_com(self, q: Array) -> Array:
        """System centre of mass [m] in the inertial frame."""
        return np.array(pin.centerOfMass(self.model, self.data, q))

    def velocity(self, q: Array, dq_joints: Array, centroidal_momentum: Array | None = None) -> Array:
        """Full ``v`` (Pinocchio order) whose base part conserves the total momentum.

        Solves ``A_G v = h`` for the base velocity, with ``A_G`` the centroidal momentum matrix and
        ``h = [P; L_G]`` (zero by default, as in the paper).

        Args:
            q: configuration (19,).
            dq_joints: joint rates [rad/s], (12,), mission arm first.
            centroidal_momentum: conserved ``[P; L_G]`` (6,), default zero.
        """
        Ag = pin.computeCentroidalMap(self.model, self.data, q)
        v = np.zeros(self.model.nv)
        v[self.joint_v_index] = dq_joints
        rhs = -Ag[:, 6:] @ v[6:]
        if centroidal_momentum is not None:
            rhs = rhs + centroidal_momentum
        v[:6] = np.linalg.solve(Ag[:, :6], rhs)
        return v

    def base_twist_world(self, q: Array, v: Array) -> Array:
        """World-frame base twist V_0 = [v_0; ω_0] from Pinocchio's base-frame ``v[:6]``."""
        R = pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix()
        return np.concatenate((R @ v[:3], R @ v[3:6]))

    def generalized_jacobian(self, q: Array, arm: int) -> Array:
        """Generalized Jacobian of the end-effector of ``arm`` for zero momentum (6x12).

        ``V_e = J_g dq_joints`` with the base moving through momentum conservation:
        :math:`J_g = [J_m^1 \\;\\; 0] \\text{ or } [0 \\;\\; J_m^2] - J_0 H_b^{-1} [H_{bm1} \\;\\; H_{bm2}]`
        (Umetani-Yoshida; docs/model.md §2). World-aligned, linear part first, at the end-effector.
        """
        self.update_kinematics(q)
        mats = self.momentum_matrices(q)
        p_e = self.data.oMf[int(self.ee_frame_ids[arm])].translation
        J_0 = np.eye(6)
        J_0[:3, 3:] = -skew(p_e - q[:3])
        J_g = -J_0 @ np.linalg.solve(mats.H_b, np.hstack(mats.H_bm))
        J_g[:, 6 * arm : 6 * arm + 6] += self.arm_jacobian(arm)
        return J_g

    # ------------------------------------------------------------------------ integrator
    def step(self, q: Array, dq_joints: Array, dt: float, centroidal_momentum: Array | None = None) -> tuple[Array, Array]:
        """Advance ``q`` by ``dt`` [s] with joint rates held constant (explicit midpoint on SE(3)).

        The base velocity is re-solved from momentum conservation at the half step, and the base
        moves with ``pin.integrate`` (exponential map), so the quaternion stays unit.

        Returns:
            ``(q_next, v_mid)``: the new configuration and the velocity applied over the step.
        """
        v0 = self.velocity(q, dq_joints, centroidal_momentum)
        q_half = pin.integrate(self.model, q, v0 * (0.5 * dt))
        v_mid = self.velocity(q_half, dq_joints, centroidal_momentum)
        return pin.integrate(self.model, q, v_mid * dt), v_mid


def check_state(q: Array, dq_joints: Array | None = None) -> None:
    """Raise :class:`InvalidInputError` if ``q`` (19,) or ``dq_joints`` (12,) is malformed."""
    for name, value, size in (("q", q, 19), ("dq_joints", dq_joints, 12)):
        if value is None:
            continue
        arr = np.asarray(value)
        if arr.shape != (size,) or not np.all(np.isfinite(arr)):
            raise InvalidInputError(f"{name} must be {size} finite numbers, got shape {arr.shape}: {arr}")


def _changed_robot(urdf_path: Path, changes: tuple) -> Robot:
    return Robot(urdf_path).with_inertial_changes(*changes)


def load_robot(name: str = "ffsr_dual_arm") -> Robot:
    """Load a robot: a shipped name (``envs/robots/<name>/<name>.urdf``) or a path to a robot folder or URDF.

    Cached per process and per version of the robot's files (an edited robot folder loads anew).
    """
    urdf = robot_files(name)[0]
    return _load(str(urdf), files_stamp(urdf.parent))


def files_stamp(folder: Path) -> tuple:
    """(name, size, modification time) of every file in ``folder``: a cache key that changes when a file does."""
    return tuple((p.name, p.stat().st_size, p.stat().st_mtime_ns) for p in sorted(folder.iterdir()) if p.is_file())


@lru_cache(maxsize=8)
def _load(urdf: str, stamp: tuple) -> Robot:
    return Robot(urdf)
