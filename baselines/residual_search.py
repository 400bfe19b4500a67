"""Entries of CMA-ES over one constant residual action (12 joint rates, faded as FFSR-Residual-v2 fades them), per tier.

    python baselines/residual_search.py --leaderboard leaderboards [--version v2] [--tasks 20] [--evaluations 120]

The residual counterpart of ``optimisers.py``: CMA-ES (the ``cma`` package, seed 1, start at zero, step 0.3)
minimises 1 − the mean score over the first ``--tasks`` tasks of the tier's *training* pool
(``ffsr_gym.bench.planner_scores.residual_training_loss``: the certificate replay, which the
environment reproduces bit for bit) inside [-1, 1]^12; the best action, rounded to float32, is then
scored on the tier's test pool as a fixed policy of ``FFSR-Residual-v2`` (``ffsr_gym.evaluate`` with a
12-tuple, which ``ffsr-gym leaderboard verify`` re-runs). An existing entry is kept, so a killed run
resumes at the next tier. Compute: episodes run during the search and wall time.
"""

import argparse
import time
from concurrent.futures import ProcessPoolExecutor
from functools import partial
from pathlib import Path

import cma
import numpy as np

import ffsr_gym
from ffsr_gym.bench.planner_scores import residual_training_loss
from ffsr_gym.tasks.splits import version_tiers
from ffsr_gym.versions.registry import spec_for_version


def search(tier: str, tasks: int, evaluations: int, pool: ProcessPoolExecutor, version: str) -> tuple[tuple, dict, float]:
    """The best constant residual of a CMA-ES run on the training pool, what it cost, and its training loss."""
    loss = partial(residual_training_loss, tier=tier, tasks=tasks, version=version)
    es = cma.CMAEvolutionStrategy(np.zeros(12), 0.3, {"bounds": [-1, 1], "seed": 1, "maxfevals": evaluations,
                                                     "verbose": -9})
    while not es.stop():
        candidates = es.ask()
        es.tell(candidates, list(pool.map(loss, candidates)))
        print(f"  {tier}: {es.result.evaluations} evaluations, best training loss {es.result.fbest:.4f}", flush=True)
    action = tuple(float(x) for x in np.clip(es.result.xbest, -1.0, 1.0).astype(np.float32))
    return action, {"objective_evaluations": int(es.result.evaluations) * tasks}, float(es.result.fbest)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", default="v2", help="a pool benchmark version (default: v2; or capture-v0)")
    parser.add_argument("--tiers", nargs="+", default=None, help="tiers (default: every tier of the version)")
    parser.add_argument("--leaderboard", required=True, help="leaderboard root; entries go to <root>/<version>/<tier>/")
    parser.add_argument("--tasks", type=int, default=20, help="training tasks per loss evaluation (default: 20)")
    parser.add_argument("--evaluations", type=int, default=120, help="CMA-ES loss evaluations (default: 120)")
    parser.add_argument("--workers", type=int, default=2, help="worker processes (default: 2)")
    args = parser.parse_args()
    env_id = spec_for_version(args.version).ids.residual
    with ProcessPoolExecutor(args.workers) as pool:
        for tier in args.tiers or version_tiers(args.version):
            folder = Path(args.leaderboard) / args.version / tier
            if (folder / "cmaes_residual.json").exists():
                print("kept", folder / "cmaes_residual.json")
                continue
            start = time.perf_counter()
            action, compute, loss = search(tier, args.tasks, args.evaluations, pool, args.version)
            compute["wall_time_s"] = time.perf_counter() - start
            report = ffsr_gym.evaluate(action, env_id, task=tier, name="cmaes_residual",
                                       training_pool=f"{tier}/train (first {args.tasks} tasks)", compute=compute)
            report.extra["method"] = "CMA-ES (cma) over one constant residual action: " + ", ".join(f"{x:+.3f}"
                                                                                                  for x in action)
            report.extra["best_training_loss"] = loss
            print("cmaes_residual", tier, f"IQM {report.metrics['score_iqm']:.3f}", "->", report.save(folder))


if __name__ == "__main__":
    main()
