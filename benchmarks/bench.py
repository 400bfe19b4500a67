"""Speed benchmark: every figure is a ratio against a reference measured in the same run.

Run: ``python benchmarks/bench.py`` (``pip install -e ".[bench]"`` adds MuJoCo for the Pusher-v5
reference). Prints the machine, then one line per target with the measured numbers and ratio.
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from concurrent.futures import ProcessPoolExecutor

import gymnasium as gym
import numpy as np

import ffsr_gym


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


def _evaluate(params: tuple[float, float]) -> float:
    return ffsr_gym.objective_for_params(*params)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--ga-sample", type=int, default=16, help="evaluations timed to project the 100 x 100 GA")
    args = parser.parse_args()
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, {platform.platform()}, "
          f"Python {platform.python_version()}")

    ffsr_gym.simulate("paper", backend="kernel")  # compile (cached on disk afterwards)
    kernel = best_of(lambda: ffsr_gym.simulate("paper", backend="kernel"), args.repeats)
    reference = best_of(lambda: ffsr_gym.simulate("paper", backend="pinocchio"), 1)
    print(f"[1] 20 s paper rollout, dt = 0.01 s: kernel {kernel * 1e3:.1f} ms, Pinocchio {reference * 1e3:.0f} ms, "
          f"speed-up {reference / kernel:.1f}x (target >= 10x and <= 20 ms)")

    ours = per_step(gym.make("FFSR-Residual-v0", scenario="paper"), 400)
    try:
        pusher = per_step(gym.make("Pusher-v5"), 2000)
        print(f"[2] one env step: FFSR-Residual-v0 {ours * 1e6:.0f} us (10 physics steps of 0.01 s), Pusher-v5 "
              f"{pusher * 1e6:.0f} us, ratio {ours / pusher:.2f} (target <= 1)")
    except Exception as exc:  # noqa: BLE001 - MuJoCo is optional
        print(f"[2] one env step: FFSR-Residual-v0 {ours * 1e6:.0f} us; Pusher-v5 unavailable ({exc.__class__.__name__}: "
              "pip install -e '.[bench]')")

    rng = np.random.default_rng(0)
    sample = [(float(m), 2.19) for m in rng.uniform(0.05, 0.95, args.ga_sample)]
    workers = os.cpu_count() or 1
    with ProcessPoolExecutor(workers) as pool:
        list(pool.map(_evaluate, sample[:workers]))  # warm the workers (kernel load)
        start = time.perf_counter()
        list(pool.map(_evaluate, sample))
        elapsed = time.perf_counter() - start
    projected = elapsed / len(sample) * 100 * 100
    serial = reference * 100 * 100 / workers
    print(f"[3] paper-scale GA (100 x 100 evaluations) on {workers} processes: projected {projected:.0f} s from "
          f"{len(sample)} timed evaluations ({elapsed / len(sample) * 1e3:.0f} ms each); with the Pinocchio "
          f"implementation {serial:.0f} s, ratio {serial / projected:.1f}x (target <= 60 s)")

    steps_per_s = workers * 2000 / kernel
    print(f"[4] control steps per second, {workers} cores, one rollout per core: {steps_per_s:,.0f} "
          f"(target >= 300,000; no batched vector env yet)")


if __name__ == "__main__":
    main()
