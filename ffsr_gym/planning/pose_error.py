"""Pose errors of the end-effector and the base (docs/model.md §4, reconstructed eqs. R6-R7).

Quaternions are scalar-first. The attitude error has two variants, both verified against finite
differences (``tests/library/planning/test_pose_error.py``):

* ``"world"`` (default): δσ = σ ⊗ σ_d*, e_o = δε,
  :math:`\\dot e_o = J_o \\omega - J_{od} \\omega_d`, J_o = ½(δη I − S(δε)), J_od = ½(δη I + S(δε)).
* ``"body"``: δσ = σ_d* ⊗ σ, e_o = δε, :math:`\\dot e_o = J_o (\\omega - \\omega_d)` with
  J_o = J_od = ½(δη I + S(δε)) R(σ)ᵀ.

ω, ω_d are world-frame angular velocities [rad/s]. The sign of σ is chosen so that δη ≥ 0 (the
short way round); J_o is then invertible (det J_o = δη/8) except at a 180° error.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ffsr_gym.model import quaternion as quat
from ffsr_gym.types import Array

VARIANTS = ("world", "body")


@dataclass(frozen=True)
class AttitudeError:
    """Attitude error e_o (3,) and its Jacobians J_o, J_od (3x3) w.r.t. world ω and ω_d."""

    e_o: Array
    J_o: Array
    J_od: Array
    delta_eta: float


def attitude_error(sigma: Array, sigma_d: Array, variant: str = "world") -> AttitudeError:
    """Attitude error of ``sigma`` relative to ``sigma_d`` (scalar-first unit quaternions).

    Args:
        sigma: actual attitude.
        sigma_d: desired attitude.
        variant: ``"world"`` or ``"body"`` (see the module docstring).
    """
    sigma = np.asarray(sigma, dtype=float)
    if sigma @ np.asarray(sigma_d) < 0.0:
        sigma = -sigma
    if variant == "world":
        delta = quat.multiply(sigma, quat.conjugate(sigma_d))
        eta, eps = delta[0], delta[1:]
        J_o = 0.5 * (eta * np.eye(3) - quat.skew(eps))
        J_od = 0.5 * (eta * np.eye(3) + quat.skew(eps))
        return AttitudeError(eps, J_o, J_od, float(eta))
    if variant == "body":
        delta = quat.multiply(quat.conjugate(sigma_d), sigma)
        eta, eps = delta[0], delta[1:]
        J_o = 0.5 * (eta * np.eye(3) + quat.skew(eps)) @ quat.to_rotation(sigma).T
        return AttitudeError(eps, J_o, J_o, float(eta))
    raise ValueError(f"attitude error variant {variant!r}; allowed: {list(VARIANTS)}")


def pose_error(position: Array, sigma: Array, position_d: Array, sigma_d: Array, variant: str) -> tuple[Array, Array, Array]:
    """Pose error e = [p − p_d; e_o] (6,) with J = blkdiag(I, J_o) and J_d = blkdiag(I, J_od).

    So that :math:`\\dot e = J V - J_d V_d` for world twists V = [v; ω] (R6, R7).
    """
    att = attitude_error(sigma, sigma_d, variant)
    J, J_d = np.eye(6), np.eye(6)
    J[3:, 3:] = att.J_o
    J_d[3:, 3:] = att.J_od
    return np.concatenate((np.asarray(position) - position_d, att.e_o)), J, J_d
