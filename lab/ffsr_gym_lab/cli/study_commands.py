"""Sub-commands of the long studies: ``tasks`` (build, best-known, tables, freeze-reference), ``dataset``."""

from __future__ import annotations

import argparse
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from ffsr_gym.bench.options import add_scheduler_option, positive_int
from ffsr_gym.cli.choices import all_task_tiers, build_targets, capture_tiers, tier_versions


def add_study_commands(sub: Any, groups: dict[str, Any]) -> None:
    """Sub-commands tasks and dataset (``groups``: the library's groups; none is joined)."""
    tasks = sub.add_parser("tasks", help="a benchmark version's task tiers")
    tasks_sub = tasks.add_subparsers(dest="action", required=True)
    tb = tasks_sub.add_parser("build", help="apply the tier rule to candidate seeds and write the pool file "
                                            "(resumable: finished chunks in --work are kept)")
    _add_version(tb, "benchmark version whose rule files apply")
    tb.add_argument("--tier", default="base", choices=build_targets(),
                    help="base: the easy, medium and hard pools; debris, robust or servo: that tier, on top of the "
                         "version's pool file's tier tasks; slow or fast: that capture tier (--version capture-v0); sweep or "
                         "nutation: that capture v1 or v2 tier (--version capture-v1, capture-v2) "
                         "(default: base)")
    tb.add_argument("--work", default=None, help="folder of the finished chunks (default: studies/tasks-<version>, kept "
                                                 "in git so that a build resumes on any machine; "
                                                 "a perturbed tier uses <work>/<tier>)")
    tb.add_argument("--out", default=None, help="pool file to write (default: the shipped "
                                                "envs/benchmark/<version>_tasks.json, or <version>_<tier>_tasks.json)")
    tb.add_argument("--chunk", type=positive_int, default=100, help="candidates per chunk (default: 100)")
    tb.add_argument("--workers", type=positive_int, default=2, help="worker processes (default: 2)")
    add_scheduler_option(tb, "chunks of candidates (instead of --workers)")
    tb.add_argument("--max-candidates", type=positive_int, default=50_000, help="give up after this many per split (default: 50000)")
    tb.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    tb.set_defaults(func=_tasks)
    bk = tasks_sub.add_parser("best-known", help="the best known score of every pool task (a per-task CMA-ES over "
                                                 "action schedules; resumable) into envs/benchmark/<version>_best_known.json "
                                                 "(training pools: <version>_best_known_train.json)")
    _add_version(bk)
    bk.add_argument("--tiers", nargs="+", default=None, choices=all_task_tiers() + capture_tiers(),
                    help="tiers (default: every tier of --version)")
    bk.add_argument("--splits", nargs="+", default=["test", "validation"], choices=["train", "validation", "test"],
                    help="pools searched (default: test validation)")
    bk.add_argument("--work", default="studies/best-known",
                    help="finished tasks, one jsonl per pool (default: studies/best-known, kept in git)")
    bk.add_argument("--doubled", type=positive_int, default=None, metavar="N",
                    help="instead: re-run N random stored tasks of these pools with twice the generations and store "
                         "the gap in the file")
    bk.add_argument("--screened", action="store_true",
                    help="instead: search again, on the screened objective, every stored task family whose best "
                         "candidates failed the certificate test; what beats the stored score and passes it is kept")
    bk.add_argument("--write-shipped", action="store_true",
                    help="write the package's own best-known files (a build of each whole file, from a source "
                         "checkout); default: their copies inside --work")
    bk.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    add_scheduler_option(bk, "tasks' searches")
    bk.set_defaults(func=_tasks_best_known)
    tt = tasks_sub.add_parser("tables", help="the tier tables of a version's pool files (docs/envs.md shows them)")
    _add_version(tt)
    tt.add_argument("--docs", default=None, help="write them between their markers in this file (default: print)")
    tt.set_defaults(func=_tasks_tables)
    fr = tasks_sub.add_parser("freeze-reference", help="write a version's frozen reference (the normalised column's "
                                                       "divisor) from its best-known file, once")
    _add_version(fr)
    fr.add_argument("--out", default=None, help="file to write (default: the shipped envs/benchmark/<version>_reference.json)")
    fr.set_defaults(func=_tasks_freeze_reference)
    ds = sub.add_parser("dataset", help="the best known trajectories of a tier's pool as a Minari dataset (offline RL, "
                                        "imitation); needs pip install \"ffsr-gym[dataset]\"")
    ds.add_argument("--tier", default="easy", choices=all_task_tiers(), help="tier (default: easy)")
    ds.add_argument("--env-id", default="FFSR-Residual-v2", choices=["FFSR-Residual-v2", "FFSR-v2"],
                    help="the env whose actions are recorded (default: FFSR-Residual-v2)")
    ds.add_argument("--split", default="train", choices=["train", "validation"],
                    help="pool (default: train; validation is for model selection; the test pool is never a dataset)")
    ds.add_argument("--root", default=None, help="datasets folder (default: MINARI_DATASETS_PATH or Minari's default)")
    ds.add_argument("--author", default=None, help="who builds it (default: git's user.name, where set)")
    ds.add_argument("--author-email", default=None, help="their contact (default: git's user.email, where set)")
    ds.set_defaults(func=_dataset)

@contextmanager
def _executor(args: argparse.Namespace, local_workers: int = 1) -> Iterator[tuple[Any, int]]:
    """``(executor, slots)`` of a long command: :func:`ffsr_gym.cluster.study_executor` of its ``--scheduler``."""
    from ffsr_gym.cluster import study_executor
    from ffsr_gym_lab.pools.build import die_with_parent

    with study_executor(args.scheduler, local_workers, die_with_parent) as pair:
        yield pair


def _tasks(args: argparse.Namespace) -> None:
    from ffsr_gym_lab.pools.build import build

    with _executor(args, args.workers) as (executor, workers):
        version = args.version
        work = args.work or f"studies/tasks-{version}"
        data = build(work, version=version, target=version if args.tier == "base" else args.tier, out=args.out,
                     chunk=args.chunk, max_candidates=args.max_candidates, executor=executor, workers=workers,
                     progress=not args.no_progress)
    for split, summary in data["splits"].items():
        print(f"{split}: {summary['candidates']} candidates, tiers {summary['tier_counts']}, "
              f"rejected {summary['rejection_counts']}")


def _tasks_best_known(args: argparse.Namespace) -> None:
    import shlex

    import numpy as np

    from ffsr_gym.exceptions import InvalidInputError
    from ffsr_gym.tasks.splits import version_tiers
    from ffsr_gym_lab.best_known import build
    from ffsr_gym_lab.best_known.records import records

    work = Path(args.work)
    if work.exists() and not work.is_dir():  # before any search, not after the first task's
        raise InvalidInputError(f"--work {args.work!r}: not a folder; allowed: a folder (made when missing)")
    args.tiers = args.tiers or list(version_tiers(args.version))
    wrong = sorted(set(args.tiers) - set(version_tiers(args.version)))
    if wrong:
        raise InvalidInputError(f"--tiers {wrong} with --version {args.version}; allowed: "
                                f"{list(version_tiers(args.version))}")
    if args.scheduler is not None and (args.doubled or args.screened):
        raise InvalidInputError("--scheduler with --doubled or --screened; allowed: --scheduler for the search alone")
    if args.doubled and args.screened:
        raise InvalidInputError("--doubled with --screened; allowed: one of them")
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
    if args.screened:
        from ffsr_gym_lab.best_known.screen import rescreen

        for tier in args.tiers:
            for split in args.splits:
                raised = rescreen(tier, split, work, version=args.version, progress=not args.no_progress)
                print(f"{tier}/{split}: the screened search raised {raised} task families")
    else:
        with _executor(args) as (executor, _):
            for tier in args.tiers:
                for split in args.splits:
                    build.run(tier, split, work, version=args.version, progress=not args.no_progress,
                              executor=executor)
    command = shlex.join(["ffsr-gym", "tasks", "best-known", "--version", args.version, "--tiers", *args.tiers,
                          "--splits", *args.splits] + (["--screened"] if args.screened else [])
                         + (["--write-shipped"] if args.write_shipped else []))
    for path in build.assemble(work, version=args.version, command=command, splits=args.splits,
                               shipped=args.write_shipped):
        print("wrote", path)


def _tasks_tables(args: argparse.Namespace) -> None:
    from ffsr_gym.provenance import write_text_atomic
    from ffsr_gym_lab.pools.tables import docs_tables, splice_docs_tables

    if args.docs is None:
        for name, table in docs_tables(args.version).items():
            print(f"{name}:\n{table}")
        return
    from ffsr_gym.environments.info import docs_section
    from ffsr_gym.provenance import splice_generated
    from ffsr_gym.user_files import read_text

    path = Path(args.docs)
    text = splice_docs_tables(read_text(path), args.version, where=str(path))
    text = splice_generated(text, "<!-- info-keys:begin -->", "<!-- info-keys:end -->", docs_section(), where=str(path))
    write_text_atomic(path, text)
    print("wrote the tier tables and the info keys into", path)


def _dataset(args: argparse.Namespace) -> None:
    from ffsr_gym_lab.publish.dataset import write_dataset

    dataset = write_dataset(args.tier, args.env_id, split=args.split, root=args.root, author=args.author,
                            author_email=args.author_email)
    print(f"wrote {dataset.spec.dataset_id}: {dataset.total_episodes} episodes, {dataset.total_steps} steps"
          + (f" under {args.root}" if args.root else " (MINARI_DATASETS_PATH or Minari's default folder)")
          + f"\n{dataset.storage.metadata['description']}")  # says how much of the pool it holds


def _tasks_freeze_reference(args: argparse.Namespace) -> None:
    from ffsr_gym_lab.pools.freeze import freeze

    print("wrote", freeze(args.version, out=args.out, command=" ".join(["ffsr-gym", *args.argv])))


def _add_version(parser: argparse.ArgumentParser, text: str = "benchmark version") -> None:
    """The ``--version`` option of the ``tasks`` commands: a version with task tiers, the ranked one by default."""
    parser.add_argument("--version", default=tier_versions()[0], choices=tier_versions(),
                        help=f"{text} (default: {tier_versions()[0]})")
