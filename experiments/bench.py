"""Speed benchmark: every figure is a ratio against a reference measured in the same run.

Run: ``python experiments/bench.py`` (``pip install -e ".[bench]"`` adds MuJoCo for the Pusher-v5
reference; ``--quick`` projects the GA instead of running it). Prints one line per measurement,
writes ``experiments/results.json`` (with provenance) and, with ``--readme docs/speed.md``, the speed page's
speed table (``--runs 3`` gives the ranges it shows; a test checks the table against the JSON).

Before it overwrites them, each row is compared with the committed results (``--against``), scaled by a yardstick
measured in both runs (``experiments/speed_guard.py``): a row slower by more than ``speed_guard.TOLERANCE`` is printed
as ``SLOWER`` and kept in the results (``slower_than_committed``). A change to ``ffsr_gym/kernel/`` is followed by
a run of this script (a test fails when the committed results predate the newest kernel change).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import gymnasium as gym
import numpy as np

import ffsr_gym
from ffsr_gym.optim import ga
from ffsr_gym.provenance import provenance, splice_generated, write_json_atomic, write_text_atomic

sys.path.insert(0, str(Path(__file__).parent))
import speed_guard  # noqa: E402  (experiments/speed_guard.py)
from servo_bench import servo_mjcf, servo_speed  # noqa: E402,F401  (re-exported: tests and servo_plant.py use them)
from speed_tables import (  # noqa: E402,F401  (experiments/speed_tables.py: the page's tables, re-exported for the tests)
    BUDGET_END,
    BUDGET_PARTS,
    BUDGET_START,
    README_END,
    README_START,
    budget_table,
    clock_ghz,
    speed_table,
)
from timing import _no_gc, best_of, decision_time, kernel_time  # noqa: E402


def per_step(env, steps: int) -> float:
    """Mean wall time [s] of one ``env.step`` with random actions (resets excluded; one warm-up episode first)."""
    env.reset(seed=0)
    env.action_space.seed(0)
    while not any(env.step(env.action_space.sample())[2:4]):
        pass
    env.reset(seed=1)
    total, count = 0.0, 0
    with _no_gc():
        while count < steps:
            action = env.action_space.sample()
            start = time.perf_counter()
            _, _, terminated, truncated, _ = env.step(action)
            total += time.perf_counter() - start
            count += 1
            if terminated or truncated:
                env.reset()
    return total / count


def step_budget(env_id: str, task: str, steps: int) -> dict[str, float]:
    """Where the wall time [s] of one ``env_id`` step goes (means per step, random actions).

    ``compiled``: inside the native decision (physics, score terms, observation); ``episode_end``:
    the extra time of the episodes' last steps (final sample, trajectory, score), spread over all
    steps; ``wrappers``: Gymnasium's wrappers (:func:`_wrapper_time`); ``python``: the rest.
    """
    env = gym.make(env_id, task=task)
    wrapped = per_step(env, steps)
    with decision_time() as inside:
        bare, ends = _bare_steps(env.unwrapped, steps)
        in_decision = inside[0] / steps
    return {"total": wrapped, "compiled": in_decision, "episode_end": ends, "wrappers": _wrapper_time(env, steps),
            "python": bare - in_decision - ends}


def _wrapper_time(env, steps: int) -> float:
    """Mean time [s] Gymnasium's wrappers of ``env`` add to a step, measured around an env that does nothing: the
    same wrapper classes over a stub with ``env``'s spaces, its wrapped step minus its bare step. Their cost does not
    depend on the env inside, and against a ~100 us step it is below what two timings of the real env resolve (they
    gave negative differences)."""
    class Stub(gym.Env):
        observation_space, action_space = env.observation_space, env.action_space

        def reset(self, *, seed=None, options=None):
            super().reset(seed=seed)
            return self.observation_space.sample(), {}

        def step(self, action):
            return observation.copy(), 0.0, False, False, {}

    observation = env.observation_space.sample()
    wrappers, layer = [], env
    while isinstance(layer, gym.Wrapper):
        wrappers.append(type(layer))
        layer = layer.env
    bare = Stub()
    wrapped = bare
    for wrapper in reversed(wrappers):
        wrapped = (wrapper(wrapped, max_episode_steps=10**9) if wrapper is gym.wrappers.TimeLimit
                   else wrapper(wrapped))
    action = env.action_space.sample()
    means = []
    for target in (wrapped, bare):
        target.reset(seed=0)
        target.step(action)  # the env checker's first-step checks
        with _no_gc():
            start = time.perf_counter()
            for _ in range(steps * 10):
                target.step(action)
            means.append((time.perf_counter() - start) / (steps * 10))
    return means[0] - means[1]


def _bare_steps(env, steps: int) -> tuple[float, float]:
    """Mean step time [s] of an unwrapped env, and its episode-end steps' extra time per step."""
    env.reset(seed=1)
    env.action_space.seed(1)
    total, last, count, ended = 0.0, 0.0, 0, []
    with _no_gc():
        while count < steps:
            action = env.action_space.sample()
            start = time.perf_counter()
            _, _, terminated, truncated, _ = env.step(action)
            last = time.perf_counter() - start
            total += last
            count += 1
            if terminated or truncated:
                ended.append(last)
                env.reset()
    mean = total / count
    return mean, sum(t - mean for t in ended) / count


def vector_throughput(env_id: str, num_envs: int, decisions: int, threads: int, **kwargs) -> tuple[float, float, float]:
    """Physics steps per second, wall time [s] per vector step of a batched env (zero actions), and
    physics steps per second of its compiled decisions alone (``nan`` for an env without them).

    For the residual ids a zero action is the reference planner; copies run whole episodes (ends
    scored, resets included) for ``decisions`` decisions after a first one.
    """
    venv = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", threads=threads, **kwargs)
    venv.reset(seed=0)
    actions = np.zeros(venv.action_space.shape, dtype=np.float32)
    venv.step(actions)
    with _no_gc(), kernel_time() as kernel:
        steps, start = 0, time.perf_counter()
        for _ in range(decisions):
            venv.step(actions)
            steps += int(venv.engine.out[:, 0].sum())
    elapsed = time.perf_counter() - start
    return steps / elapsed, elapsed / decisions, steps / kernel[0] if kernel[0] > 0.0 else float("nan")


def measure(workers: int, repeats: int, quick: bool) -> tuple[list[dict], dict]:
    """One run of every measurement: rows of (what, value, reference measured in this run, ratio, target),
    and the step budget of ``FFSR-Residual-v2``."""
    rows = []

    def row(key: str, what: str, value: float, unit: str, reference: str, ratio: float | None, target: str,
            met: bool | None) -> None:
        rows.append({"key": key, "what": what, "value": value, "unit": unit, "reference": reference, "ratio": ratio,
                     "target": target, "met": met})
        shown = f", ratio {ratio:.2f}" if ratio is not None else ""
        print(f"  {what}: {value:,.4g} {unit} vs {reference}{shown} ({target})")

    ffsr_gym.simulate("paper", backend="kernel")  # compile (cached on disk afterwards)
    kernel = best_of(lambda: ffsr_gym.simulate("paper", backend="kernel"), repeats)
    reference = best_of(lambda: ffsr_gym.simulate("paper", backend="pinocchio"), 1)
    row("rollout", "20 s paper rollout at dt = 0.01 s, kernel", kernel * 1e3, "ms", f"Pinocchio {reference * 1e3:.0f} ms",
        reference / kernel, "speed-up >= 10x and <= 5 ms", reference / kernel >= 10 and kernel <= 0.005)

    try:
        pusher = per_step(gym.make("Pusher-v5"), 4000)
    except Exception as exc:  # noqa: BLE001 - MuJoCo is optional
        print(f"  Pusher-v5 unavailable ({exc.__class__.__name__}: pip install -e '.[bench]')")
        pusher = None
    budget = step_budget("FFSR-Residual-v2", "easy", 2000)
    v0 = per_step(gym.make("FFSR-Residual-v0"), 2000)
    singles = (("step_v0", "one FFSR-Residual-v0 step (10 physics steps)", v0),
               ("step_pool", "one FFSR-Residual-v2 step on easy (10 physics steps)", budget["total"]),
               ("step_pool_parameters", "one FFSR-v2 step on easy (10 physics steps)",
                per_step(gym.make("FFSR-v2", task="easy"), 2000)))
    _, vector_step, _ = vector_throughput("FFSR-Residual-v2", 64, 200, workers, task="easy")
    for key, name, value in (*singles, ("step_batched", f"one batched FFSR-Residual-v2 step per copy (64 copies, "
                                                         f"{workers} threads)", vector_step / 64)):
        ratio = None if pusher is None else value / pusher
        bound = 0.7 if key == "step_pool_parameters" else 1.0
        row(key, name, value * 1e6, "us", "Pusher-v5 " + ("n/a" if pusher is None else f"{pusher * 1e6:.0f} us"), ratio,
            f"ratio <= {bound:g}", None if ratio is None else ratio <= bound)

    serial = reference * 100 * 100 / workers
    with ProcessPoolExecutor(workers) as pool:
        list(pool.map(_evaluate, [(0.3, 2.19)] * workers))  # warm the workers (kernel load)
        if quick:
            rng = np.random.default_rng(0)
            sample = [(float(m), 2.19) for m in rng.uniform(0.05, 0.95, 16)]
            start = time.perf_counter()
            list(pool.map(_evaluate, sample))
            ga_time, what = (time.perf_counter() - start) / len(sample) * 100 * 100, "paper-scale GA (projected)"
        else:
            ga_time, what = ga.run(ga.GAConfig(), executor=pool, progress=False).wall_time_s, "full paper-scale GA"
    row("ga", f"{what}, 100 x 100, genes m and T_c, {workers} processes", ga_time, "s",
        f"Pinocchio without cache {serial:.0f} s", serial / ga_time, "<= 60 s", ga_time <= 60)

    for env_id, key in (("FFSR-Residual-v2", "batched"), ("FFSR-Residual-v0", "batched_v0")):
        kwargs = {"task": "easy"} if env_id.endswith("v2") else {}
        if kwargs:  # an untimed pass draws the pool tasks of the timed passes (cached per process, as in
            vector_throughput(env_id, 64, 400, workers, **kwargs)  # a long run), so neither pays first draws
        single, _, _ = vector_throughput(env_id, 64, 400, 1, **kwargs)  # 400 decisions: two whole episodes per copy
        steps_per_s, _, compiled = vector_throughput(env_id, 64, 400, workers, **kwargs)
        goal = 1_000_000 if kwargs else 600_000  # v2's target; v0's, as it was
        row(key, f"batched {env_id}{' on easy' if kwargs else ''}, 64 copies, {workers} threads, whole episodes"
            f"{' (tasks drawn before)' if kwargs else ''}",
            steps_per_s, "physics steps/s", f"1 thread {single:,.0f} steps/s", steps_per_s / single,
            f">= {goal:,} steps/s", steps_per_s >= goal)
        if not math.isnan(compiled):  # the v2 env: its compiled decisions alone bound the row above
            row(f"{key}_compiled", "the same pass, its native decisions alone (`EpisodeBatch.decide`, Python excluded)",
                compiled, "physics steps/s", f"whole episodes {steps_per_s:,.0f} steps/s", compiled / steps_per_s,
                f"bound on whole episodes: >= {goal:,} needed", compiled >= goal)

    from ffsr_gym.bench.evaluation import evaluate as evaluate_pool
    from ffsr_gym.tasks.tiers import ALL_TIERS

    for tier in ALL_TIERS:  # a fixed-parameter entry on each test pool
        alone = best_of(lambda tier=tier: evaluate_pool((0.3, 4.0), "FFSR-v2", task=tier, batched=False), 1)
        batched = best_of(lambda tier=tier: evaluate_pool((0.3, 4.0), "FFSR-v2", task=tier, batched=True), 1)
        with ProcessPoolExecutor(workers) as pool:
            evaluate_pool((0.3, 4.0), "FFSR-v2", task=tier, indices=list(range(2 * workers)), executor=pool, chunk=1)  # warm
            spread = best_of(lambda tier=tier, pool=pool: evaluate_pool((0.3, 4.0), "FFSR-v2", task=tier, executor=pool), 1)
        row(f"pool_{tier}_batched", f"(0.3, 4 s) on the {tier} test pool through `evaluate` (batched, whole episodes)",
            batched, "s", f"single env {alone:.2f} s", alone / batched, "<= 0.25 s", batched <= 0.25)
        row(f"pool_{tier}_workers", f"(0.3, 4 s) on the {tier} test pool, {workers} worker processes", spread, "s",
            f"single env {alone:.2f} s", alone / spread, "faster than single env", spread < alone)
    ours, mujoco_time, extra = servo_speed(repeats)
    row("servo", "servo plant, 1 simulated second at a 1 ms physics step (12 velocity servos, free base), kernel",
        ours * 1e3, "ms per simulated s",
        "MuJoCo " + ("n/a" if mujoco_time is None else f"{mujoco_time * 1e3:.1f} ms (same bodies, drives, step; "
                     f"implicitfast; {extra['mujoco_loop']})"), None if mujoco_time is None else ours / mujoco_time, "ratio <= 1",
        None if mujoco_time is None else ours <= mujoco_time)
    training = training_throughput("FFSR-Residual-v2", 8, 8192)
    if training is not None:
        batched_rate, single_rate = training
        row("training_batched", "PPO training on FFSR-Residual-v2 easy, 8 copies, 8192 env steps, batched SB3 adapter",
            batched_rate, "env steps/s", f"make_vec_env of 8 single envs {single_rate:,.0f} env steps/s",
            batched_rate / single_rate, "faster than make_vec_env", batched_rate > single_rate)
    dask = dask_scaling(workers)
    if dask is not None:
        one, many = dask
        row("dask", f"(0.3, 4 s) on the easy test pool, Dask LocalCluster, {workers} workers", many, "s",
            f"1 worker {one:.2f} s", one / many, "scales with workers (ratio > 1)", one / many > 1.0)
    return rows, budget


def training_throughput(env_id: str, n_envs: int, steps: int) -> tuple[float, float] | None:
    """Env steps per second of the same PPO training (shipped hyperparameters, ``n_envs`` copies, ``steps`` steps,
    seed 0) on the batched adapter and on SB3's ``make_vec_env``: the same episodes, so the same work (None
    without stable-baselines3)."""
    try:
        import torch
        from stable_baselines3 import PPO
    except ImportError:
        print("  stable-baselines3 unavailable: pip install -e '.[rl]'")
        return None
    from ffsr_gym.optim.rl import load_hyperparams, training_env

    torch.set_num_threads(1)
    params = load_hyperparams("ppo", env_id)
    for key in ("n_envs", "n_timesteps", "policy"):
        params.pop(key, None)
    rates = []
    for vec_env in ("batched", "single"):
        env = training_env(env_id, n_envs, 0, {"task": "easy", "split": "train"}, vec_env)
        model = PPO("MlpPolicy", env, seed=0, device="cpu", **params)
        model.learn(n_envs * params["n_steps"])  # warm-up: compile, first task draws
        with _no_gc():
            start = time.perf_counter()
            model.learn(steps, reset_num_timesteps=True)
            rates.append(steps / (time.perf_counter() - start))
        env.close()
    return rates[0], rates[1]


def dask_scaling(workers: int) -> tuple[float, float] | None:
    """Wall time [s] of a fixed-parameter entry on the easy test pool on a Dask LocalCluster of 1 and of ``workers``
    single-threaded worker processes (warm: the kernel loaded in every worker); None without ``distributed``."""
    try:
        import distributed
    except ImportError:
        print("  Dask unavailable (pip install -e '.[bench]')")
        return None
    from ffsr_gym.bench.evaluation import evaluate as evaluate_pool

    times = []
    for n in (1, workers):
        cluster = distributed.LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None)
        with cluster, distributed.Client(cluster) as client:
            executor = client.get_executor()
            evaluate_pool((0.3, 4.0), "FFSR-v2", task="easy", indices=list(range(2 * n)), executor=executor, chunk=1)
            with _no_gc():
                start = time.perf_counter()
                evaluate_pool((0.3, 4.0), "FFSR-v2", task="easy", executor=executor, chunk=10)
                times.append(time.perf_counter() - start)
    return times[0], times[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeats", type=int, default=3, help="timed repeats of the rollout (best of; default: 3)")
    parser.add_argument("--runs", type=int, default=1, help="whole runs of every measurement (default: 1)")
    parser.add_argument("--quick", action="store_true", help="project the GA from 16 evaluations instead of running it")
    parser.add_argument("--out", default="experiments/results.json", help="results with provenance (default: %(default)s)")
    parser.add_argument("--readme", default=None, help="splice the speed table between its markers in this file")
    parser.add_argument("--against", default="experiments/results.json",
                        help="committed results each row is compared with (default: %(default)s)")
    parser.add_argument("--render-only", action="store_true",
                        help="measure nothing: render the page's blocks from the results file (--out) again")
    args = parser.parse_args()
    if args.render_only:
        splice_page(json.loads(Path(args.out).read_text()), args.readme)
        return
    committed = json.loads(Path(args.against).read_text()) if Path(args.against).is_file() else None
    workers = os.cpu_count() or 1
    machine = (f"{platform.processor() or platform.machine()}, {workers} CPUs, Python {platform.python_version()}, "
               "native kernel")
    print("machine:", machine)
    start, runs, budgets = time.perf_counter(), [], []
    for k in range(args.runs):
        print(f"run {k + 1} of {args.runs}")
        rows, budget = measure(workers, args.repeats, args.quick)
        runs.append(rows)
        budgets.append(budget)
    results = {"machine": machine, "workers": workers, "quick": args.quick, "runs": runs, "budgets": budgets,
               "clock_ghz": clock_ghz(),
               "yardstick_s": speed_guard.yardstick_s(),
               "provenance": provenance(command="python experiments/bench.py " + " ".join(sys.argv[1:]),
                                        wall_time_s=time.perf_counter() - start)}
    if committed is not None:
        results = speed_guard.compare_into(results, committed)
    write_json_atomic(args.out, results)
    print(speed_table(results))
    print(speed_guard.guard_block(results))
    print(budget_table(results))
    if args.readme:
        splice_page(results, args.readme)


def splice_page(results: dict, page: str | None) -> None:
    """Write the speed page's generated blocks into ``page`` (nothing without one)."""
    if page:
        text = Path(page).read_text(encoding="utf-8")
        text = splice_generated(text, README_START, README_END, speed_table(results), where=page)
        text = splice_generated(text, BUDGET_START, BUDGET_END, budget_table(results), where=page)
        text = splice_generated(text, speed_guard.START, speed_guard.END, speed_guard.guard_block(results),
                                where=page)
        write_text_atomic(page, text)


def _evaluate(params: tuple[float, float]) -> float:
    return ffsr_gym.objective_for_params(*params)


if __name__ == "__main__":
    main()
