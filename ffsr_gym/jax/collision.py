"""Collision distances as pure JAX functions: the robot's capsules and base box against obstacle spheres, the arms
against each other and against the base (docs/model.md §11).

The same closed forms as the kernel (``ffsr_gym.kernel.collision``): a capsule is its axis segment and a radius;
a segment against the base box is the box's signed distance minimised along the segment, exactly, piece by piece
between the 23 parameters where its formula changes. Every pair is measured (no pruning by bounds), so each
clearance is a ``min`` over fixed arrays. The pair lists are static, read from the kernel's arrays.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ffsr_gym.jax.physics import Kinematics, jax, jnp
from ffsr_gym.kernel.arrays import KernelModel

_PAIRS = ((0, 1), (0, 2), (1, 2))


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class Shapes:
    """The collision capsules (axis ends in their parent joint's frame [m], radii [m]) and the base box's half
    extents [m]; static: each capsule's parent joint (-1 the base), the arm-arm pairs and the capsules checked
    against the base."""

    cap_a: jnp.ndarray
    cap_b: jnp.ndarray
    radius: jnp.ndarray
    box_half: jnp.ndarray
    parent: tuple[int, ...] = field(metadata={"static": True})
    arm_pairs: tuple[tuple[int, int], ...] = field(metadata={"static": True})
    vs_base: tuple[int, ...] = field(metadata={"static": True})


def shapes_of(kernel: KernelModel) -> Shapes:
    """:class:`Shapes` of a robot's kernel arrays."""
    arm = [int(a) for a in kernel.cap_arm]
    pairs = tuple((i, j) for i in range(len(arm)) if arm[i] == 0 for j in range(len(arm)) if arm[j] == 1)
    f = lambda v: jnp.asarray(np.asarray(v, dtype=np.float64))  # noqa: E731
    return Shapes(f(kernel.cap_a), f(kernel.cap_b), f(kernel.cap_radius), f(kernel.box_half),
                  tuple(int(p) for p in kernel.cap_parent), pairs,
                  tuple(i for i, flag in enumerate(kernel.cap_vs_base) if flag))


def capsule_ends(shapes: Shapes, kin: Kinematics, x: jnp.ndarray) -> tuple[jnp.ndarray, jnp.ndarray]:
    """World end points (n, 3) of every capsule's axis at the state ``x`` (its kinematics ``kin``)."""
    parent = np.array(shapes.parent)
    R = jnp.where((parent < 0)[:, None, None], kin.R_b[None], kin.Rj[np.maximum(parent, 0)])
    origin = jnp.where((parent < 0)[:, None], x[:3][None], kin.pj[np.maximum(parent, 0)])
    return (origin + jnp.einsum("kij,kj->ki", R, shapes.cap_a), origin + jnp.einsum("kij,kj->ki", R, shapes.cap_b))


def _safe_sqrt(value: jnp.ndarray) -> jnp.ndarray:
    positive = value > 0.0
    return jnp.where(positive, jnp.sqrt(jnp.where(positive, value, 1.0)), 0.0)


def box_sdf_local(p: jnp.ndarray, half: jnp.ndarray) -> jnp.ndarray:
    """Signed distance [m] of box-frame points ``p`` (..., 3) to a box of half extents ``half`` (negative inside)."""
    d = jnp.abs(p) - half
    outside = jnp.sum(jnp.maximum(d, 0.0) ** 2, axis=-1)
    return jnp.where(outside > 0.0, _safe_sqrt(outside), jnp.max(d, axis=-1))


def _candidates(la: jnp.ndarray, d: jnp.ndarray, half: jnp.ndarray) -> jnp.ndarray:
    """The 23 parameters t (the kernel's ``_candidate``): the ends, x_i = −h_i, 0, h_i, and the crossings
    |x_i| − h_i = |x_j| − h_j; one that does not exist or lies outside [0, 1] is 0 (a repeated cut is harmless)."""
    ts = [jnp.array(0.0), jnp.array(1.0)]
    for i in range(3):
        for level in (-1.0, 0.0, 1.0):
            ok = d[i] != 0.0
            ts.append(jnp.where(ok, (half[i] * level - la[i]) / jnp.where(ok, d[i], 1.0), -1.0))
    for i, j in _PAIRS:
        for sj in (-1.0, 1.0):
            for si in (-1.0, 1.0):
                denominator = si * d[i] - sj * d[j]
                ok = denominator != 0.0
                ts.append(jnp.where(ok, (half[i] - half[j] - si * la[i] + sj * la[j]) / jnp.where(ok, denominator, 1.0),
                                    -1.0))
    ts = jnp.stack(ts)
    return jnp.where((ts >= 0.0) & (ts <= 1.0), ts, 0.0)


def segment_box_local(la: jnp.ndarray, d: jnp.ndarray, half: jnp.ndarray) -> jnp.ndarray:
    """Minimum over t in [0, 1] of the box SDF at ``la + t d`` (box-frame coordinates), exact: the values at the
    cuts, and on each piece between cuts the closed-form minimiser of the squared outside distance."""
    ts = jnp.sort(_candidates(la, d, half))
    at_cuts = box_sdf_local(la[None, :] + ts[:, None] * d[None, :], half)
    lo, hi = ts[:-1], ts[1:]
    middle = la[None, :] + (0.5 * (lo + hi))[:, None] * d[None, :]
    out = jnp.abs(middle) > half[None, :]
    s = jnp.where(middle > 0.0, 1.0, -1.0)
    numerator = -jnp.sum(jnp.where(out, (s * la[None, :] - half[None, :]) * s * d[None, :], 0.0), axis=1)
    denominator = jnp.sum(jnp.where(out, d[None, :] ** 2, 0.0), axis=1)
    t_min = jnp.clip(numerator / jnp.where(denominator > 0.0, denominator, 1.0), lo, hi)
    pieces = box_sdf_local(la[None, :] + t_min[:, None] * d[None, :], half)
    pieces = jnp.where((denominator > 0.0) & (hi > lo), pieces, jnp.inf)
    return jnp.minimum(jnp.min(at_cuts), jnp.min(pieces))


def segment_box(a: jnp.ndarray, b: jnp.ndarray, R: jnp.ndarray, centre: jnp.ndarray, half: jnp.ndarray) -> jnp.ndarray:
    """Signed distance [m] of the segment a → b (world) to a box (rotation ``R``, ``centre``, ``half`` extents)."""
    la = R.T @ (a - centre)
    return segment_box_local(la, R.T @ (b - centre) - la, half)


def point_segment(p: jnp.ndarray, A: jnp.ndarray, B: jnp.ndarray) -> tuple[jnp.ndarray, jnp.ndarray]:
    """Distances [m] from ``p`` to the segments A → B (rows), and the vectors nearest point → p (n, 3)."""
    d = B - A
    t = jnp.clip(jnp.sum((p[None, :] - A) * d, axis=1) / jnp.sum(d * d, axis=1), 0.0, 1.0)
    e = p[None, :] - A - t[:, None] * d
    return _safe_sqrt(jnp.sum(e * e, axis=1)), e


def segment_segment(A1, B1, A2, B2) -> jnp.ndarray:
    """Distance [m] between the segments A1 → B1 and A2 → B2 (the kernel's clamped closed form)."""
    d1, d2, r = B1 - A1, B2 - A2, A1 - A2
    a, e, f, c, b = d1 @ d1, d2 @ d2, d2 @ r, d1 @ r, d1 @ d2
    denominator = a * e - b * b
    general = denominator > 1e-14 * a * e
    s = jnp.where(general, jnp.clip((b * f - c * e) / jnp.where(general, denominator, 1.0), 0.0, 1.0), 0.0)
    t = (b * s + f) / e
    s = jnp.where(t < 0.0, jnp.clip(-c / a, 0.0, 1.0), jnp.where(t > 1.0, jnp.clip((b - c) / a, 0.0, 1.0), s))
    t = jnp.clip(t, 0.0, 1.0)
    gap = r + s * d1 - t * d2
    return _safe_sqrt(gap @ gap)


def obstacle_clearance(shapes: Shapes, R_b: jnp.ndarray, p_b: jnp.ndarray, A: jnp.ndarray, B: jnp.ndarray,
                       p_o: jnp.ndarray, r_o: jnp.ndarray) -> tuple[jnp.ndarray, jnp.ndarray]:
    """Signed distance [m] of the robot (capsules and base box) to the sphere (``p_o``, ``r_o``), and the vector
    from the nearest robot point to the nearest obstacle point (the kernel's ``obstacle_clearance``)."""
    local = R_b.T @ (p_o - p_b)
    box = box_sdf_local(local, shapes.box_half) - r_o
    rel = p_o - (p_b + R_b @ jnp.clip(local, -shapes.box_half, shapes.box_half))
    n = _safe_sqrt(rel @ rel)
    rel = jnp.where(n > 0.0, rel - r_o * rel / jnp.where(n > 0.0, n, 1.0), rel)
    dist, e = point_segment(p_o, A, B)
    values = dist - shapes.radius - r_o
    k = jnp.argmin(values)
    capsule_rel = e[k] * jnp.where(dist[k] > 0.0, 1.0 - (shapes.radius[k] + r_o) / jnp.where(dist[k] > 0.0, dist[k],
                                                                                              1.0), 0.0)
    closer = values[k] < box
    return jnp.where(closer, values[k], box), jnp.where(closer, capsule_rel, rel)


def self_clearance(shapes: Shapes, R_b: jnp.ndarray, p_b: jnp.ndarray, A: jnp.ndarray, B: jnp.ndarray) -> jnp.ndarray:
    """Smallest signed distance [m] arm–arm and arm–base (mounting links excluded)."""
    i, j = (np.array(side) for side in zip(*shapes.arm_pairs))
    arms = jax.vmap(segment_segment)(A[i], B[i], A[j], B[j]) - shapes.radius[i] - shapes.radius[j]
    k = np.array(shapes.vs_base)
    base = jax.vmap(lambda a, b: segment_box(a, b, R_b, p_b, shapes.box_half))(A[k], B[k]) - shapes.radius[k]
    return jnp.minimum(jnp.min(arms), jnp.min(base))
