"""RL study on a pool benchmark version: PPO and SAC on FFSR-v2 and FFSR-Residual-v2, every tier, 5 seeds each.

    python baselines/rl_study.py --leaderboard leaderboards [--version v2] [--work runs/rl-v2] [--workers 2]
                                 [--scale 1.0] [--seeds 0 1 2 3 4]

One study piece is one (algorithm, env id, tier): its agents train on the tier's training pool
(budgets in ``ffsr_gym/hyperparams``, times ``--scale``), each is scored on the test pool, and
the piece becomes one leaderboard entry (``ffsr_gym.optim.rl.train_and_evaluate``; learning curves
on the validation pool). Pieces
run in parallel on ``--workers`` processes. A piece whose entry exists is skipped, and inside a
piece a seed whose folder in ``--work`` holds its model and scores is loaded, not retrained, so a
killed study resumes where it stopped. The learning curve of every seed has 5 points after the
untrained one. To rerun it bigger: ``--scale 10`` trains ten times as long (write to a new
``--leaderboard`` root or delete the old entries first).
"""

import argparse
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

from tqdm.auto import tqdm

from ffsr_gym.model.spec import spec_for_version
from ffsr_gym.optim.rl import load_hyperparams
from ffsr_gym.optim.rl import train_and_evaluate
from ffsr_gym.tasks.tiers import ALL_TIERS

ALGOS = ("sac", "ppo")


def entry_name(algo: str, env_id: str, tier: str) -> str:
    return f"{algo}_{'residual_' if 'Residual' in env_id else ''}{tier}"


def run_piece(algo: str, env_id: str, tier: str, seeds: list[int], scale: float, work: str, root: str,
              version: str) -> str:
    steps = int(round(load_hyperparams(algo, env_id)["n_timesteps"] * scale))
    report = train_and_evaluate(algo, env_id, task=tier, seeds=seeds, out=work, timesteps=steps,
                                   curve_every=max(1, steps // 5), progress=False)
    path = report.save(Path(root) / version / tier)
    return f"{report.name}: IQM {report.metrics['score_iqm']:.3f}, success {report.metrics['success_rate']:.2f} -> {path}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", default="v2", help="a pool benchmark version (default: v2)")
    parser.add_argument("--leaderboard", required=True, help="leaderboard root; entries go to <root>/<version>/<tier>/")
    parser.add_argument("--work", default=None, help="models, training records, scores (default: runs/rl-<version>)")
    parser.add_argument("--workers", type=int, default=2, help="pieces trained at once (default: 2)")
    parser.add_argument("--scale", type=float, default=1.0, help="multiplies every training budget (default: 1)")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4], help="training seeds (default: 0-4)")
    parser.add_argument("--algos", nargs="+", default=list(ALGOS), choices=ALGOS, help="algorithms (default: sac ppo)")
    parser.add_argument("--tiers", nargs="+", default=list(ALL_TIERS), choices=ALL_TIERS, help="tiers (default: all)")
    args = parser.parse_args()
    version, work = args.version, args.work or f"runs/rl-{args.version}"
    env_ids = spec_for_version(version).env_ids[::-1]  # residual first: the longer trainings start first
    pieces = [(algo, env_id, tier) for algo in args.algos for env_id in env_ids for tier in args.tiers
              if not (Path(args.leaderboard) / version / tier / f"{entry_name(algo, env_id, tier)}.json").exists()]
    start = time.perf_counter()
    with ProcessPoolExecutor(args.workers) as pool:
        futures = [pool.submit(run_piece, *piece, args.seeds, args.scale, work, args.leaderboard, version)
                   for piece in pieces]
        for future in tqdm(as_completed(futures), total=len(futures), desc="RL study pieces"):
            tqdm.write(future.result())
    print(f"{len(pieces)} pieces in {time.perf_counter() - start:.0f} s")


if __name__ == "__main__":
    main()
