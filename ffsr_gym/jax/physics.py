"""The robot's physics as pure JAX functions: kinematics, momentum matrices, the momentum-conserving base velocity
and the explicit midpoint step on SE(3) (docs/model.md §1-2, §12).

The same equations as the compiled kernel (``ffsr_gym.kernel.physics``), written as array expressions for ``jit``,
``vmap``, ``lax.scan`` and ``grad``: no Python branch on a traced value, no in-place write. The model is the
kernel's (:class:`Model`, from :func:`ffsr_gym.kernel.arrays.extract`, the URDF read through Pinocchio); its joint
tree is static, so the passes over it are unrolled when traced. State ``x`` (19,): base position [m], base
quaternion (x, y, z, w), 12 joint angles [rad], mission arm first.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from ffsr_gym.exceptions import MissingDependencyError
from ffsr_gym.kernel.arrays import KernelModel

try:
    import jax
    import jax.numpy as jnp
except ImportError as exc:
    raise MissingDependencyError('ffsr_gym.jax needs JAX: pip install "ffsr-gym[jax]"') from exc
jax.config.update("jax_enable_x64", True)


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class Model:
    """The kernel's model arrays as JAX arrays, and its joint tree as static Python numbers (a pytree whose leaves
    are the arrays, so it passes through ``jit`` as an argument)."""

    parent: tuple[int, ...] = field(metadata={"static": True})
    ee_parent: tuple[int, int] = field(metadata={"static": True})
    placement_R: jnp.ndarray
    placement_p: jnp.ndarray
    axis: jnp.ndarray
    mass: jnp.ndarray
    lever: jnp.ndarray
    inertia: jnp.ndarray
    ee_R: jnp.ndarray
    ee_p: jnp.ndarray


def model_of(kernel: KernelModel) -> Model:
    """:class:`Model` of a robot's kernel arrays (``ffsr_gym.sim.setup.robot_assets(name).kernel``)."""
    as_jax = lambda a: jnp.asarray(np.asarray(a, dtype=np.float64))  # noqa: E731
    return Model(tuple(int(p) for p in kernel.parent), tuple(int(p) for p in kernel.ee_parent),
                 as_jax(kernel.placement_R), as_jax(kernel.placement_p), as_jax(kernel.axis), as_jax(kernel.mass),
                 as_jax(kernel.lever), as_jax(kernel.inertia), as_jax(kernel.ee_R), as_jax(kernel.ee_p))


class Kinematics(NamedTuple):
    """Frames at a state, world frame: joint rotations (12, 3, 3) and origins (12, 3), joint axes (12, 3), the base
    rotation (3, 3), end-effector rotations (2, 3, 3) and positions (2, 3), mission arm first."""

    Rj: jnp.ndarray
    pj: jnp.ndarray
    z: jnp.ndarray
    R_b: jnp.ndarray
    Re: jnp.ndarray
    pe: jnp.ndarray


class Momentum(NamedTuple):
    """Momentum matrices about the base CoM, world frame (docs/model.md §2): H_b (6, 6), H_bm (2, 6, 6), and the
    system CoM [m]."""

    H_b: jnp.ndarray
    H_bm: jnp.ndarray
    com: jnp.ndarray


def skew(v: jnp.ndarray) -> jnp.ndarray:
    """The cross-product matrix of ``v`` (3,): ``skew(v) @ u == cross(v, u)``."""
    zero = jnp.zeros_like(v[0])
    return jnp.array([[zero, -v[2], v[1]], [v[2], zero, -v[0]], [-v[1], v[0], zero]])


def quat_matrix(q: jnp.ndarray) -> jnp.ndarray:
    """Rotation matrix of the unit quaternion ``q`` = (x, y, z, w)."""
    x, y, z, w = q[0], q[1], q[2], q[3]
    return jnp.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                      [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                      [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def axis_rotation(axis: jnp.ndarray, angle: jnp.ndarray) -> jnp.ndarray:
    """Rotation by ``angle`` [rad] about the unit ``axis`` (Rodrigues)."""
    K = skew(axis)
    return jnp.eye(3) + jnp.sin(angle) * K + (1.0 - jnp.cos(angle)) * (K @ K)


def kinematics(model: Model, x: jnp.ndarray) -> Kinematics:
    """Forward kinematics of the state ``x`` (19,)."""
    R_b = quat_matrix(x[3:7])
    Rs, ps = [], []
    for k, q in enumerate(model.parent):
        P, origin = (R_b, x[:3]) if q < 0 else (Rs[q], ps[q])
        ps.append(origin + P @ model.placement_p[k])
        Rs.append(P @ model.placement_R[k] @ axis_rotation(model.axis[k], x[7 + k]))
    Rj, pj = jnp.stack(Rs), jnp.stack(ps)
    z = jnp.einsum("kij,kj->ki", Rj, model.axis)
    ee = jnp.array(model.ee_parent)
    Re = jnp.einsum("aij,ajk->aik", Rj[ee], model.ee_R)
    pe = pj[ee] + jnp.einsum("aij,aj->ai", Rj[ee], model.ee_p)
    return Kinematics(Rj, pj, z, R_b, Re, pe)


def momentum(model: Model, x: jnp.ndarray, kin: Kinematics) -> Momentum:
    """H_b, H_bm and the system CoM at ``x`` (its :func:`kinematics` ``kin``), by composite bodies.

    Joint k's subtree has mass M_k, first moment D_k = Σ m_i d_i and second moment A_k = Σ (I_i + m_i (|d_i|² 1 −
    d_i d_iᵀ)) about the base CoM (d_i = r_i − x_base, I_i the body's world inertia); with e_k = p_k − x_base,
    column k of H_bm is [z_k × (D_k − M_k e_k); A_k z_k − D_k × (z_k × e_k)], and the whole robot gives H_b.
    """
    base = x[:3]
    d = kin.pj - base + jnp.einsum("kij,kj->ki", kin.Rj, model.lever[1:])  # body CoMs from the base CoM
    world_I = jnp.einsum("kij,kjl,kml->kim", kin.Rj, model.inertia[1:], kin.Rj)
    m = model.mass[1:]
    second = world_I + m[:, None, None] * (jnp.sum(d * d, axis=1)[:, None, None] * jnp.eye(3)
                                           - d[:, :, None] * d[:, None, :])
    M, D, A = list(m), list(m[:, None] * d), list(second)
    for k in range(11, -1, -1):  # subtree sums, tips first
        q = model.parent[k]
        if q >= 0:
            M[q], D[q], A[q] = M[q] + M[k], D[q] + D[k], A[q] + A[k]
    M, D, A = jnp.stack(M), jnp.stack(D), jnp.stack(A)
    e = kin.pj - base
    linear = jnp.cross(kin.z, D - M[:, None] * e)
    angular = jnp.einsum("kij,kj->ki", A, kin.z) - jnp.cross(D, jnp.cross(kin.z, e))
    H_bm = jnp.concatenate((linear, angular), axis=1).reshape(2, 6, 6).transpose(0, 2, 1)
    roots = [k for k, q in enumerate(model.parent) if q < 0]
    total = model.mass[0] + sum(M[k] for k in roots)
    first = sum(D[k] for k in roots)
    rot = kin.R_b @ model.inertia[0] @ kin.R_b.T + sum(A[k] for k in roots)
    S = skew(first)
    H_b = jnp.block([[total * jnp.eye(3), S.T], [S, rot]])
    return Momentum(H_b, H_bm, base + first / total)


def base_velocity(x: jnp.ndarray, dq: jnp.ndarray, h: jnp.ndarray, kin: Kinematics, mom: Momentum) -> jnp.ndarray:
    """Base twist (6,) in the base frame [v; ω] that conserves the total momentum ``h`` = [P; L_G] (about the
    system CoM) while the joints move at ``dq`` (12,): H_b V_0 = C − H_bm1 dq1 − H_bm2 dq2."""
    about_base = jnp.concatenate((h[:3], h[3:] + jnp.cross(mom.com - x[:3], h[:3])))
    rhs = about_base - mom.H_bm[0] @ dq[:6] - mom.H_bm[1] @ dq[6:]
    world = jnp.linalg.solve(mom.H_b, rhs)
    return jnp.concatenate((kin.R_b.T @ world[:3], kin.R_b.T @ world[3:]))


def integrate(x: jnp.ndarray, v_base: jnp.ndarray, dq: jnp.ndarray, dt: float) -> jnp.ndarray:
    """``x`` ⊕ (v dt): the base by the SE(3) exponential of its base-frame twist, the joints additively."""
    w, u = v_base[3:] * dt, v_base[:3] * dt
    theta2 = jnp.sum(w * w)
    small = theta2 < 1e-12
    safe2 = jnp.where(small, 1.0, theta2)  # the branch not taken must stay finite for grad
    theta = jnp.sqrt(safe2)
    c1 = jnp.where(small, 0.5 - theta2 / 24.0, (1.0 - jnp.cos(theta)) / safe2)
    c2 = jnp.where(small, 1.0 / 6.0 - theta2 / 120.0, (theta - jnp.sin(theta)) / (safe2 * theta))
    half = jnp.where(small, 0.5 - theta2 / 48.0, jnp.sin(0.5 * theta) / theta)
    cos_half = jnp.where(small, 1.0 - theta2 / 8.0, jnp.cos(0.5 * theta))
    wu = jnp.cross(w, u)
    v = u + c1 * wu + c2 * jnp.cross(w, wu)
    q = x[3:7]
    position = x[:3] + quat_matrix(q) @ v
    dx, dy, dz, dw = half * w[0], half * w[1], half * w[2], cos_half
    qx, qy, qz, qw = q[0], q[1], q[2], q[3]
    new = jnp.array([qw * dx + qx * dw + qy * dz - qz * dy, qw * dy - qx * dz + qy * dw + qz * dx,
                     qw * dz + qx * dy - qy * dx + qz * dw, qw * dw - qx * dx - qy * dy - qz * dz])
    return jnp.concatenate((position, new / jnp.linalg.norm(new), x[7:] + dq * dt))


def midpoint(model: Model, x: jnp.ndarray, dq: jnp.ndarray, h: jnp.ndarray, dt: float) -> tuple[jnp.ndarray,
                                                                                                  jnp.ndarray]:
    """One explicit midpoint step of ``dt`` [s] with the joint rates ``dq`` held, the base velocity re-solved from
    momentum conservation at the half step. Returns ``(x_next, v_mid)``."""
    kin = kinematics(model, x)
    v0 = base_velocity(x, dq, h, kin, momentum(model, x, kin))
    half = integrate(x, v0, dq, 0.5 * dt)
    kin_half = kinematics(model, half)
    v_mid = base_velocity(half, dq, h, kin_half, momentum(model, half, kin_half))
    return integrate(x, v_mid, dq, dt), v_mid
