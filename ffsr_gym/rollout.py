"""The closed loop: a :class:`Rollout` advances planner and robot; ``simulate`` runs one to the end."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
from tqdm.auto import tqdm

from ffsr_gym.collision import CollisionModel, Proximity, SphereObstacle
from ffsr_gym.exceptions import FFSRError, InvalidInputError
from ffsr_gym.planner import Planner, PlanStep
from ffsr_gym.robot import Robot, check_state, load_robot
from ffsr_gym.scenario import Scenario, load_scenario
from ffsr_gym.trajectory import Trajectory
from ffsr_gym.types import Array


def initial_configuration(robot: Robot, scenario: Scenario) -> Array:
    """Pinocchio configuration ``q`` of the scenario's initial state."""
    initial = scenario.initial
    return robot.configuration(
        base_position_m=np.array(initial.base_position_m),
        base_quaternion_wxyz=np.array(initial.base_quaternion_wxyz),
        joints_rad=np.radians(np.array(initial.mission_joints_deg + initial.balance_joints_deg)),
    )


def obstacles_of(scenario: Scenario) -> list[SphereObstacle]:
    """The scenario's obstacle as a collision sphere (empty list in free space)."""
    if scenario.obstacle is None:
        return []
    return [SphereObstacle(np.array(scenario.obstacle.position_m), scenario.obstacle.radius_m)]


STATUS = ("ok", "rate_limit", "collision")
BACKENDS = ("auto", "kernel", "pinocchio")


class Rollout:
    """A closed-loop run advanced step by step: ``simulate`` and the environments both drive it.

    This is the Pinocchio reference backend; :class:`ffsr_gym.kernel_rollout.KernelRollout` has
    the same interface and numbers (to 1e-9) on the compiled kernel. Use :func:`make_rollout`.

    Each :meth:`step` plans at (t_k, q_k), records the sample, and integrates to q_{k+1}.
    :meth:`finish` records the final sample at t_n (planned, never applied).

    Args:
        scenario: the scenario (validated).
        method: planning method, one of :data:`ffsr_gym.planner.METHODS`.
        m, T_c: initial predefined-time parameters (default: the scenario's).
        q0: initial configuration (default: the scenario's initial state).
    """

    backend = "pinocchio"

    def __init__(self, scenario: Scenario, *, method: str = "predefined_time", m: float | None = None,
                 T_c: float | None = None, q0: Array | None = None) -> None:
        self.scenario = scenario
        self.robot = load_robot(scenario.robot)
        self.collision = CollisionModel(self.robot)
        self.obstacles = obstacles_of(scenario)
        q_nominal = initial_configuration(self.robot, scenario)
        self.planner = Planner(self.robot, scenario, method=method, m=m, T_c=T_c, initial_q=q_nominal)
        if q0 is not None:
            check_state(q0)
        self.q = q_nominal if q0 is None else np.array(q0, dtype=float)
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

    def _record(self, residual: Array | None) -> Array:
        plan = self.planner(self.t, self.q)
        dq = plan.dq_joints if residual is None else plan.dq_joints + residual
        if not np.all(np.isfinite(dq)):
            raise FFSRError(f"planner produced non-finite joint rates at t = {self.t:.3f} s")
        v = self.robot.velocity(self.q, dq, self.momentum)
        self.collision.place(self.q)
        obstacle = self.collision.obstacle_proximity(self.q, self.obstacles, place=False) if self.obstacles else None
        self_clear = self.collision.self_proximity(self.q, place=False).distance_m
        e1, e0 = plan.ee_error, plan.base_error
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
        self.q, _ = self.robot.step(self.q, dq, self.dt, self.momentum)
        self.k += 1

    def finish(self) -> None:
        """Record the final sample (at the current time; its rates are not applied)."""
        if not self.finished:
            self._record(None)
            self.finished = True

    def set_parameters(self, m: float, T_c: float) -> None:
        """Change (m, T_c [s]) from the next step on."""
        self.planner.set_parameters(m, T_c)

    def advance(self, n: int, residual: Array | None = None, *, stop_on_violation: bool = False) -> tuple[Array, str]:
        """Take up to ``n`` steps (fewer at the end of the run).

        With ``stop_on_violation``, stop after the first step whose applied rates exceed the
        scenario's limit (``objective.max_rate_deg_s`` and ``rate_limit_scope``) or whose sample
        has a negative clearance.

        Returns:
            ``(applied, status)``: the applied rates (steps, 12) [rad/s] and ``"ok"``,
            ``"rate_limit"`` or ``"collision"``.
        """
        start = self.k
        objective = self.scenario.objective
        first = 6 if objective.rate_limit_scope == "balance_arm" else 0
        while self.k < self.n_steps and self.k - start < n:
            self.step(residual)
            if not stop_on_violation:
                continue
            if np.any(np.degrees(np.abs(self.latest("dq_joints")[first:])) > objective.max_rate_deg_s):
                return np.array(self._log["dq_joints"][start:]), STATUS[1]
            if self.latest("clearance_m") < 0.0 or self.latest("self_clearance_m") < 0.0:
                return np.array(self._log["dq_joints"][start:]), STATUS[2]
        return np.array(self._log["dq_joints"][start:]), STATUS[0]

    def observation(self) -> tuple[Array, Array, Array, Array, float]:
        """Joint angles (12), EE error (6), base error (6), obstacle-relative vector (3), clearance [m]."""
        plan = self.planner(self.t, self.q)
        relative, clearance = np.zeros(3), np.inf
        if self.obstacles:
            prox = self.collision.obstacle_proximity(self.q, self.obstacles)
            relative, clearance = prox.witness_points[1] - prox.witness_points[0], prox.distance_m
        return self.robot.joint_angles(self.q), plan.ee_error, plan.base_error, relative, clearance

    def latest(self, key: str) -> Any:
        """The last recorded value of ``key`` (a :class:`Trajectory` field name)."""
        return self._log[key][-1]

    def samples(self, start: int = 0) -> dict[str, Array]:
        """Recorded samples from index ``start`` on, as arrays."""
        return {key: np.array(val[start:]) for key, val in self._log.items()}

    def trajectory(self) -> Trajectory:
        """The :class:`Trajectory` recorded so far."""
        n = len(self._log["q"])
        info = {"scenario": self.scenario.name, "scenario_sha256": self.scenario.sha256(),
                "method": self.planner.method, "m": self.planner.m, "T_c_s": self.planner.T_c,
                "dt_s": self.dt, "duration_s": self.scenario.simulation.duration_s, "backend": "pinocchio"}
        return Trajectory(t=np.arange(n) * self.dt, **self.samples(), info=info)


def kernel_available() -> bool:
    """Whether the compiled kernel (numba) can be used."""
    try:
        import numba  # noqa: F401
    except ImportError:
        return False
    return True


def make_rollout(scenario: Scenario, *, backend: str = "auto", **kwargs: Any) -> Rollout:
    """A rollout on the requested backend: ``"kernel"``, ``"pinocchio"`` or ``"auto"`` (kernel if numba imports).

    Keyword arguments are those of :class:`Rollout` (``method``, ``m``, ``T_c``, ``q0``).
    """
    if backend not in BACKENDS:
        raise InvalidInputError(f"backend {backend!r}; allowed: {list(BACKENDS)}")
    if backend == "kernel" or (backend == "auto" and kernel_available()):
        from ffsr_gym.kernel_rollout import KernelRollout

        return KernelRollout(scenario, **kwargs)
    return Rollout(scenario, **kwargs)


def simulate(scenario: Scenario | str, *, method: str = "predefined_time", m: float | None = None,
             T_c: float | None = None, dt: float | None = None, q0: Array | None = None,
             backend: str = "auto", progress: bool = False, stop_on_violation: bool = False) -> Trajectory:
    """Run the closed loop planner → robot for one scenario.

    Args:
        scenario: a :class:`Scenario` or a scenario name/path.
        method: planning method, one of :data:`ffsr_gym.planner.METHODS`.
        m: predefined-time shape parameter in (0, 1); default: the scenario's.
        T_c: predefined time [s]; default: the scenario's.
        dt: time step [s]; default: the scenario's ``simulation.dt_s``.
        q0: start from this configuration (19,) instead of the scenario's initial state. The
            desired path and the base set-point still come from the scenario's initial state, so
            this is how an initial pose error is imposed.
        backend: ``"auto"`` (the compiled kernel when numba is installed), ``"kernel"`` or
            ``"pinocchio"`` (the reference implementation).
        progress: show a progress bar.
        stop_on_violation: end the run after the first step that exceeds the rate limit or
            collides (the trajectory then ends one sample after it; its score is +inf either way).

    Returns:
        The :class:`Trajectory`, sampled at every step.
    """
    scenario = load_scenario(scenario)
    if dt is not None:
        scenario = scenario.replace(simulation=dataclasses.replace(scenario.simulation, dt_s=float(dt)))
    rollout = make_rollout(scenario, backend=backend, method=method, m=m, T_c=T_c, q0=q0)
    chunk = max(1, rollout.n_steps // 100) if progress else rollout.n_steps
    with tqdm(total=rollout.n_steps, disable=not progress, desc=f"{scenario.name}/{method}", unit="step") as bar:
        while rollout.k < rollout.n_steps:
            applied, status = rollout.advance(chunk, stop_on_violation=stop_on_violation)
            bar.update(len(applied))
            if status != "ok":
                break
    rollout.finish()
    return rollout.trajectory()


_LOGGED = ("q", "v", "dq_joints", "ee_position_error_m", "ee_attitude_error", "base_position_error_m",
           "base_attitude_error", "clearance_m", "self_clearance_m", "mu", "cdf", "sigma_min")
