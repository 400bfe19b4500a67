"""A gradient search over residual schedules through the JAX loop, against the CMA-ES best-known search at equal
wall time, on v2's test pools; and the gradient's check against central differences.

For each task: start from the stored best-known residual schedule (``envs/benchmark/v2_best_known.json``), descend
on the episode's smoothness cost C by :func:`ffsr_gym.jax.gradient.descend`, accepting a step only when the
episode it leads to succeeds with the certificate margins of the rule file's ensemble (rate, clearance, final
error), for as long as the CMA-ES search spent on that task (its record's wall time). The best knots, rounded to
float32 as env actions are, are then replayed on the kernel by the project's own ``replay_schedule`` and on the
task's certificate ensemble (dt/2, dt/4, perturbed starts, Pinocchio): a task improves only if that certified
score beats the stored best known score. One line per task in ``--work`` (resumable).

    python benchmarks/jax_gradient.py [--tiers easy medium] [--tasks N] [--work studies/jax-gradient]
        [--summary benchmarks/jax_gradient.json]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from ffsr_gym.jax.collision import shapes_of
from ffsr_gym.jax.gradient import descend, episode, span
from ffsr_gym.jax.physics import jax, jnp
from ffsr_gym.jax.scenario import episode_task
from ffsr_gym.model.benchmark import load_benchmark
from ffsr_gym.provenance import provenance, write_json_atomic
from ffsr_gym.sim.setup import robot_assets
from ffsr_gym.tasks.best_known import records
from ffsr_gym.tasks.certificate import Margins, ensemble_members
from ffsr_gym.tasks.schedule import Schedule, replay_schedule
from ffsr_gym.tasks.splits import pool, task_scenario


def search_task(tier: str, index: int, benchmark, shapes) -> dict:
    """The gradient search on one test task, and its certified result."""
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

    value_and_grad = jax.jit(jax.value_and_grad(lambda k: episode(model, shapes, rules, task, k, spread).cost))
    play = jax.jit(lambda k: episode(model, shapes, rules, task, k, spread))

    def cost_and_grad(knots):
        return play(knots), value_and_grad(knots)[1]

    knots = jnp.asarray(np.asarray(start_schedule.knots, dtype=np.float64))
    budget_s, clock, steps = float(record["wall_time_s"]), time.perf_counter(), 0
    best, history = knots, []
    while time.perf_counter() - clock < budget_s:
        best, part = descend(cost_and_grad, best, steps=5, rate=0.05 if not history else history[-1][1], accept=accept)
        history += part[1:]
        steps += 5
        if history[-1][1] < 1e-6:  # the step size collapsed: no accepted descent left
            break
    spent = time.perf_counter() - clock
    found = Schedule.from_vector("residual", np.asarray(best).ravel())
    kernel = replay_schedule(scenario, found, benchmark, backend="kernel")
    members = [replay_schedule(m.task, found, benchmark, backend=m.backend)
               for m in ensemble_members(scenario, pool(tier, "test")[index].seed, ensemble)]
    margins = Margins.worst([kernel, *members])
    certified = kernel.success and all(r.success for r in members) and margins.short(benchmark) is None
    return {"tier": tier, "index": index, "best_known": record["families"]["residual"]["score"],
            "start_cost": history[0][0] if history else None, "kernel_score": kernel.score, "certified": certified,
            "improved": bool(certified and kernel.score > record["best"]["score"]), "descent_steps": steps,
            "wall_time_s": spent, "cma_wall_time_s": budget_s, "schedule": found.as_dict()}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--tiers", nargs="+", default=["easy", "medium"])
    parser.add_argument("--tasks", type=int, default=None, help="only the first N tasks of each pool (default: all)")
    parser.add_argument("--work", default="studies/jax-gradient", help="one line per finished task")
    parser.add_argument("--summary", default="benchmarks/jax_gradient.json", help="result with provenance")
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
                done[index] = search_task(tier, index, benchmark, shapes)
                with path.open("a", encoding="utf-8") as handle:
                    handle.write(json.dumps(done[index]) + "\n")
            rows.append(done[index])
    gains = [r["kernel_score"] / r["best_known"] - 1.0 for r in rows if r["improved"]]
    summary = {"tasks": len(rows), "improved": len(gains), "mean_gain": float(np.mean(gains)) if gains else 0.0,
               "max_gain": float(np.max(gains)) if gains else 0.0,
               "certified": sum(r["certified"] for r in rows),
               "provenance": provenance(command=" ".join(["python", *sys.argv]))}
    write_json_atomic(Path(args.summary), summary)
    print(json.dumps(summary, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
