"""The compiled-kernel backend of :class:`ffsr_gym.sim.rollout.Rollout` (the native kernel; same interface, same
numbers as the Pinocchio reference to 1e-9)."""

from __future__ import annotations

from typing import Any

import numpy as np

from ffsr_gym import _native
from ffsr_gym.exceptions import FFSRError, InvalidInputError
from ffsr_gym.kernel.layout import LOG_FIELDS, N_STATE, STATUS_NONFINITE, X_PEAK, X_SATURATED, X_STEPS, X_V
from ffsr_gym.kernel.planner import planner_settings
from ffsr_gym.model.robot import check_state
from ffsr_gym.model.scenario import Scenario
from ffsr_gym.planning import ptsf
from ffsr_gym.planning.planner import planner_parameters
from ffsr_gym.planning.timed_approach import TimingState
from ffsr_gym.sim.budget import check_run
from ffsr_gym.sim.rollout import STATUS
from ffsr_gym.sim.setup import prepare
from ffsr_gym.sim.trajectory import Trajectory
from ffsr_gym.types import Array


def new_log(rows: int, *batch: int) -> dict[str, Array]:
    """Zeroed trajectory buffers of the kernel (``LOG_FIELDS``), ``rows`` samples each, optional leading batch axes."""
    return {key: np.zeros((*batch, rows, *shape)) for key, shape in LOG_FIELDS.items()}


def initial_state(setup: Any, q: Array) -> Array:
    """The kernel state (40,) of configuration ``q`` (Pinocchio order) at rest: the servo plant's joints still, its
    base moving as the scenario's momentum makes it (:mod:`ffsr_gym.kernel.layout`)."""
    scenario, model = setup.scenario, setup.assets.kernel
    x = np.zeros(N_STATE)
    x[:7], x[7:19] = q[:7], q[model.q_index]
    if scenario.simulation.plant == "servo":
        x[X_V:X_V + 6] = setup.plant.velocity(q, np.zeros(12), scenario.initial.momentum)[:6]
    return x


def saturation(x: Array) -> dict[str, float]:
    """The servo plant's torque saturation recorded in the state ``x``: physics steps, the fraction of them with a
    joint at its torque limit, and the peak |τ| / τ_max."""
    steps = float(x[X_STEPS])
    return {"physics_steps": int(steps), "saturated_fraction": float(x[X_SATURATED]) / max(steps, 1.0),
            "peak_torque_ratio": float(x[X_PEAK])}


def trajectory_of(log: dict[str, Array], rows: int, scenario: Scenario, model: Any, info: dict[str, Any],
                  x: Array) -> Trajectory:
    """The :class:`Trajectory` of a kernel log's first ``rows`` rows, in Pinocchio order (``x``: the state after
    them, for the servo plant's saturation record)."""
    n = rows
    q = np.zeros((n, 19))
    q[:, :7] = log["x"][:n, :7]
    q[:, model.q_index] = log["x"][:n, 7:]
    v = np.zeros((n, 18))
    v[:, :6] = log["v"][:n, :6]
    v[:, model.v_index] = log["v"][:n, 6:]
    err = log["err"][:n]
    servo_plant = scenario.simulation.plant == "servo"
    if servo_plant:
        info["torque_saturation"] = saturation(x)
    return Trajectory(t=np.arange(n) * scenario.simulation.dt_s, q=q, v=v, dq_joints=log["dq"][:n].copy(),
                      ee_position_error_m=err[:, 0].copy(), ee_attitude_error=err[:, 1].copy(),
                      base_position_error_m=err[:, 2].copy(), base_attitude_error=err[:, 3].copy(),
                      clearance_m=log["clear"][:n].copy(), self_clearance_m=log["self"][:n].copy(),
                      mu=log["mu"][:n].copy(), cdf=log["cdf"][:n].copy(), sigma_min=log["smin"][:n].copy(), info=info,
                      joint_torque_Nm=log["tau"][:n].copy() if servo_plant else None)


def trajectory_info(scenario: Scenario, method: str, m: float, T_c: float) -> dict[str, Any]:
    """The ``info`` of a kernel trajectory."""
    return {"scenario": scenario.name, "scenario_sha256": scenario.sha256(), "method": method, "m": m, "T_c_s": T_c,
            "dt_s": scenario.simulation.dt_s, "duration_s": scenario.simulation.duration_s, "backend": "kernel",
            "plant": scenario.simulation.plant}


class KernelRollout:
    """Closed loop on the native kernel; the interface of :class:`ffsr_gym.sim.rollout.Rollout`.

    ``log`` (optional): trajectory buffers of :func:`new_log` to write into instead of new ones.
    """

    backend = "kernel"

    def __init__(self, scenario: Scenario, *, method: str = "predefined_time", m: float | None = None,
                 T_c: float | None = None, q0: Array | None = None, log: dict[str, Array] | None = None) -> None:
        m, T_c = planner_parameters(scenario, method, m, T_c)
        self.scenario, self._method = scenario, method
        self.setup = setup = prepare(scenario)
        self.robot, self.model = setup.robot, setup.assets.kernel
        self._native, self._plant = setup.assets.native, setup.native_plant
        if q0 is not None:
            check_state(q0)
        self.x = initial_state(setup, setup.q0 if q0 is None else np.array(q0, dtype=float))
        self.settings = planner_settings(setup, method=method, m=m, T_c=T_c)
        #: a commanded approach's state (command, s, ṡ, w, ẇ; None without one), advanced by the kernel
        self.timing = np.array(setup.path.state.values()) if scenario.commanded_approach is not None else None
        self.dt, self.n_steps = scenario.simulation.dt_s, scenario.n_steps
        self.k, self.rows, self.finished = 0, 0, False
        if log is None:
            check_run(steps=self.n_steps, copies=1, steps_per_decision=1, substeps=max(1, scenario.physics_substeps),
                      what=f"a run of {scenario.name}")
        self._log = new_log(self.n_steps + 1) if log is None else log

    @property
    def t(self) -> float:
        """Current time [s]."""
        return self.k * self.dt

    @property
    def q(self) -> Array:
        """Current configuration in Pinocchio order (19,)."""
        q = np.empty(19)
        q[:7] = self.x[:7]
        q[self.model.q_index] = self.x[7:19]
        return q

    @property
    def method(self) -> str:
        """Planning method."""
        return self._method

    @property
    def m(self) -> float:
        """Current predefined-time shape parameter."""
        return float(self.settings.m)

    @property
    def T_c(self) -> float:
        """Current predefined time [s]."""
        return float(self.settings.T_c)

    def set_parameters(self, m: float, T_c: float) -> None:
        """Change (m, T_c [s]) from the next step on (validated like the reference planner)."""
        ptsf.check_parameters(float(T_c), float(m), self.scenario.planner.phi_form)
        self.settings.m, self.settings.T_c = float(m), float(T_c)

    def set_command(self, command: float) -> None:
        """Command a commanded approach (u in [0, 2]) from the next step on (docs/model.md §23)."""
        if self.timing is None:
            raise InvalidInputError(f"scenario {self.scenario.name!r} has no [commanded_approach] to command")
        state = TimingState(*self.timing)
        state.set_command(command)
        self.timing[0] = state.command

    def _step(self, x: Array, k: int, n: int, residual: Array | None, stop: bool, record_only: bool,
              logs: dict[str, Array] | None = None, timing: Array | None = None) -> tuple:
        res = np.zeros(12) if residual is None else np.ascontiguousarray(residual, dtype=float)
        return _native.run(self._native, self.settings, x, k, self.n_steps, n, res, stop, record_only, self._plant,
                           logs, timing)

    def _run(self, n: int, residual: Array | None, stop: bool, record_only: bool) -> int:
        views = {key: rows[self.rows:] for key, rows in self._log.items()}  # the kernel writes its rows there
        x, rows, status, _ = self._step(self.x, self.k, n, residual, stop, record_only, views, self.timing)
        if status == STATUS_NONFINITE:
            raise FFSRError(f"planner produced non-finite joint rates at t = {(self.k + rows) * self.dt:.3f} s")
        self.rows += rows
        if not record_only:
            self.x, self.k = x, self.k + rows
        return status

    def advance(self, n: int, residual: Array | None = None, *, stop_on_violation: bool = False) -> tuple[Array, str]:
        """Take up to ``n`` steps; see :meth:`ffsr_gym.sim.rollout.Rollout.advance`."""
        if self.k >= self.n_steps:
            raise FFSRError(f"the run is over: {self.n_steps} steps of {self.dt} s were taken")
        start = self.rows
        status = self._run(n, residual, stop_on_violation, False)
        return self._log["dq"][start:self.rows].copy(), STATUS[status]

    def finish(self) -> None:
        """Record the final sample (its rates are not applied)."""
        if not self.finished:
            self._run(1, None, False, True)
            self.finished = True

    def replay_step(self, q: Array, k: int, timing: Array | None = None) -> tuple[dict[str, Array], Array]:
        """One kernel step from an arbitrary state (validation): the sample at (t_k, q) and q_{k+1}; ``timing``: a
        commanded approach's state at step k (default: this rollout's).

        Does not change this rollout. Returns the sample as a dict of :class:`Trajectory` field
        names (one row each) and the next configuration in Pinocchio order.
        """
        if self.timing is not None:
            timing = np.array(self.timing if timing is None else timing, dtype=float)
        x_next, _, _, logs = self._step(initial_state(self.setup, q), k, 1, None, False, False, None, timing)
        v_pin = np.zeros(18)
        v_pin[:6], v_pin[self.model.v_index] = logs["v"][0, :6], logs["v"][0, 6:]
        q_next = np.empty(19)
        q_next[:7], q_next[self.model.q_index] = x_next[:7], x_next[7:19]
        err = logs["err"][0]
        sample = {"v": v_pin, "dq_joints": logs["dq"][0], "ee_position_error_m": err[0], "ee_attitude_error": err[1],
                  "base_position_error_m": err[2], "base_attitude_error": err[3], "clearance_m": logs["clear"][0],
                  "self_clearance_m": logs["self"][0], "mu": logs["mu"][0], "cdf": logs["cdf"][0],
                  "sigma_min": logs["smin"][0]}
        return sample, q_next

    def observation(self) -> tuple[Array, Array, Array, Array, float]:
        """Joint angles, EE error (6), base error (6), obstacle-relative vector (3), clearance [m]."""
        plan = _native.plan(self._native, self.settings, self.x[:19].copy(), self.t, self.timing)
        clear, _, rel = _native.clearances(self._native, self.settings, self.x[:19].copy(), self.t)
        return self.x[7:19].copy(), plan["e1"], plan["e0"], rel, float(clear)

    def min_margin(self, last: int) -> float:
        """Smallest margin to a collision [m] over the last ``last`` samples (:meth:`Rollout.min_margin`)."""
        window = slice(self.rows - last, self.rows)
        return float(min(np.min(self._log["clear"][window]) - self.settings.keep_out,
                         np.min(self._log["self"][window])))

    def trajectory(self) -> Trajectory:
        """The :class:`Trajectory` recorded so far, in Pinocchio order."""
        return trajectory_of(self._log, self.rows, self.scenario, self.model,
                             trajectory_info(self.scenario, self.method, self.m, self.T_c), self.x)

    def saturation(self) -> dict[str, float]:
        """The servo plant's torque saturation so far (:func:`saturation`)."""
        return saturation(self.x)

    def __getstate__(self) -> dict:
        """Pickled without the native objects (rebuilt from the setup on load, with the same (m, T_c))."""
        state = self.__dict__.copy()
        del state["_native"], state["_plant"]
        state["settings"] = (self.m, self.T_c)
        return state

    def __setstate__(self, state: dict) -> None:
        m, T_c = state.pop("settings")
        self.__dict__.update(state)
        self._native, self._plant = self.setup.assets.native, self.setup.native_plant
        self.settings = planner_settings(self.setup, method=self._method, m=m, T_c=T_c)
