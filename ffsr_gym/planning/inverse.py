"""Singularity-robust inverse and the blend projector (docs/model.md §7, reconstructed eqs. R13-R15)."""

from __future__ import annotations

import numpy as np

from ffsr_gym.types import Array


def filtered_inverse(J: Array, *, lambda_max: float, epsilon: float) -> tuple[Array, Array, float]:
    """Per-singular-value damped inverse of a square matrix, and its pseudo-inverse projector.

    :math:`J^\\# = \\sum_i \\frac{\\sigma_i}{\\sigma_i^2 + \\lambda_i^2} v_i u_i^T` with
    :math:`\\lambda_i^2 = \\lambda_m^2 (1 - (\\sigma_i/\\varepsilon)^2)` if :math:`\\sigma_i < \\varepsilon`,
    else 0 (R13, R14). Equals :math:`J^{-1}` when every :math:`\\sigma_i \\ge \\varepsilon`.

    Args:
        J: (n, n) matrix.
        lambda_max: maximum damping λ_m (units of J).
        epsilon: singular-value threshold ε (units of J).

    Returns:
        ``(J_sharp, J_pinv_J, sigma_min)``: the damped inverse, the projector J⁺J onto the row
        space (rank tolerance as ``numpy.linalg.pinv``), and the smallest singular value.
    """
    U, s, Vt = np.linalg.svd(J)
    damping = np.where(s < epsilon, lambda_max**2 * (1.0 - (s / epsilon) ** 2), 0.0) if epsilon > 0 else np.zeros_like(s)
    denom = s * s + damping
    gain = np.divide(s, denom, out=np.zeros_like(s), where=denom > 0)
    J_sharp = (Vt.T * gain) @ U.T
    rank = s > s[0] * max(J.shape) * np.finfo(float).eps
    J_pinv_J = (Vt[rank].T @ Vt[rank])
    return J_sharp, J_pinv_J, float(s[-1])
