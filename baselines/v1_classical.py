"""Benchmark-v1 entries of the classical planners on every tier's test pool (the perturbed tiers included).

    python baselines/v1_classical.py --leaderboard leaderboards [--tune-tasks 50]

Per tier:
* ``reference_v1_default``: the predefined-time planner at v1's (0.3, 4 s);
* ``reference_paper_default``: at the paper's (0.1, 3 s);
* ``reference_best_constant``: the (m, T_c) of the tier rule's 6 x 6 grid with the best mean v1
  score over the first ``--tune-tasks`` tasks of the tier's *training* pool;
* ``proportional_tuned``: the proportional-feedback planner (phi(e) = K e, same avoidance) with
  the gain K in {0.25, 0.5, 1, 2, 4, 8} 1/s of best mean training score, chosen the same way.

Tuning runs on the training pool only; the entry records it and the episodes it cost. An entry
already in the folder is kept (a killed run resumes where it stopped).
"""

import argparse
import time
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from ffsr_gym.bench.planner_scores import evaluate_planner
from ffsr_gym.tasks.certificate import planner_episode
from ffsr_gym.model.benchmark import load_benchmark
from ffsr_gym.tasks.splits import pool, task_scenario
from ffsr_gym.tasks.tiers import ALL_TIERS

GAINS_PER_S = (0.25, 0.5, 1.0, 2.0, 4.0, 8.0)


def tune(tier: str, candidates: list[dict], tasks: int) -> tuple[dict, dict]:
    """The candidate with the best mean v1 score on the first ``tasks`` training tasks, and its cost."""
    benchmark, start = load_benchmark("v1"), time.perf_counter()
    scenarios = [task_scenario(tier, t.seed, benchmark) for t in pool(tier, "train")[:tasks]]
    means = [np.mean([planner_episode(s, benchmark, **c).score for s in scenarios])
             for c in tqdm(candidates, desc=f"tune {tier}", leave=False)]
    best = candidates[int(np.argmax(means))]
    return best, {"objective_evaluations": len(candidates) * len(scenarios), "wall_time_s": time.perf_counter() - start,
                  "best_mean_training_score": float(max(means))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--leaderboard", required=True, help="leaderboard root; entries go to <root>/v1/<tier>/")
    parser.add_argument("--tune-tasks", type=int, default=50, help="training tasks per tuning candidate (default: 50)")
    args = parser.parse_args()
    rule = load_benchmark("v1").tasks
    grid = [{"method": "predefined_time", "m": m, "T_c": T_c} for m in rule.grid_m for T_c in rule.grid_T_c_s]
    gains = [{"method": "proportional", "gain_per_s": k} for k in GAINS_PER_S]
    jobs = {"reference_v1_default": [{"method": "predefined_time", "m": 0.3, "T_c": 4.0}],
            "reference_paper_default": [{"method": "predefined_time", "m": 0.1, "T_c": 3.0}],
            "reference_best_constant": grid, "proportional_tuned": gains}
    for tier in ALL_TIERS:
        folder = Path(args.leaderboard) / "v1" / tier
        for name, candidates in jobs.items():
            if (folder / f"{name}.json").exists():
                print("kept", folder / f"{name}.json")
                continue
            if len(candidates) == 1:
                setting, compute, trained_on = candidates[0], {}, None
            else:
                (setting, compute), trained_on = tune(tier, candidates, args.tune_tasks), f"{tier}/train"
            settings = {key: value for key, value in setting.items() if key != "method"}
            report = evaluate_planner(setting["method"], task=tier, name=name, training_pool=trained_on,
                                      compute=compute, **settings)
            report.extra["method"] = f"{setting['method']} planner {settings}"
            print(name, tier, settings, f"IQM {report.metrics['score_iqm']:.3f}", "->", report.save(folder))


if __name__ == "__main__":
    main()
