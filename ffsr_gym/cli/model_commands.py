"""Sub-commands of the model and the paper: ``list``, ``info``, ``reproduce``, ``ga``."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from ffsr_gym.bench.options import add_scheduler_option, natural, positive_float, positive_int


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


def _reproduce(args: argparse.Namespace) -> None:
    from ffsr_gym.report.reproduction import reproduce
    from ffsr_gym.user_files import read_text

    if args.readme:
        read_text(args.readme)  # a page that cannot be updated is named before the run, not after it
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
        write_text_atomic(readme, splice_readme(read_text(readme), result))
        print(f"updated the generated tables in {readme}")


def _ga(args: argparse.Namespace) -> None:
    from ffsr_gym.optim.ga import GAConfig
    from ffsr_gym.optim.ga_study import run_study

    config = GAConfig(population=args.population, generations=args.generations, seed=args.seed,
                      selection=args.selection, scenario=args.scenario)
    results = run_study(args.out, modes=tuple(args.modes), config=config, executor=args.executor,
                        workers=args.workers, leaderboard=args.leaderboard, progress=not args.no_progress,
                        scheduler=args.scheduler)
    for mode, summary in results.items():
        o = summary["optimum"]
        print(f"{mode}: m = {o['m']:.4f}, T_c = {o['T_c_s']:.3f} s, B = {o['score']} "
              f"(non-optimised: {summary['baseline_score']}); {summary['wall_time_s']:.0f} s")


def add_model_commands(sub: Any) -> None:
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
    rep.add_argument("--readme", default=None, help="also write the claims and gain-sweep tables into this Markdown file, between their markers (in a checkout: docs/reproduction.md)")
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
    add_scheduler_option(ga, "evaluations (instead of --executor)")
    ga.add_argument("--leaderboard", default=None, help="write leaderboard entries under this folder")
    ga.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    ga.set_defaults(func=_ga)
