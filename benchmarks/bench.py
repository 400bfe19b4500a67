"""Speed benchmark: every figure is a ratio against a reference measured in the same run.

Run: ``python benchmarks/bench.py`` (``pip install -e ".[bench]"`` adds MuJoCo for the Pusher-v5
reference; ``--quick`` projects the GA instead of running it, ~1 min instead of ~3). Prints the
machine, then one line per target with the measured numbers and ratio.
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from concurrent.futures import ProcessPoolExecutor

import gymnasium as gym
import numba
import numpy as np

import ffsr_gym
from ffsr_gym.optim import ga


def best_of(fn, repeats: int) -> float:
    """Smallest wall time [s] of ``repeats`` calls (after one warm-up call)."""
    fn()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def per_step(env, steps: int) -> float:
    """Mean wall time [s] of one ``env.step`` with random actions (resets excluded)."""
    env.reset(seed=0)
    env.action_space.seed(0)
    total, count = 0.0, 0
    while count < steps:
        action = env.action_space.sample()
        start = time.perf_counter()
        _, _, terminated, truncated, _ = env.step(action)
        total += time.perf_counter() - start
        count += 1
        if terminated or truncated:
            env.reset()
    return total / count


def vector_throughput(num_envs: int, decisions: int, threads: int) -> tuple[float, float]:
    """Physics steps per second and wall time [s] per vector step of the batched FFSR-Residual-v0."""
    numba.set_num_threads(threads)
    venv = gym.make_vec("FFSR-Residual-v0", num_envs=num_envs, vectorization_mode="vector_entry_point")
    venv.reset(seed=0)
    actions = np.zeros(venv.action_space.shape, dtype=np.float32)  # the reference planner
    venv.step(actions)
    steps, start = 0, time.perf_counter()
    for _ in range(decisions):
        venv.step(actions)
        steps += int(venv._rows.sum())
    elapsed = time.perf_counter() - start
    return steps / elapsed, elapsed / decisions


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--quick", action="store_true", help="project the GA from 16 evaluations instead of running it")
    args = parser.parse_args()
    workers = os.cpu_count() or 1
    print(f"machine: {platform.processor() or platform.machine()}, {workers} CPUs, {platform.platform()}, "
          f"Python {platform.python_version()}, numba {numba.__version__}")

    ffsr_gym.simulate("paper", backend="kernel")  # compile (cached on disk afterwards)
    kernel = best_of(lambda: ffsr_gym.simulate("paper", backend="kernel"), args.repeats)
    reference = best_of(lambda: ffsr_gym.simulate("paper", backend="pinocchio"), 1)
    print(f"[1] 20 s paper rollout, dt = 0.01 s: kernel {kernel * 1e3:.1f} ms ({kernel / 2000 * 1e6:.1f} us per step), "
          f"Pinocchio {reference * 1e3:.0f} ms, speed-up {reference / kernel:.1f}x (target >= 10x and <= 20 ms)")

    ours = per_step(gym.make("FFSR-Residual-v0", scenario="paper"), 400)
    _, vector_step = vector_throughput(64, 200, workers)
    try:
        pusher = per_step(gym.make("Pusher-v5"), 2000)
        print(f"[2] one env step: FFSR-Residual-v0 {ours * 1e6:.0f} us (10 physics steps of 0.01 s), Pusher-v5 "
              f"{pusher * 1e6:.0f} us, ratio {ours / pusher:.2f} (target <= 1); batched, per copy (64 copies, "
              f"{workers} threads): {vector_step / 64 * 1e6:.0f} us, ratio {vector_step / 64 / pusher:.2f}")
    except Exception as exc:  # noqa: BLE001 - MuJoCo is optional
        print(f"[2] one env step: FFSR-Residual-v0 {ours * 1e6:.0f} us; batched per copy {vector_step / 64 * 1e6:.0f} us; "
              f"Pusher-v5 unavailable ({exc.__class__.__name__}: pip install -e '.[bench]')")

    serial = reference * 100 * 100 / workers
    with ProcessPoolExecutor(workers) as pool:
        list(pool.map(_evaluate, [(0.3, 2.19)] * workers))  # warm the workers (kernel load)
        if args.quick:
            rng = np.random.default_rng(0)
            sample = [(float(m), 2.19) for m in rng.uniform(0.05, 0.95, 16)]
            start = time.perf_counter()
            list(pool.map(_evaluate, sample))
            projected = (time.perf_counter() - start) / len(sample) * 100 * 100
            print(f"[3] paper-scale GA (100 x 100) on {workers} processes: projected {projected:.0f} s from 16 "
                  f"evaluations without the cache; Pinocchio {serial:.0f} s (target <= 60 s)")
        else:
            state = ga.run(ga.GAConfig(), executor=pool, progress=False)
            m, T_c, score = ga.best(state)
            print(f"[3] full paper-scale GA (100 x 100, genes m and T_c) on {workers} processes: {state.wall_time_s:.0f} s, "
                  f"{len(state.cache)} distinct evaluations, optimum m = {m:.4f}, T_c = {T_c:.3f} s, B = {score:.3g}; "
                  f"Pinocchio (no cache) {serial:.0f} s (target <= 60 s)")

    single, _ = vector_throughput(64, 200, 1)  # 200 decisions: whole episodes, with their ends and resets
    steps_per_s, _ = vector_throughput(64, 200, workers)
    wide, _ = vector_throughput(128, 200, workers)
    print(f"[4] batched FFSR-Residual-v0 (64 copies, vector_entry_point): {steps_per_s:,.0f} physics steps of dt per "
          f"second on {workers} threads, {single:,.0f} on 1 ({steps_per_s / single:.2f}x); 128 copies: {wide:,.0f} "
          f"(target >= 300,000)")

    from ffsr_gym.bench.evaluation_v1 import evaluate_v1

    for tier in ("easy", "medium", "hard"):  # a fixed-parameter entry on each test pool (100 tasks)
        serial = best_of(lambda tier=tier: evaluate_v1((0.3, 4.0), "FFSR-v1", task=tier, batched=False), 1)
        batched = best_of(lambda tier=tier: evaluate_v1((0.3, 4.0), "FFSR-v1", task=tier, batched=True), 1)
        with ProcessPoolExecutor(workers) as pool:
            evaluate_v1((0.3, 4.0), "FFSR-v1", task=tier, indices=list(range(2 * workers)), executor=pool, chunk=1)  # warm
            spread = best_of(lambda tier=tier, pool=pool: evaluate_v1((0.3, 4.0), "FFSR-v1", task=tier, executor=pool), 1)
        print(f"[5] (0.3, 4 s) on the {tier} test pool: single env {serial:.2f} s; batched env {batched:.2f} s "
              f"({serial / batched:.1f}x); {workers} worker processes {spread:.2f} s ({serial / spread:.2f}x)")


def _evaluate(params: tuple[float, float]) -> float:
    return ffsr_gym.objective_for_params(*params)


if __name__ == "__main__":
    main()
