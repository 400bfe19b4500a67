"""RL study on a pool benchmark version: PPO and SAC on FFSR-v2 and FFSR-Residual-v2, every tier, 5 seeds each.

    python baselines/rl_study.py --leaderboard leaderboards [--version v2] [--work runs/rl-v2]
                                 [--workers 2 | --scheduler ADDRESS] [--algos ppo sac] [--tiers easy hard]
                                 [--seeds 0 1 2 3 4] [--points 20] [--plan]

One piece is one (algorithm, env id, tier, training seed): the agent trains on the tier's
training pool for the budget of ``ffsr_gym/hyperparams/<algo>.yml`` (times ``--scale``), is
scored on the validation pool ``--points`` times (the learning curve and the checkpoint
selection), and its last and best-on-validation checkpoints are scored once on the test pool
(``ffsr_gym.optim.rl``). Pieces run on ``--workers`` processes, one core each, or on the Dask cluster
``--scheduler`` names (docs/cluster.md), whose workers send each seed's records back to this process. A piece whose
folder in ``--work`` holds its training record and test scores is taken from them, never retrained
(``studies/`` keeps these small files in git, so a study resumes in any later session); when every
seed of an (algorithm, env id, tier) is done, its two leaderboard entries (``<name>`` and
``<name>_valbest``) are written, but only when ``--seeds`` covers the study's five (0-4): a run
with fewer seeds trains and records its pieces and leaves the entries to the full run. An existing
entry is kept; one written from fewer seeds than asked is refused by name.
"""

import argparse
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

from tqdm.auto import tqdm

from ffsr_gym.bench.options import add_scheduler_option
from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.optim.rl import load_hyperparams
from ffsr_gym.optim.rl_study import scored_seed_files, seed_folder, seed_piece, train_and_evaluate, write_seed
from ffsr_gym.tasks.splits import version_tiers
from ffsr_gym.versions.registry import spec_for_version
from ffsr_gym_lab.studies import plan as study_plan

ALGOS = ("ppo", "sac")


def budget(algo: str, env_id: str, scale: float, points: int) -> tuple[int, int]:
    """(env steps per seed, steps between validation scorings)."""
    steps = round(load_hyperparams(algo, env_id)["n_timesteps"] * scale)
    return steps, max(1, steps // points)


def run_seed(algo: str, env_id: str, tier: str, seed: int, scale: float, points: int, work: str) -> str | None:
    """One piece; None when another process is training it (its folder's lock)."""
    steps, every = budget(algo, env_id, scale, points)
    try:
        reports = train_and_evaluate(algo, env_id, task=tier, seeds=[seed], out=work, timesteps=steps,
                                     curve_every=every, progress=False)
    except InvalidInputError as exc:
        if "is being trained by process" in str(exc):
            return None
        raise
    return " | ".join(f"{r.name} seed {seed}: mean {r.metrics['score_mean']:.3f}" for r in reports.values())


def write_entries(algo: str, env_id: str, tier: str, seeds: list[int], scale: float, points: int, work: str,
                  root: Path) -> str:
    steps, every = budget(algo, env_id, scale, points)
    reports = train_and_evaluate(algo, env_id, task=tier, seeds=seeds, out=work, timesteps=steps, curve_every=every,
                                 progress=False)  # every seed is loaded from its folder
    return "\n".join(f"{r.name}: IQM {r.metrics['score_iqm']:.3f} -> {r.save(root, overwrite=True)}"
                     for r in reports.values())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", default="v2", help="a pool benchmark version (default: v2)")
    parser.add_argument("--leaderboard", required=True, help="leaderboard root; entries go to <root>/<version>/<tier>/")
    parser.add_argument("--work", default=None, help="training records and scores, models (default: studies/rl-<version>; "
                                                     "the records are kept in git, the models not)")
    parser.add_argument("--workers", type=int, default=2, help="seeds trained at once, one core each (default: 2)")
    parser.add_argument("--scale", type=float, default=1.0, help="multiplies every training budget (default: 1)")
    parser.add_argument("--points", type=int, default=20, help="validation scorings per run after step 0 (default: 20)")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4], help="training seeds (default: 0-4)")
    parser.add_argument("--algos", nargs="+", default=list(ALGOS), choices=ALGOS, help="algorithms (default: ppo sac)")
    parser.add_argument("--tiers", nargs="+", default=None, help="tiers (default: every tier of the version)")
    parser.add_argument("--env-ids", nargs="+", default=None, help="env ids (default: the version's two)")
    add_scheduler_option(parser, "seeds (one piece each, instead of --workers)")
    parser.add_argument("--plan", action="store_true", help="print what is left (seeds done and left, and the "
                                                            "core-hours left, estimated from finished seeds) and stop")
    args = parser.parse_args()
    version, work = args.version, args.work or f"studies/rl-{args.version}"
    env_ids = args.env_ids or list(spec_for_version(version).env_ids)
    tiers = args.tiers or version_tiers(version)
    unknown = sorted(set(tiers) - set(version_tiers(version)))
    if unknown:
        parser.error(f"--tiers {unknown}: allowed {list(version_tiers(version))} (the tiers of {version})")
    asked = [(algo, env_id, tier) for tier in tiers for algo in args.algos for env_id in env_ids]
    study_plan.check_entry_seeds(Path(args.leaderboard), version, asked, args.seeds)
    groups = [group for group in asked if not study_plan.entries_written(Path(args.leaderboard), version, *group)]
    if args.plan:
        print(study_plan.render(study_plan.plan(groups, args.seeds, work, args.leaderboard, version)))
        return
    writes = study_plan.writes_entries(args.seeds)
    if not writes:
        print(f"seeds {args.seeds} do not cover the study's {list(study_plan.STUDY_SEEDS)}: "
              "pieces are trained and recorded, entries are left to a run with every seed")
    start = time.perf_counter()
    entries = (lambda group: write_entries(*group, args.seeds, args.scale, args.points, work,
                                           Path(args.leaderboard) / version / group[2])) if writes else None
    run = run_on_cluster if args.scheduler is not None else run_here
    pieces = run(groups, args, work, entries)
    print(f"{len(groups)} entry pair{'s' * (len(groups) != 1)}, {pieces} seeds in {time.perf_counter() - start:.0f} s")


def run_here(groups: list[tuple], args: argparse.Namespace, work: str, entries) -> int:
    """The seeds on ``--workers`` local processes, each training into the study's folder (locked while it trains)."""
    with ProcessPoolExecutor(args.workers) as pool:
        futures = {pool.submit(run_seed, *group, seed, args.scale, args.points, work): group
                   for group in groups for seed in args.seeds}
        left, blocked = {group: len(args.seeds) for group in groups}, set()
        for future in tqdm(as_completed(futures), total=len(futures), desc="RL study seeds"):
            done, group = future.result(), futures[future]
            if done is None:
                blocked.add(group)
            tqdm.write(done or f"{group}: a seed is being trained by another process; its entries are left for later")
            left[group] -= 1
            if left[group] == 0 and group not in blocked and entries is not None:
                tqdm.write(entries(group))
    return len(futures)


def run_on_cluster(groups: list[tuple], args: argparse.Namespace, work: str, entries) -> int:
    """The seeds not yet scored as pieces on the ``--scheduler`` cluster (each trained in a folder of its worker's);
    this process writes each seed's records into the study's folder as it arrives, and a group's entries once
    its last seed is in."""
    from ffsr_gym.cluster import cluster_executor

    with cluster_executor(args.scheduler) as (executor, _):
        futures = {}
        for group in groups:
            steps, every = budget(group[0], group[1], args.scale, args.points)
            for seed in args.seeds:
                if not scored_seed_files(seed_folder(work, *group, seed)):
                    futures[executor.submit(seed_piece, *group, seed, steps, every, list(sys.argv))] = (group, seed)
        left = {group: sum(g == group for g, _ in futures.values()) for group in groups}
        for group in (g for g in groups if left[g] == 0 and entries is not None):
            tqdm.write(entries(group))  # every seed was already scored
        for future in tqdm(as_completed(futures), total=len(futures), desc="RL study seeds"):
            group, seed = futures[future]
            tqdm.write(f"{group} seed {seed}: records in {write_seed(work, *group, seed, future.result())}")
            left[group] -= 1
            if left[group] == 0 and entries is not None:
                tqdm.write(entries(group))
    return len(futures)


if __name__ == "__main__":
    main()
