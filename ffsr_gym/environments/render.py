"""matplotlib 3D drawing of the robot, obstacle, target and end-effector trace (env rendering)."""

from __future__ import annotations

import numpy as np

from ffsr_gym.model import quaternion as quat
from ffsr_gym.model.scenario import Scenario
from ffsr_gym.sim.rollout import Rollout

_CUBE_EDGES = [(a, b) for a in range(8) for b in range(a + 1, 8) if bin(a ^ b).count("1") == 1]
_CORNERS = np.array([[x, y, z] for x in (-0.4, 0.4) for y in (-0.4, 0.4) for z in (-0.4, 0.4)])  # base cube [m]


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
        """Draw the current state; return an RGB array (H, W, 3) unless interactive.

        The artists are built on the first call (and when the scenario changes) and then only
        get new data, so a frame costs one canvas draw.
        """
        robot = rollout.robot
        if getattr(self, "_scenario", None) is not scenario:
            self._build(scenario)
        robot.update_kinematics(rollout.q)
        base = robot.data.oMi[1]
        corners = _CORNERS @ base.rotation.T + base.translation
        for line, (a, b) in zip(self._cube, _CUBE_EDGES):
            line.set_data_3d(*corners[[a, b]].T)
        for arm, line in enumerate(self._arms):
            points, _ = robot.joint_points(arm)
            line.set_data_3d(*points.T)
        self._trace.set_data_3d(*np.array(list(self._ee_trace(rollout))).T)
        self.ax.set_title(f"{scenario.name}: t = {rollout.t:.2f} s")
        self.fig.canvas.draw()
        if self.interactive:
            self.plt.pause(0.001)
            return None
        return np.asarray(self.fig.canvas.buffer_rgba())[..., :3].copy()

    def _build(self, scenario: Scenario) -> None:
        """The static scene (target frame, obstacle, limits, labels) and the moving artists."""
        ax = self.ax
        ax.clear()
        self._scenario = scenario
        self._cube = [ax.plot([], [], [], color="0.4", lw=1)[0] for _ in _CUBE_EDGES]
        self._arms = [ax.plot([], [], [], "-o", color=color, lw=3, ms=3, label=name)[0]
                      for color, name in (("tab:blue", "mission arm"), ("tab:orange", "balance arm"))]
        self._trace = ax.plot([], [], [], color="tab:green", lw=1, label="EE trace")[0]
        target = np.array(scenario.target.position_m)
        rotation = quat.to_rotation(np.array(scenario.target.quaternion_wxyz))
        for i, c in enumerate(("r", "g", "b")):
            ax.plot(*np.array([target, target + 0.1 * rotation[:, i]]).T, color=c, lw=2)
        if scenario.obstacle is not None:
            self._sphere(np.array(scenario.obstacle.position_m), scenario.obstacle.danger_radius_m)
        center = np.array(scenario.initial.base_position_m)
        ax.set(xlabel="x [m]", ylabel="y [m]", zlabel="z [m]", xlim=(center[0] - 1.2, center[0] + 1.5),
               ylim=(center[1] - 1.2, center[1] + 1.5), zlim=(center[2] - 1.2, center[2] + 1.5))
        ax.legend(loc="upper left", fontsize=7)

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
