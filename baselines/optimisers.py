"""Entries of the paper's GA and of CMA-ES over constant (m, T_c), on every tier of a benchmark version.

    python baselines/optimisers.py --version v2 --leaderboard leaderboards [--tasks 20] [--work runs/optimisers-v2]
    python baselines/optimisers.py --version capture-v0 --leaderboard leaderboards [--tiers slow]
    python baselines/optimisers.py --version capture-v1 --leaderboard leaderboards

Both minimise the same loss, 1 − the mean score over the first ``--tasks`` tasks of the tier's
*training* pool (``ffsr_gym.bench.planner_scores.training_loss``), inside the version's (m, T_c)
action box (m in [0.05, 0.6], T_c in [1, 10] s); the optimum is then scored on the tier's test
pool. On a version whose action commands the approach (capture v1) both search a third gene, the go time
go_s in [0, the last moment of the tier rule's ``go_s``] (the insertion commanded from the first decision at
or after it), with the same loss. The GA checkpoints every generation in ``--work`` and an existing entry is
kept, so a killed run resumes. Compute: episodes run during the search (evaluations x tasks) and wall time.
"""

import argparse
import time
from concurrent.futures import ProcessPoolExecutor
from functools import partial
from pathlib import Path

import cma
import numpy as np

from ffsr_gym.bench.planner_scores import evaluate_planner, training_loss
from ffsr_gym.optim import ga
from ffsr_gym.tasks.splits import version_tiers
from ffsr_gym.versions.registry import CAPTURE_VERSIONS, VERSIONS, load_benchmark, spec_for_version
from ffsr_gym_lab.board.tables import headline


def go_box(version):
    """The go time's search box [s] on a version whose action commands the approach (None: no such gene)."""
    benchmark = load_benchmark(version)
    return (0.0, float(max(benchmark.tasks.go_s))) if spec_for_version(version).actions.command else None


def run_ga(tier, tasks, work, pool, generations, population, version):
    box = load_benchmark(version).action
    config = ga.GAConfig(population=population, generations=generations, m_bounds=tuple(box.m_bounds),
                         T_c_bounds_s=tuple(box.T_c_bounds_s), go_bounds_s=go_box(version), seed=0,
                         scenario=f"{version}:{tier}")
    state = ga.run(config, executor=pool, checkpoint=Path(work) / f"ga_{tier}.json",
                   fitness=partial(training_loss, tier=tier, tasks=tasks, version=version), progress=True)
    m, T_c, loss = ga.best(state)
    go = ga.best_go_s(state)
    return (m, T_c) + (() if go is None else (go,)), {"objective_evaluations": len(state.cache) * tasks}, loss


def run_cmaes(tier, tasks, pool, evaluations, version):
    box, go = load_benchmark(version).action, go_box(version)
    low = np.array([box.m_bounds[0], box.T_c_bounds_s[0]] + ([go[0]] if go else []))
    high = np.array([box.m_bounds[1], box.T_c_bounds_s[1]] + ([go[1]] if go else []))
    loss = partial(training_loss, tier=tier, tasks=tasks, version=version)
    start = [0.45, 0.33] + ([0.5] if go else [])
    es = cma.CMAEvolutionStrategy(start, 0.2, {"bounds": [0, 1], "seed": 1, "maxfevals": evaluations, "verbose": -9})
    while not es.stop():
        candidates = es.ask()
        params = [tuple(float(x) for x in np.clip(low + np.clip(z, 0, 1) * (high - low), low, high))
                  for z in candidates]  # in the box
        es.tell(candidates, list(pool.map(ga.call_fitness, [loss] * len(params), params)))
    best = low + np.clip(es.result.xbest, 0, 1) * (high - low)
    compute = {"objective_evaluations": int(es.result.evaluations) * tasks}
    return tuple(float(x) for x in best), compute, float(es.result.fbest)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", default=VERSIONS[-1], choices=VERSIONS + CAPTURE_VERSIONS,
                        help=f"default: {VERSIONS[-1]}")
    parser.add_argument("--tiers", nargs="+", default=None, help="tiers (default: every tier of the version)")
    parser.add_argument("--leaderboard", required=True, help="leaderboard root; entries go to <root>/<version>/<tier>/")
    parser.add_argument("--tasks", type=int, default=20, help="training tasks per loss evaluation (default: 20)")
    parser.add_argument("--work", default=None, help="GA checkpoints (default: runs/optimisers-<version>)")
    parser.add_argument("--generations", type=int, default=15, help="GA generations (default: 15)")
    parser.add_argument("--population", type=int, default=16, help="GA population (default: 16)")
    parser.add_argument("--evaluations", type=int, default=120, help="CMA-ES loss evaluations (default: 120)")
    parser.add_argument("--workers", type=int, default=2, help="worker processes (default: 2)")
    args = parser.parse_args()
    version, work = args.version, args.work or f"runs/optimisers-{args.version}"
    names = {f"ga_{version}": "paper GA", f"cmaes_{version}": "CMA-ES (cma)"}
    with ProcessPoolExecutor(args.workers) as pool:
        for tier in args.tiers or version_tiers(version):
            folder = Path(args.leaderboard) / version / tier
            ga_name, cmaes_name = names
            searches = {ga_name: partial(run_ga, tier, args.tasks, work, pool, args.generations, args.population, version),
                        cmaes_name: partial(run_cmaes, tier, args.tasks, pool, args.evaluations, version)}
            for name, search in searches.items():
                if (folder / f"{name}.json").exists():
                    print("kept", folder / f"{name}.json")
                    continue
                start = time.perf_counter()
                (m, T_c, *go), compute, loss = search()
                compute["wall_time_s"] = time.perf_counter() - start
                report = evaluate_planner("predefined_time", task=tier, m=m, T_c=T_c, go_s=go[0] if go else None,
                                          name=name, training_pool=f"{tier}/train (first {args.tasks} tasks)",
                                          compute=compute, version=version)
                found = f"({m:.4f}, {T_c:.3f} s" + (f", {go[0]:.2f} s)" if go else ")")
                report.extra["method"] = names[name] + (" over (m, T_c, go_s): " if go else " over (m, T_c): ") + found
                report.extra["best_training_loss"] = loss
                shown = headline(spec_for_version(version), report.metrics)
                print(name, tier, found, shown, "->", report.save(folder))


if __name__ == "__main__":
    main()
