"""matplotlib 3D drawing of the robot, obstacle, target and end-effector trace (env rendering)."""

from __future__ import annotations

import numpy as np

from ffsr_gym.model import quaternion as quat
from ffsr_gym.model.scenario import Scenario
from ffsr_gym.sim.rollout import Rollout

_CUBE_EDGES = [(a, b) for a in range(8) for b in range(a + 1, 8) if bin(a ^ b).count("1") == 1]


class SceneRenderer:
    """Draws one frame per call; ``interactive`` shows a window (``render_mode="human"``)."""

    def __init__(self, interactive: bool = False) -> None:
        import matplotlib

        if not interactive:
            matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        self.plt = plt
        self.interactive = interactive
        self.fig = plt.figure(figsize=(6, 6), dpi=80)
        self.ax = self.fig.add_subplot(projection="3d")

    def draw(self, rollout: Rollout, scenario: Scenario) -> np.ndarray | None:
        """Draw the current state; return an RGB array (H, W, 3) unless interactive."""
        ax, robot = self.ax, rollout.robot
        ax.clear()
        robot.update_kinematics(rollout.q)
        base = robot.data.oMi[1]
        corners = np.array([[x, y, z] for x in (-0.4, 0.4) for y in (-0.4, 0.4) for z in (-0.4, 0.4)])
        corners = corners @ base.rotation.T + base.translation
        for a, b in _CUBE_EDGES:
            ax.plot(*corners[[a, b]].T, color="0.4", lw=1)
        for arm, color in ((0, "tab:blue"), (1, "tab:orange")):
            points, _ = robot.joint_points(arm)
            ax.plot(*points.T, "-o", color=color, lw=3, ms=3, label=("mission arm", "balance arm")[arm])
        trace = np.array([q_ee for q_ee in self._ee_trace(rollout)])
        ax.plot(*trace.T, color="tab:green", lw=1, label="EE trace")
        target = np.array(scenario.target.position_m)
        rotation = quat.to_rotation(np.array(scenario.target.quaternion_wxyz))
        for i, c in enumerate(("r", "g", "b")):
            ax.plot(*np.array([target, target + 0.1 * rotation[:, i]]).T, color=c, lw=2)
        if scenario.obstacle is not None:
            self._sphere(np.array(scenario.obstacle.position_m), scenario.obstacle.danger_radius_m)
        ax.set(xlabel="x [m]", ylabel="y [m]", zlabel="z [m]", title=f"t = {rollout.t:.2f} s")
        center = base.translation
        for setter, c in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), center):
            setter(c - 1.2, c + 1.5)
        ax.legend(loc="upper left", fontsize=7)
        self.fig.canvas.draw()
        if self.interactive:
            self.plt.pause(0.001)
            return None
        return np.asarray(self.fig.canvas.buffer_rgba())[..., :3].copy()

    @staticmethod
    def _ee_trace(rollout: Rollout):
        robot = rollout.robot
        qs = rollout.trajectory().q
        for q in qs[:: max(1, len(qs) // 100)] if len(qs) else [rollout.q]:
            yield robot.transform_ee_to_world(q, 0).translation

    def _sphere(self, center: np.ndarray, radius: float) -> None:
        u, v = np.mgrid[0:2 * np.pi:16j, 0:np.pi:8j]
        xyz = [center[0] + radius * np.cos(u) * np.sin(v), center[1] + radius * np.sin(u) * np.sin(v),
               center[2] + radius * np.cos(v)]
        self.ax.plot_wireframe(*xyz, color="tab:red", alpha=0.3, lw=0.5)
        self.ax.scatter(*center, color="tab:red", s=20, label="obstacle / danger radius")

    def close(self) -> None:
        """Close the figure."""
        self.plt.close(self.fig)
