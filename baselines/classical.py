"""Entries of the classical planners on every tier's test pool of a benchmark version (perturbed tiers included).

    python baselines/classical.py --version v2 --leaderboard leaderboards [--tune-tasks 50]
    python baselines/classical.py --version capture-v0 --leaderboard leaderboards [--tiers slow]
    python baselines/classical.py --version capture-v1 --leaderboard leaderboards [--tune-tasks 20]

Per tier:
* ``reference_<version>_default``: the predefined-time planner at the version's default (m, T_c);
* ``reference_paper_default``: at the paper's (0.1, 3 s);
* ``reference_best_constant``: the (m, T_c) of the tier rule's 6 x 6 grid with the best mean
  score over the first ``--tune-tasks`` tasks of the tier's *training* pool;
* ``proportional_tuned``: the proportional-feedback planner (phi(e) = K e, same avoidance) with
  the gain K in {0.25, 0.5, 1, 2, 4, 8} 1/s of best mean training score, chosen the same way.

On a version whose action commands the approach (capture v1) every planner also has a go time, when
the insertion is commanded: the two references go straight in (0 s); the tuned ones choose theirs
from the tier rule's ``go_s`` with their (m, T_c) or K (one constant timing for the whole pool).

Tuning runs on the training pool only; the entry records it and the episodes it cost. An entry
already in the folder is kept (a killed run resumes where it stopped).
"""

import argparse
import time
from concurrent.futures import Executor, ProcessPoolExecutor
from functools import partial
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from ffsr_gym.bench.planner_scores import evaluate_planner
from ffsr_gym.tasks.certificate import planner_episode
from ffsr_gym.tasks.splits import pool, task_scenario, version_tiers
from ffsr_gym.versions.registry import CAPTURE_VERSIONS, VERSIONS, load_benchmark, spec_for_version
from ffsr_gym_lab.board.tables import headline

GAINS_PER_S = (0.25, 0.5, 1.0, 2.0, 4.0, 8.0)


def mean_training_score(candidate: dict, tier: str, tasks: int, version: str) -> float:
    """The mean score of one planner setting on the first ``tasks`` tasks of the tier's training pool."""
    benchmark = load_benchmark(version)
    scenarios = [task_scenario(tier, t.seed, benchmark) for t in pool(tier, "train", version=version)[:tasks]]
    return float(np.mean([planner_episode(s, benchmark, **candidate).score for s in scenarios]))


def tune(tier: str, candidates: list[dict], tasks: int, version: str, executor: Executor) -> tuple[dict, dict, float]:
    """The candidate with the best mean score on the first ``tasks`` training tasks, its cost, and that mean."""
    start, count = time.perf_counter(), len(pool(tier, "train", version=version)[:tasks])
    means = list(tqdm(executor.map(partial(mean_training_score, tier=tier, tasks=tasks, version=version), candidates),
                      total=len(candidates), desc=f"tune {tier}", leave=False))
    best = candidates[int(np.argmax(means))]
    return (best, {"objective_evaluations": len(candidates) * count, "wall_time_s": time.perf_counter() - start},
            float(max(means)))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", default=VERSIONS[-1], choices=VERSIONS + CAPTURE_VERSIONS,
                        help=f"default: {VERSIONS[-1]}")
    parser.add_argument("--tiers", nargs="+", default=None, help="tiers (default: every tier of the version)")
    parser.add_argument("--leaderboard", required=True, help="leaderboard root; entries go to <root>/<version>/<tier>/")
    parser.add_argument("--tune-tasks", type=int, default=50, help="training tasks per tuning candidate (default: 50)")
    parser.add_argument("--workers", type=int, default=1, help="worker processes while tuning (default: 1)")
    args = parser.parse_args()
    benchmark = load_benchmark(args.version)
    rule, default = benchmark.tasks, benchmark.planner
    timed = spec_for_version(args.version).actions.command
    go = [{"go_s": float(g)} for g in rule.go_s] if timed else [{}]  # capture v1: when the insertion is commanded
    straight = {"go_s": 0.0} if timed else {}
    grid = [{"method": "predefined_time", "m": m, "T_c": T_c, **g} for m in rule.grid_m for T_c in rule.grid_T_c_s
            for g in go]
    gains = [{"method": "proportional", "gain_per_s": k, **g} for k in GAINS_PER_S for g in go]
    jobs = {f"reference_{args.version}_default": [{"method": "predefined_time", "m": default.m, "T_c": default.T_c_s,
                                                   **straight}],
            "reference_paper_default": [{"method": "predefined_time", "m": 0.1, "T_c": 3.0, **straight}],
            "reference_best_constant": grid, "proportional_tuned": gains}
    with ProcessPoolExecutor(args.workers) as executor:
        for tier in args.tiers or version_tiers(args.version):
            entries(tier, jobs, args, executor)


def entries(tier: str, jobs: dict[str, list[dict]], args: argparse.Namespace, executor: Executor) -> None:
    """The tier's entries of ``jobs`` (name: its candidate settings) not yet in the leaderboard folder."""
    folder = Path(args.leaderboard) / args.version / tier
    for name, candidates in jobs.items():
        if (folder / f"{name}.json").exists():
            print("kept", folder / f"{name}.json")
            continue
        found = {}
        if len(candidates) == 1:
            setting, compute, trained_on = candidates[0], {}, None
        else:
            setting, compute, found["best_mean_training_score"] = tune(tier, candidates, args.tune_tasks, args.version,
                                                                       executor)
            trained_on = f"{tier}/train"
        settings = {key: value for key, value in setting.items() if key != "method"}
        report = evaluate_planner(setting["method"], task=tier, name=name, training_pool=trained_on,
                                  compute=compute, version=args.version, **settings)
        report.extra["method"] = f"{setting['method']} planner {settings}"
        report.extra.update(found)
        shown = headline(spec_for_version(args.version), report.metrics)
        print(name, tier, settings, shown, "->", report.save(folder))


if __name__ == "__main__":
    main()
