"""Predefined-time stable functions (paper eqs. 2, 3, 9, 10; docs/model.md §3).

The reference form (Sánchez-Torres et al. 2018) is

.. math:: \\varphi(x; T_c, m) = \\frac{1}{m T_c} e^{\\|x\\|^m} \\|x\\|^{1-m} \\frac{x}{\\|x\\|},\\quad \\varphi(0) = 0,

and the system :math:`\\dot x = -\\varphi(x)` reaches 0 at :math:`T_c (1 - e^{-\\|x_0\\|^m}) < T_c`.
The paper prints the form without the :math:`\\|x\\|^{1-m}` factor; it is available as
``form="printed"`` to document the erratum: its settling time is unbounded in ``x_0`` (supremum
:math:`T_c \\Gamma(1/m)`) and it chatters in discrete time.
"""

from __future__ import annotations

import math

import numpy as np

from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.types import Array

FORMS = ("sanchez_torres", "printed")
# exp(709.78) is the largest finite double; the magnitude is capped just below it.
_LOG_MAGNITUDE_CAP = 700.0


def check_parameters(T_c: float, m: float, form: str) -> None:
    """Raise :class:`InvalidInputError` unless m ∈ (0, 1), T_c ∈ (0, ∞) [s] and ``form`` is known."""
    if not (0.0 < m < 1.0):
        raise InvalidInputError(f"m = {m!r} is out of range; allowed: (0, 1)")
    if not (T_c > 0.0 and math.isfinite(T_c)):
        raise InvalidInputError(f"T_c = {T_c!r} is out of range; allowed: (0, inf) seconds")
    if form not in FORMS:
        raise InvalidInputError(f"form = {form!r}; allowed: {list(FORMS)}")


def _scaled_norm(x: Array) -> float:
    """Euclidean norm that neither overflows nor underflows for extreme finite entries."""
    scale = float(np.max(np.abs(x))) if x.size else 0.0
    if scale == 0.0:
        return 0.0
    return scale * float(np.sqrt(np.sum((x / scale) ** 2)))


def phi(x: Array, T_c: float, m: float, *, form: str = "sanchez_torres") -> Array:
    """Predefined-time function of a vector (or scalar) ``x`` (docs/model.md §3).

    Args:
        x: error vector, any shape; the norm is taken over all entries.
        T_c: predefined time [s], > 0.
        m: shape parameter in (0, 1).
        form: ``"sanchez_torres"`` (settles before ``T_c``) or ``"printed"`` (paper's eq. 3).

    Returns:
        An array like ``x``, parallel to it, always finite: the magnitude is capped at
        ``exp(700)`` (reached only for ``||x||^m > ~700``).
    """
    check_parameters(T_c, m, form)
    x = np.asarray(x, dtype=float)
    r = _scaled_norm(x)
    if r == 0.0 or not math.isfinite(r):
        if not np.all(np.isfinite(x)):
            raise InvalidInputError(f"phi needs a finite x, got {x}")
        return np.zeros_like(x)
    log_r = math.log(r)
    log_mag = min(math.exp(m * log_r), _LOG_MAGNITUDE_CAP) - math.log(m * T_c)
    if form == "sanchez_torres":
        log_mag += (1.0 - m) * log_r
    log_mag = min(log_mag, _LOG_MAGNITUDE_CAP)
    # x / r is a unit vector; scale in two steps so that neither factor overflows.
    return (x / r) * math.exp(log_mag)


def settling_time(x0_norm: float, T_c: float, m: float) -> float:
    """Settling time [s] of ``dx/dt = -phi(x)`` (reference form): ``T_c (1 - exp(-||x0||^m))``."""
    check_parameters(T_c, m, "sanchez_torres")
    return T_c * -math.expm1(-(x0_norm**m))
