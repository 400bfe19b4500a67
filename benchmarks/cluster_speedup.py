"""The speed-up of a Dask cluster of two single-threaded workers over one, on the per-task best-known search.

Both runs search the same first ``--tasks`` tasks of one pool (each into a work folder of its own under ``--out``,
from scratch), one after the other in this process, on ``local:1`` and then ``local:2``; the ratio of their wall
times is the speed-up. Run it on an otherwise idle machine with at least two cores:

    python benchmarks/cluster_speedup.py [--version capture-v0] [--tier slow] [--split test] [--tasks 20]

Prints the two wall times and their ratio, and writes them with provenance to ``--summary``.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import time
from pathlib import Path

from ffsr_gym.cluster import cluster_executor
from ffsr_gym.optim import best_known_build as build
from ffsr_gym.provenance import provenance, write_json_atomic


def timed_search(workers: int, work: Path, args: argparse.Namespace) -> float:
    """Wall time [s] of the search of the first ``args.tasks`` tasks on a local cluster of ``workers`` workers."""
    shutil.rmtree(work, ignore_errors=True)
    with cluster_executor(f"local:{workers}", say=lambda text: None) as (executor, _):
        executor.submit(int, 0).result()  # the workers are up before the clock starts
        start = time.perf_counter()
        build.run(args.tier, args.split, work, version=args.version, indices=list(range(args.tasks)),
                  generations=args.generations, executor=executor, progress=True)
        return time.perf_counter() - start


def _results(records: list[dict]) -> list[dict]:
    """The records by task, without their wall times."""
    return [{k: v for k, v in r.items() if k != "wall_time_s"} for r in sorted(records, key=lambda r: r["index"])]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--version", default="capture-v0", help="pool version (default: capture-v0)")
    parser.add_argument("--tier", default="slow", help="tier (default: slow)")
    parser.add_argument("--split", default="test", help="split (default: test)")
    parser.add_argument("--tasks", type=int, default=20, help="tasks searched per run (default: 20)")
    parser.add_argument("--generations", type=int, default=build.search.GENERATIONS,
                        help=f"CMA-ES generations per family (default: the search's {build.search.GENERATIONS})")
    parser.add_argument("--out", default="runs/cluster_speedup", help="the runs' work folders")
    parser.add_argument("--summary", default="benchmarks/cluster_speedup.json", help="result with provenance")
    args = parser.parse_args(argv)
    if args.tasks < 2:
        parser.error(f"--tasks {args.tasks}; allowed: 2 or more (two workers need two pieces)")
    times = {workers: timed_search(workers, Path(args.out) / f"workers{workers}", args) for workers in (1, 2)}
    same = build.read_lines(build.work_file(Path(args.out) / "workers1", args.tier, args.split))
    other = build.read_lines(build.work_file(Path(args.out) / "workers2", args.tier, args.split))
    equal = _results(same) == _results(other)
    result = {"pool": f"{args.version} {args.tier}/{args.split}", "tasks": args.tasks,
              "generations": args.generations, "wall_time_s": times,
              "speedup": times[1] / times[2], "same_records": equal,
              "provenance": provenance(command=" ".join(["python", *sys.argv]))}
    write_json_atomic(Path(args.summary), result)
    print(f"{args.tasks} tasks of {result['pool']}: one worker {times[1]:.0f} s, two workers {times[2]:.0f} s, "
          f"speed-up {result['speedup']:.2f}x; the same records: {equal}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
