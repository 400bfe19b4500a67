"""The JAX planner (``ffsr_gym.jax.planner``) against the numpy planner (``ffsr_gym.planning``, on Pinocchio): the
joint rates, errors, blend factors, danger fields and σ_min at states near each scenario's start and at times
across its episode, on the paper's scenario and on a test task of every kinematic tier; and its gradient against
central differences."""

from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest

pytest.importorskip("jax")

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402

from ffsr_gym.jax.planner import plan  # noqa: E402
from ffsr_gym.jax.scenario import from_scenario  # noqa: E402
from ffsr_gym.model.scenario import load_scenario  # noqa: E402
from ffsr_gym.planning.planner import Planner  # noqa: E402
from ffsr_gym.sim.setup import prepare  # noqa: E402
from ffsr_gym.tasks.splits import pool, task_scenario  # noqa: E402
from ffsr_gym.versions.registry import load_benchmark  # noqa: E402

DECIDE = jax.jit(plan, static_argnums=2)


def _scenario(name):
    if name == "paper":
        return load_scenario("paper")
    if name.endswith("-near"):  # the obstacle 6 cm from the mission arm's fourth segment: the avoidance acts
        scenario = _scenario(name.removesuffix("-near"))
        setup = prepare(scenario)
        setup.robot.update_kinematics(setup.q0)
        points, _ = setup.robot.joint_points(0)
        near = 0.5 * (points[3] + points[4]) + np.array([0.0, 0.0, 0.06])
        return scenario.replace(obstacle=dataclasses.replace(scenario.obstacle, position_m=tuple(near)))
    return task_scenario(name, pool(name, "test")[3].seed, load_benchmark("v2"))


@pytest.mark.parametrize("name", ["paper", *(pytest.param(n, marks=pytest.mark.slow) for n in ("easy", "medium", "hard")),
                                  "debris", "hard-near", "debris-near"])
def test_the_jax_planner_decides_what_the_numpy_planner_decides(name):
    scenario = _scenario(name)
    setup = prepare(scenario)
    reference = Planner(setup.robot, scenario, method="predefined_time", path=setup.path,
                        base_target=setup.base_target, estimates=setup.estimates,
                        estimate_interval_s=setup.estimate_interval_s)
    model, task, rules, x0 = from_scenario(scenario)
    decide = lambda t, x: DECIDE(model, task, rules, t, x)  # noqa: E731  (one compile per obstacle count)
    rng = np.random.default_rng(7)
    q_index = setup.assets.kernel.q_index
    avoided = 0
    for k in range(12):
        x = np.asarray(x0).copy()
        if k:
            x[:3] += rng.normal(scale=0.02, size=3)
            x[7:] += rng.normal(scale=0.05 if name.endswith("-near") else 0.3, size=12)
        t = 0.0 if k == 0 else float(rng.uniform(0.0, 20.0))
        q = np.empty(19)
        q[:7], q[q_index] = x[:7], x[7:]
        ref = reference(t, q)
        ours = decide(t, jnp.asarray(x))
        scale = max(1.0, np.abs(ref.dq_joints).max())
        np.testing.assert_allclose(ours.dq, ref.dq_joints, rtol=0, atol=1e-9 * scale, err_msg=f"{name} k={k}")
        np.testing.assert_allclose(ours.ee_error, ref.ee_error, rtol=0, atol=1e-12)
        np.testing.assert_allclose(ours.base_error, ref.base_error, rtol=0, atol=1e-12)
        np.testing.assert_allclose(ours.mu, ref.mu, rtol=1e-10)
        np.testing.assert_allclose(ours.cdf, ref.cdf, rtol=1e-10)
        np.testing.assert_allclose(ours.sigma_min, ref.sigma_min, rtol=1e-9)
        avoided += int(np.any(ref.mu < 1.0))
    if name.endswith("-near"):
        assert avoided > 0  # the avoidance branch was compared, not only tracking


@pytest.mark.slow
def test_the_planners_gradient_matches_finite_differences():
    model, task, rules, x0 = from_scenario(_scenario("hard"))
    weights = jnp.asarray(np.random.default_rng(8).normal(size=12))

    def f(m_and_T):
        chosen = task.__class__(**{**task.__dict__, "m": m_and_T[0], "T_c": m_and_T[1]})
        return weights @ plan(model, chosen, rules, 0.7, x0).dq

    point = jnp.array([0.3, 4.0])
    grad = np.asarray(jax.grad(f)(point))
    fd = np.array([(f(point + e) - f(point - e)) / 2e-6 for e in (jnp.array([1e-6, 0.0]), jnp.array([0.0, 1e-6]))])
    np.testing.assert_allclose(grad, fd, rtol=1e-6)


@pytest.mark.parametrize(("tier", "named"), [("robust", "[target_noise]"), ("servo", "[servo]")])
def test_what_the_jax_loop_does_not_cover_is_refused_by_name(tier, named):
    from ffsr_gym.exceptions import InvalidInputError

    scenario = task_scenario(tier, pool(tier, "test")[0].seed, load_benchmark("v2"))
    with pytest.raises(InvalidInputError, match=re.escape(named)):
        from_scenario(scenario)
