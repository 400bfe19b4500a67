"""Entries of the classical planners on every tier's test pool of a benchmark version (perturbed tiers included).

    python baselines/classical.py --version v2 --leaderboard leaderboards [--tune-tasks 50]
    python baselines/classical.py --version capture-v0 --leaderboard leaderboards [--tiers slow]

Per tier:
* ``reference_<version>_default``: the predefined-time planner at the version's default (m, T_c);
* ``reference_paper_default``: at the paper's (0.1, 3 s);
* ``reference_best_constant``: the (m, T_c) of the tier rule's 6 x 6 grid with the best mean
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
from ffsr_gym.model.benchmark import CAPTURE_VERSIONS, VERSIONS, load_benchmark
from ffsr_gym.tasks.certificate import planner_episode
from ffsr_gym.tasks.splits import pool, task_scenario, version_tiers

GAINS_PER_S = (0.25, 0.5, 1.0, 2.0, 4.0, 8.0)


def tune(tier: str, candidates: list[dict], tasks: int, version: str) -> tuple[dict, dict, float]:
    """The candidate with the best mean score on the first ``tasks`` training tasks, its cost, and that mean."""
    benchmark, start = load_benchmark(version), time.perf_counter()
    scenarios = [task_scenario(tier, t.seed, benchmark) for t in pool(tier, "train", version=version)[:tasks]]
    means = [np.mean([planner_episode(s, benchmark, **c).score for s in scenarios])
             for c in tqdm(candidates, desc=f"tune {tier}", leave=False)]
    best = candidates[int(np.argmax(means))]
    return (best, {"objective_evaluations": len(candidates) * len(scenarios), "wall_time_s": time.perf_counter() - start},
            float(max(means)))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", default=VERSIONS[-1], choices=VERSIONS + CAPTURE_VERSIONS,
                        help=f"default: {VERSIONS[-1]}")
    parser.add_argument("--tiers", nargs="+", default=None, help="tiers (default: every tier of the version)")
    parser.add_argument("--leaderboard", required=True, help="leaderboard root; entries go to <root>/<version>/<tier>/")
    parser.add_argument("--tune-tasks", type=int, default=50, help="training tasks per tuning candidate (default: 50)")
    args = parser.parse_args()
    benchmark = load_benchmark(args.version)
    rule, default = benchmark.tasks, benchmark.planner
    grid = [{"method": "predefined_time", "m": m, "T_c": T_c} for m in rule.grid_m for T_c in rule.grid_T_c_s]
    gains = [{"method": "proportional", "gain_per_s": k} for k in GAINS_PER_S]
    jobs = {f"reference_{args.version}_default": [{"method": "predefined_time", "m": default.m, "T_c": default.T_c_s}],
            "reference_paper_default": [{"method": "predefined_time", "m": 0.1, "T_c": 3.0}],
            "reference_best_constant": grid, "proportional_tuned": gains}
    for tier in args.tiers or version_tiers(args.version):
        folder = Path(args.leaderboard) / args.version / tier
        for name, candidates in jobs.items():
            if (folder / f"{name}.json").exists():
                print("kept", folder / f"{name}.json")
                continue
            found = {}
            if len(candidates) == 1:
                setting, compute, trained_on = candidates[0], {}, None
            else:
                setting, compute, found["best_mean_training_score"] = tune(tier, candidates, args.tune_tasks, args.version)
                trained_on = f"{tier}/train"
            settings = {key: value for key, value in setting.items() if key != "method"}
            report = evaluate_planner(setting["method"], task=tier, name=name, training_pool=trained_on,
                                      compute=compute, version=args.version, **settings)
            report.extra["method"] = f"{setting['method']} planner {settings}"
            report.extra.update(found)
            print(name, tier, settings, f"IQM {report.metrics['score_iqm']:.3f}", "->", report.save(folder))


if __name__ == "__main__":
    main()
