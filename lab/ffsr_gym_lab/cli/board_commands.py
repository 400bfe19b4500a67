"""Sub-command ``leaderboard``: render, check, update, plot, aggregates, pareto, verify."""

from __future__ import annotations

import argparse
import functools
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ffsr_gym.cli.verify_commands import write_stamp
from ffsr_gym.exceptions import InvalidInputError


def _leaderboard(args: argparse.Namespace) -> int:
    from ffsr_gym.provenance import write_text_atomic
    from ffsr_gym.user_files import read_text
    from ffsr_gym_lab.board.leaderboard import splice_summary, write_readme

    pages = [Path(page) for page in args.readme or ()]
    for page in pages:
        if not page.is_file():
            raise InvalidInputError(f"--readme {str(page)!r} is not a file")
    if args.check:
        return _check_leaderboard(args.root, pages)
    print("updated" if write_readme(args.root) else "already up to date", f"{args.root}/README.md")
    for page in pages:
        write_text_atomic(page, splice_summary(read_text(page), args.root, where=str(page)))
        print("updated the generated leaderboard blocks in", page)
    return 0


def _check_leaderboard(root: str, readme: list[Path]) -> int:
    """``leaderboard render --check``: 1 when an entry is refused, or a table, the aggregates or a figure is out of
    date."""
    from ffsr_gym.versions.registry import all_specs, ranked_spec
    from ffsr_gym_lab.board.leaderboard import check, load_entries, verified
    from ffsr_gym_lab.board.plots import stale_figures

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
    from ffsr_gym.versions.registry import ranked_spec
    from ffsr_gym_lab.board.leaderboard import load_entries, verified

    return verified(load_entries(root, ranked_spec()))


def _leaderboard_plot(args: argparse.Namespace) -> None:
    from ffsr_gym_lab.board.plots import draw_all

    for what, path in draw_all(args.root, _verified(args.root)).items():
        print(f"wrote {path}" if path else f"no data for the {what} figure under {args.root}: not drawn")


def _leaderboard_update(args: argparse.Namespace) -> int:
    """Everything a submission changes, in order: the replays of the entries changed since they were last verified
    (each reproduced one stamped), aggregates, tables (and the pages' generated blocks), figures."""
    from ffsr_gym.exceptions import require
    from ffsr_gym_lab.board.leaderboard import check, checks_once
    from ffsr_gym_lab.board.plots import stale_figures

    require("rliable", "analysis", "rliable, pandas", "the aggregates across tiers need")  # before anything is written
    replayed = _replay_changed(args.root, full=args.full)
    with checks_once():  # each entry file is checked once, though the steps load the board several times
        _leaderboard_aggregates(args)  # from the verified entries; the summary page shows them
        _leaderboard(argparse.Namespace(root=args.root, readme=args.readme, check=False))
        if stale_figures(args.root, _verified(args.root)):
            _leaderboard_plot(args)
        else:
            print("figures already up to date (their inputs and PNGs unchanged)")
        problems = check(args.root, args.readme)  # the figures were just drawn
    for line in problems:
        print(line, file=sys.stderr)
    if replayed == 1:
        problems.append("a replayed entry differs from its file")
    print("updated; every entry verifies" if not problems else "updated, but the leaderboard cannot be published")
    return 1 if problems else 0


def _replay_changed(root: str, *, full: bool) -> int:
    """Replay the entries changed since their last verified state (:mod:`ffsr_gym_lab.board.update_plan`), stamp those
    reproduced, say what was skipped and why; 1 if a replay differs, else 0."""
    from collections import defaultdict

    from tqdm.auto import tqdm

    from ffsr_gym.bench.replay import replay_entry
    from ffsr_gym_lab.board.update_plan import plan

    steps = plan(root, full=full)
    skipped = defaultdict(list)
    for step in steps:
        if not step.replay:
            skipped[step.reason].append(step.path.name)
    for reason, names in skipped.items():
        print(f"skipped {len(names)} ({reason}): {', '.join(names[:3])}{' ...' if len(names) > 3 else ''}")
    todo = [step for step in steps if step.replay]
    print(f"replaying {len(todo)} of {len(steps)} entries (--full replays every one)")
    worst = 0
    for step in tqdm(todo, desc="replays", unit="entry", leave=False):
        verdict = replay_entry(step.path)
        print(f"{step.path}: {verdict.status} (replayed: {step.reason}): {verdict.text}",
              file=sys.stdout if verdict.exit_code == 0 else sys.stderr)
        if verdict.status == "reproduced":
            write_stamp(str(step.path), verdict.entry_text)
        worst = max(worst, 1 if verdict.exit_code == 1 else 0)
    return worst


def _leaderboard_aggregates(args: argparse.Namespace) -> None:
    from ffsr_gym.versions.registry import ranked_spec
    from ffsr_gym_lab.board import aggregates
    from ffsr_gym_lab.board.plots import plot_aggregates

    spec = ranked_spec()
    entries = _verified(args.root)
    if aggregates.up_to_date(args.root, spec, entries):
        print(f"aggregates already up to date under {args.root} (their inputs unchanged)")
        return
    path = aggregates.write(args.root, spec, entries)
    if path is None:
        print(f"nothing to aggregate under {args.root}: no tier whose test tasks all have best known scores, or no "
              f"{aggregates.REFERENCE.format(version=spec.rules.version)} entry")
        return
    print("wrote", path, "and", plot_aggregates(path))


def _leaderboard_pareto(args: argparse.Namespace) -> None:
    from ffsr_gym.bench.policies import load_model
    from ffsr_gym.versions.registry import ranked_spec
    from ffsr_gym_lab.board.pareto import task_pareto
    from ffsr_gym_lab.board.plots import PARETO_FILE

    out = Path(args.root) / ranked_spec().version / PARETO_FILE
    print("wrote", task_pareto(args.root, out, args.models, load_model=load_model, progress=not args.no_progress,
                               command=" ".join(["ffsr-gym", *args.argv]), trust_model=args.trust_model))


def _leaderboard_store(args: argparse.Namespace) -> int:
    from ffsr_gym.bench.changes import entry_files
    from ffsr_gym.bench.trace_file import store_entries

    changed = store_entries(entry_files(args.root))
    for path, before, after, moved in changed:
        what = "trace moved to its file, " if moved else ""
        print(f"{path}: {what}{before / 1e6:.3f} MB -> {after / 1e6:.3f} MB (entry and trace file)")
    before, after = sum(c[1] for c in changed), sum(c[2] for c in changed)
    moved = sum(c[3] for c in changed)
    print(f"rewrote {len(changed)} entries in the storage format: {before / 1e6:.1f} MB -> {after / 1e6:.1f} MB"
          + (f"; the stamps of the {moved} whose trace moved were dropped: 'ffsr-gym leaderboard update' replays and "
             "stamps them" if moved else ""))
    return 0


def _once(func: Callable[[argparse.Namespace], Any]) -> Callable[[argparse.Namespace], Any]:
    """``func`` run inside :func:`~ffsr_gym_lab.board.leaderboard.checks_once`: a command that loads the entries several
    times verifies each file once."""

    @functools.wraps(func)
    def run(args: argparse.Namespace) -> Any:
        from ffsr_gym_lab.board.leaderboard import checks_once

        with checks_once():
            return func(args)
    return run


def add_board_commands(sub: Any, groups: dict[str, Any]) -> None:
    """The leaderboard's maintenance sub-commands, in its group (``leaderboard``, whose ``verify`` is the library's):
    plot, aggregates, pareto, render, update, store."""
    board_sub = groups["leaderboard"]
    plot = board_sub.add_parser("plot", help="the ranked version's figures (IQM with CIs, performance profiles, learning "
                                             "curves, the Pareto plot) under <root>/<version>/, from the JSON only")
    plot.add_argument("--root", default="leaderboards", help="leaderboard root (default: leaderboards)")
    plot.set_defaults(func=_once(_leaderboard_plot))
    agg = board_sub.add_parser("aggregates", help="rliable aggregates across tiers (IQM of score / best known score with "
                                                  "bootstrap CIs over tasks and runs, probability of improvement over the "
                                                  "reference planner, performance profiles): "
                                                  "<root>/<version>/aggregates.json and .png")
    agg.add_argument("--root", default="leaderboards", help="leaderboard root (default: leaderboards)")
    agg.set_defaults(func=_once(_leaderboard_aggregates))
    pareto = board_sub.add_parser("pareto", help="run the planner grid and every baseline on the first easy test task; "
                                                 "writes <root>/<version>/pareto.json")
    pareto.add_argument("--root", default="leaderboards", help="leaderboard root (default: leaderboards)")
    pareto.add_argument("--models", default=None,
                        help="folder of the RL study's models (<algo>_<env id>_<tier>_seed<s>/model.zip); "
                             "without it RL entries are listed as not run (default: none)")
    pareto.add_argument("--trust-model", action="store_true",
                        help="consent to unpickle the SB3 models under --models (unpickling runs code of their "
                             "maker's choosing)")
    pareto.add_argument("--no-progress", action="store_true", help="hide the progress bars")
    pareto.set_defaults(func=_once(_leaderboard_pareto))
    render = board_sub.add_parser("render", help="regenerate the tables in <root>/README.md from the JSON entries")
    render.add_argument("--root", default="leaderboards", help="leaderboard root (default: leaderboards)")
    render.add_argument("--check", action="store_true",
                        help="exit 1 if an entry is refused or a table, the aggregates or a figure is out of date; "
                             "write nothing")
    render.add_argument("--readme", nargs="+", default=None, metavar="PAGE",
                        help="also regenerate the generated leaderboard blocks between their markers in these "
                             "Markdown files (in a checkout: README.md docs/baselines.md)")
    render.set_defaults(func=_once(_leaderboard))
    update = board_sub.add_parser("update", help="replay the entries changed since they were last verified (and "
                                                 "stamp them), regenerate everything a submission changes (tables, the "
                                                 "pages' generated blocks, aggregates, figures), then check it all "
                                                 "(needs the 'analysis' extra)")
    update.add_argument("--root", default="leaderboards", help="leaderboard root (default: leaderboards)")
    update.add_argument("--readme", nargs="+", default=None, metavar="PAGE",
                        help="also the generated leaderboard blocks between their markers in these Markdown files")
    update.add_argument("--full", action="store_true",
                        help="replay every entry, not only those changed since their stamp (entry, pool, reference or "
                             "replayed code)")
    update.set_defaults(func=_once(_leaderboard_update))
    store = board_sub.add_parser("store", help="rewrite every entry in the storage format: an action trace written "
                                               "as text inside the entry moves to a trace file beside it (<name>.trace, "
                                               "compressed, named by sha256), and the JSON is written compact (a row "
                                               "per line); the content and stamps are kept (the stamp is dropped where a "
                                               "trace moved); prints the bytes before and after")
    store.add_argument("--root", default="leaderboards", help="leaderboard root (default: leaderboards)")
    store.set_defaults(func=_once(_leaderboard_store))
