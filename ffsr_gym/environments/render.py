"""matplotlib 3D drawing of the robot, the obstacles where they are now, the target, the end-effector
trace and, once the episode is over, how it ended (env rendering)."""

from __future__ import annotations

import numpy as np

from ffsr_gym.model import quaternion as quat
from ffsr_gym.model.scenario import Scenario
from ffsr_gym.sim.episode_end import EpisodeEnd, episode_end, with_capture
from ffsr_gym.sim.rollout import Rollout

_CUBE_EDGES = [(a, b) for a in range(8) for b in range(a + 1, 8) if bin(a ^ b).count("1") == 1]
_CORNERS = np.array([[x, y, z] for x in (-0.4, 0.4) for y in (-0.4, 0.4) for z in (-0.4, 0.4)])  # base cube [m]


def ending(engine, index: int = 0) -> EpisodeEnd | None:
    """How the episode of copy ``index`` of an :class:`~ffsr_gym.environments.engine.EpisodeEngine` ended (None
    while it runs): its first violation or last sample, and under a capture rule the capture window."""
    if not engine.finished(index):
        return None
    end = episode_end(engine.rollout(index))
    rules = getattr(engine.rule, "benchmark", None)
    if rules is not None and rules.capture is not None:  # the capture window, from the episode's result
        end = with_capture(end, engine.results[index].capture_time_s, rules.capture.hold_s)
    return end


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

    def draw(self, rollout: Rollout, scenario: Scenario, end: EpisodeEnd | None = None) -> np.ndarray | None:
        """Draw the current state; return an RGB array (H, W, 3) unless interactive.

        Every obstacle (``[obstacle]`` and each ``[debris]`` sphere) is drawn where it is at the
        rollout's time, with its track since t = 0; ``end`` (the episode is over) marks where and
        when it ended and why. The robot's artists are built on the first call (and when the
        scenario changes) and then only get new data.
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
        self._draw_obstacles(rollout, scenario)
        self._draw_body(rollout, scenario)
        self._draw_end(end)
        self.ax.set_title(f"{scenario.name}: t = {rollout.t:.2f} s", fontsize=10)
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
        if scenario.tumbling_target is None:  # a moving grasp frame is drawn with its body, where it is now
            for i, c in enumerate(("r", "g", "b")):
                ax.plot(*np.array([target, target + 0.1 * rotation[:, i]]).T, color=c, lw=2)
        self._moving: list = []
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

    def _draw_obstacles(self, rollout: Rollout, scenario: Scenario) -> None:
        """Each obstacle at time t: its body, the (shared) danger radius, its track since t = 0, its name."""
        for artist in self._moving:
            artist.remove()
        self._moving = []
        field = rollout.setup.obstacles
        if not len(field) or scenario.obstacle is None:
            return
        now, start = field.at(rollout.t), field.at(0.0)
        danger = scenario.obstacle.danger_radius_m
        for i, (p, p0, radius) in enumerate(zip(now, start, field.radii_m)):
            name = "obstacle" if i == 0 else f"debris {i}"
            color = "tab:red" if i == 0 else "tab:purple"
            first = i <= 1  # one legend entry per kind
            self._moving.append(self._sphere(p, danger, color, alpha=0.15))
            self._moving.append(self._sphere(p, max(radius, 0.01), color, alpha=0.8))
            self._moving.append(self.ax.scatter(*p, color=color, s=15, label=f"{'obstacle' if i == 0 else 'debris'} "
                                                                              "(danger radius)" if first else None))
            if np.any(field.velocities_m_s[i]):
                self._moving += self.ax.plot(*np.array([p0, p]).T, ":", color=color, lw=1)
            self._moving.append(self.ax.text(*p, f" {name}", color=color, fontsize=7))
        self.ax.legend(loc="upper left", fontsize=7)

    def _draw_body(self, rollout: Rollout, scenario: Scenario) -> None:
        """A tumbling target where it is now: the box's edges, the grasp frame (the handle) with its axes, the
        spin axis through the centre (its length the spin rate, 0.1 m per 10 deg/s) and the centre's track."""
        setup = rollout.setup
        motion, grasp = setup.target_motion, setup.grasp
        if motion is None or grasp is None:
            return
        k = min(rollout.k, len(motion.position_m) - 1)
        centre, rotation = motion.position_m[k], quat.to_rotation(motion.quaternion[k])
        half = np.array(scenario.tumbling_target.size_m) / 2.0
        corners = (_CORNERS / 0.4 * half) @ rotation.T + centre
        for n, (a, b) in enumerate(_CUBE_EDGES):
            self._moving += self.ax.plot(*corners[[a, b]].T, color="tab:brown", lw=1.5,
                                         label="target body" if n == 0 else None)
        handle, frame = grasp.position_m[k], quat.to_rotation(grasp.quaternion[k])
        for i, c in enumerate(("r", "g", "b")):
            self._moving += self.ax.plot(*np.array([handle, handle + 0.1 * frame[:, i]]).T, color=c, lw=2)
        self._moving.append(self.ax.scatter(*handle, color="k", s=12, label="grasp frame"))
        spin = rotation @ motion.omega_body_rad_s[k]  # the world angular velocity now
        tip = centre + np.degrees(spin) / 10.0 * 0.1
        self._moving += self.ax.plot(*np.array([centre, tip]).T, "--", color="tab:brown", lw=1, label="spin axis")
        self._moving += self.ax.plot(*motion.position_m[:k + 1:10].T, ":", color="tab:brown", lw=1)
        self.ax.legend(loc="upper left", fontsize=7)

    def _draw_end(self, end: EpisodeEnd | None) -> None:
        """The end marker: a star where the episode ended, and what happened there."""
        if end is None:
            return
        color = "tab:red" if end.failed else "tab:green"
        self._moving.append(self.ax.scatter(*end.point_m, marker="*", s=250, color=color, edgecolor="black",
                                            depthshade=False, zorder=10))
        self._moving.append(self.fig.text(0.5, 0.02, end.text, ha="center", fontsize=8, color=color, wrap=True))

    def _sphere(self, center: np.ndarray, radius: float, color: str, alpha: float):
        u, v = np.mgrid[0:2 * np.pi:16j, 0:np.pi:8j]
        xyz = [center[0] + radius * np.cos(u) * np.sin(v), center[1] + radius * np.sin(u) * np.sin(v),
               center[2] + radius * np.cos(v)]
        return self.ax.plot_wireframe(*xyz, color=color, alpha=alpha, lw=0.5)

    def close(self) -> None:
        """Close the figure."""
        self.plt.close(self.fig)
