"""The predefined-time function: settling before T_c, finiteness, and the printed form's erratum."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad, solve_ivp

from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.planning.ptsf import phi, settling_time

T_C = 3.0


def _numerical_settling_time(x0: np.ndarray, m: float, form: str = "sanchez_torres") -> float:
    """Integrate dx/dt = -phi(x) in log-radius form u = ln||x|| with an adaptive solver.

    The state is the full vector x = e^u d; the rate u' = -(d . phi(e^u d)) / e^u is evaluated
    through the vector phi. Integration stops at ||x|| = ||x0|| 1e-4^(1/m), where the time still
    to go is below 1e-4 of the whole (near 0 the radius shrinks like (time to go)^(1/m)).
    """
    direction = x0 / np.linalg.norm(x0)
    u_end = math.log(np.linalg.norm(x0)) + math.log(1e-4) / m

    def rate(_t, u):
        r = math.exp(u[0])
        return [-(direction @ phi(r * direction, T_C, m, form=form)) / r]

    def reached(_t, u):
        return u[0] - u_end

    reached.terminal = True
    sol = solve_ivp(rate, (0.0, 100 * T_C), [math.log(np.linalg.norm(x0))], method="LSODA",
                    events=reached, rtol=1e-10, atol=1e-12)
    assert sol.status == 1, sol.message
    return float(sol.t_events[0][0])


@pytest.mark.parametrize("r0", [1e-6, 1e-3, 1.0, 10.0, 100.0])
@pytest.mark.parametrize("m", [0.05, 0.25, 0.5, 0.75, 0.95])
@pytest.mark.parametrize("dim", [1, 6])
def test_settles_before_T_c_at_the_analytic_time(r0, m, dim):
    rng = np.random.default_rng(int(r0 * 1e6) % 1000 + dim)
    direction = rng.normal(size=dim)
    x0 = r0 * direction / np.linalg.norm(direction)
    analytic = settling_time(r0, T_C, m)
    numeric = _numerical_settling_time(x0, m)
    assert analytic <= T_C  # equal in floating point once exp(-r0^m) < 1e-16
    assert numeric == pytest.approx(analytic, rel=0.01)


def test_phi_is_parallel_to_x_with_the_closed_form_magnitude():
    x = np.array([0.3, -0.4, 1.2])
    r, m = np.linalg.norm(x), 0.3
    expected = math.exp(r**m) * r ** (1 - m) / (m * T_C)
    assert np.allclose(phi(x, T_C, m), expected * x / r, rtol=1e-14)
    assert np.allclose(phi(x, T_C, m, form="printed"), math.exp(r**m) / (m * T_C) * x / r, rtol=1e-14)


@pytest.mark.parametrize("value", [0.0, 1e-320, 1e-300, 1e-12, 1.0, 1e3, 1e100, 1e300, 1.7e308])
@pytest.mark.parametrize("m", [0.01, 0.5, 0.99])
@pytest.mark.parametrize("form", ["sanchez_torres", "printed"])
def test_phi_is_finite_for_every_finite_input(value, m, form):
    for x in (np.array([value, -value, value]), np.array([value]), np.array([value, 0.0])):
        out = phi(x, T_C, m, form=form)
        assert np.all(np.isfinite(out)), (value, m, out)
        assert np.all(np.sign(out) * np.sign(x) >= 0)  # never points against x


def test_phi_rejects_bad_parameters():
    with pytest.raises(InvalidInputError, match=r"m = 1.5 is out of range; allowed: \(0, 1\)"):
        phi(np.ones(3), T_C, 1.5)
    with pytest.raises(InvalidInputError, match="T_c"):
        phi(np.ones(3), -1.0, 0.5)
    with pytest.raises(InvalidInputError, match="finite"):
        phi(np.array([np.nan, 1.0]), T_C, 0.5)


def test_printed_form_misses_the_T_c_bound():
    """Erratum (docs/model.md §3): the printed eq. (2) settles at m T_c ∫_0^r0 exp(-r^m) dr, unbounded in r0."""
    m, r0 = 0.1, 100.0
    closed_form = m * T_C * quad(lambda r: math.exp(-(r**m)), 0.0, r0, limit=200)[0]
    assert closed_form > 2 * T_C  # 7.2 s > 3 s
    # A direct Euler integration agrees, and chatters at about dt / (m T_c) once at the origin.
    dt, x, t = 1e-3, r0, 0.0
    while x > 0 and t < 20 * T_C:
        x -= dt * phi(np.array([x]), T_C, m, form="printed")[0]
        t += dt
    assert t == pytest.approx(closed_form, rel=0.01)
    tail = []
    for _ in range(1000):
        x -= dt * phi(np.array([x]), T_C, m, form="printed")[0]
        tail.append(abs(x))
    assert max(tail) > 0.5 * dt / (m * T_C)


def test_reference_form_does_not_chatter_in_discrete_time():
    dt, x, m = 1e-3, np.array([1.0, -2.0]), 0.1
    for _ in range(int(T_C / dt) + 1):
        x = x - dt * phi(x, T_C, m)
    assert np.linalg.norm(x) < 1e-12
