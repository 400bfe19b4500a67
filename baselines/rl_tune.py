"""Hyperparameter search for an RL baseline on one tier's training and validation pools (Optuna).

    python baselines/rl_tune.py --algo ppo --env-id FFSR-v2 [--tier medium] [--trials 24]
                                [--timesteps 200000] [--points 10] [--work runs/tune]

Runs trials until the study holds ``--trials`` finished (complete or pruned) ones, then writes
``ffsr_gym/hyperparams/search/<algo>_<env id>.json``: the search space, every trial, the best
trial's hyperparameters and what the search cost (``ffsr_gym.optim.tuning``). The study is an
SQLite file in ``--work``, so a killed search resumes with the trials it finished. The shipped
``<algo>.yml`` takes the best trial's values (a test checks that they agree).
"""

import argparse
import shlex
import sys
from pathlib import Path

from tqdm.auto import tqdm

from ffsr_gym.optim.tuning import objective, optuna_module, summary
from ffsr_gym.provenance import write_json_atomic

SEARCH = Path(__file__).resolve().parents[1] / "ffsr_gym" / "hyperparams" / "search"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--algo", required=True, choices=["ppo", "sac"])
    parser.add_argument("--env-id", required=True, choices=["FFSR-v2", "FFSR-Residual-v2"])
    parser.add_argument("--tier", default="medium", help="the tier whose train/validation pools are searched on")
    parser.add_argument("--trials", type=int, default=24, help="finished trials wanted (default: 24)")
    parser.add_argument("--timesteps", type=int, default=200_000, help="env steps per trial (default: 200000)")
    parser.add_argument("--points", type=int, default=10, help="validation scorings per trial (default: 10)")
    parser.add_argument("--work", default="studies/tune",
                        help="study database (kept in git) and trial runs (default: studies/tune)")
    parser.add_argument("--out", default=None, help="the record (default: ffsr_gym/hyperparams/search/<algo>_<env id>.json)")
    args = parser.parse_args()
    optuna = optuna_module()
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    name = f"{args.algo}_{args.env_id}_{args.tier}"
    work = Path(args.work) / name
    work.mkdir(parents=True, exist_ok=True)
    study = optuna.create_study(study_name=name, storage=f"sqlite:///{work / 'study.db'}", load_if_exists=True,
                                direction="maximize", sampler=optuna.samplers.TPESampler(seed=0),
                                pruner=optuna.pruners.MedianPruner(n_startup_trials=5, n_warmup_steps=1))
    finished = (optuna.trial.TrialState.COMPLETE, optuna.trial.TrialState.PRUNED)
    done = sum(t.state in finished for t in study.trials)
    run = objective(args.algo, args.env_id, args.tier, args.timesteps, args.points, work)
    with tqdm(total=args.trials, initial=min(done, args.trials), desc=f"tune {name}", unit="trial") as bar:
        while done < args.trials:
            study.optimize(run, n_trials=1)
            done = sum(t.state in finished for t in study.trials)
            bar.update(1)
            bar.set_postfix(best=f"{study.best_value:.4f}")
    record = summary(study, algo=args.algo, env_id=args.env_id, tier=args.tier, timesteps=args.timesteps,
                     points=args.points, command=shlex.join(["python", *sys.argv]))
    path = Path(args.out) if args.out else SEARCH / f"{args.algo}_{args.env_id}.json"
    write_json_atomic(path, record)
    print(f"best trial {record['best']['number']}: {record['best']['value']:.4f} {record['best']['params']}")
    print(f"cost: {record['cost']}; wrote {path}")


if __name__ == "__main__":
    main()
