"""The servo plant's speed row: the kernel's open-loop servo drive against MuJoCo on the same bodies, drives and
step (``bench.py`` and ``servo_plant.py`` print it)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from timing import best_of  # noqa: E402  (experiments/timing.py)


def servo_mjcf(model, drive: np.ndarray, h: float) -> str:
    """A MuJoCo model of the robot's servo plant: the same bodies (from the kernel's arrays), a free joint, 12
    velocity servos with the drives' gains and torque limits, armature and damping; ``implicitfast`` at step ``h``."""
    import mujoco

    def quat(R: np.ndarray) -> str:
        q = np.zeros(4)
        mujoco.mju_mat2Quat(q, np.ascontiguousarray(R).ravel())
        return " ".join(f"{v:.17g}" for v in q)

    def inertial(b: int) -> str:
        I = model.inertia[b]
        full = " ".join(f"{v:.17g}" for v in (I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2]))
        pos = " ".join(f"{v:.17g}" for v in model.lever[b])
        return f'<inertial pos="{pos}" mass="{model.mass[b]:.17g}" fullinertia="{full}"/>'

    def body(k: int) -> str:
        pos = " ".join(f"{v:.17g}" for v in model.placement_p[k])
        axis = " ".join(f"{v:.17g}" for v in model.axis[k])
        children = "".join(body(c) for c in range(12) if model.parent[c] == k)
        return (f'<body name="link{k}" pos="{pos}" quat="{quat(model.placement_R[k])}">'
                f'<joint name="j{k}" type="hinge" axis="{axis}" armature="{drive[k, 2]:.17g}" damping="{drive[k, 3]:.17g}"/>'
                f'{inertial(k + 1)}{children}</body>')

    roots = "".join(body(k) for k in range(12) if model.parent[k] < 0)
    servos = "".join(f'<velocity joint="j{k}" kv="{drive[k, 0]:.17g}" forcelimited="true" '
                     f'forcerange="{-drive[k, 1]:.17g} {drive[k, 1]:.17g}"/>' for k in range(12))
    return (f'<mujoco><option timestep="{h}" integrator="implicitfast" gravity="0 0 0"/><worldbody>'
            f'<body name="base"><freejoint/>{inertial(0)}{roots}</body></worldbody>'
            f'<actuator>{servos}</actuator></mujoco>')


def servo_speed(repeats: int, h: float = 0.001, seconds: float = 1.0) -> tuple[float, float | None, dict]:
    """Wall time per simulated second [s/s] of the kernel's servo plant and of MuJoCo on a model of the same
    robot and drives (None without MuJoCo), the same commands at the same step; and their final joint rates'
    largest difference [rad/s] (the two are different integrators of the same dynamics)."""
    from ffsr_gym import _native
    from ffsr_gym.kernel.layout import N_STATE, X_V
    from ffsr_gym.kernel.robot import native_plant
    from ffsr_gym.model.scenario import load_scenario
    from ffsr_gym.sim.setup import prepare

    setup = prepare(load_scenario("paper"))
    kernel, drive = setup.assets.kernel, setup.plant_arrays[3]
    if not drive.any():
        from ffsr_gym.model.drives import drive_array, drives_path, load_drives
        from ffsr_gym.model.resources import robot_dir

        drive = drive_array(load_drives(drives_path(robot_dir("ffsr_dual_arm"))))
    n = int(round(seconds / h))
    cmds = np.sin(3.0 * np.arange(n)[:, None] * h + np.arange(12)[None, :])  # [rad/s]
    start = np.zeros(N_STATE)
    start[:7], start[7:19] = setup.q0[:7], setup.q0[kernel.q_index]
    plant = native_plant(kernel, (kernel.mass, kernel.lever, kernel.inertia, drive))
    ours = best_of(lambda: _native.drive_open_loop(plant, start, cmds, h, np.zeros(6), 10), repeats) / seconds
    states, _ = _native.drive_open_loop(plant, start, cmds, h, np.zeros(6), 10)
    try:
        import mujoco
    except ImportError:
        return ours, None, {}
    mj = mujoco.MjModel.from_xml_string(servo_mjcf(kernel, drive, h))
    data = mujoco.MjData(mj)

    def run_mujoco() -> None:
        mujoco.mj_resetData(mj, data)
        data.qpos[:3], data.qpos[3] = setup.q0[:3], setup.q0[6]  # MuJoCo's quaternion is (w, x, y, z)
        data.qpos[4:7], data.qpos[7:] = setup.q0[3:6], setup.q0[kernel.q_index]
        for k in range(n):
            data.ctrl[:] = cmds[k]
            mujoco.mj_step(mj, data)

    run_mujoco()
    gap = float(np.abs(data.qvel[6:] - states[-1, X_V + 6:X_V + 18]).max())
    try:  # MuJoCo's own C loop over the steps (no Python per step), where this MuJoCo has it
        from mujoco import rollout
    except ImportError:
        return ours, best_of(run_mujoco, repeats) / seconds, {"final_joint_rate_gap_rad_s": gap, "mujoco_loop": "python"}
    mujoco.mj_resetData(mj, data)
    data.qpos[:3], data.qpos[3], data.qpos[4:7], data.qpos[7:] = (setup.q0[:3], setup.q0[6], setup.q0[3:6],
                                                                  setup.q0[kernel.q_index])
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    initial = np.zeros(mujoco.mj_stateSize(mj, spec))
    mujoco.mj_getState(mj, data, initial, spec)
    out = np.zeros((1, n, initial.size))
    theirs = best_of(lambda: rollout.rollout(mj, data, initial[None], cmds[None], state=out), repeats) / seconds
    return ours, theirs, {"final_joint_rate_gap_rad_s": gap, "mujoco_loop": "mujoco.rollout"}
