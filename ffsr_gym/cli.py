"""The ``ffsr-gym`` command line."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from ffsr_gym.exceptions import FFSRError


def _info(args: argparse.Namespace) -> None:
    from ffsr_gym.model.quaternion import from_rotation
    from ffsr_gym.model.scenario import load_scenario
    from ffsr_gym.sim.setup import prepare

    scenario = load_scenario(args.scenario)
    setup = prepare(scenario)
    robot, q = setup.robot, setup.q0
    ee = robot.transform_ee_to_world(q, 0)
    robot.update_kinematics(q)
    mats = robot.momentum_matrices(q)
    clearance = setup.assets.collision.clearance(q, setup.obstacles.spheres(0.0))
    rows = [
        ("scenario", f"{scenario.name} ({scenario.source})"),
        ("scenario sha256", scenario.sha256()[:16]),
        ("robot", f"{scenario.robot}, total mass {robot.total_mass:.1f} kg"),
        ("base CoM [m]", np.round(q[:3], 4)),
        ("system CoM [m]", np.round(robot.system_com(q), 4)),
        ("mission EE position [m]", np.round(ee.translation, 4)),
        ("mission EE attitude [w x y z]", np.round(from_rotation(ee.rotation), 4)),
        ("target position [m]", np.round(scenario.target.position_m, 4)),
        ("sigma(J_m mission)", np.round(np.linalg.svd(robot.arm_jacobian(0), compute_uv=False), 4)),
        ("sigma(H_bm balance)", np.round(np.linalg.svd(mats.H_bm[1], compute_uv=False), 3)),
        ("clearance [m]", f"{clearance.distance_m:.4f} ({clearance.pair[0]} - {clearance.pair[1]})"),
    ]
    width = max(len(k) for k, _ in rows)
    for key, value in rows:
        print(f"{key:<{width}}  {value}")


def _list(args: argparse.Namespace) -> None:
    import gymnasium

    from ffsr_gym.environments.env_v1 import TASKS
    from ffsr_gym.model.resources import envs_dir, scenario_names
    from ffsr_gym.tasks.splits import SPLITS, pool

    ids = sorted(env_id for env_id in gymnasium.registry if env_id.startswith("FFSR-"))
    robots = sorted(p.name for p in (envs_dir() / "robots").iterdir() if p.is_dir())
    print("environment ids:", ", ".join(ids))
    print("v1 tasks (task=):", ", ".join(TASKS))
    for tier in TASKS[1:]:
        print(f"  {tier}: " + ", ".join(f"{split} pool {len(pool(tier, split))} tasks" for split in SPLITS))
    print("scenarios (v0 scenario=):", ", ".join(scenario_names()))
    print("robots:", ", ".join(robots))


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
    from ffsr_gym.optim.rl import train_and_evaluate
    from ffsr_gym.optim.rl_v1 import train_and_evaluate_v1

    if args.env_id.endswith("-v1"):
        report = train_and_evaluate_v1(args.algo, args.env_id, tier=args.task, seeds=args.seeds, out=args.out,
                                       timesteps=args.timesteps, hyperparams=args.hyperparams,
                                       curve_every=args.curve_every, progress=not args.no_progress)
        folder = Path(args.leaderboard or ".") / "v1" / args.task
    else:
        report = train_and_evaluate(args.algo, args.env_id, seeds=args.seeds, out=args.out, scenario=args.scenario,
                                    timesteps=args.timesteps, hyperparams=args.hyperparams, progress=not args.no_progress)
        folder = Path(args.leaderboard or ".") / args.env_id
    print(f"{report.name}: {report.metrics}")
    if args.leaderboard:
        print("wrote", report.save(folder))


def _leaderboard(args: argparse.Namespace) -> int:
    from ffsr_gym.bench.leaderboard import render_readme, write_readme
    from ffsr_gym.bench.leaderboard_v1 import splice_summary
    from ffsr_gym.exceptions import InvalidInputError
    from ffsr_gym.provenance import write_text_atomic

    readme = Path(args.readme) if args.readme else None
    if readme is not None and not readme.is_file():
        raise InvalidInputError(f"--readme {args.readme!r} is not a file")
    if args.check:
        stale = [f"{args.root}/README.md"] if render_readme(args.root) != (Path(args.root) / "README.md").read_text() else []
        if readme is not None and splice_summary(readme.read_text(encoding="utf-8"), args.root) != readme.read_text(encoding="utf-8"):
            stale.append(str(readme))
        if stale:
            print(f"out of date: {', '.join(stale)}; run ffsr-gym leaderboard render", file=sys.stderr)
            return 1
        print("leaderboard tables are up to date")
        return 0
    print("updated" if write_readme(args.root) else "already up to date", f"{args.root}/README.md")
    if readme is not None:
        write_text_atomic(readme, splice_summary(readme.read_text(encoding="utf-8"), args.root))
        print("updated the v1 summary in", readme)
    return 0


def _leaderboard_plot(args: argparse.Namespace) -> None:
    from ffsr_gym.report.leaderboard_plots import plot_iqm, plot_learning_curves, plot_pareto, plot_profiles

    for path in (plot_iqm(args.root), plot_profiles(args.root), plot_learning_curves(args.root)):
        print("wrote" if path else "no v1 entries under", path or args.root)
    pareto = plot_pareto(args.root)
    if pareto is None:
        print("no paper_pareto.json yet: run ffsr-gym leaderboard pareto")
    else:
        print("wrote", pareto)


def _leaderboard_pareto(args: argparse.Namespace) -> None:
    from ffsr_gym.bench.pareto import paper_pareto
    from ffsr_gym.optim.rl import load_model
    from ffsr_gym.report.leaderboard_plots import PARETO_FILE

    out = Path(args.root) / "v1" / PARETO_FILE
    print("wrote", paper_pareto(args.root, out, args.models, load_model=load_model, progress=not args.no_progress,
                                command=" ".join(["ffsr-gym", *args.argv])))


def load_policy(spec: str, algo: str | None):
    """A policy from the command line: ``"m,T_c"`` (fixed parameters), an SB3 ``.zip`` (with ``algo``),
    or ``module:callable`` (imported; called with an observation, returns an action).

    Raises:
        InvalidInputError: none of these, naming the accepted forms.
    """
    import importlib

    from ffsr_gym.exceptions import InvalidInputError

    parts = spec.split(",")
    if len(parts) == 2:
        try:
            return float(parts[0]), float(parts[1])
        except ValueError:
            pass
    if spec.endswith(".zip"):
        from ffsr_gym.optim.rl import ALGOS, load_model

        if algo not in ALGOS:
            raise InvalidInputError(f"--algo {algo!r}: an SB3 .zip needs --algo, one of {sorted(ALGOS)}")
        if not Path(spec).is_file():
            raise InvalidInputError(f"--policy {spec!r}: no such file")
        return load_model(algo, spec)
    module, _, name = spec.partition(":")
    if module and name:
        try:
            policy = getattr(importlib.import_module(module), name)
        except (ImportError, AttributeError) as exc:
            raise InvalidInputError(f"--policy {spec!r}: {exc}") from None
        if callable(policy):
            return policy
    raise InvalidInputError(f"--policy {spec!r}; allowed: 'm,T_c' (e.g. 0.3,4), an SB3 .zip with --algo, "
                            "or module:callable")


ENV_IDS = ["FFSR-v0", "FFSR-Residual-v0", "FFSR-v1", "FFSR-Residual-v1"]


def _add_policy_arguments(parser: argparse.ArgumentParser, *, env_id: str | None, policy: str | None, task: str,
                          split: str, split_help: str) -> None:
    """The options that name an environment and a policy (``evaluate``, ``render``); None: required."""
    parser.add_argument("--env-id", required=env_id is None, default=env_id, choices=ENV_IDS,
                        help="environment id" + (f" (default: {env_id})" if env_id else ""))
    parser.add_argument("--policy", required=policy is None, default=policy,
                        help="'m,T_c' (fixed parameters, e.g. 0.3,4), an SB3 .zip (with --algo), or module:callable"
                             + (f" (default: {policy})" if policy else ""))
    parser.add_argument("--algo", default=None, choices=["ppo", "sac", "td3"], help="the algorithm of an SB3 .zip")
    parser.add_argument("--task", default=task, choices=["paper", "easy", "medium", "hard"],
                        help=f"v1: task or tier (default: {task})")
    parser.add_argument("--split", default=split, choices=["train", "test"], help=f"v1: {split_help} (default: {split})")
    parser.add_argument("--scenario", default="paper", help="v0: scenario name or TOML path (default: paper)")


def _env_kwargs(args: argparse.Namespace) -> dict:
    """``gymnasium.make`` arguments of ``--env-id``: the v1 task and split, or the v0 scenario."""
    return {"task": args.task, "split": args.split} if args.env_id.endswith("-v1") else {"scenario": args.scenario}


def _evaluate(args: argparse.Namespace) -> None:
    from concurrent.futures import ProcessPoolExecutor

    from ffsr_gym.bench.evaluation import evaluate
    from ffsr_gym.exceptions import InvalidInputError

    policy = load_policy(args.policy, args.algo)
    v1 = args.env_id.endswith("-v1")
    if args.workers < 1 or (args.workers > 1 and not v1):
        raise InvalidInputError(f"--workers {args.workers}; allowed: >= 1, and more than 1 only for the v1 ids")
    executor = ProcessPoolExecutor(args.workers) if args.workers > 1 else None
    try:
        report = evaluate(policy, args.env_id, name=args.name, progress=not args.no_progress,
                          **(_env_kwargs(args) | {"training_pool": args.training_pool, "executor": executor} if v1
                             else {"env_kwargs": _env_kwargs(args)}))
    finally:
        if executor is not None:
            executor.shutdown()
    print(f"{report.name}: {report.metrics}")
    if args.leaderboard:
        folder = Path(args.leaderboard) / ("v1" if v1 else args.env_id) / (args.task if v1 else "")
        print("wrote", report.save(folder))


def _render(args: argparse.Namespace) -> None:
    import gymnasium
    from PIL import Image

    from ffsr_gym.bench.entry import stepper
    from ffsr_gym.exceptions import InvalidInputError

    if args.every < 1 or args.speed <= 0:
        raise InvalidInputError(f"--every {args.every} (allowed: >= 1), --speed {args.speed} (allowed: > 0)")
    policy = load_policy(args.policy, args.algo)
    env = gymnasium.make(args.env_id, render_mode="rgb_array", **_env_kwargs(args))
    obs, _ = env.reset(seed=args.seed)
    step, frames, decisions, done, info = stepper(policy, env), [env.render()], 0, False, {}
    while not done:
        obs, _, terminated, truncated, info = step(obs)
        decisions, done = decisions + 1, terminated or truncated
        if decisions % args.every == 0 or done:
            frames.append(env.render())
    env.close()
    interval_ms = 1000.0 * args.every * env.unwrapped.family.env.decision_interval_s / args.speed
    images = [Image.fromarray(frame) for frame in frames]
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    images[0].save(out, save_all=True, append_images=images[1:], duration=round(interval_ms), loop=0)
    outcome = {k: info.get(k) for k in ("score", "success", "failure") if k in info}
    print(f"wrote {out}: {len(frames)} frames, {decisions} decisions, {outcome}")


def _tasks(args: argparse.Namespace) -> None:
    from concurrent.futures import ProcessPoolExecutor

    from ffsr_gym.tasks.build import build

    workers = max(1, args.workers)
    executor = ProcessPoolExecutor(workers) if workers > 1 else None
    try:
        data = build(args.work, target=args.tier, out=args.out, chunk=args.chunk, max_candidates=args.max_candidates, executor=executor,
                     workers=workers, progress=not args.no_progress)
    finally:
        if executor is not None:
            executor.shutdown()
    for split, summary in data["splits"].items():
        print(f"{split}: {summary['candidates']} candidates, tiers {summary['tier_counts']}, "
              f"rejected {summary['rejection_counts']}")


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``ffsr-gym`` console script."""
    from ffsr_gym import __version__

    parser = argparse.ArgumentParser(prog="ffsr-gym", description=__doc__)
    parser.add_argument("--version", action="version", version=f"ffsr-gym {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    listing = sub.add_parser("list", help="list the environment ids, v1 tasks and tiers, scenarios and robots")
    listing.set_defaults(func=_list)
    info = sub.add_parser("info", help="print the initial state of a scenario")
    info.add_argument("--scenario", default="paper", help="scenario name or TOML path (default: paper)")
    info.set_defaults(func=_info)
    rep = sub.add_parser("reproduce", help="run the paper's Section 5 and write figures and a metrics table")
    rep.add_argument("--out", required=True, help="output folder, e.g. runs/paper")
    rep.add_argument("--duration", type=float, default=None, help="shorten every run to this many seconds")
    rep.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    rep.add_argument("--readme", default=None, help="also write the claims and gain-sweep tables into this README (between their markers)")
    rep.set_defaults(func=_reproduce)
    ga = sub.add_parser("ga", help="the paper's GA over (m, T_c): both modes, figures, table, leaderboard entries")
    ga.add_argument("--out", required=True, help="output folder; checkpoints there make a killed run resume")
    ga.add_argument("--modes", nargs="+", default=["reproduction", "full"], choices=["reproduction", "full"])
    ga.add_argument("--population", type=int, default=100, help="individuals per generation (default: 100, the paper's)")
    ga.add_argument("--generations", type=int, default=100, help="generations (default: 100, the paper's)")
    ga.add_argument("--seed", type=int, default=0, help="random seed of the GA (default: 0)")
    ga.add_argument("--selection", default="inverse", choices=["inverse", "literal"],
                    help="roulette weights: 1/B ('inverse', default) or B as printed ('literal')")
    ga.add_argument("--scenario", default="paper", help="scenario name or TOML path (default: paper)")
    ga.add_argument("--executor", default="process", choices=["process", "dask", "none"],
                    help="where objective evaluations run (default: process pool)")
    ga.add_argument("--workers", type=int, default=None, help="worker processes (default: all cores)")
    ga.add_argument("--leaderboard", default=None, help="write leaderboard entries under this folder")
    ga.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    ga.set_defaults(func=_ga)
    tr = sub.add_parser("train", help="train stable-baselines3 agents and score them with ffsr_gym.evaluate")
    tr.add_argument("--algo", required=True, choices=["ppo", "sac", "td3"])
    tr.add_argument("--env-id", default="FFSR-v0", choices=ENV_IDS)
    tr.add_argument("--scenario", default="paper", help="v0 only: scenario name or TOML path (default: paper)")
    tr.add_argument("--task", default="easy", choices=["easy", "medium", "hard"],
                    help="v1 only: the tier; trains on its training pool, scores its test pool (default: easy)")
    tr.add_argument("--curve-every", type=int, default=5000,
                    help="v1 only: env steps between learning-curve points (default: 5000)")
    tr.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4])
    tr.add_argument("--timesteps", type=int, default=None, help="default: n_timesteps of the hyperparameter file")
    tr.add_argument("--hyperparams", default=None, help="folder with <algo>.yml (default: baselines/hyperparams)")
    tr.add_argument("--out", default="runs/rl")
    tr.add_argument("--leaderboard", default=None, help="write the entry under this folder")
    tr.add_argument("--no-progress", action="store_true")
    tr.set_defaults(func=_train)
    tasks = sub.add_parser("tasks", help="benchmark v1 task tiers")
    tasks_sub = tasks.add_subparsers(dest="action", required=True)
    tb = tasks_sub.add_parser("build", help="apply the tier rule to candidate seeds and write the pool file "
                                            "(resumable: finished chunks in --work are kept)")
    tb.add_argument("--tier", default="v1", choices=("v1", "debris", "robust"),
                    help="v1: the easy, medium and hard pools; debris or robust: that perturbed tier, on top of the v1 "
                         "pool file's tier tasks (default: v1)")
    tb.add_argument("--work", default="runs/tasks-v1", help="folder of the finished chunks (default: runs/tasks-v1; "
                                                            "a perturbed tier uses <work>/<tier>)")
    tb.add_argument("--out", default=None, help="pool file to write (default: the shipped envs/benchmark/v1_tasks.json, "
                                                "or v1_<tier>_tasks.json)")
    tb.add_argument("--chunk", type=int, default=100, help="candidates per chunk (default: 100)")
    tb.add_argument("--workers", type=int, default=2, help="worker processes (default: 2)")
    tb.add_argument("--max-candidates", type=int, default=50_000, help="give up after this many per split (default: 50000)")
    tb.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    tb.set_defaults(func=_tasks)
    ev = sub.add_parser("evaluate", help="score a policy with ffsr_gym.evaluate and optionally write a leaderboard entry")
    _add_policy_arguments(ev, env_id=None, policy=None, task="easy", split="test", split_help="pool scored")
    ev.add_argument("--training-pool", default=None, help="v1: what the policy was trained or tuned on (recorded)")
    ev.add_argument("--name", default="submission", help="entry name (default: submission)")
    ev.add_argument("--workers", type=int, default=1,
                    help="v1: score the pool on this many processes; the same entry as with 1 (default: 1)")
    ev.add_argument("--leaderboard", default=None, help="write the entry under this leaderboard root")
    ev.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    ev.set_defaults(func=_evaluate)
    rd = sub.add_parser("render", help="an episode of a policy as an animated GIF")
    _add_policy_arguments(rd, env_id="FFSR-v1", policy="0.3,4", task="paper", split="train", split_help="pool of a tier")
    rd.add_argument("--seed", type=int, default=0, help="reset seed: picks a tier's task (default: 0)")
    rd.add_argument("--every", type=int, default=2, help="one frame every N decisions of 0.1 s (default: 2)")
    rd.add_argument("--speed", type=float, default=2.0, help="playback speed over real time (default: 2)")
    rd.add_argument("--out", default="runs/episode.gif", help="GIF file (default: runs/episode.gif)")
    rd.set_defaults(func=_render)
    board = sub.add_parser("leaderboard", help="leaderboard tables and figures")
    board_sub = board.add_subparsers(dest="action", required=True)
    plot = board_sub.add_parser("plot", help="the v1 figures (IQM with CIs, performance profiles, learning curves, "
                                             "the paper Pareto plot) under <root>/v1/, from the JSON only")
    plot.add_argument("--root", default="leaderboards", help="leaderboard root (default: leaderboards)")
    plot.set_defaults(func=_leaderboard_plot)
    pareto = board_sub.add_parser("pareto", help="run the planner grid and every v1 baseline on the paper task; "
                                                 "writes <root>/v1/paper_pareto.json")
    pareto.add_argument("--root", default="leaderboards", help="leaderboard root (default: leaderboards)")
    pareto.add_argument("--models", default=None,
                        help="folder of the RL study's models (<algo>_<env id>_<tier>_seed<s>/model.zip); "
                             "without it RL entries are listed as not run (default: none)")
    pareto.add_argument("--no-progress", action="store_true", help="hide the progress bars")
    pareto.set_defaults(func=_leaderboard_pareto)
    render = board_sub.add_parser("render", help="regenerate the tables in <root>/README.md from the JSON entries")
    render.add_argument("--root", default="leaderboards", help="leaderboard root (default: leaderboards)")
    render.add_argument("--check", action="store_true", help="exit 1 if the tables are out of date, write nothing")
    render.add_argument("--readme", default=None,
                        help="also regenerate the v1 summary between its markers in this file (e.g. README.md)")
    render.set_defaults(func=_leaderboard)
    argv = sys.argv[1:] if argv is None else argv
    args = parser.parse_args(argv)
    args.argv = argv
    try:
        code = args.func(args)
    except FFSRError as exc:
        print(f"ffsr-gym: error: {exc}", file=sys.stderr)
        return 2
    return int(code or 0)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
