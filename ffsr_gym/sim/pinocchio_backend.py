"""The Pinocchio reference backend of the closed loop (readable, slow; validates the kernel)."""

from __future__ import annotations

from typing import Any

import numpy as np

from ffsr_gym.exceptions import FFSRError, InvalidInputError
from ffsr_gym.model.collision import Proximity
from ffsr_gym.model.robot import check_state
from ffsr_gym.model.scenario import Scenario
from ffsr_gym.planning.planner import Planner, PlanStep
from ffsr_gym.sim.budget import check_run
from ffsr_gym.sim.rollout import STATUS
from ffsr_gym.sim.setup import prepare
from ffsr_gym.sim.trajectory import Trajectory
from ffsr_gym.types import Array

_LOGGED = ("q", "v", "dq_joints", "ee_position_error_m", "ee_attitude_error", "base_position_error_m",
           "base_attitude_error", "clearance_m", "self_clearance_m", "mu", "cdf", "sigma_min")


class PinocchioRollout:
    """The Pinocchio reference backend of :class:`~ffsr_gym.sim.rollout.Rollout`.

    The readable implementation of the planner equations; :class:`~ffsr_gym.sim.compiled.KernelRollout`
    has the same interface and numbers (to 1e-9) on the compiled kernel. Use
    :func:`~ffsr_gym.sim.simulate.make_rollout`.

    Each :meth:`step` plans at (t_k, q_k), records the sample, and integrates to q_{k+1}.
    :meth:`finish` records the final sample at t_n (planned, never applied).

    Args:
        scenario: the scenario (validated).
        method: planning method, one of :data:`ffsr_gym.planning.planner.METHODS`.
        m, T_c: initial predefined-time parameters (default: the scenario's).
        q0: initial configuration (default: the scenario's initial state).
    """

    backend = "pinocchio"

    def __init__(self, scenario: Scenario, *, method: str = "predefined_time", m: float | None = None,
                 T_c: float | None = None, q0: Array | None = None) -> None:
        self.scenario = scenario
        check_run(steps=scenario.n_steps, copies=1, steps_per_decision=1, substeps=max(1, scenario.physics_substeps),
                  what=f"a run of {scenario.name}")
        self.setup = setup = prepare(scenario)
        self.robot, self.collision, self.obstacles = setup.robot, setup.assets.collision, setup.obstacles
        self.plant = setup.plant  # the physics' robot (the planner keeps self.robot)
        path, estimates = setup.path, setup.estimates
        if scenario.commanded_approach is not None:  # this rollout's own approach state (docs/model.md §23)
            path = setup.path.fresh()
            estimates = (path,)
        #: a commanded approach's path (None without one): its state is advanced after every step
        self.timed = path if scenario.commanded_approach is not None else None
        self.planner = Planner(self.robot, scenario, method=method, m=m, T_c=T_c, path=path,
                               base_target=setup.base_target, estimates=estimates,
                               estimate_interval_s=setup.estimate_interval_s, body=setup.body_field)
        if q0 is not None:
            check_state(q0)
        self.q = setup.q0.copy() if q0 is None else np.array(q0, dtype=float)
        self.momentum = np.array(scenario.initial.momentum)
        self.dt, self.n_steps = scenario.simulation.dt_s, scenario.n_steps
        self.k = 0
        self.finished = False
        self.last_plan: PlanStep | None = None
        self.last_proximity: Proximity | None = None
        self._log: dict[str, list] = {key: [] for key in _LOGGED}

    @property
    def t(self) -> float:
        """Current time [s]."""
        return self.k * self.dt

    @property
    def method(self) -> str:
        """Planning method."""
        return self.planner.method

    @property
    def m(self) -> float:
        """Current predefined-time shape parameter."""
        return self.planner.m

    @property
    def T_c(self) -> float:
        """Current predefined time [s]."""
        return self.planner.T_c

    def _record(self, residual: Array | None) -> Array:
        plan = self.planner(self.t, self.q)
        dq = plan.dq_joints if residual is None else plan.dq_joints + residual
        if not np.all(np.isfinite(dq)):
            raise FFSRError(f"planner produced non-finite joint rates at t = {self.t:.3f} s")
        v = self.plant.velocity(self.q, dq, self.momentum)
        self.collision.place(self.q)
        obstacles = self.setup.obstacles_at(self.k)
        obstacle = self.collision.obstacle_proximity(self.q, obstacles, place=False) if obstacles else None
        self_clear = self.collision.self_proximity(self.q, place=False).distance_m
        e1, e0 = plan.true_ee_error, plan.base_error  # logged and scored against the true target
        row = (self.q, v, dq, np.linalg.norm(e1[:3]), np.linalg.norm(e1[3:]), np.linalg.norm(e0[:3]),
               np.linalg.norm(e0[3:]), np.inf if obstacle is None else obstacle.distance_m, self_clear,
               plan.mu, plan.cdf, plan.sigma_min)
        for key, value in zip(_LOGGED, row):
            self._log[key].append(value)
        self.last_plan, self.last_proximity = plan, obstacle
        return dq

    def step(self, residual: Array | None = None) -> None:
        """Plan, record and integrate one step of ``dt``; ``residual`` [rad/s] (12,) is added to the plan."""
        if self.k >= self.n_steps:
            raise FFSRError(f"the run is over: {self.n_steps} steps of {self.dt} s were taken")
        dq = self._record(residual)
        self.q, _ = self.plant.step(self.q, dq, self.dt, self.momentum)
        if self.timed is not None:
            self.timed.state.advance(self.timed.limits, self.dt)
        self.k += 1

    def finish(self) -> None:
        """Record the final sample (at the current time; its rates are not applied)."""
        if not self.finished:
            self._record(None)
            self.finished = True

    def set_parameters(self, m: float, T_c: float) -> None:
        """Change (m, T_c [s]) from the next step on."""
        self.planner.set_parameters(m, T_c)

    @property
    def timing(self) -> Array | None:
        """A commanded approach's state (command, s, ṡ, w, ẇ), or None without one."""
        return None if self.timed is None else np.array(self.timed.state.values())

    def set_command(self, command: float) -> None:
        """Command a commanded approach (u in [0, 2]) from the next step on (docs/model.md §23)."""
        if self.timed is None:
            raise InvalidInputError(f"scenario {self.scenario.name!r} has no [commanded_approach] to command")
        self.timed.state.set_command(command)

    def advance(self, n: int, residual: Array | None = None, *, stop_on_violation: bool = False) -> tuple[Array, str]:
        """Take up to ``n`` steps; see :meth:`ffsr_gym.sim.rollout.Rollout.advance`."""
        start = self.k
        objective = self.scenario.objective
        first = 6 if objective.rate_limit_scope == "balance_arm" else 0
        while self.k < self.n_steps and self.k - start < n:
            self.step(residual)
            if not stop_on_violation:
                continue
            if np.any(np.degrees(np.abs(self.latest("dq_joints")[first:])) > objective.max_rate_deg_s):
                return np.array(self._log["dq_joints"][start:]), STATUS[1]
            if self.latest("clearance_m") < self.scenario.objective.keep_out_m or self.latest("self_clearance_m") < 0.0:
                return np.array(self._log["dq_joints"][start:]), STATUS[2]
        return np.array(self._log["dq_joints"][start:]), STATUS[0]

    def observation(self) -> tuple[Array, Array, Array, Array, float]:
        """Joint angles (12), EE error (6), base error (6), vector to the nearest sphere obstacle (3; a tumbling
        target's body is not one: its motion is in the desired twist), clearance to every obstacle [m]."""
        plan = self.planner(self.t, self.q)
        relative, clearance = np.zeros(3), np.inf
        obstacles = self.setup.obstacles_at(self.k)
        spheres = obstacles[:len(self.obstacles)]
        if spheres:
            prox = self.collision.obstacle_proximity(self.q, spheres)
            relative, clearance = prox.witness_points[1] - prox.witness_points[0], prox.distance_m
        if len(obstacles) > len(spheres):
            clearance = min(clearance, self.collision.obstacle_proximity(self.q, obstacles[len(spheres):]).distance_m)
        return self.robot.joint_angles(self.q), plan.ee_error, plan.base_error, relative, clearance

    def latest(self, key: str) -> Any:
        """The last recorded value of ``key`` (a :class:`Trajectory` field name)."""
        return self._log[key][-1]

    def samples(self, start: int = 0) -> dict[str, Array]:
        """Recorded samples from index ``start`` on, as arrays."""
        return {key: np.array(val[start:]) for key, val in self._log.items()}

    def min_margin(self, last: int) -> float:
        """Smallest margin to a collision [m] over the last ``last`` samples (:meth:`Rollout.min_margin`)."""
        window = slice(len(self._log["clearance_m"]) - last, None)
        keep_out = self.scenario.objective.keep_out_m
        return float(min(np.min(self._log["clearance_m"][window]) - keep_out,
                         np.min(self._log["self_clearance_m"][window])))

    def trajectory(self) -> Trajectory:
        """The :class:`Trajectory` recorded so far."""
        n = len(self._log["q"])
        info = {"scenario": self.scenario.name, "scenario_sha256": self.scenario.sha256(),
                "method": self.planner.method, "m": self.planner.m, "T_c_s": self.planner.T_c,
                "dt_s": self.dt, "duration_s": self.scenario.simulation.duration_s, "backend": "pinocchio"}
        return Trajectory(t=np.arange(n) * self.dt, **self.samples(), info=info)
