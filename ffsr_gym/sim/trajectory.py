"""The record of one closed-loop run and the metrics computed from it."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ffsr_gym.types import Array

CONVERGENCE_THRESHOLD_M = 1e-6


@dataclass(frozen=True)
class Trajectory:
    """Samples of one run at t_k = k dt, k = 0..n (the rates at t_k are held over [t_k, t_k+1)).

    Attributes:
        t: (n+1,) time [s].
        q: (n+1, 19) configuration, Pinocchio order (free-flyer first, quaternion x, y, z, w).
        v: (n+1, 18) velocity, Pinocchio order (base part in the base frame) [m/s, rad/s].
        dq_joints: (n+1, 12) joint rates [rad/s], mission arm first: the planned ones on the
            kinematic plant; on the servo plant the ones the joints made (their mean over the step;
            the last sample's: its rates at that instant).
        ee_position_error_m: (n+1,) ||p_e − p_d|| [m].
        ee_attitude_error: (n+1,) ||e_o|| of the end-effector (sin of half the error angle).
        base_position_error_m: (n+1,) ||r_0 − r_0d|| [m].
        base_attitude_error: (n+1,) ||e_o|| of the base.
        clearance_m: (n+1,) signed distance robot ↔ obstacle [m] (+inf without obstacle).
        self_clearance_m: (n+1,) signed distance arm ↔ arm and arm ↔ base [m].
        mu: (n+1, 2) blend factors (mission, balance).
        cdf: (n+1, 2) danger field of each arm at the obstacle.
        sigma_min: (n+1, 2) smallest singular values of J_m¹ and J_c².
        info: run description (scenario, method, m, T_c, dt, plant, ...; the servo plant adds its
            torque saturation).
        joint_torque_Nm: (n+1, 12) the servo plant's drive torques [N m], per step the one of largest
            magnitude (None for the kinematic plant; the last sample's row is 0).
    """

    t: Array
    q: Array
    v: Array
    dq_joints: Array
    ee_position_error_m: Array
    ee_attitude_error: Array
    base_position_error_m: Array
    base_attitude_error: Array
    clearance_m: Array
    self_clearance_m: Array
    mu: Array
    cdf: Array
    sigma_min: Array
    info: dict[str, Any] = field(default_factory=dict)
    joint_torque_Nm: Array | None = None

    @property
    def dt(self) -> float:
        """Time step [s]."""
        return float(self.t[1] - self.t[0])

    def head(self, rows: int) -> Trajectory:
        """The first ``rows`` samples (the last of them becomes the final sample: its rates are not applied)."""
        if not 1 <= rows <= len(self.t):
            raise ValueError(f"rows = {rows}; allowed 1 to {len(self.t)}")
        cut = {f.name: getattr(self, f.name)[:rows] for f in dataclasses.fields(self)
               if f.name != "info" and getattr(self, f.name) is not None}
        return dataclasses.replace(self, **cut)

    def avoidance_release_time(self) -> float | None:
        """Time [s] after which μ of the mission arm stays 1 (None if avoidance never acted)."""
        active = np.flatnonzero(self.mu[:, 0] < 1.0)
        return None if active.size == 0 else float(self.t[min(active[-1] + 1, len(self.t) - 1)])

    def convergence_time(self, threshold_m: float = CONVERGENCE_THRESHOLD_M) -> float | None:
        """First time [s] after which the EE position error stays below ``threshold_m`` (None if never)."""
        above = np.flatnonzero(self.ee_position_error_m >= threshold_m)
        if above.size == 0:
            return float(self.t[0])
        if above[-1] == len(self.t) - 1:
            return None
        return float(self.t[above[-1] + 1])

    def metrics(self) -> dict[str, Any]:
        """Summary numbers (JSON-ready; ``None`` where a quantity does not exist)."""
        rates_deg = np.degrees(self.dq_joints[:-1])
        peak = np.max(np.abs(rates_deg), axis=0).reshape(2, 6)
        signed_peak = rates_deg[np.argmax(np.abs(rates_deg), axis=0), np.arange(12)].reshape(2, 6)
        release = self.avoidance_release_time()
        converged = self.convergence_time()
        min_clearance = float(np.min(self.clearance_m))
        min_self = float(np.min(self.self_clearance_m))
        return {
            "final_ee_position_error_m": float(self.ee_position_error_m[-1]),
            "final_ee_attitude_error": float(self.ee_attitude_error[-1]),
            "max_ee_position_error_m": float(np.max(self.ee_position_error_m)),
            "convergence_time_s": converged,
            "avoidance_release_time_s": release,
            "convergence_after_release_s": None if converged is None or release is None else converged - release,
            "final_base_position_error_m": float(self.base_position_error_m[-1]),
            "max_base_position_error_m": float(np.max(self.base_position_error_m)),
            "max_base_attitude_error": float(np.max(self.base_attitude_error)),
            "peak_joint_rate_deg_s": {"mission": peak[0].tolist(), "balance": peak[1].tolist()},
            "signed_peak_joint_rate_deg_s": {"mission": signed_peak[0].tolist(), "balance": signed_peak[1].tolist()},
            "max_joint_rate_deg_s": {"mission": float(peak[0].max()), "balance": float(peak[1].max())},
            "min_clearance_m": _finite_or_none(min_clearance),
            "min_self_clearance_m": min_self,
            "collided": bool(min_clearance < 0.0 or min_self < 0.0),
            "min_sigma_J_m": float(np.min(self.sigma_min[:, 0])),
            "min_sigma_J_c": float(np.min(self.sigma_min[:, 1])),
        }


def _finite_or_none(x: float) -> float | None:
    return x if math.isfinite(x) else None
