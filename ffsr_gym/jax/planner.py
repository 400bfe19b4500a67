"""The reference planner as pure JAX functions (docs/model.md §3-10): the predefined-time function, pose errors,
the trapezoidal desired path, the singularity-robust inverse, the cumulative danger field and its blend, and the
joint rates of both arms at one instant.

The same equations as ``ffsr_gym.planning`` (readable numpy) and the compiled kernel; every branch is a ``where``
whose untaken side stays finite, so ``grad`` passes through. What a scenario fixes is a :class:`PlanTask` (arrays,
traced) and its :class:`PlanRules` (static: the method and the settings' choices).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.jax.physics import Kinematics, Model, jax, jnp, kinematics, momentum, quat_matrix, skew

#: exp(709.78) is the largest finite double; φ's magnitude is capped below it (``ffsr_gym.planning.ptsf``).
LOG_CAP = 700.0
_MIN_LENGTH = 1e-12
_MIN_HEIGHT = 1e-12


@dataclass(frozen=True)
class PlanRules:
    """What of a scenario's planner settings is a choice rather than a number (static under ``jit``)."""

    method: str = "predefined_time"
    phi_split: bool = False
    attitude_error: str = "world"
    mu_law: str = "cdf"
    balance_avoids: bool = True
    segments: tuple[tuple[bool, ...], ...] = ((True,) * 6, (True,) * 6)  # the arms' segments longer than 1e-12 m

    def __post_init__(self) -> None:
        allowed = {"method": ("predefined_time", "proportional", "no_feedback", "no_avoidance"),
                   "attitude_error": ("world", "body"), "mu_law": ("cdf", "distance")}
        for name, choices in allowed.items():
            if getattr(self, name) not in choices:
                raise InvalidInputError(f"{name} {getattr(self, name)!r}; allowed: {list(choices)}")


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class PlanTask:
    """The numbers a scenario gives the planner (a pytree: every field a float64 array).

    Path: ``start_position``, ``target_position`` [m], ``start_attitude`` (w, x, y, z), the rotation to the
    target as ``axis`` and ``angle`` [rad], ``motion_time``, ``accel_time`` [s]. Base set-point: ``base_position``
    [m], ``base_attitude`` (w, x, y, z). Obstacles: ``obstacle_position`` (n, 3) [m] at t = 0,
    ``obstacle_velocity`` (n, 3) [m/s], ``obstacle_mask`` (n,): 1 for an obstacle, 0 for a padding row (so that
    tasks with fewer obstacles stack with the others), ``danger_radius`` [m] (the first obstacle's). ``momentum``: the conserved
    [P; L_G]. Settings: ``m``, ``T_c`` [s], ``gain`` [1/s] (proportional), ``lambda_max``, ``epsilon`` (mission,
    balance), ``cdf_k1``, ``cdf_xi``, ``cdf_delta``.
    """

    start_position: jnp.ndarray
    target_position: jnp.ndarray
    start_attitude: jnp.ndarray
    axis: jnp.ndarray
    angle: jnp.ndarray
    motion_time: jnp.ndarray
    accel_time: jnp.ndarray
    base_position: jnp.ndarray
    base_attitude: jnp.ndarray
    obstacle_position: jnp.ndarray
    obstacle_velocity: jnp.ndarray
    obstacle_mask: jnp.ndarray
    danger_radius: jnp.ndarray
    momentum: jnp.ndarray
    m: jnp.ndarray
    T_c: jnp.ndarray
    gain: jnp.ndarray
    lambda_max: jnp.ndarray
    epsilon: jnp.ndarray
    cdf_k1: jnp.ndarray
    cdf_xi: jnp.ndarray
    cdf_delta: jnp.ndarray
    n_obstacles: int = field(default=1, metadata={"static": True})


class Plan(NamedTuple):
    """The planner's decision at one instant (``ffsr_gym.planning.planner.PlanStep``): joint rates (12,) [rad/s],
    the end-effector and base pose errors (6,), μ, CDF, arm distances [m] and σ_min of both arms (2,)."""

    dq: jnp.ndarray
    ee_error: jnp.ndarray
    base_error: jnp.ndarray
    mu: jnp.ndarray
    cdf: jnp.ndarray
    distance: jnp.ndarray
    sigma_min: jnp.ndarray


# ----------------------------------------------------------------------------------------------- quaternions
def quat_multiply(a: jnp.ndarray, b: jnp.ndarray) -> jnp.ndarray:
    """Hamilton product of scalar-first quaternions."""
    return jnp.concatenate((jnp.array([a[0] * b[0] - a[1:] @ b[1:]]), a[0] * b[1:] + b[0] * a[1:] + jnp.cross(a[1:], b[1:])))


def quat_conjugate(q: jnp.ndarray) -> jnp.ndarray:
    return q * jnp.array([1.0, -1.0, -1.0, -1.0])


def quat_from_rotation(R: jnp.ndarray) -> jnp.ndarray:
    """Scalar-first unit quaternion (w >= 0) of a rotation matrix: Shepperd's method, the kernel's choice of form
    (the trace when positive, else the largest diagonal entry)."""
    trace = R[0, 0] + R[1, 1] + R[2, 2]
    forms = jnp.stack([
        jnp.array([1.0 + trace, R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]),
        jnp.array([R[2, 1] - R[1, 2], 1.0 + R[0, 0] - R[1, 1] - R[2, 2], R[0, 1] + R[1, 0], R[0, 2] + R[2, 0]]),
        jnp.array([R[0, 2] - R[2, 0], R[0, 1] + R[1, 0], 1.0 - R[0, 0] + R[1, 1] - R[2, 2], R[1, 2] + R[2, 1]]),
        jnp.array([R[1, 0] - R[0, 1], R[0, 2] + R[2, 0], R[1, 2] + R[2, 1], 1.0 - R[0, 0] - R[1, 1] + R[2, 2]])])
    form = jnp.where(trace > 0.0, 0, jnp.where((R[0, 0] > R[1, 1]) & (R[0, 0] > R[2, 2]), 1,
                                               jnp.where(R[1, 1] > R[2, 2], 2, 3)))
    q = forms[form]  # 4 times the quaternion's (nonzero) component of the form, times the quaternion
    q = q / jnp.linalg.norm(q)
    return jnp.where(q[0] < 0.0, -q, q)


# ----------------------------------------------------------------------------------------- feedback, errors
def safe_norm(x: jnp.ndarray) -> tuple[jnp.ndarray, jnp.ndarray]:
    """``(norm, is_zero)`` of ``x``, with a gradient that stays finite at 0."""
    squared = jnp.sum(x * x)
    zero = squared == 0.0
    return jnp.where(zero, 0.0, jnp.sqrt(jnp.where(zero, 1.0, squared))), zero


def phi(x: jnp.ndarray, T_c: jnp.ndarray, m: jnp.ndarray) -> jnp.ndarray:
    """The predefined-time function of the vector ``x`` (Sánchez-Torres form, docs/model.md §3), φ(0) = 0."""
    r, zero = safe_norm(x)
    log_r = jnp.log(jnp.where(zero, 1.0, r))
    log_mag = jnp.minimum(jnp.exp(m * log_r), LOG_CAP) - jnp.log(m * T_c) + (1.0 - m) * log_r
    magnitude = jnp.exp(jnp.minimum(log_mag, LOG_CAP))
    return jnp.where(zero, 0.0, x / jnp.where(zero, 1.0, r) * magnitude)


def feedback(error: jnp.ndarray, task: PlanTask, rules: PlanRules) -> jnp.ndarray:
    """φ(e) of the method (6,)."""
    if rules.method == "no_feedback":
        return jnp.zeros(6)
    if rules.method == "proportional":
        return task.gain * error
    if rules.phi_split:
        return jnp.concatenate((phi(error[:3], task.T_c, task.m), phi(error[3:], task.T_c, task.m)))
    return phi(error, task.T_c, task.m)


def pose_error(position, sigma, position_d, sigma_d, variant: str):
    """``(e, J, J_d)``: e = [p − p_d; e_o] and ė = J V − J_d V_d (``ffsr_gym.planning.pose_error``)."""
    sigma = jnp.where(sigma @ sigma_d < 0.0, -sigma, sigma)
    if variant == "world":
        delta = quat_multiply(sigma, quat_conjugate(sigma_d))
        eta, eps = delta[0], delta[1:]
        J_o, J_od = 0.5 * (eta * jnp.eye(3) - skew(eps)), 0.5 * (eta * jnp.eye(3) + skew(eps))
    else:
        delta = quat_multiply(quat_conjugate(sigma_d), sigma)
        eta, eps = delta[0], delta[1:]
        J_o = J_od = 0.5 * (eta * jnp.eye(3) + skew(eps)) @ quat_rotation(sigma).T
    zero = jnp.zeros((3, 3))
    J = jnp.block([[jnp.eye(3), zero], [zero, J_o]])
    J_d = jnp.block([[jnp.eye(3), zero], [zero, J_od]])
    return jnp.concatenate((position - position_d, eps)), J, J_d


def quat_rotation(q: jnp.ndarray) -> jnp.ndarray:
    """Rotation matrix of the scalar-first unit quaternion ``q``."""
    return quat_matrix(jnp.array([q[1], q[2], q[3], q[0]]))


def desired(task: PlanTask, t: jnp.ndarray) -> tuple[jnp.ndarray, jnp.ndarray, jnp.ndarray]:
    """Desired end-effector position [m], attitude (w, x, y, z) and world twist at ``t`` (trapezoidal profile)."""
    t_f, t_a = task.motion_time, task.accel_time
    speed = 1.0 / (t_f - t_a)
    accel = speed / t_a
    s = jnp.where(t <= 0.0, 0.0, jnp.where(t < t_a, 0.5 * accel * t * t, jnp.where(
        t <= t_f - t_a, 0.5 * accel * t_a * t_a + speed * (t - t_a),
        jnp.where(t < t_f, 1.0 - 0.5 * accel * (t_f - t) ** 2, 1.0))))
    s_dot = jnp.where(t <= 0.0, 0.0, jnp.where(t < t_a, accel * t, jnp.where(
        t <= t_f - t_a, speed, jnp.where(t < t_f, accel * (t_f - t), 0.0))))
    chord = task.target_position - task.start_position
    half = 0.5 * s * task.angle
    turn = jnp.concatenate((jnp.array([jnp.cos(half)]), jnp.sin(half) * task.axis))
    return (task.start_position + s * chord, quat_multiply(turn, task.start_attitude),
            jnp.concatenate((s_dot * chord, s_dot * task.angle * task.axis)))


# ------------------------------------------------------------------------------------------------- inverse
def filtered_inverse(J: jnp.ndarray, lambda_max: jnp.ndarray, epsilon: jnp.ndarray):
    """``(J#, J⁺J, σ_min)``: the per-singular-value damped inverse (R13, R14) and the row-space projector."""
    U, s, Vt = jnp.linalg.svd(J)
    damping = jnp.where(s < epsilon, lambda_max ** 2 * (1.0 - (s / epsilon) ** 2), 0.0)
    denominator = s * s + damping
    gain = jnp.where(denominator > 0.0, s / jnp.where(denominator > 0.0, denominator, 1.0), 0.0)
    rank = s > s[0] * J.shape[0] * np.finfo(float).eps
    return (Vt.T * gain) @ U.T, (Vt.T * rank) @ Vt, s[-1]


# -------------------------------------------------------------------------------------------- danger field
def _segment(p_o, a, b):
    """Integrals over the segment a → b of 1/ρ, 1/ρ³ and s/ρ³ (ρ the distance to ``p_o``), and min ρ [m]
    (``ffsr_gym.planning.avoidance``)."""
    L = b - a
    length = jnp.linalg.norm(L)
    w = p_o - a
    t0 = (w @ L) / length
    h = jnp.maximum(jnp.linalg.norm(jnp.cross(L, w)) / length, _MIN_HEIGHT)
    tau1, tau2 = -t0, length - t0
    rho1, rho2 = jnp.hypot(tau1, h), jnp.hypot(tau2, h)
    flip = tau2 <= 0.0
    lo, hi = jnp.where(flip, -tau2, tau1), jnp.where(flip, -tau1, tau2)
    r_lo, r_hi = jnp.where(flip, rho2, rho1), jnp.where(flip, rho1, rho2)
    off = lo >= 0.0  # the foot of the perpendicular is off the segment
    inv1 = jnp.where(off, jnp.log((hi + r_hi) / (lo + r_lo)), jnp.arcsinh(hi / h) + jnp.arcsinh(-lo / h))
    inv3 = jnp.where(off, (hi * hi - lo * lo) / (r_lo * r_hi * (hi * r_lo + lo * r_hi)), (hi / r_hi - lo / r_lo) / (h * h))
    I0 = inv3 / length
    I1 = (1.0 / rho1 - 1.0 / rho2) / (length * length) + (t0 / length) * I0
    return inv1 / length, I0, I1, jnp.where(off, r_lo, h)


def danger(points, axes, p_o, k1, used: tuple[bool, ...]):
    """CDF of one arm at ``p_o``, the arm's distance to it [m] and the CDF's joint-space gradient (6,) (R16, R17)."""
    cdf, distance, grad = 0.0, jnp.inf, jnp.zeros(6)
    for i in range(6):
        if not used[i]:
            continue
        a, b = points[i], points[i + 1]
        F, I0, I1, nearest = _segment(p_o, a, b)
        cdf, distance = cdf + F, jnp.minimum(distance, nearest)
        c0 = jnp.cross(a - points[: i + 1], p_o - a)
        c1 = jnp.cross(b - a, p_o - points[: i + 1])
        grad = grad.at[: i + 1].add(jnp.sum(axes[: i + 1] * (c0 * I0 + c1 * I1), axis=1))
    return k1 * cdf, distance, k1 * grad


def _avoidance(arm, kin: Kinematics, t, task: PlanTask, rules: PlanRules):
    """μ, Θ̇_c [rad/s], CDF and distance [m] of ``arm`` at ``t`` (R16-R18)."""
    if task.n_obstacles == 0:
        return 1.0, jnp.zeros(6), 0.0, jnp.inf
    rows = slice(6 * arm, 6 * arm + 6)
    points = jnp.concatenate((kin.pj[rows], kin.pe[arm][None, :]))
    positions = task.obstacle_position + task.obstacle_velocity * t
    cdf, distance, grad = 0.0, jnp.inf, jnp.zeros(6)
    for o in range(task.n_obstacles):
        part, nearest, g = danger(points, kin.z[rows], positions[o], task.cdf_k1, rules.segments[arm])
        real = task.obstacle_mask[o] > 0.0
        cdf = cdf + jnp.where(real, part, 0.0)
        distance = jnp.minimum(distance, jnp.where(real, nearest, jnp.inf))
        grad = grad + jnp.where(real, g, 0.0)
    if rules.mu_law == "cdf":
        mu = jnp.where(cdf <= task.cdf_delta, 1.0, task.cdf_delta / jnp.where(cdf > 0.0, cdf, 1.0))
    else:
        mu = jnp.minimum(1.0, distance / task.danger_radius) ** 2
    if rules.method == "no_avoidance" or (arm == 1 and not rules.balance_avoids):
        mu = jnp.ones_like(mu)
    keep = mu >= 1.0
    return jnp.where(keep, 1.0, mu), jnp.where(keep, 0.0, -task.cdf_xi * grad), cdf, distance


def plan(model: Model, task: PlanTask, rules: PlanRules, t: jnp.ndarray, x: jnp.ndarray) -> Plan:
    """Joint rates of both arms at time ``t`` [s] and state ``x`` (docs/model.md §8 steps 1-8)."""
    kin = kinematics(model, x)
    mom = momentum(model, x, kin)
    sigma_b = jnp.array([x[6], x[3], x[4], x[5]])
    e0, J_b, _ = pose_error(x[:3], sigma_b, task.base_position, task.base_attitude, rules.attitude_error)
    V0 = -jnp.linalg.solve(J_b, feedback(e0, task, rules))
    p_d, sigma_d, V_ed = desired(task, t)
    e1, J_e, J_ed = pose_error(kin.pe[0], quat_from_rotation(kin.Re[0]), p_d, sigma_d, rules.attitude_error)
    J_0 = jnp.eye(6).at[:3, 3:].set(-skew(kin.pe[0] - x[:3]))
    x1 = jnp.linalg.solve(J_e, J_ed @ V_ed - feedback(e1, task, rules)) - J_0 @ V0
    mu1, dq_c1, cdf1, d1 = _avoidance(0, kin, t, task, rules)
    J_m = arm_jacobian(kin, 0)
    J_sharp, P, smin1 = filtered_inverse(J_m, task.lambda_max[0], task.epsilon[0])
    dq1 = mu1 * J_sharp @ x1 + (dq_c1 - mu1 * P @ dq_c1)
    C = jnp.concatenate((task.momentum[:3], task.momentum[3:] + jnp.cross(mom.com - x[:3], task.momentum[:3])))
    x2 = mom.H_bm[0] @ dq1 + mom.H_b @ V0 - C
    mu2, dq_c2, cdf2, d2 = _avoidance(1, kin, t, task, rules)
    J_sharp, P, smin2 = filtered_inverse(-mom.H_bm[1], task.lambda_max[1], task.epsilon[1])
    dq2 = mu2 * J_sharp @ x2 + (dq_c2 - mu2 * P @ dq_c2)
    pair = lambda a, b: jnp.stack((jnp.asarray(a, float), jnp.asarray(b, float)))  # noqa: E731
    return Plan(jnp.concatenate((dq1, dq2)), e1, e0, pair(mu1, mu2), pair(cdf1, cdf2), pair(d1, d2),
                pair(smin1, smin2))


def arm_jacobian(kin: Kinematics, arm: int) -> jnp.ndarray:
    """Fixed-base Jacobian (6, 6) of ``arm`` at its end-effector, world-aligned, linear part first (R4)."""
    rows = slice(6 * arm, 6 * arm + 6)
    z, p = kin.z[rows], kin.pj[rows]
    return jnp.concatenate((jnp.cross(z, kin.pe[arm] - p).T, z.T))
