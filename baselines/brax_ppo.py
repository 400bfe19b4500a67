"""Brax's PPO trained end to end in JAX on a v2 tier (the JAX loop, ``ffsr_gym.jax``), scored by ``ffsr_gym.evaluate``
on the test pool like any other entry.

    python baselines/brax_ppo.py [--tier easy] [--seeds 0 1 2 3 4] [--timesteps 1000000] [--points 10]
                                 [--work studies/brax-ppo] [--leaderboard leaderboards]

Per training seed: Brax's ``ppo.train`` on ``FFSRBraxEnv(tier, "train")`` (residual actions), each of ``--points``
checkpoints scored on the whole validation pool by the JAX loop (deterministic actions); the last and the best
checkpoint on validation are then scored on the test pool through ``FFSR-Residual-v2`` (the kernel), which records
their applied actions for ``leaderboard verify``. A seed's records (training curve, wall time, both evaluations) go
to ``--work/<tier>_seed<s>/`` as soon as they exist, so a killed study resumes seed by seed; its parameters
(``*.msgpack``) stay out of git. With every seed scored, one entry per checkpoint is written under
``--leaderboard``, its compute column the seeds' summed training time.

Hyperparameters follow the tuned SB3 PPO of ``FFSR-Residual-v2`` where Brax has the same knob (16 copies, 4,096
steps per update in minibatches of 256, 10 epochs, learning rate, γ, λ, clip range, no entropy bonus, 256-256
networks); Brax's policy is its own (tanh-squashed normal, observations normalised).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from ffsr_gym.bench.entry import EvalReport
from ffsr_gym.bench.evaluation import evaluate
from ffsr_gym.jax.brax_env import FFSRBraxEnv
from ffsr_gym.jax.physics import jax, jnp
from ffsr_gym.jax.replay import play_policy, pool_tasks
from ffsr_gym.model.spec import spec_for_version
from ffsr_gym.optim.rl_study import merged_traces
from ffsr_gym.provenance import provenance, write_json_atomic
from ffsr_gym.scoring.rules import score_rule

ENV_ID = "FFSR-Residual-v2"
HYPERPARAMS = {"num_envs": 16, "unroll_length": 16, "batch_size": 16, "num_minibatches": 16,
               "num_updates_per_batch": 10, "learning_rate": 7.458774994615878e-4, "discounting": 0.98,
               "gae_lambda": 0.98, "clipping_epsilon": 0.1, "entropy_cost": 0.0, "normalize_observations": True,
               "reward_scaling": 1.0, "episode_length": 200}
NETWORK = {"policy_hidden_layer_sizes": (256, 256), "value_hidden_layer_sizes": (256, 256)}


class JaxPolicy:
    """A Brax checkpoint as the callable ``evaluate`` plays: float32 observation in, action in [-1, 1] out."""

    def __init__(self, make_policy, params) -> None:
        self.params, self._act = params, jax.jit(lambda p, obs: make_policy(p, deterministic=True)(
            obs, jax.random.PRNGKey(0))[0])

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        return np.asarray(self._act(self.params, jnp.asarray(obs)), dtype=np.float32)


def train_seed(tier: str, seed: int, timesteps: int, points: int, folder: Path) -> tuple[dict, dict]:
    """Train one seed; returns its record and ``{checkpoint: policy}`` (last, best on validation)."""
    from brax.io import model as brax_model
    from brax.training.agents.ppo import networks as ppo_networks
    from brax.training.agents.ppo import train as ppo

    model, rules, validation, _ = pool_tasks(tier, "validation")
    curve, kept, act = [], {}, {}

    def on_checkpoint(steps, make_policy, params):
        if "fn" not in act:  # one object: the validation play compiles once
            act["fn"] = lambda p, obs: make_policy(p, deterministic=True)(obs, jax.random.PRNGKey(0))[0]
        mean = float(play_policy(model, rules, validation, params, act["fn"]).mean())
        curve.append({"steps": int(steps), "validation_mean": mean})
        kept["last"] = (make_policy, params)
        if mean >= max(point["validation_mean"] for point in curve):
            kept["best_on_validation"] = (make_policy, params)

    start = time.perf_counter()
    network = lambda *a, **k: ppo_networks.make_ppo_networks(*a, **{**k, **NETWORK})  # noqa: E731
    ppo.train(environment=FFSRBraxEnv(tier, "train"), num_timesteps=timesteps, num_evals=points + 1, seed=seed,
              network_factory=network, policy_params_fn=on_checkpoint, run_evals=False, **HYPERPARAMS)
    wall = time.perf_counter() - start
    best = max(curve, key=lambda point: point["validation_mean"])
    for name, (_, params) in kept.items():
        brax_model.save_params(str(folder / f"{name}.msgpack"), params)
    record = {"seed": seed, "timesteps": timesteps, "trained_steps": curve[-1]["steps"], "wall_time_s": wall,
              "curve": curve, "best_on_validation": best, "hyperparams": HYPERPARAMS, "network": NETWORK}
    return record, {name: JaxPolicy(*pair) for name, pair in kept.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--tier", default="easy", choices=["easy", "medium", "hard", "debris"])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4])
    parser.add_argument("--timesteps", type=int, default=1_000_000)
    parser.add_argument("--points", type=int, default=10, help="validation scorings after step 0 (default: 10)")
    parser.add_argument("--work", default="studies/brax-ppo", help="per-seed records (kept in git)")
    parser.add_argument("--leaderboard", default=None, help="write the entries under this root (default: do not)")
    args = parser.parse_args()
    spec, runs, rows = spec_for_version("v2"), [], {"last": [], "best_on_validation": []}
    traces: dict[str, list] = {"last": [], "best_on_validation": []}
    library = f"brax {__import__('brax').__version__}, jax {jax.__version__}"
    for seed in args.seeds:
        folder = Path(args.work) / f"{args.tier}_seed{seed}"
        files = {c: folder / f"evaluation{'' if c == 'last' else '_' + c}.json" for c in rows}
        if not all(f.is_file() for f in files.values()) or not (folder / "train_record.json").is_file():
            folder.mkdir(parents=True, exist_ok=True)
            record, policies = train_seed(args.tier, seed, args.timesteps, args.points, folder)
            for checkpoint, policy in policies.items():
                report = evaluate(policy, ENV_ID, task=args.tier, training_pool=f"{args.tier}/train",
                                  policy_library=library)
                write_json_atomic(files[checkpoint], report.to_json())
            write_json_atomic(folder / "train_record.json", record)
        record = json.loads((folder / "train_record.json").read_text())
        runs.append(record)
        for checkpoint, path in files.items():
            scored = json.loads(path.read_text())
            rows[checkpoint] += [row | {"train_seed": seed} for row in scored["episodes"]]
            traces[checkpoint].append(scored["extra"].get("trace"))
    compute = {"env_steps": sum(r["trained_steps"] for r in runs), "wall_time_s": sum(r["wall_time_s"] for r in runs),
               "hardware": "this machine's CPU cores, one seed at a time"}
    for checkpoint, episodes in rows.items():
        how = {"last": "last checkpoint", "best_on_validation": "checkpoint best on the validation pool"}[checkpoint]
        extra = {"method": f"PPO (Brax, trained in JAX on ffsr_gym.jax), {len(runs)} training seeds, "
                           f"{args.timesteps:,} env steps each, {how}", "training_seeds": args.seeds,
                 "checkpoint": checkpoint, "runs": runs, "compute": compute, "timesteps_per_seed": args.timesteps,
                 "training_pool": f"{args.tier}/train", "evaluation_pool": f"{args.tier}/test",
                 "selection_pool": f"{args.tier}/validation"}
        if all(traces[checkpoint]):  # ``leaderboard verify`` replays every seed's episodes from their actions
            extra["trace"] = merged_traces(traces[checkpoint])
        name = f"brax_ppo_{args.tier}" + ("" if checkpoint == "last" else "_valbest")
        report = EvalReport(ENV_ID, {"task": args.tier, "split": "test"}, score_rule(spec).aggregate(episodes),
                            episodes, provenance(seeds=args.seeds, command=" ".join(["python", *sys.argv])),
                            name=name, extra=extra, score_rule=spec.score.text)
        print(name, report.metrics)
        if args.leaderboard:
            print("wrote", report.save(Path(args.leaderboard) / "v2" / args.tier))


if __name__ == "__main__":
    main()
