"""A gradient search over residual schedules through the JAX loop, against the CMA-ES best-known search at equal
wall time, on v2's test pools.

For each task: start from the stored best-known residual schedule (``envs/benchmark/v2_best_known.json``), descend
on the episode's smoothness cost C by :func:`ffsr_gym.jax.gradient.descend`, accepting a step only when the
episode it leads to succeeds with the certificate margins of the rule file's ensemble (rate, clearance, final
error), for as long as the CMA-ES search spent on that task (its record's wall time, both families; the JAX
compilation, once per tier, is timed apart). The best knots, rounded to float32 as env actions are, are then
offered to the best-known records (:func:`ffsr_gym.optim.best_known_build.offer`: replayed on the kernel, kept
only when they beat the stored residual score and pass the certificate test, as an absorbed line of
``--best-known-work``; ``assemble`` or ``absorb_best_known.py`` writes them into the file, never into the frozen
reference). A task improves when its certified score beats the task's best known score. One line per task in
``--work`` (resumable).

    python benchmarks/jax_gradient.py [--tiers easy medium] [--tasks N] [--work studies/jax-gradient]
        [--best-known-work studies/best-known] [--summary benchmarks/jax_gradient.json]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from functools import cache
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from ffsr_gym.jax.collision import shapes_of
from ffsr_gym.jax.gradient import descend, episode, span
from ffsr_gym.jax.physics import jax, jnp
from ffsr_gym.jax.scenario import episode_task
from ffsr_gym.model.benchmark import load_benchmark
from ffsr_gym.optim import best_known_build as build
from ffsr_gym.provenance import provenance, write_json_atomic
from ffsr_gym.sim.setup import robot_assets
from ffsr_gym.tasks.best_known import records
from ffsr_gym.tasks.schedule import Schedule, replay_schedule
from ffsr_gym.tasks.splits import pool, task_scenario


@cache
def compiled(rules, spread: int) -> tuple:
    """(play, value_and_grad) of the episode of a residual schedule, jitted once per (rules, spread): the model, the
    collision shapes and the task are arguments, so every task of a tier reuses one compilation."""
    def play(model, shapes, task, knots):
        return episode(model, shapes, rules, task, knots, spread)

    return jax.jit(play), jax.jit(jax.value_and_grad(lambda *args: play(*args).cost, argnums=3))


def search_task(tier: str, index: int, benchmark, shapes, best_known_work: str) -> dict:
    """The gradient search on one test task; its result offered to the best-known records (certified there)."""
    record = records(tier, "test", "v2")[index]
    start_schedule = Schedule.from_dict(record["families"]["residual"]["schedule"])
    scenario = task_scenario(tier, pool(tier, "test")[index].seed, benchmark)
    model, rules, task = episode_task(scenario)
    spread = span(task, scenario.env.decision_interval_s, scenario.desired_path.motion_time_s)
    ensemble = benchmark.tasks.ensemble
    limit, keep_out = benchmark.score.max_rate_deg_s, benchmark.score.keep_out_m
    tolerance = benchmark.score.ee_position_tolerance_m

    def accept(played):
        return (bool(played.success) and float(played.peak) <= ensemble.rate_margin * limit
                and float(played.min_clear) >= keep_out + ensemble.clearance_margin_m
                and float(played.min_self) >= ensemble.clearance_margin_m
                and float(played.final_error) <= ensemble.error_margin * tolerance)

    play, value_and_grad = compiled(rules, spread)

    def cost_and_grad(knots):
        return play(model, shapes, task, knots), value_and_grad(model, shapes, task, knots)[1]

    knots = jnp.asarray(np.asarray(start_schedule.knots, dtype=np.float64))
    clock = time.perf_counter()
    jax.block_until_ready(cost_and_grad(knots))  # the first task of a tier compiles here: timed apart
    compile_s = time.perf_counter() - clock
    budget_s, clock = float(record["wall_time_s"]), time.perf_counter()
    # one step past the budget at most: the clock is read after every step, and a collapsed step size ends it
    best, history = descend(cost_and_grad, knots, steps=10_000, rate=0.05, accept=accept,
                            stop=lambda: time.perf_counter() - clock >= budget_s, min_rate=1e-6)
    steps = len(history) - 1
    spent = time.perf_counter() - clock
    found = Schedule.from_vector("residual", np.asarray(best).ravel())
    kernel = replay_schedule(scenario, found, benchmark, backend="kernel")
    kept = build.offer(found, tier, "test", index, best_known_work, "jax gradient descent")
    return {"tier": tier, "index": index, "best_known": record["best"]["score"],
            "residual_best_known": record["families"]["residual"]["score"],
            "start_cost": history[0][0], "end_cost": history[-1][0], "kernel_score": kernel.score,
            "kernel_success": kernel.success, "raised_residual": kept is not None,
            "improved": bool(kept is not None and kernel.score > record["best"]["score"]), "descent_steps": steps,
            "compile_s": compile_s, "wall_time_s": spent, "cma_wall_time_s": budget_s, "schedule": found.as_dict()}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--tiers", nargs="+", default=["easy", "medium"])
    parser.add_argument("--tasks", type=int, default=None, help="only the first N tasks of each pool (default: all)")
    parser.add_argument("--work", default="studies/jax-gradient", help="one line per finished task")
    parser.add_argument("--summary", default="benchmarks/jax_gradient.json", help="result with provenance")
    parser.add_argument("--best-known-work", default="studies/best-known",
                        help="the best-known work folder that certified improvements go to (as absorbed lines)")
    args = parser.parse_args(argv)
    benchmark, shapes = load_benchmark("v2"), shapes_of(robot_assets("ffsr_dual_arm").kernel)
    work = Path(args.work)
    work.mkdir(parents=True, exist_ok=True)
    rows = []
    for tier in args.tiers:
        path = work / f"{tier}_test.jsonl"
        done = {json.loads(line)["index"]: json.loads(line) for line in path.read_text().splitlines()} \
            if path.is_file() else {}
        count = len(pool(tier, "test")) if args.tasks is None else min(args.tasks, len(pool(tier, "test")))
        for index in tqdm(range(count), desc=f"gradient {tier}", unit="task"):
            if index not in done:
                done[index] = search_task(tier, index, benchmark, shapes, args.best_known_work)
                with path.open("a", encoding="utf-8") as handle:
                    handle.write(json.dumps(done[index]) + "\n")
            rows.append(done[index])
    gains = [r["kernel_score"] / r["best_known"] - 1.0 for r in rows if r["improved"]]
    summary = {"tasks": len(rows), "improved": len(gains), "mean_gain": float(np.mean(gains)) if gains else 0.0,
               "max_gain": float(np.max(gains)) if gains else 0.0,
               "raised_residual_family": sum(r["raised_residual"] for r in rows),
               "cost_lowered": sum(r["end_cost"] < r["start_cost"] for r in rows),
               "wall_time_s": sum(r["wall_time_s"] for r in rows),
               "cma_wall_time_s": sum(r["cma_wall_time_s"] for r in rows),
               "compile_s": {tier: max(r["compile_s"] for r in rows if r["tier"] == tier) for tier in args.tiers},
               "provenance": provenance(command=" ".join(["python", *sys.argv]))}
    write_json_atomic(Path(args.summary), summary)
    print(json.dumps(summary, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
