"""Sub-commands of a user's policy: ``evaluate`` (an entry), ``render`` (a GIF) and ``train`` (stable-baselines3
agents, scored as entries)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from ffsr_gym.bench.options import add_scheduler_option, natural, positive_float, positive_int
from ffsr_gym.cli.choices import algorithm_names
from ffsr_gym.versions.registry import all_splits, all_task_names, registered_ids


def add_policy_commands(sub: Any) -> None:
    """Sub-commands evaluate, render and train."""
    ev = sub.add_parser("evaluate", help="score a policy with ffsr_gym.evaluate and optionally write a leaderboard entry")
    _add_policy_arguments(ev, env_id=None, policy=None, task="easy", split="test", split_help="pool scored")
    ev.add_argument("--training-pool", default=None, help="pool versions: what the policy was trained or tuned on (recorded)")
    ev.add_argument("--seeds", type=natural, nargs="+", default=None,
                    help="reset seeds: of a custom --scenario (default: 0) or of a version scored on seeds "
                         "(default: its public evaluation seeds)")
    ev.add_argument("--compute", default=None, metavar="ENV_STEPS,WALL_TIME_S",
                    help="what training the policy cost, recorded for the compute column (default: none)")
    ev.add_argument("--name", default="submission", help="entry name (default: submission)")
    ev.add_argument("--policy-library", default=None, metavar="TEXT",
                    help="the library that made the policy, e.g. 'tianshou 2.0.1', recorded in the entry's provenance "
                         "(default: the package of the policy object's module)")
    ev.add_argument("--workers", type=positive_int, default=1,
                    help="pool versions: score the pool on this many processes; the same entry as with 1 (default: 1)")
    add_scheduler_option(ev, "pool's episodes (instead of --workers); the same entry")
    ev.add_argument("--leaderboard", default=None,
                    help="write the entry under this leaderboard root: <root>/<version>/<tier>/ (a custom --scenario: "
                         "<root>/<version>/custom/, unranked) (default: do not write)")
    ev.add_argument("--force", action="store_true", help="replace an entry of the same name (default: refuse)")
    ev.add_argument("--allow-dirty", action="store_true", default=None,
                    help="save into a leaderboard table from a checkout with uncommitted code changes "
                         "(default: refuse, unless FFSR_GYM_ALLOW_DIRTY=1)")
    ev.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    ev.set_defaults(func=_evaluate)
    rd = sub.add_parser("render", help="an episode of a policy as an animated GIF")
    _add_policy_arguments(rd, env_id="FFSR-v2", policy="reference", task="easy", split="train", split_help="pool of a tier")
    rd.add_argument("--seed", type=natural, default=0, help="reset seed: picks a tier's task (default: 0)")
    rd.add_argument("--task-index", type=natural, default=None,
                    help="play this task of the tier's pool instead of the one the seed picks (default: none)")
    rd.add_argument("--every", type=positive_int, default=2, help="one frame every N decisions of 0.1 s (default: 2)")
    rd.add_argument("--speed", type=positive_float, default=2.0, help="playback speed over real time (default: 2)")
    rd.add_argument("--out", default="runs/episode.gif", help="GIF file (default: runs/episode.gif)")
    rd.set_defaults(func=_render)
    tr = sub.add_parser("train", help="train stable-baselines3 agents and score them with ffsr_gym.evaluate")
    tr.add_argument("--algo", required=True, choices=algorithm_names(),
                    help="a stable-baselines3 algorithm with a shipped hyperparameter file")
    tr.add_argument("--env-id", default="FFSR-v0", choices=registered_ids(), help="environment id (default: FFSR-v0)")
    tr.add_argument("--scenario", default="paper",
                    help="versions scored on seeds: scenario name or TOML path (default: paper)")
    tr.add_argument("--task", default="easy", choices=all_task_names(),
                    help="versions with tiers: the tier; trains on its training pool, scores its test pool (default: easy)")
    tr.add_argument("--curve-every", type=positive_int, default=5000,
                    help="versions with tiers: env steps between scorings on the validation pool (the learning curve "
                         "and the checkpoint selection; default: 5000)")
    tr.add_argument("--seeds", type=natural, nargs="+", default=[0, 1, 2, 3, 4], help="training seeds (default: 0 1 2 3 4)")
    tr.add_argument("--timesteps", type=positive_int, default=None,
                    help="env steps per seed (default: n_timesteps of the hyperparameter file)")
    tr.add_argument("--n-envs", type=positive_int, default=None,
                    help="environment copies stepped together (default: n_envs of the hyperparameter file)")
    tr.add_argument("--vec-env", default="batched", choices=["batched", "single"],
                    help="batched: all copies in one batched-kernel env (SB3 VecEnv adapter); single: SB3's make_vec_env "
                         "over single envs; the same episodes either way (default: batched)")
    tr.add_argument("--hyperparams", default=None, help="folder with <algo>.yml (default: the shipped ffsr_gym/hyperparams)")
    tr.add_argument("--out", default="runs/rl", help="folder of the models and records (default: runs/rl)")
    tr.add_argument("--leaderboard", default=None, help="write the entry under this folder")
    tr.add_argument("--force", action="store_true", help="replace an entry of the same name (default: refuse)")
    tr.add_argument("--allow-dirty", action="store_true", default=None,
                    help="save into a leaderboard table from a checkout with uncommitted code changes "
                         "(default: refuse, unless FFSR_GYM_ALLOW_DIRTY=1)")
    tr.add_argument("--no-progress", action="store_true")
    tr.set_defaults(func=_train)

def _load_policy(spec: str, algo: str | None, trust: bool, env: Any = None):
    """``--policy``; ``reference`` needs the env (its action mode and task defaults)."""
    from ffsr_gym.bench.policies import load_policy

    if spec == "reference":  # the reference planner: the zero residual, or the task's own (m, T_c)
        planner, command = env.unwrapped.family.planner, env.unwrapped.benchmark_spec.actions.command
        if env.unwrapped.residual:  # capture v1: going straight in (a = +1)
            return (0.0,) * 12 + ((1.0,) if command else ())
        return (planner.m, planner.T_c_s) + ((0.0,) if command else ())
    return load_policy(spec, algo, trust=trust)


def _add_policy_arguments(parser: argparse.ArgumentParser, *, env_id: str | None, policy: str | None, task: str,
                          split: str, split_help: str) -> None:
    """The options that name an environment and a policy (``evaluate``, ``render``); None: required."""
    parser.add_argument("--env-id", required=env_id is None, default=env_id, choices=registered_ids(),
                        help="environment id" + (f" (default: {env_id})" if env_id else ""))
    parser.add_argument("--policy", required=policy is None, default=policy,
                        help="'reference' (the reference planner: the zero residual, or the task's (m, T_c); capture "
                             "v1: going straight in), 'm,T_c' (fixed parameters, e.g. 0.3,4), 'm,T_c,go_s' (capture "
                             "v1: the insertion from go_s on), an SB3 .zip (with --algo), module:callable or "
                             "path/to/file.py:callable" + (f" (default: {policy})" if policy else ""))
    parser.add_argument("--algo", default=None, choices=algorithm_names(), help="the algorithm of an SB3 .zip")
    parser.add_argument("--task", default=None, choices=all_task_names(),
                        help=f"task or tier of the versions with tiers (default: {task})")
    parser.add_argument("--split", default=None, choices=all_splits(),
                        help=f"versions with tiers: {split_help} (default: {split})")
    parser.set_defaults(default_task=task, default_split=split)
    parser.add_argument("--scenario", default=None,
                        help="scenario name or TOML path; v0: the scenario (default: paper); versions with tiers: a "
                             "custom task played instead of --task (unranked; default: none)")
    parser.add_argument("--trust-model", action="store_true",
                        help="load the SB3 .zip of --policy (loading unpickles it: it can run any code its maker "
                             "chose)")


def _env_kwargs(args: argparse.Namespace) -> dict:
    """``gymnasium.make`` arguments of ``--env-id``: its version's task keyword (and split).

    Raises:
        InvalidInputError: ``--task`` or ``--split`` given with ``--scenario`` (they would be ignored).
    """
    from ffsr_gym.exceptions import InvalidInputError
    from ffsr_gym.versions.registry import spec_of

    spec = spec_of(args.env_id)
    if spec.tasks.splits:
        if args.scenario is not None:  # a custom task: no tier, no split
            given = [f"--{name} {value}" for name, value in (("task", args.task), ("split", args.split))
                     if value is not None]
            if given:
                raise InvalidInputError(f"{' and '.join(given)} with --scenario: a custom task has no tier or pool; "
                                        "allowed: --scenario alone, or --task/--split alone")
            return {spec.tasks.keyword: args.scenario}
        return {spec.tasks.keyword: args.task or args.default_task, "split": args.split or args.default_split}
    return {spec.tasks.keyword: args.scenario or "paper"}


def _compute(text: str | None) -> dict | None:
    """``--compute ENV_STEPS,WALL_TIME_S`` as :func:`ffsr_gym.evaluate`'s ``compute``."""
    if text is None:
        return None
    from ffsr_gym.bench.entry import check_compute
    from ffsr_gym.exceptions import InvalidInputError

    parts = text.split(",")
    try:
        if len(parts) != 2:
            raise ValueError(text)
        steps, seconds = int(parts[0]), float(parts[1])
    except ValueError:
        raise InvalidInputError(f"--compute {text!r}; allowed: ENV_STEPS,WALL_TIME_S, e.g. 1000000,5400") from None
    return check_compute({"env_steps": steps, "wall_time_s": seconds})


def _evaluate(args: argparse.Namespace) -> None:
    from ffsr_gym.bench.evaluation import evaluate
    from ffsr_gym.bench.options import free_entry
    from ffsr_gym.cluster import study_executor
    from ffsr_gym.exceptions import InvalidInputError
    from ffsr_gym.versions.registry import spec_of

    spec = spec_of(args.env_id)
    pooled = spec.evaluation.protocol == "pool"
    custom = pooled and args.scenario is not None
    if args.workers > 1 and (not pooled or custom):
        raise InvalidInputError(f"--workers {args.workers}; more than 1 only for a tier's pool")
    if args.scheduler is not None and (not pooled or custom):
        raise InvalidInputError(f"--scheduler {args.scheduler}; only for a tier's pool")
    if args.seeds is not None and pooled and not custom:
        raise InvalidInputError("--seeds: a tier's pool is scored one episode per task; --seeds applies to a custom "
                                "--scenario or to a version scored on seeds")
    folder = Path(args.leaderboard or ".") / (spec.version + "/custom" if custom
                                              else spec.folder(args.env_id, (args.task or args.default_task) if pooled
                                                               else ""))
    if args.leaderboard:
        free_entry(folder, args.name, force=args.force, allow_dirty=args.allow_dirty)  # before any work
    compute = _compute(args.compute)
    if args.policy == "reference":
        import gymnasium

        with gymnasium.make(args.env_id, **_env_kwargs(args)) as env:
            policy = _load_policy(args.policy, args.algo, args.trust_model, env)
    else:
        policy = _load_policy(args.policy, args.algo, args.trust_model)
    with study_executor(args.scheduler, args.workers) as (executor, _):
        report = evaluate(policy, args.env_id, name=args.name, progress=not args.no_progress, compute=compute,
                          seeds=args.seeds, policy_library=args.policy_library,
                          **(_env_kwargs(args) | {"training_pool": args.training_pool, "executor": executor} if pooled
                             else {"env_kwargs": _env_kwargs(args)}))
    if not isinstance(policy, tuple):  # what `ffsr-gym leaderboard verify --run-code` runs (with the file's hash)
        from ffsr_gym.bench.policies import policy_record

        report.extra["policy"] = policy_record(args.policy, args.algo)
    print(f"{report.name}: {report.metrics}")
    if args.leaderboard:
        print("wrote", report.save(folder, overwrite=args.force, allow_dirty=args.allow_dirty))


def _render(args: argparse.Namespace) -> None:
    import gymnasium

    from ffsr_gym.bench.entry import stepper
    from ffsr_gym.report.episode_gif import check_gif_path, frame_interval_ms, record_episode, write_gif

    out = check_gif_path(args.out)  # before the episode runs
    env = gymnasium.make(args.env_id, render_mode="rgb_array", **_env_kwargs(args))
    interval_ms = frame_interval_ms(args.every, env.unwrapped.family.env.decision_interval_s, args.speed)
    policy = _load_policy(args.policy, args.algo, args.trust_model, env)
    options = None if args.task_index is None else {"task_index": args.task_index}
    frames, decisions, info = record_episode(env, stepper(policy, env), seed=args.seed, every=args.every,
                                             options=options)
    from ffsr_gym.environments.render import ending

    end, played = ending(env.unwrapped.engine), env.unwrapped.scenario.name
    env.close()
    write_gif(frames, out, interval_ms)
    outcome = {k: info.get(k) for k in ("score", "success", "failure") if k in info}
    print(f"wrote {out}: task {played}, {len(frames)} frames, {decisions} decisions, {outcome}")
    print(f"last frame: {end.text}")


def _train(args: argparse.Namespace) -> None:
    from ffsr_gym.bench.entry import entry_name
    from ffsr_gym.bench.options import free_entry, unique_seeds
    from ffsr_gym.bench.verify import CHECKPOINTS
    from ffsr_gym.optim.rl_study import train_and_evaluate
    from ffsr_gym.versions.registry import spec_of

    spec = spec_of(args.env_id)
    task = args.task if spec.evaluation.protocol == "pool" else args.scenario
    folder = Path(args.leaderboard or ".") / spec.folder(args.env_id, task)
    unique_seeds(args.seeds)
    checkpoints = list(CHECKPOINTS) if spec.evaluation.protocol == "pool" else ["last"]
    if args.leaderboard:  # before any training: a committed entry is never replaced by accident
        for checkpoint in checkpoints:
            free_entry(folder, entry_name(args.algo, spec, args.env_id, task) + CHECKPOINTS[checkpoint],
                       force=args.force, allow_dirty=args.allow_dirty)
    reports = train_and_evaluate(args.algo, args.env_id, task=task, seeds=args.seeds, out=args.out,
                                 timesteps=args.timesteps, hyperparams=args.hyperparams, curve_every=args.curve_every,
                                 progress=not args.no_progress, n_envs=args.n_envs, vec_env=args.vec_env)
    for report in reports.values():
        print(f"{report.name}: {report.metrics}")
        if args.leaderboard:
            print("wrote", report.save(folder, overwrite=args.force, allow_dirty=args.allow_dirty))
