"""The ``ffsr-gym`` command line (:data:`DESCRIPTION` is what ``ffsr-gym --help`` says)."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from typing import Any

from ffsr_gym.bench.options import natural, positive_float, positive_int, shard
from ffsr_gym.exceptions import FFSRError
from ffsr_gym.model.spec import all_splits, all_task_names, registered_ids

DESCRIPTION = ("Dual-arm free-floating space robot: reproduce the paper's predefined-time planner, play and score "
               "the Gymnasium benchmark ({ids}), train baselines, build task pools and render leaderboards.")


def _info(args: argparse.Namespace) -> None:
    from ffsr_gym.model.scenario import load_scenario
    from ffsr_gym.report.scenario_info import initial_state_rows

    rows = initial_state_rows(load_scenario(args.scenario))
    width = max(len(k) for k, _ in rows)
    for key, value in rows:
        print(f"{key:<{width}}  {value}")


def _list(args: argparse.Namespace) -> None:
    from ffsr_gym.report.scenario_info import registry_lines

    print("\n".join(registry_lines()))


def build_targets() -> list[str]:
    """What ``tasks build --tier`` builds: ``base`` (easy, medium and hard together) or one perturbed tier."""
    from ffsr_gym.tasks.perturbation import PERTURBED_TIERS

    return ["base", *PERTURBED_TIERS]


def all_task_tiers() -> list[str]:
    """Every tier of a pool version: easy, medium, hard and the perturbed ones."""
    from ffsr_gym.tasks.tiers import ALL_TIERS

    return list(ALL_TIERS)


def tier_versions() -> list[str]:
    """The benchmark versions with task tiers (a rule file), newest last."""
    from ffsr_gym.model.benchmark import VERSIONS

    return list(VERSIONS)


def algorithm_names() -> list[str]:
    """The algorithms with a shipped hyperparameter file."""
    from ffsr_gym.optim.rl import algorithms

    return sorted(algorithms())


def _reproduce(args: argparse.Namespace) -> None:
    from ffsr_gym.report.reproduction import reproduce

    command = " ".join(["ffsr-gym", *args.argv])
    result = reproduce(args.out, duration_s=args.duration, progress=not args.no_progress, command=command)
    width = max(len(c["claim"]) for c in result["claims"])
    for claim in result["claims"]:
        print(f"{'holds' if claim['holds'] else 'FAILS'}  {claim['claim']:<{width}}  ours: {claim['ours']}  paper: {claim['paper']}")
    print(f"wrote figures, reproduction.json and reproduction.md to {args.out}")
    if args.readme:
        from ffsr_gym.provenance import write_text_atomic
        from ffsr_gym.report.reproduction import splice_readme

        readme = Path(args.readme)
        write_text_atomic(readme, splice_readme(readme.read_text(encoding="utf-8"), result))
        print(f"updated the generated tables in {readme}")


def _ga(args: argparse.Namespace) -> None:
    from ffsr_gym.optim.ga import GAConfig
    from ffsr_gym.optim.ga_study import run_study

    config = GAConfig(population=args.population, generations=args.generations, seed=args.seed,
                      selection=args.selection, scenario=args.scenario)
    results = run_study(args.out, modes=tuple(args.modes), config=config, executor=args.executor,
                        workers=args.workers, leaderboard=args.leaderboard, progress=not args.no_progress)
    for mode, summary in results.items():
        o = summary["optimum"]
        print(f"{mode}: m = {o['m']:.4f}, T_c = {o['T_c_s']:.3f} s, B = {o['score']} "
              f"(non-optimised: {summary['baseline_score']}); {summary['wall_time_s']:.0f} s")


def _train(args: argparse.Namespace) -> None:
    from ffsr_gym.bench.evaluation import spec_of
    from ffsr_gym.bench.options import free_entry, unique_seeds
    from ffsr_gym.optim.rl import CHECKPOINTS, entry_name, train_and_evaluate

    spec = spec_of(args.env_id)
    task = args.task if spec.evaluation.protocol == "pool" else args.scenario
    folder = Path(args.leaderboard or ".") / spec.folder(args.env_id, task)
    unique_seeds(args.seeds)
    checkpoints = list(CHECKPOINTS) if spec.evaluation.protocol == "pool" else ["last"]
    if args.leaderboard:  # before any training: a committed entry is never replaced by accident
        for checkpoint in checkpoints:
            free_entry(folder, entry_name(args.algo, spec, args.env_id, task) + CHECKPOINTS[checkpoint], force=args.force)
    reports = train_and_evaluate(args.algo, args.env_id, task=task, seeds=args.seeds, out=args.out,
                                 timesteps=args.timesteps, hyperparams=args.hyperparams, curve_every=args.curve_every,
                                 progress=not args.no_progress, n_envs=args.n_envs, vec_env=args.vec_env)
    for report in reports.values():
        print(f"{report.name}: {report.metrics}")
        if args.leaderboard:
            print("wrote", report.save(folder, overwrite=args.force))


def _leaderboard(args: argparse.Namespace) -> int:
    from ffsr_gym.bench.leaderboard import splice_summary, write_readme
    from ffsr_gym.exceptions import InvalidInputError
    from ffsr_gym.provenance import write_text_atomic

    readme = Path(args.readme) if args.readme else None
    if readme is not None and not readme.is_file():
        raise InvalidInputError(f"--readme {args.readme!r} is not a file")
    if args.check:
        return _check_leaderboard(args.root, readme)
    print("updated" if write_readme(args.root) else "already up to date", f"{args.root}/README.md")
    if readme is not None:
        write_text_atomic(readme, splice_summary(readme.read_text(encoding="utf-8"), args.root))
        print("updated the leaderboard summary in", readme)
    return 0


def _check_leaderboard(root: str, readme: Path | None) -> int:
    """``leaderboard render --check``: 1 when an entry is refused, or a table, the aggregates or a figure is out of
    date."""
    from ffsr_gym.bench.leaderboard import check, load_entries, verified
    from ffsr_gym.model.spec import all_specs, ranked_spec
    from ffsr_gym.report.leaderboard_plots import stale_figures

    loaded = {version: load_entries(root, spec) for version, spec in all_specs().items()}  # read and verified once
    problems = check(root, readme, loaded)
    problems += [f"out of date: {line}; run ffsr-gym leaderboard update"
                 for line in stale_figures(root, verified(loaded[ranked_spec().version]))]
    for line in problems:
        print(line, file=sys.stderr)
    if not problems:
        print("leaderboard tables are up to date, and every entry verifies")
    return 1 if problems else 0


def _verified(root: str) -> dict:
    """The ranked version's entries that verify, by tier (what the figures draw)."""
    from ffsr_gym.bench.leaderboard import load_entries, verified
    from ffsr_gym.model.spec import ranked_spec

    return verified(load_entries(root, ranked_spec()))


def _leaderboard_plot(args: argparse.Namespace) -> None:
    from ffsr_gym.report.leaderboard_plots import draw_all

    for what, path in draw_all(args.root, _verified(args.root)).items():
        print(f"wrote {path}" if path else f"no data for the {what} figure under {args.root}: not drawn")


def _leaderboard_update(args: argparse.Namespace) -> int:
    """Everything a submission changes, in order: tables (and the README summary), aggregates, figures."""
    from ffsr_gym.exceptions import require

    require("rliable", "analysis", "rliable, pandas", "the aggregates across tiers need")  # before anything is written
    _leaderboard_aggregates(args)  # from the verified entries; the README summary shows them
    _leaderboard(argparse.Namespace(root=args.root, readme=args.readme, check=False))
    _leaderboard_plot(args)
    from ffsr_gym.bench.leaderboard import check

    problems = check(args.root, Path(args.readme) if args.readme else None)  # the figures were just drawn
    for line in problems:
        print(line, file=sys.stderr)
    print("updated; every entry verifies" if not problems else "updated, but the leaderboard cannot be published")
    return 1 if problems else 0


def _dataset(args: argparse.Namespace) -> None:
    from ffsr_gym.bench.dataset import write_dataset

    dataset = write_dataset(args.tier, args.env_id, split=args.split, root=args.root)
    print(f"wrote {dataset.spec.dataset_id}: {dataset.total_episodes} episodes, {dataset.total_steps} steps"
          + (f" under {args.root}" if args.root else " (MINARI_DATASETS_PATH or Minari's default folder)")
          + f"\n{dataset.storage.metadata['description']}")  # says how much of the pool it holds


def _leaderboard_aggregates(args: argparse.Namespace) -> None:
    from ffsr_gym.bench import aggregates
    from ffsr_gym.model.spec import ranked_spec
    from ffsr_gym.report.leaderboard_plots import plot_aggregates

    spec = ranked_spec()
    entries = _verified(args.root)
    path = aggregates.write(args.root, spec, entries)
    if path is None:
        print(f"nothing to aggregate under {args.root}: no tier whose test tasks all have best known scores, or no "
              f"{aggregates.REFERENCE.format(version=spec.rules.version)} entry")
        return
    print("wrote", path, "and", plot_aggregates(path))


def _leaderboard_pareto(args: argparse.Namespace) -> None:
    from ffsr_gym.bench.pareto import task_pareto
    from ffsr_gym.bench.policies import load_model
    from ffsr_gym.model.spec import ranked_spec
    from ffsr_gym.report.leaderboard_plots import PARETO_FILE

    out = Path(args.root) / ranked_spec().version / PARETO_FILE
    print("wrote", task_pareto(args.root, out, args.models, load_model=load_model, progress=not args.no_progress,
                               command=" ".join(["ffsr-gym", *args.argv])))


def _load_policy(spec: str, algo: str | None, trust: bool, env: Any = None):
    """``--policy``; ``reference`` needs the env (its action mode and task defaults)."""
    from ffsr_gym.bench.policies import load_policy

    if spec == "reference":  # the reference planner: the zero residual, or the task's own (m, T_c)
        planner = env.unwrapped.family.planner
        return (0.0,) * 12 if env.unwrapped.residual else (planner.m, planner.T_c_s)
    return load_policy(spec, algo, trust=trust)


def _add_policy_arguments(parser: argparse.ArgumentParser, *, env_id: str | None, policy: str | None, task: str,
                          split: str, split_help: str) -> None:
    """The options that name an environment and a policy (``evaluate``, ``render``); None: required."""
    parser.add_argument("--env-id", required=env_id is None, default=env_id, choices=registered_ids(),
                        help="environment id" + (f" (default: {env_id})" if env_id else ""))
    parser.add_argument("--policy", required=policy is None, default=policy,
                        help="'reference' (the reference planner: the zero residual, or the task's (m, T_c)), 'm,T_c' (fixed "
                             "parameters, e.g. 0.3,4), an SB3 .zip (with --algo), module:callable or "
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
    from ffsr_gym.bench.evaluation import spec_of
    from ffsr_gym.exceptions import InvalidInputError

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
    from concurrent.futures import ProcessPoolExecutor

    from ffsr_gym.bench.evaluation import evaluate, spec_of
    from ffsr_gym.bench.options import free_entry
    from ffsr_gym.exceptions import InvalidInputError

    spec = spec_of(args.env_id)
    pooled = spec.evaluation.protocol == "pool"
    custom = pooled and args.scenario is not None
    if args.workers > 1 and (not pooled or custom):
        raise InvalidInputError(f"--workers {args.workers}; more than 1 only for a tier's pool")
    if args.seeds is not None and pooled and not custom:
        raise InvalidInputError("--seeds: a tier's pool is scored one episode per task; --seeds applies to a custom "
                                "--scenario or to a version scored on seeds")
    folder = Path(args.leaderboard or ".") / (spec.version + "/custom" if custom
                                              else spec.folder(args.env_id, (args.task or args.default_task) if pooled
                                                               else ""))
    if args.leaderboard:
        free_entry(folder, args.name, force=args.force)  # before any work: a late error would lose the run
    compute = _compute(args.compute)
    if args.policy == "reference":
        import gymnasium

        with gymnasium.make(args.env_id, **_env_kwargs(args)) as env:
            policy = _load_policy(args.policy, args.algo, args.trust_model, env)
    else:
        policy = _load_policy(args.policy, args.algo, args.trust_model)
    executor = ProcessPoolExecutor(args.workers) if args.workers > 1 else None
    try:
        report = evaluate(policy, args.env_id, name=args.name, progress=not args.no_progress, compute=compute,
                          seeds=args.seeds, policy_library=args.policy_library,
                          **(_env_kwargs(args) | {"training_pool": args.training_pool, "executor": executor} if pooled
                             else {"env_kwargs": _env_kwargs(args)}))
    finally:
        if executor is not None:
            executor.shutdown()
    if not isinstance(policy, tuple):  # what `ffsr-gym leaderboard verify --run-code` runs (with the file's hash)
        from ffsr_gym.bench.policies import policy_record

        report.extra["policy"] = policy_record(args.policy, args.algo)
    print(f"{report.name}: {report.metrics}")
    if args.leaderboard:
        print("wrote", report.save(folder, overwrite=args.force))


def _verify(args: argparse.Namespace) -> int:
    from ffsr_gym.bench.replay import replay_entry

    verdict = replay_entry(args.entry, run_code=args.run_code)
    print(f"{args.entry}: {verdict.status}: {verdict.text}", file=sys.stdout if verdict.exit_code == 0 else sys.stderr)
    return verdict.exit_code


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
    from ffsr_gym.sim.episode_end import episode_end

    end, played = episode_end(env.unwrapped.rollout), env.unwrapped.scenario.name
    env.close()
    write_gif(frames, out, interval_ms)
    outcome = {k: info.get(k) for k in ("score", "success", "failure") if k in info}
    print(f"wrote {out}: task {played}, {len(frames)} frames, {decisions} decisions, {outcome}")
    print(f"last frame: {end.text}")


def _tasks(args: argparse.Namespace) -> None:
    from concurrent.futures import ProcessPoolExecutor

    from ffsr_gym.tasks.build import build, die_with_parent

    workers = args.workers
    executor = ProcessPoolExecutor(workers, initializer=die_with_parent) if workers > 1 else None
    try:
        version = args.version
        work = args.work or f"runs/tasks-{version}"
        data = build(work, version=version, target=version if args.tier == "base" else args.tier, out=args.out,
                     chunk=args.chunk, max_candidates=args.max_candidates, executor=executor, workers=workers,
                     progress=not args.no_progress)
    finally:
        if executor is not None:
            executor.shutdown()
    for split, summary in data["splits"].items():
        print(f"{split}: {summary['candidates']} candidates, tiers {summary['tier_counts']}, "
              f"rejected {summary['rejection_counts']}")


def _tasks_best_known(args: argparse.Namespace) -> None:
    import shlex

    import numpy as np

    from ffsr_gym.exceptions import InvalidInputError
    from ffsr_gym.optim import best_known_build as build
    from ffsr_gym.tasks.best_known import records

    work = Path(args.work)
    if args.doubled and args.shard is not None:
        raise InvalidInputError("--shard with --doubled; allowed: --shard only for the search (without --doubled)")
    if args.doubled:
        rng = np.random.default_rng(0)
        stored = [(t, s, r["index"]) for t in args.tiers for s in args.splits for r in records(t, s, args.version)]
        if not stored:
            raise InvalidInputError(f"--doubled: no stored best known score in {args.tiers} x {args.splits} yet")
        sample = [stored[k] for k in sorted(rng.choice(len(stored), min(args.doubled, len(stored)), replace=False))]
        summary = build.convergence(work, sample, version=args.version, progress=not args.no_progress,
                                    out=build.target_file(work, args.version, "test", shipped=args.write_shipped))
        print(f"doubled budget on {len(sample)} tasks: mean gap {summary['mean_gap']:.4f}, median relative gap "
              f"{summary['median_relative_gap']:.4f}, max {summary['max_relative_gap']:.4f}")
        return
    for tier in args.tiers:
        for split in args.splits:
            build.run(tier, split, work, version=args.version, shard=args.shard, progress=not args.no_progress)
    command = shlex.join(["ffsr-gym", "tasks", "best-known", "--tiers", *args.tiers, "--splits", *args.splits]
                         + ([] if args.shard is None else ["--shard", "/".join(map(str, args.shard))])
                         + (["--write-shipped"] if args.write_shipped else []))
    for path in build.assemble(work, version=args.version, command=command, splits=args.splits,
                               shipped=args.write_shipped):
        print("wrote", path)


def _tasks_tables(args: argparse.Namespace) -> None:
    from ffsr_gym.provenance import write_text_atomic
    from ffsr_gym.tasks.build import docs_tables, splice_docs_tables

    if args.docs is None:
        for name, table in docs_tables(args.version).items():
            print(f"{name}:\n{table}")
        return
    from ffsr_gym.environments.info import docs_section
    from ffsr_gym.provenance import splice_generated

    path = Path(args.docs)
    text = splice_docs_tables(path.read_text(encoding="utf-8"), args.version, where=str(path))
    text = splice_generated(text, "<!-- info-keys:begin -->", "<!-- info-keys:end -->", docs_section(), where=str(path))
    write_text_atomic(path, text)
    print("wrote the tier tables and the info keys into", path)


def _add_model_commands(sub: Any) -> None:
    """Sub-commands list, info, reproduce and ga."""
    listing = sub.add_parser("list", help="list the environment ids, each version's tasks and tiers, scenarios and robots")
    listing.set_defaults(func=_list)
    info = sub.add_parser("info", help="print the initial state of a scenario")
    info.add_argument("--scenario", default="paper", help="scenario name or TOML path (default: paper)")
    info.set_defaults(func=_info)
    rep = sub.add_parser("reproduce", help="run the paper's Section 5 and write figures and a metrics table")
    rep.add_argument("--out", required=True, help="output folder, e.g. runs/paper")
    rep.add_argument("--duration", type=positive_float, default=None, help="shorten every run to this many seconds")
    rep.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    rep.add_argument("--readme", default=None, help="also write the claims and gain-sweep tables into this README (between their markers)")
    rep.set_defaults(func=_reproduce)
    ga = sub.add_parser("ga", help="the paper's GA over (m, T_c): both modes, figures, table, leaderboard entries")
    ga.add_argument("--out", required=True, help="output folder; checkpoints there make a killed run resume")
    ga.add_argument("--modes", nargs="+", default=["reproduction", "full"], choices=["reproduction", "full"])
    ga.add_argument("--population", type=positive_int, default=100, help="individuals per generation (default: 100, the paper's)")
    ga.add_argument("--generations", type=positive_int, default=100, help="generations (default: 100, the paper's)")
    ga.add_argument("--seed", type=natural, default=0, help="random seed of the GA (default: 0)")
    ga.add_argument("--selection", default="inverse", choices=["inverse", "literal"],
                    help="roulette weights: 1/B ('inverse', default) or B as printed ('literal')")
    ga.add_argument("--scenario", default="paper", help="scenario name or TOML path (default: paper)")
    ga.add_argument("--executor", default="process", choices=["process", "dask", "none"],
                    help="where objective evaluations run (default: process pool)")
    ga.add_argument("--workers", type=positive_int, default=None, help="worker processes (default: all cores)")
    ga.add_argument("--leaderboard", default=None, help="write leaderboard entries under this folder")
    ga.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    ga.set_defaults(func=_ga)


def _add_study_commands(sub: Any) -> None:
    """Sub-commands train, tasks, evaluate and render."""
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
    tr.add_argument("--no-progress", action="store_true")
    tr.set_defaults(func=_train)
    tasks = sub.add_parser("tasks", help="a benchmark version's task tiers")
    tasks_sub = tasks.add_subparsers(dest="action", required=True)
    tb = tasks_sub.add_parser("build", help="apply the tier rule to candidate seeds and write the pool file "
                                            "(resumable: finished chunks in --work are kept)")
    tb.add_argument("--version", default=tier_versions()[-1], choices=tier_versions(),
                    help=f"benchmark version whose rule files apply (default: {tier_versions()[-1]})")
    tb.add_argument("--tier", default="base", choices=build_targets(),
                    help="base: the easy, medium and hard pools; debris, robust or servo: that tier, on top of the "
                         "version's pool file's tier tasks (default: base)")
    tb.add_argument("--work", default=None, help="folder of the finished chunks (default: runs/tasks-<version>; "
                                                 "a perturbed tier uses <work>/<tier>)")
    tb.add_argument("--out", default=None, help="pool file to write (default: the shipped "
                                                "envs/benchmark/<version>_tasks.json, or <version>_<tier>_tasks.json)")
    tb.add_argument("--chunk", type=positive_int, default=100, help="candidates per chunk (default: 100)")
    tb.add_argument("--workers", type=positive_int, default=2, help="worker processes (default: 2)")
    tb.add_argument("--max-candidates", type=positive_int, default=50_000, help="give up after this many per split (default: 50000)")
    tb.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    tb.set_defaults(func=_tasks)
    bk = tasks_sub.add_parser("best-known", help="the best known score of every pool task (a per-task CMA-ES over "
                                                 "action schedules; resumable) into envs/benchmark/<version>_best_known.json "
                                                 "(training pools: <version>_best_known_train.json)")
    bk.add_argument("--version", default=tier_versions()[-1], choices=tier_versions(),
                    help=f"benchmark version (default: {tier_versions()[-1]})")
    bk.add_argument("--tiers", nargs="+", default=list(all_task_tiers()), choices=all_task_tiers(),
                    help="tiers (default: all)")
    bk.add_argument("--splits", nargs="+", default=["test", "validation"], choices=["train", "validation", "test"],
                    help="pools searched (default: test validation)")
    bk.add_argument("--work", default="studies/best-known",
                    help="finished tasks, one jsonl per pool (default: studies/best-known, kept in git)")
    bk.add_argument("--shard", type=shard, default=None, metavar="K/N",
                    help="only the tasks whose index is K modulo N, into a work file of the shard's own: run N "
                         "processes with 0/N ... N-1/N to share the pools (default: every task)")
    bk.add_argument("--doubled", type=positive_int, default=None, metavar="N",
                    help="instead: re-run N random stored tasks of these pools with twice the generations and store "
                         "the gap in the file")
    bk.add_argument("--write-shipped", action="store_true",
                    help="write the package's own best-known files (a build of each whole file, from a source "
                         "checkout); default: their copies inside --work")
    bk.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    bk.set_defaults(func=_tasks_best_known)
    tt = tasks_sub.add_parser("tables", help="the tier tables of a version's pool files (docs/envs.md shows them)")
    tt.add_argument("--version", default=tier_versions()[-1], choices=tier_versions(),
                    help=f"benchmark version (default: {tier_versions()[-1]})")
    tt.add_argument("--docs", default=None, help="write them between their markers in this file (default: print)")
    tt.set_defaults(func=_tasks_tables)
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
    ev.add_argument("--leaderboard", default=None,
                    help="write the entry under this leaderboard root: <root>/<version>/<tier>/ (a custom --scenario: "
                         "<root>/<version>/custom/, unranked) (default: do not write)")
    ev.add_argument("--force", action="store_true", help="replace an entry of the same name (default: refuse)")
    ev.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    ev.set_defaults(func=_evaluate)
    ds = sub.add_parser("dataset", help="the best known trajectories of a tier's pool as a Minari dataset (offline RL, "
                                        "imitation); needs pip install \"ffsr-gym[dataset]\"")
    ds.add_argument("--tier", default="easy", choices=all_task_tiers(), help="tier (default: easy)")
    ds.add_argument("--env-id", default="FFSR-Residual-v2", choices=["FFSR-Residual-v2", "FFSR-v2"],
                    help="the env whose actions are recorded (default: FFSR-Residual-v2)")
    ds.add_argument("--split", default="train", choices=["train", "validation"],
                    help="pool (default: train; validation is for model selection; the test pool is never a dataset)")
    ds.add_argument("--root", default=None, help="datasets folder (default: MINARI_DATASETS_PATH or Minari's default)")
    ds.set_defaults(func=_dataset)
    rd = sub.add_parser("render", help="an episode of a policy as an animated GIF")
    _add_policy_arguments(rd, env_id="FFSR-v2", policy="reference", task="easy", split="train", split_help="pool of a tier")
    rd.add_argument("--seed", type=natural, default=0, help="reset seed: picks a tier's task (default: 0)")
    rd.add_argument("--task-index", type=natural, default=None,
                    help="play this task of the tier's pool instead of the one the seed picks (default: none)")
    rd.add_argument("--every", type=positive_int, default=2, help="one frame every N decisions of 0.1 s (default: 2)")
    rd.add_argument("--speed", type=positive_float, default=2.0, help="playback speed over real time (default: 2)")
    rd.add_argument("--out", default="runs/episode.gif", help="GIF file (default: runs/episode.gif)")
    rd.set_defaults(func=_render)


def _add_board_commands(sub: Any) -> None:
    """Sub-command leaderboard (render, plot, pareto)."""
    board = sub.add_parser("leaderboard", help="leaderboard tables and figures")
    board_sub = board.add_subparsers(dest="action", required=True)
    plot = board_sub.add_parser("plot", help="the ranked version's figures (IQM with CIs, performance profiles, learning "
                                             "curves, the Pareto plot) under <root>/<version>/, from the JSON only")
    plot.add_argument("--root", default="leaderboards", help="leaderboard root (default: leaderboards)")
    plot.set_defaults(func=_leaderboard_plot)
    agg = board_sub.add_parser("aggregates", help="rliable aggregates across tiers (IQM of score / best known score with "
                                                  "bootstrap CIs over tasks and runs, probability of improvement over the "
                                                  "reference planner, performance profiles): "
                                                  "<root>/<version>/aggregates.json and .png")
    agg.add_argument("--root", default="leaderboards", help="leaderboard root (default: leaderboards)")
    agg.set_defaults(func=_leaderboard_aggregates)
    pareto = board_sub.add_parser("pareto", help="run the planner grid and every baseline on the first easy test task; "
                                                 "writes <root>/<version>/pareto.json")
    pareto.add_argument("--root", default="leaderboards", help="leaderboard root (default: leaderboards)")
    pareto.add_argument("--models", default=None,
                        help="folder of the RL study's models (<algo>_<env id>_<tier>_seed<s>/model.zip); "
                             "without it RL entries are listed as not run (default: none)")
    pareto.add_argument("--no-progress", action="store_true", help="hide the progress bars")
    pareto.set_defaults(func=_leaderboard_pareto)
    verify = board_sub.add_parser("verify", help="replay an entry's trace (or planner, fixed parameters) and compare "
                                                 "its rows exactly (exit 0: reproduced, 1: differ, 3: skipped code)")
    verify.add_argument("entry", help="the entry's JSON file")
    verify.add_argument("--run-code", default=None, metavar="TEXT",
                        help="consent to run the code the entry names: exactly its extra.policy callable or SB3 .zip "
                             "(importing a file or unpickling a model runs code of its maker's choosing)")
    verify.set_defaults(func=_verify)
    render = board_sub.add_parser("render", help="regenerate the tables in <root>/README.md from the JSON entries")
    render.add_argument("--root", default="leaderboards", help="leaderboard root (default: leaderboards)")
    render.add_argument("--check", action="store_true",
                        help="exit 1 if an entry is refused or a table, the aggregates or a figure is out of date; "
                             "write nothing")
    render.add_argument("--readme", default=None,
                        help="also regenerate the leaderboard summary between its markers in this file (e.g. README.md)")
    render.set_defaults(func=_leaderboard)
    update = board_sub.add_parser("update", help="regenerate everything a submission changes (tables, the README "
                                                 "summary, aggregates, figures), then check it all (needs the "
                                                 "'analysis' extra)")
    update.add_argument("--root", default="leaderboards", help="leaderboard root (default: leaderboards)")
    update.add_argument("--readme", default=None, help="also the summary between its markers in this file")
    update.set_defaults(func=_leaderboard_update)


class _DefaultsShown(argparse.HelpFormatter):
    """Every option's help ends with its default, unless the help text already names it."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        if ("default" in text or not action.option_strings or action.required or action.default is argparse.SUPPRESS
                or isinstance(action, (argparse._StoreTrueAction, argparse._VersionAction, argparse._HelpAction))):
            return text
        value = action.default
        shown = "none" if value is None else " ".join(map(str, value)) if isinstance(value, (list, tuple)) else value
        return f"{text} (default: {shown})"


class _Parser(argparse.ArgumentParser):
    """The command line's parsers: each shows its options' defaults (sub-command parsers are of this class too)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("formatter_class", _DefaultsShown)
        super().__init__(*args, **kwargs)


def build_parser() -> argparse.ArgumentParser:
    """The ``ffsr-gym`` argument parser, every sub-command on it."""
    from ffsr_gym import __version__

    parser = _Parser(prog="ffsr-gym", description=DESCRIPTION.format(ids=", ".join(registered_ids())),
                     epilog="Each command has its own --help. Documentation: README.md, docs/envs.md, docs/model.md, "
                            "docs/robots.md, leaderboards/README.md.")
    parser.add_argument("--version", action="version", version=f"ffsr-gym {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    for add in (_add_model_commands, _add_study_commands, _add_board_commands):
        add(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``ffsr-gym`` console script."""
    parser = build_parser()
    argv = sys.argv[1:] if argv is None else argv
    try:
        args = parser.parse_args(argv)
    except SystemExit as stop:  # argparse's named errors (a bad option, a number out of range) return 2
        if not stop.code:
            raise  # --help, --version
        return int(stop.code)
    args.argv = argv
    from ffsr_gym.bench.leaderboard import checks_once

    try:
        with checks_once():  # a command that loads the entries several times verifies each file once
            code = args.func(args)
    except FFSRError as exc:
        print(f"ffsr-gym: error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # the reader went away (``ffsr-gym info | head``): stop quietly, as other tools do
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1
    return int(code or 0)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
