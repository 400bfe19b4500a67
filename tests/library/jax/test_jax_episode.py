"""The JAX episode (``ffsr_gym.jax.episode``) against the environments (the kernel's decision): decision by
decision against ``FFSR-Residual-v2`` (observations, rewards, smoothness increments, violation costs), and whole
certificate replays against the stored verdicts and scores.

Where the end-effector error is near zero, the predefined-time feedback's discrete chatter amplifies rounding: the
kernel and the Pinocchio backend then differ by a few 1e-3 of a score on some tasks, and so does the JAX loop;
verdicts do not move (docs/jax.md, ``experiments/jax_agreement.json``)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("jax")

import gymnasium  # noqa: E402
import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402

import ffsr_gym  # noqa: E402, F401  (registers the ids)
from ffsr_gym.jax import episode as ep  # noqa: E402
from ffsr_gym.jax.collision import shapes_of  # noqa: E402
from ffsr_gym.jax.replay import certificate_tasks, play  # noqa: E402
from ffsr_gym.jax.scenario import episode_task  # noqa: E402
from ffsr_gym.sim.setup import robot_assets  # noqa: E402
from ffsr_gym.tasks.splits import pool, task_scenario  # noqa: E402
from ffsr_gym.versions.registry import load_benchmark  # noqa: E402

SHAPES = shapes_of(robot_assets("ffsr_dual_arm").kernel)


@pytest.mark.slow  # about a minute; in CI the vector env's test compares 25 decisions' observations and rewards
@pytest.mark.parametrize("tier", ["debris"])
def test_decisions_match_the_environment_step_by_step(tier):
    """The first 40 decisions (4 s) of a residual certificate, side by side with ``FFSR-Residual-v2`` (debris: two
    or more obstacles, drifting); then a NaN action."""
    index = next(i for i, t in enumerate(pool(tier, "test")) if t.certificate.residual is not None)
    task_record = pool(tier, "test")[index]
    scenario = task_scenario(tier, task_record.seed, load_benchmark("v2"))
    model, rules, task = episode_task(scenario, m=task_record.certificate.m, T_c=task_record.certificate.T_c_s)
    action = np.asarray(task_record.certificate.residual, dtype=np.float32)
    step = jax.jit(lambda state, a: ep.step(model, SHAPES, rules, task, state, a))
    state, seen = ep.reset(model, SHAPES, rules, task)
    with gymnasium.make("FFSR-Residual-v2", task=tier, split="test") as env:
        obs, info = env.reset(options={"task_index": index})
        np.testing.assert_allclose(seen.obs, obs, rtol=0, atol=2e-6)
        for decision in range(40):
            obs, reward, terminated, truncated, info = env.step(action)
            state, seen, jax_reward, jax_info = step(state, jnp.asarray(action, dtype=jnp.float64))
            np.testing.assert_allclose(seen.obs, obs, rtol=0, atol=2e-6, err_msg=f"decision {decision}")
            assert float(jax_reward) == pytest.approx(reward, rel=1e-9, abs=1e-13)
            assert float(jax_info["smoothness_increment"]) == pytest.approx(info["smoothness_increment"], rel=1e-9)
            assert float(jax_info["cost"]) == pytest.approx(info["cost"], abs=1e-12)
            assert not terminated and not truncated and not bool(state.done)
    # A compiled step cannot raise: a non-finite action shows as a failed end that moved nothing, never NaN states.
    after, seen_after, reward, info = step(state, jnp.full(12, jnp.nan))
    assert bool(after.done) and int(info["status"]) == ep.STATUS_BAD_ACTION and not bool(info["success"])
    np.testing.assert_array_equal(after.x, state.x)
    np.testing.assert_array_equal(seen_after.obs, seen.obs)
    assert float(reward) == pytest.approx(-1.0 / (1.0 + float(state.cost))) and float(info["score"]) == 0.0


@pytest.mark.slow  # compile-bound (a minute); experiments/jax_agreement.py replays every test certificate
@pytest.mark.parametrize("tier", ["hard", "debris"])
def test_certificates_replay_to_their_stored_verdicts(tier):
    model, rules, tasks, actions, stored = certificate_tasks(tier, indices=[0, 1])
    out = play(model, rules, tasks, actions)
    assert np.array_equal(out["success"], stored > 0.0)
    np.testing.assert_allclose(out["score"], stored, rtol=2e-3)
    assert np.all(out["k"] == tasks.n_steps) and np.all(out["status"] == 0)


@pytest.mark.slow
def test_the_episode_cost_gradient_matches_central_differences():
    """d C / d knots through the whole closed loop (2000 physics steps) against central differences of the
    episode itself (step 1e-4: at 1e-3 the largest component's difference quotient is 0.9 % off by curvature, and
    it converges onto the gradient as the step shrinks), on a task whose success the perturbations do not
    change."""
    from ffsr_gym.jax.gradient import episode, span

    t = pool("easy", "test")[1]
    scenario = task_scenario("easy", t.seed, load_benchmark("v2"))
    model, rules, task = episode_task(scenario)
    spread = span(task, scenario.env.decision_interval_s, scenario.desired_path.motion_time_s)
    knots = jnp.full((4, 12), 0.05)
    play = jax.jit(lambda k: episode(model, SHAPES, rules, task, k, spread))
    gradient = np.asarray(jax.grad(lambda k: episode(model, SHAPES, rules, task, k, spread).cost)(knots))
    for i, j in [(0, 0), (0, 2), (2, 7), (3, 11)]:
        e = jnp.zeros((4, 12)).at[i, j].set(1e-4)
        up, down = play(knots + e), play(knots - e)
        assert bool(up.success) and bool(down.success)
        fd = (float(up.cost) - float(down.cost)) / 2e-4
        assert fd == pytest.approx(gradient[i, j], rel=1e-3)



def test_the_projected_descent_keeps_the_box_refuses_what_fails_and_stops_on_its_clock():
    """On C(k) = |k - t|² with t partly outside [-1, 1]: the descent ends at the box's closest point (the projection
    of t); a refused step is never taken; ``stop`` and ``min_rate`` end it."""
    from typing import NamedTuple

    from ffsr_gym.jax.gradient import descend

    class Played(NamedTuple):
        cost: float
        ok: bool

    target = jnp.array([[0.3, 1.7], [-2.0, -0.4]])

    def cost_and_grad(knots):
        return Played(float(jnp.sum((knots - target) ** 2)), True), 2.0 * (knots - target)

    knots, history = descend(cost_and_grad, jnp.zeros((2, 2)), steps=200, rate=0.05, accept=lambda p: p.ok)
    np.testing.assert_allclose(knots, jnp.clip(target, -1.0, 1.0), atol=1e-6)
    assert all(b[0] <= a[0] for a, b in zip(history, history[1:]))  # C never rises
    start = jnp.zeros((2, 2))
    refused, history = descend(cost_and_grad, start, steps=5, rate=0.05, accept=lambda p: False)
    np.testing.assert_array_equal(refused, start)
    assert [rate for _, rate in history] == [0.05 * 0.5 ** k for k in range(6)]  # every refusal halves the step
    calls = iter(range(100))
    _, history = descend(cost_and_grad, start, steps=50, rate=0.05, accept=lambda p: p.ok,
                         stop=lambda: next(calls) >= 3)
    assert len(history) == 4
    _, history = descend(cost_and_grad, start, steps=50, rate=0.05, accept=lambda p: False, min_rate=0.01)
    assert history[-1][1] < 0.01 <= history[-2][1]


def test_schedule_actions_with_a_traced_spread_are_the_schedules_actions():
    """One compilation for every spread: under ``jit`` with the spread as an argument, the knots' actions are
    :meth:`Schedule.actions` (which rounds to float32) for spreads shorter and longer than the knots."""
    from ffsr_gym.jax.gradient import schedule_actions
    from ffsr_gym.tasks.schedule import Schedule

    scenario = task_scenario("easy", pool("easy", "test")[0].seed, load_benchmark("v2"))
    decisions = round(scenario.simulation.duration_s / scenario.env.decision_interval_s)
    knots = np.random.default_rng(3).uniform(-1.0, 1.0, (4, 12)).astype(np.float32).astype(float)
    schedule = Schedule("residual", tuple(map(tuple, knots)))
    actions = jax.jit(schedule_actions, static_argnums=1)
    for spread in (3, schedule.span(scenario), decisions):
        got = np.asarray(actions(jnp.asarray(knots), decisions, jnp.asarray(spread)))
        at = np.minimum(np.arange(decisions), spread - 1)
        where = np.linspace(0.0, spread - 1.0, 4)
        want = np.stack([np.interp(at, where, knots[:, j]) for j in range(12)], axis=1)
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-15)
        if spread == schedule.span(scenario):
            np.testing.assert_allclose(got, schedule.actions(scenario), rtol=0, atol=6e-8)  # float32 rounding
