"""The compiled-kernel backend of :class:`ffsr_gym.sim.rollout.Rollout` (same interface, same numbers)."""

from __future__ import annotations

from typing import Any

import numpy as np

from ffsr_gym.exceptions import FFSRError
from ffsr_gym.kernel import cache as kernel_cache
from ffsr_gym.kernel import first_use, servo
from ffsr_gym.kernel import loop as kernel_loop
from ffsr_gym.kernel import settings as ks
from ffsr_gym.model import portable
from ffsr_gym.model.robot import check_state
from ffsr_gym.model.scenario import Scenario
from ffsr_gym.model.tumbling import rotations
from ffsr_gym.planning import ptsf
from ffsr_gym.planning.planner import planner_parameters
from ffsr_gym.sim.budget import check_run
from ffsr_gym.sim.rollout import STATUS
from ffsr_gym.sim.setup import ScenarioSetup, prepare
from ffsr_gym.sim.trajectory import Trajectory
from ffsr_gym.types import Array

kernel_cache.refresh()  # a cache written by other kernel sources is flushed (its first use then says it compiles)


def settings_vectors(setup: ScenarioSetup, *, method: str, m: float, T_c: float) -> tuple[Array, Array]:
    """The kernel's float and integer settings of a scenario, a method and (m, T_c [s]) (layout:
    :mod:`ffsr_gym.kernel.settings`)."""
    scenario = setup.scenario
    estimates, body = setup.estimates, scenario.tumbling_target
    frames = 0 if body is None else scenario.n_steps + 1
    s, ip = scenario.planner, np.zeros(ks.N_IP, dtype=np.int64)
    fp = np.zeros(ks.N_FP + ks.TARGET_FIELDS * len(estimates) + ks.FRAME_FIELDS * frames)
    obstacle, field = scenario.obstacle, setup.obstacles
    fp[[ks.F_M, ks.F_TC, ks.F_K]] = m, T_c, s.proportional_gain_per_s
    fp[[ks.F_LAM1, ks.F_LAM2, ks.F_EPS1, ks.F_EPS2]] = s.lambda_max_mission, s.lambda_max_balance, s.epsilon_mission, s.epsilon_balance
    fp[[ks.F_XI, ks.F_DELTA, ks.F_K1]] = s.cdf_xi, s.cdf_delta, s.cdf_k1
    path = setup.path
    fp[[ks.F_TF, ks.F_TA, ks.F_EST_DT, ks.F_DT, ks.F_RATE_MAX]] = (
        path.motion_time, path.accel_time, setup.estimate_interval_s, scenario.simulation.dt_s,
        scenario.objective.max_rate_deg_s)
    fp[ks.F_P0:ks.F_P0 + 3], fp[ks.F_Q0:ks.F_Q0 + 4] = path.start_position, path.start_attitude
    if body is None:
        for start, target in ((ks.F_TRUE, path), *((ks.N_FP + ks.TARGET_FIELDS * k, e) for k, e in enumerate(estimates))):
            fp[start:start + 3], fp[start + 3:start + 6], fp[start + 6] = target.target_position, target.axis, target.angle
    else:
        _frame_records(setup, fp[ks.N_FP + ks.TARGET_FIELDS * len(estimates):])
    fp[ks.F_R0D:ks.F_R0D + 3], fp[ks.F_SBD:ks.F_SBD + 4] = setup.base_target
    fp[ks.F_H:ks.F_H + 6] = scenario.initial.momentum
    if obstacle is not None:
        fp[ks.F_DANGER] = obstacle.danger_radius_m
    fp[ks.F_KEEP_OUT] = scenario.objective.keep_out_m
    records = fp[ks.F_OBSTACLES:ks.F_OBSTACLES + ks.OBSTACLE_FIELDS * len(field)].reshape(-1, ks.OBSTACLE_FIELDS)
    records[:, :3], records[:, 3:6], records[:, 6] = field.positions_m, field.velocities_m_s, field.radii_m
    ip[:] = (ks.METHOD_CODES[method], s.phi_form == "printed", s.phi_split, s.attitude_error == "body",
             s.mu_law == "distance", s.balance_avoids, len(field),
             scenario.objective.rate_limit_scope == "balance_arm", scenario.plant is not None, len(estimates),
             scenario.physics_substeps, frames, body is not None)
    if body is not None:
        fp[ks.F_BODY_HALF:ks.F_BODY_HALF + 3] = np.array(body.size_m) / 2.0
        fp[ks.F_BODY_RB], fp[ks.F_BODY_DANGER] = 0.5 * portable.norm(body.size_m), body.danger_radius_m
    return fp, ip


def _frame_records(setup: ScenarioSetup, out: Array) -> None:
    """A tumbling target's frame records (``ffsr_gym.kernel.settings.FRAME_FIELDS`` floats per step) into ``out``:
    the desired end-effector pose and twist, then the body's centre and rotation."""
    path, motion = setup.path, setup.target_motion
    records = out.reshape(-1, ks.FRAME_FIELDS)
    records[:, 0:3], records[:, 3:7], records[:, 7:13] = path.position_m, path.attitude, path.twist
    records[:, 13:16], records[:, 16:25] = motion.position_m, rotations(motion.quaternion).reshape(-1, 9)


LOG_FIELDS = {"x": (19,), "v": (18,), "dq": (12,), "err": (4,), "clear": (), "self": (), "mu": (2,), "cdf": (2,),
              "smin": (2,), "tau": (12,)}


def new_log(rows: int, *batch: int) -> dict[str, Array]:
    """Zeroed trajectory buffers of the kernel (``LOG_FIELDS``), ``rows`` samples each, optional leading batch axes."""
    return {key: np.zeros((*batch, rows, *shape)) for key, shape in LOG_FIELDS.items()}


class KernelRollout:
    """Closed loop on the compiled kernel; the interface of :class:`ffsr_gym.sim.rollout.Rollout`.

    ``log`` (optional): trajectory buffers of :func:`new_log` to write into instead of new ones
    (the batched environments hand each copy a slice of one stacked buffer).
    """

    backend = "kernel"

    def __init__(self, scenario: Scenario, *, method: str = "predefined_time", m: float | None = None,
                 T_c: float | None = None, q0: Array | None = None, log: dict[str, Array] | None = None) -> None:
        m, T_c = planner_parameters(scenario, method, m, T_c)
        self.scenario, self._method = scenario, method
        self.setup = setup = prepare(scenario)
        self.robot = setup.robot
        self.model, self._mdl = setup.assets.kernel, setup.assets.kernel_arrays
        self.plant = setup.plant_arrays  # (mass, lever, inertia) of the robot the physics integrates
        if q0 is not None:
            check_state(q0)
        q = setup.q0 if q0 is None else np.array(q0, dtype=float)
        self.x = self._state(q)
        self.fp, self.ip = settings_vectors(setup, method=method, m=m, T_c=T_c)
        self.dt, self.n_steps = scenario.simulation.dt_s, scenario.n_steps
        self.k, self.rows, self.finished = 0, 0, False
        if log is None:
            check_run(steps=self.n_steps, copies=1, steps_per_decision=1, substeps=max(1, scenario.physics_substeps),
                      what=f"a run of {scenario.name}")
        self._log = new_log(self.n_steps + 1) if log is None else log

    def _state(self, q: Array) -> Array:
        """The kernel state of configuration ``q`` (Pinocchio order) at rest: the servo plant's joints still,
        its base moving as the scenario's momentum makes it (``ffsr_gym.kernel.servo``)."""
        x = np.zeros(servo.N_STATE)
        x[:7], x[7:19] = q[:7], q[self.model.q_index]
        if self.scenario.simulation.plant == "servo":
            x[servo.X_V:servo.X_V + 6] = self.setup.plant.velocity(q, np.zeros(12), self.scenario.initial.momentum)[:6]
        return x

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
        return float(self.fp[ks.F_M])

    @property
    def T_c(self) -> float:
        """Current predefined time [s]."""
        return float(self.fp[ks.F_TC])

    def set_parameters(self, m: float, T_c: float) -> None:
        """Change (m, T_c [s]) from the next step on (validated like the reference planner)."""
        ptsf.check_parameters(float(T_c), float(m), self.scenario.planner.phi_form)
        self.fp[ks.F_M], self.fp[ks.F_TC] = float(m), float(T_c)

    def _run(self, n: int, residual: Array | None, stop: bool, record_only: bool) -> int:
        res = np.zeros(12) if residual is None else np.asarray(residual, dtype=float)
        outs = [self._log[key][self.rows:] for key in LOG_FIELDS]
        x, rows, status = first_use.call("closed loop", kernel_loop.run, self._mdl, self.plant, self.x, self.k,
                                         self.n_steps, n, self.fp, self.ip, res, stop, record_only, *outs)
        if status == 3:
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

    def replay_step(self, q: Array, k: int) -> tuple[dict[str, Array], Array]:
        """One kernel step from an arbitrary state (validation): the sample at (t_k, q) and q_{k+1}.

        Does not change this rollout. Returns the sample as a dict of :class:`Trajectory` field
        names (one row each) and the next configuration in Pinocchio order.
        """
        x = self._state(q)
        outs = list(new_log(1).values())
        x_next, _, _ = kernel_loop.run(self._mdl, self.plant, x, k, self.n_steps, 1, self.fp, self.ip, np.zeros(12),
                                       False, False, *outs)
        _, v, dq, err, clear, self_c, mu, cdf, smin, _ = (o[0] for o in outs)
        v_pin = np.zeros(18)
        v_pin[:6], v_pin[self.model.v_index] = v[:6], v[6:]
        q_next = np.empty(19)
        q_next[:7], q_next[self.model.q_index] = x_next[:7], x_next[7:19]
        sample = {"v": v_pin, "dq_joints": dq, "ee_position_error_m": err[0], "ee_attitude_error": err[1],
                  "base_position_error_m": err[2], "base_attitude_error": err[3], "clearance_m": clear,
                  "self_clearance_m": self_c, "mu": mu, "cdf": cdf, "sigma_min": smin}
        return sample, q_next

    def observation(self) -> tuple[Array, Array, Array, Array, float]:
        """Joint angles, EE error (6), base error (6), obstacle-relative vector (3), clearance [m]."""
        e1, e0, rel, clear = kernel_loop.observe(self._mdl, self.x, self.t, self.fp, self.ip)
        return self.x[7:19].copy(), e1, e0, rel, float(clear)

    def min_margin(self, last: int) -> float:
        """Smallest margin to a collision [m] over the last ``last`` samples (:meth:`Rollout.min_margin`)."""
        window = slice(self.rows - last, self.rows)
        return float(min(np.min(self._log["clear"][window]) - self.fp[ks.F_KEEP_OUT], np.min(self._log["self"][window])))

    def trajectory(self) -> Trajectory:
        """The :class:`Trajectory` recorded so far, in Pinocchio order."""
        n, log, model = self.rows, self._log, self.model
        q = np.zeros((n, 19))
        q[:, :7] = log["x"][:n, :7]
        q[:, model.q_index] = log["x"][:n, 7:]
        v = np.zeros((n, 18))
        v[:, :6] = log["v"][:n, :6]
        v[:, model.v_index] = log["v"][:n, 6:]
        err = log["err"][:n]
        info: dict[str, Any] = {"scenario": self.scenario.name, "scenario_sha256": self.scenario.sha256(),
                                "method": self.method, "m": self.m, "T_c_s": self.T_c,
                                "dt_s": self.dt, "duration_s": self.scenario.simulation.duration_s, "backend": "kernel",
                                "plant": self.scenario.simulation.plant}
        servo_plant = self.scenario.simulation.plant == "servo"
        if servo_plant:
            info["torque_saturation"] = self.saturation()
        return Trajectory(t=np.arange(n) * self.dt, q=q, v=v, dq_joints=log["dq"][:n].copy(),
                          ee_position_error_m=err[:, 0].copy(), ee_attitude_error=err[:, 1].copy(),
                          base_position_error_m=err[:, 2].copy(), base_attitude_error=err[:, 3].copy(),
                          clearance_m=log["clear"][:n].copy(), self_clearance_m=log["self"][:n].copy(),
                          mu=log["mu"][:n].copy(), cdf=log["cdf"][:n].copy(), sigma_min=log["smin"][:n].copy(), info=info,
                          joint_torque_Nm=log["tau"][:n].copy() if servo_plant else None)

    def saturation(self) -> dict[str, float]:
        """The servo plant's torque saturation so far: physics steps, the fraction of them with a joint at its
        torque limit, and the peak |τ| / τ_max."""
        steps = float(self.x[servo.X_STEPS])
        return {"physics_steps": int(steps), "saturated_fraction": float(self.x[servo.X_SATURATED]) / max(steps, 1.0),
                "peak_torque_ratio": float(self.x[servo.X_PEAK])}
