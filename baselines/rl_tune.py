"""Hyperparameter search for an RL baseline on one tier's training and validation pools (Optuna).

    python baselines/rl_tune.py --algo ppo --env-id FFSR-v2 [--tier medium] [--trials 24]
                                [--timesteps 200000] [--points 10] [--work studies/tune]
                                [--batch 1] [--scheduler ADDRESS]

Runs trials until the study holds ``--trials`` finished (complete or pruned) ones, then writes
``ffsr_gym/hyperparams/search/<algo>_<env id>.json``: the search space, every trial, the best
trial's hyperparameters and what the search cost (``ffsr_gym_lab.studies.tuning``). The study is an
SQLite file in ``--work``, so a killed search resumes with the trials it finished. The shipped
``<algo>.yml`` takes the best trial's values (a test checks that they agree).

``--batch K`` asks K trials at a time and ``--scheduler`` trains them on a Dask cluster (docs/cluster.md); this
process keeps the study and prunes nothing itself (``ffsr_gym_lab.studies.tune_loop``). The result depends on K, never on
the cluster: ``--batch 1`` is the sequential search, and the same K gives the same trials here and on any cluster.
"""

import argparse
import shlex
import sys
from functools import partial
from pathlib import Path

from ffsr_gym.bench.options import add_scheduler_option, positive_int
from ffsr_gym.cluster import study_executor
from ffsr_gym.provenance import write_json_atomic
from ffsr_gym_lab.studies.tune_loop import default_space, search, train_trial
from ffsr_gym_lab.studies.tuning import make_pruner, make_sampler, optuna_module, summary

SEARCH = Path(__file__).resolve().parents[1] / "ffsr_gym" / "hyperparams" / "search"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--algo", required=True, choices=["ppo", "sac"])
    parser.add_argument("--env-id", required=True, choices=["FFSR-v2", "FFSR-Residual-v2"])
    parser.add_argument("--tier", default="medium", help="the tier whose train/validation pools are searched on")
    parser.add_argument("--trials", type=positive_int, default=24, help="finished trials wanted (default: 24)")
    parser.add_argument("--timesteps", type=positive_int, default=200_000,
                        help="env steps per trial (default: 200000)")
    parser.add_argument("--points", type=positive_int, default=10, help="validation scorings per trial (default: 10)")
    parser.add_argument("--batch", type=positive_int, default=1,
                        help="trials asked at a time: 1 is the sequential search; K > 1 lets K trials train at once "
                             "and is another search, the same on any cluster (default: 1)")
    parser.add_argument("--work", default="studies/tune",
                        help="study database (kept in git) and trial runs (default: studies/tune)")
    parser.add_argument("--out", default=None, help="the record (default: ffsr_gym/hyperparams/search/<algo>_<env id>.json)")
    add_scheduler_option(parser, "trials (one piece each; with --batch > 1)")
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    args = parser.parse_args()
    optuna = optuna_module()
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    name = f"{args.algo}_{args.env_id}_{args.tier}"
    work = Path(args.work) / name
    work.mkdir(parents=True, exist_ok=True)
    study = optuna.create_study(study_name=name, storage=f"sqlite:///{work / 'study.db'}", load_if_exists=True,
                                direction="maximize", sampler=make_sampler(), pruner=make_pruner())
    piece = partial(train_trial, args.algo, args.env_id, args.tier, args.timesteps, args.points)
    with study_executor(args.scheduler) as (executor, _):
        search(study, piece, default_space(args.algo, args.env_id), trials=args.trials, batch=args.batch,
               executor=executor, work=work, progress=not args.no_progress)
    record = summary(study, algo=args.algo, env_id=args.env_id, tier=args.tier, timesteps=args.timesteps,
                     points=args.points, command=shlex.join(["python", *sys.argv]), batch=args.batch)
    path = Path(args.out) if args.out else SEARCH / f"{args.algo}_{args.env_id}.json"
    write_json_atomic(path, record)
    print(f"best trial {record['best']['number']}: {record['best']['value']:.4f} {record['best']['params']}")
    print(f"cost: {record['cost']}; wrote {path}")


if __name__ == "__main__":
    main()
