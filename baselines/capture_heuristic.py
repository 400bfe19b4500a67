"""The practitioner's timing on capture v1 or v2: watch the handle, go in after its slowest moment (``slowest_pass``).

    python baselines/capture_heuristic.py --leaderboard leaderboards [--version capture-v2] [--tiers sweep]

The policy (``ffsr_gym.bench.capture_heuristic.SlowestPass``, docs/model.md §24) plays ``FFSR-Capture-v1`` (or v2) with
the default planner's (m, T_c) and decides only when to command the insertion, from what it observes. It is
not tuned on any pool. An existing entry is kept.
"""

import argparse
from pathlib import Path

import ffsr_gym
from ffsr_gym.bench.capture_heuristic import slowest_pass
from ffsr_gym.versions.registry import spec_for_version
from ffsr_gym_lab.board.tables import headline

CALLABLE = "ffsr_gym.bench.capture_heuristic:slowest_pass"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--leaderboard", required=True, help="leaderboard root; entries go to <root>/<version>/<tier>/")
    parser.add_argument("--version", default="capture-v1", choices=("capture-v1", "capture-v2"),
                        help="capture version (default: %(default)s)")
    parser.add_argument("--tiers", nargs="+", default=None, help="tiers (default: every tier of the version)")
    args = parser.parse_args()
    spec = spec_for_version(args.version)
    for tier in args.tiers or spec.tasks.tiers:
        folder = Path(args.leaderboard) / spec.version / tier
        if (folder / "slowest_pass.json").exists():
            print("kept", folder / "slowest_pass.json")
            continue
        report = ffsr_gym.evaluate(slowest_pass, spec.ids.parameters, task=tier, name="slowest_pass", progress=True)
        report.extra |= {"policy": {"callable": CALLABLE},
                         "method": "timing heuristic: the default planner, insertion commanded after the handle's "
                                   "slowest observed moment (at once on a steady sweep)"}
        print(tier, headline(spec, report.metrics), "->", report.save(folder))


if __name__ == "__main__":
    main()
