"""Speed benchmark: every figure is a ratio against a reference measured in the same run.

Run: ``python benchmarks/bench.py`` (``pip install -e ".[bench]"`` adds MuJoCo for the Pusher-v5
reference; ``--quick`` projects the GA instead of running it). Prints one line per measurement,
writes ``benchmarks/results.json`` (with provenance) and, with ``--readme README.md``, the README's
speed table (``--runs 3`` gives the ranges it shows; a test checks the table against the JSON).
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import gymnasium as gym
import numba
import numpy as np

import ffsr_gym
from ffsr_gym.optim import ga
from ffsr_gym.provenance import provenance, splice_generated, write_json_atomic, write_text_atomic


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


def measure(workers: int, repeats: int, quick: bool) -> list[dict]:
    """One run of every measurement: rows of (what, value, reference measured in this run, ratio, target)."""
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
        reference / kernel, "speed-up >= 10x and <= 20 ms", reference / kernel >= 10 and kernel <= 0.02)

    ours = per_step(gym.make("FFSR-Residual-v0", scenario="paper"), 400)
    ours_v1 = per_step(gym.make("FFSR-Residual-v1", task="easy"), 400)
    _, vector_step = vector_throughput(64, 200, workers)
    try:
        pusher = per_step(gym.make("Pusher-v5"), 2000)
    except Exception as exc:  # noqa: BLE001 - MuJoCo is optional
        print(f"  Pusher-v5 unavailable ({exc.__class__.__name__}: pip install -e '.[bench]')")
        pusher = None
    for key, name, value in (("step_v0", "one FFSR-Residual-v0 step (10 physics steps)", ours),
                             ("step_v1", "one FFSR-Residual-v1 step (10 physics steps)", ours_v1),
                             ("step_batched", f"one batched FFSR-Residual-v0 step per copy (64 copies, {workers} threads)",
                              vector_step / 64)):
        ratio = None if pusher is None else value / pusher
        row(key, name, value * 1e6, "us", "Pusher-v5 " + ("n/a" if pusher is None else f"{pusher * 1e6:.0f} us"), ratio,
            "ratio <= 1", None if ratio is None else ratio <= 1.0)

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

    single, _ = vector_throughput(64, 200, 1)  # 200 decisions: whole episodes, with their ends and resets
    steps_per_s, _ = vector_throughput(64, 200, workers)
    row("batched", f"batched FFSR-Residual-v0, 64 copies, {workers} threads, whole episodes", steps_per_s,
        "physics steps/s", f"1 thread {single:,.0f} steps/s", steps_per_s / single, ">= 600,000 steps/s",
        steps_per_s >= 600_000)

    from ffsr_gym.bench.evaluation_v1 import evaluate_v1

    for tier in ("easy", "medium", "hard"):  # a fixed-parameter entry on each test pool (100 tasks)
        alone = best_of(lambda tier=tier: evaluate_v1((0.3, 4.0), "FFSR-v1", task=tier, batched=False), 1)
        batched = best_of(lambda tier=tier: evaluate_v1((0.3, 4.0), "FFSR-v1", task=tier, batched=True), 1)
        with ProcessPoolExecutor(workers) as pool:
            evaluate_v1((0.3, 4.0), "FFSR-v1", task=tier, indices=list(range(2 * workers)), executor=pool, chunk=1)  # warm
            spread = best_of(lambda tier=tier, pool=pool: evaluate_v1((0.3, 4.0), "FFSR-v1", task=tier, executor=pool), 1)
        row(f"pool_{tier}_batched", f"(0.3, 4 s) on the {tier} test pool, batched env", batched, "s",
            f"single env {alone:.2f} s", alone / batched, "faster than single env", batched < alone)
        row(f"pool_{tier}_workers", f"(0.3, 4 s) on the {tier} test pool, {workers} worker processes", spread, "s",
            f"single env {alone:.2f} s", alone / spread, "faster than single env", spread < alone)
    return rows


README_START = "<!-- speed:start (generated by `python benchmarks/bench.py --runs 3 --readme README.md`) -->"
README_END = "<!-- speed:end -->"


def _span(values: list[float], spec: str) -> str:
    lo, hi = min(values), max(values)
    return format(lo, spec) if format(lo, spec) == format(hi, spec) else f"{format(lo, spec)}-{format(hi, spec)}"


def speed_table(results: dict) -> str:
    """The README table: each measurement's range over the runs, its in-run reference ratio, the target."""
    runs = results["runs"]
    lines = [f"{len(runs)} runs on {results['machine']}; ranges are over the runs, ratios against the reference "
             "measured in the same run.", "",
             "| measurement | value | reference (same run) | ratio | target | met |", "|---|---|---|---|---|---|"]
    for k, first in enumerate(runs[0]):
        rows = [run[k] for run in runs]
        values, ratios = [r["value"] for r in rows], [r["ratio"] for r in rows if r["ratio"] is not None]
        met = {r["met"] for r in rows}
        spec = ",.0f" if first["unit"] == "physics steps/s" else ".3g"
        lines.append(f"| {first['what']} | {_span(values, spec)} {first['unit']} | {first['reference']} (last run) | "
                     f"{_span(ratios, '.2f') if ratios else 'n/a'} | {first['target']} | "
                     f"{'n/a' if met == {None} else 'yes' if met == {True} else 'no' if met == {False} else 'in some runs'} |")
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeats", type=int, default=3, help="timed repeats of the rollout (best of; default: 3)")
    parser.add_argument("--runs", type=int, default=1, help="whole runs of every measurement (default: 1)")
    parser.add_argument("--quick", action="store_true", help="project the GA from 16 evaluations instead of running it")
    parser.add_argument("--out", default="benchmarks/results.json", help="results with provenance (default: %(default)s)")
    parser.add_argument("--readme", default=None, help="splice the speed table between its markers in this file")
    args = parser.parse_args()
    workers = os.cpu_count() or 1
    machine = (f"{platform.processor() or platform.machine()}, {workers} CPUs, Python {platform.python_version()}, "
               f"numba {numba.__version__}")
    print("machine:", machine)
    start, runs = time.perf_counter(), []
    for k in range(args.runs):
        print(f"run {k + 1} of {args.runs}")
        runs.append(measure(workers, args.repeats, args.quick))
    results = {"machine": machine, "quick": args.quick, "runs": runs,
               "provenance": provenance(command="python benchmarks/bench.py " + " ".join(sys.argv[1:]),
                                        wall_time_s=time.perf_counter() - start)}
    write_json_atomic(args.out, results)
    print(speed_table(results))
    if args.readme:
        text = Path(args.readme).read_text(encoding="utf-8")
        write_text_atomic(args.readme, splice_generated(text, README_START, README_END, speed_table(results),
                                                        where=args.readme))


def _evaluate(params: tuple[float, float]) -> float:
    return ffsr_gym.objective_for_params(*params)


if __name__ == "__main__":
    main()
