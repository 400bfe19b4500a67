"""The native kernel against the Pinocchio reference: every trajectory array, many scenarios; its parts against
closed forms, dense solves and LAPACK."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import random_states as _random_states

from ffsr_gym import _native
from ffsr_gym.bench.planner_scores import scenario_for_seed
from ffsr_gym.planning.planner import METHODS
from ffsr_gym.sim.compiled import KernelRollout
from ffsr_gym.sim.simulate import simulate

ARRAYS = ("q", "v", "dq_joints", "ee_position_error_m", "ee_attitude_error", "base_position_error_m",
          "base_attitude_error", "clearance_m", "self_clearance_m", "mu", "cdf", "sigma_min")


def assert_agree(scenario, method, rel=1e-9):
    """Every array within 1e-9 of the reference, relative to the array's scale (at least 1)."""
    kernel = simulate(scenario, method=method, backend="kernel")
    reference = simulate(scenario, method=method, backend="pinocchio")
    for name in ARRAYS:
        k, r = getattr(kernel, name), getattr(reference, name)
        assert k.shape == r.shape, name
        assert np.array_equal(np.isinf(k), np.isinf(r)), name
        finite = np.isfinite(r)
        scale = max(1.0, float(np.max(np.abs(r[finite]), initial=0.0)))
        error = float(np.max(np.abs(k[finite] - r[finite]), initial=0.0))
        assert error <= rel * scale, f"{name}: max difference {error:.3e} (scale {scale:.3g})"


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("scenario", ["paper", "free_space"])
def test_kernel_matches_reference(scenario, method):
    assert_agree(scenario, method)


def assert_steps_agree(scenario, method, rel=1e-9):
    """Replay every state of the reference trajectory through one kernel step.

    Many random-family runs chatter where the danger field crosses its threshold; there a
    1e-15 difference doubles every step or so, so whole trajectories of two correct
    implementations part after a few dozen steps. The step map itself must agree everywhere.
    """
    reference = simulate(scenario, method=method, backend="pinocchio")
    rollout = KernelRollout(scenario, method=method)
    scale = {name: max(1.0, float(np.max(np.abs(getattr(reference, name)[np.isfinite(getattr(reference, name))]),
                                         initial=0.0))) for name in ARRAYS if name != "q"}
    for k in range(len(reference.t) - 1):
        sample, q_next = rollout.replay_step(reference.q[k], k)
        assert np.max(np.abs(q_next - reference.q[k + 1])) <= rel, f"q at step {k + 1}"
        for name, value in sample.items():
            expected = getattr(reference, name)[k]
            if np.all(np.isinf(expected)):
                assert np.all(np.isinf(value)), name
                continue
            assert np.max(np.abs(value - expected)) <= rel * scale[name], f"{name} at step {k}"


@pytest.mark.parametrize(("seed", "method"), [(0, "predefined_time"), (11, "proportional")])
def test_kernel_step_map_matches_reference_random_family_short(seed, method):
    assert_steps_agree(scenario_for_seed("random", seed), method)


@pytest.mark.slow
@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("seed", range(20))
def test_kernel_step_map_matches_reference_random_family(seed, method):
    assert_steps_agree(scenario_for_seed("random", seed), method)


def test_segment_box_matches_dense_sampling():
    rng = np.random.default_rng(0)
    half = np.array([0.4, 0.3, 0.2])
    R = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    center = rng.normal(size=3)
    for _ in range(50):
        a, b = center + rng.uniform(-1, 1, 3), center + rng.uniform(-1, 1, 3)
        s = np.linspace(0, 1, 20001)[:, None]
        local = (a + s * (b - a) - center) @ R
        d = np.abs(local) - half
        sdf = np.where(np.all(d <= 0, axis=1), d.max(axis=1), np.linalg.norm(np.maximum(d, 0), axis=1))
        assert _native.segment_box(a, b, R, center, half) == pytest.approx(sdf.min(), abs=2e-4 * np.linalg.norm(b - a))
        assert _native.segment_box(a, b, R, center, half) <= sdf.min() + 1e-12


def test_segment_box_starting_on_an_edge():
    """A segment that starts on a box edge (two candidate cuts 1e-16 apart) and dips toward the box.

    Found in a random-family state: a shortcut that trusted the best cut's neighbours missed the
    interior minimum (0.10 instead of 0.071).
    """
    half = np.full(3, 0.4)
    a = np.array([0.4, 0.1, 0.5])
    b = a + np.array([0.3532342687244006, 0.04649291033568555, -0.35080473298867554])
    s = np.linspace(0, 1, 200001)[:, None]
    d = np.abs(a + s * (b - a)) - half
    sampled = np.linalg.norm(np.maximum(d, 0), axis=1).min()
    assert _native.segment_box(a, b, np.eye(3), np.zeros(3), half) == pytest.approx(sampled, abs=1e-9)
    assert sampled < 0.072


@pytest.mark.parametrize("condition", [2.0, 30.0, 1e3])
def test_smallest_singular_value_matches_lapack(condition):
    """Newton on the tridiagonalised AᵀA vs LAPACK, for matrices with prescribed singular values."""
    rng = np.random.default_rng(7)
    for _ in range(300):
        U, _ = np.linalg.qr(rng.normal(size=(6, 6)))
        V, _ = np.linalg.qr(rng.normal(size=(6, 6)))
        sigma = np.exp(rng.uniform(0.0, np.log(condition), 6)) * rng.uniform(0.05, 100.0)
        sigma[-1] = sigma.max() / condition
        sigma[-2] = sigma[-1] * rng.choice([1.0, 1.0 + 1e-9, 1.5])  # double, nearly double, separated
        A = U @ np.diag(sigma) @ V.T
        expected = np.linalg.svd(A, compute_uv=False)[-1]
        assert _native.smallest_singular_value(A) == pytest.approx(expected, rel=0, abs=1e-12 * sigma.max())


def test_smallest_singular_value_declines_what_it_cannot_certify():
    """-1 (the caller then uses the Jacobi SVD) for a singular matrix; a six-fold σ_min is found (the
    Laguerre step is exact for a root of multiplicity 6)."""
    rng = np.random.default_rng(3)
    A = rng.normal(size=(6, 6))
    A[:, 5] = A[:, 0] - 2.0 * A[:, 3]  # rank 5
    assert _native.smallest_singular_value(A) == -1.0
    s = _native.svd6(A, False)[1]
    assert s.min() < 1e-14 * s.max()
    Q, _ = np.linalg.qr(rng.normal(size=(6, 6)))
    assert _native.smallest_singular_value(3.0 * Q) == pytest.approx(3.0, rel=1e-11)


def test_paired_smallest_singular_values_equal_two_calls():
    """The interleaved pair (the planner's two arms) gives each matrix's own result bit for bit, also
    when one declines (-1) or needs more Newton steps than the other."""
    rng = np.random.default_rng(11)
    singular = rng.normal(size=(6, 6))
    singular[:, 5] = singular[:, 0] - 2.0 * singular[:, 3]
    Q, _ = np.linalg.qr(rng.normal(size=(6, 6)))
    matrices = [rng.normal(size=(6, 6)) * rng.uniform(0.01, 100.0) for _ in range(40)] + [singular, 3.0 * Q]
    seen = set()
    for i, A in enumerate(matrices):
        B = matrices[(7 * i + 3) % len(matrices)]
        pair = _native.smallest_singular_values(A, B)
        single = (_native.smallest_singular_value(A), _native.smallest_singular_value(B))
        assert pair == single, i
        seen.update(value == -1.0 for value in single)
    assert seen == {True, False}


def _pinocchio_q(rollout, x):
    q = np.empty(19)
    q[:7], q[rollout.model.q_index] = x[:7], x[7:]
    return q


def test_composite_body_momentum_matches_pinocchio():
    """H_b and H_bm from the composite-body pass against Pinocchio's centroidal map (``Robot.momentum_matrices``),
    and the system CoM against ``pinocchio.centerOfMass``, at random states."""
    from ffsr_gym.model.robot import load_robot
    from ffsr_gym.model.scenario import load_scenario

    rollout, robot = KernelRollout(load_scenario("paper")), load_robot()
    for x in _random_states(np.random.default_rng(5), 20):
        got = _native.momentum(rollout.setup.assets.native, x)
        q = _pinocchio_q(rollout, x)
        ref = robot.momentum_matrices(q)
        np.testing.assert_allclose(got["H_b"], ref.H_b, rtol=0, atol=1e-11 * np.abs(ref.H_b).max())
        np.testing.assert_allclose(got["H_bm"], ref.H_bm, rtol=0, atol=1e-11 * np.abs(ref.H_bm).max())
        np.testing.assert_allclose(got["rg"], robot.system_com(q), rtol=0, atol=1e-13)


def test_schur_base_velocity_matches_a_dense_solve():
    """The base velocity by H_b's Schur complement against numpy's dense solve of the same system."""
    from ffsr_gym.model.scenario import load_scenario

    robot, rng = KernelRollout(load_scenario("paper")).setup.assets.native, np.random.default_rng(6)
    for x in _random_states(rng, 20):
        dq, h = rng.normal(size=12), rng.normal(size=6)
        m = _native.momentum(robot, x)
        out = _native.base_velocity(robot, x, dq, h)
        d = m["rg"] - x[:3]  # [P; L_G] about the system CoM -> about the base CoM, minus the arms' part
        rhs = np.concatenate((h[:3], h[3:] + np.cross(d, h[:3]))) - m["H_bm"][0] @ dq[:6] - m["H_bm"][1] @ dq[6:]
        world = np.linalg.solve(m["H_b"], rhs)
        R = _native.kinematics(robot, x)["R_b"]
        np.testing.assert_allclose(out, np.concatenate((R.T @ world[:3], R.T @ world[3:])), rtol=0,
                                   atol=1e-12 * max(1.0, np.abs(world).max()))


def test_danger_field_segments_match_the_reference_integrals():
    """One logarithm per segment and the kept geometry against ``planning.avoidance``'s closed form (two inverse
    hyperbolic sines, hypot): the feet before, on and after the segment, nearly collinear points, and a segment
    of zero length (skipped)."""
    from ffsr_gym.planning.avoidance import _segment_integrals

    rng = np.random.default_rng(8)
    a, b = np.array([0.1, -0.2, 0.3]), np.array([0.6, 0.1, 0.2])
    direction = (b - a) / np.linalg.norm(b - a)
    normal = np.cross(direction, [0.0, 0.0, 1.0])
    normal /= np.linalg.norm(normal)
    points = [a + s * (b - a) + rng.normal(scale=0.3, size=3) for s in rng.uniform(-1.0, 2.0, 200)]
    points += [a + s * (b - a) + 1e-7 * normal for s in (-0.5, 0.3, 1.7)]  # nearly on the line
    cases = 0
    for p in points:
        F, nearest, I0, I1 = _native.segment_field(p, a, b)
        F_ref, I0_ref, I1_ref, nearest_ref = _segment_integrals(p, a, b)
        assert F == pytest.approx(F_ref, rel=1e-12) and nearest == pytest.approx(nearest_ref, rel=1e-12)
        assert I0 == pytest.approx(I0_ref, rel=1e-9) and I1 == pytest.approx(I1_ref, rel=1e-9, abs=1e-9 * abs(I0_ref))
        cases += 1
    assert cases == 203
    assert _native.segment_field(np.array([0.0, 0.0, 1.0]), a, a)[:2] == (0.0, np.inf)


def test_midpoint_kinematics_from_the_kept_cosines():
    """The half step's kinematics from the planner step's cosines and sines (angle-sum formula, series for the
    increment) equal a fresh evaluation to rounding; a state the kept values do not belong to is computed afresh."""
    from ffsr_gym.model.scenario import load_scenario

    robot = KernelRollout(load_scenario("paper")).setup.assets.native
    rng = np.random.default_rng(9)
    for x, scale in zip(_random_states(rng, 12), [0.5] * 6 + [40.0] * 6):  # small increments (series), large ones
        dq, h = rng.normal(scale=scale, size=12), 0.005
        half = x.copy()
        half[7:] = x[7:] + dq * h
        kept, fresh = _native.kinematics_from(robot, x, half, dq, h), _native.kinematics(robot, half)
        for name in ("Rj", "pj", "z", "Re", "pe"):
            np.testing.assert_allclose(kept[name], fresh[name], rtol=0, atol=4e-15, err_msg=name)
    other = _random_states(rng, 1)[0]
    kept, fresh = _native.kinematics_from(robot, x, other, dq, h), _native.kinematics(robot, other)  # of another state
    assert np.array_equal(kept["Rj"], fresh["Rj"]) and np.array_equal(kept["pj"], fresh["pj"])
