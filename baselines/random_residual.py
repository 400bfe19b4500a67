"""The lower reference: a uniformly random residual on every tier's test pool (``random_residual`` entries).

    python baselines/random_residual.py --leaderboard leaderboards [--version capture-v0|capture-v1|capture-v2]
                                        [--tiers slow]

At every decision the policy draws each entry of the version's residual action (the 12 residual rates,
and on capture v1 the approach's command) uniformly from [-1, 1]
(``ffsr_gym.bench.policies.uniform_random_residual``, seeded by the observation so that ``ffsr-gym
leaderboard verify`` re-runs it exactly). An existing entry is kept.
"""

import argparse
from pathlib import Path

import ffsr_gym
from ffsr_gym.bench.policies import uniform_random_residual
from ffsr_gym.versions.registry import spec_for_version
from ffsr_gym_lab.board.tables import headline

CALLABLE = "ffsr_gym.bench.policies:uniform_random_residual"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--leaderboard", required=True, help="leaderboard root; entries go to <root>/<version>/<tier>/")
    parser.add_argument("--version", default="v2",
                        help="a pool benchmark version (default: v2; or capture-v0, capture-v1, capture-v2)")
    parser.add_argument("--tiers", nargs="+", default=None, help="tiers (default: every tier of the version)")
    args = parser.parse_args()
    spec = spec_for_version(args.version)
    for tier in args.tiers or spec.tasks.tiers:
        folder = Path(args.leaderboard) / args.version / tier
        if (folder / "random_residual.json").exists():
            print("kept", folder / "random_residual.json")
            continue
        report = ffsr_gym.evaluate(uniform_random_residual, spec.ids.residual, task=tier, name="random_residual",
                                   progress=True)
        report.extra |= {"policy": {"callable": CALLABLE},
                         "method": "uniform random residual in [-1, 1]^12 at every decision (lower reference)"}
        print(tier, headline(spec, report.metrics), "->", report.save(folder))


if __name__ == "__main__":
    main()
