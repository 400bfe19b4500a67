"""The lower reference: a uniformly random residual on every tier's test pool (``random_residual`` entries).

    python baselines/random_residual.py --leaderboard leaderboards

At every decision the policy draws each of the 12 residual actions of ``FFSR-Residual-v2``
uniformly from [-1, 1] (``ffsr_gym.bench.policies.uniform_random_residual``, seeded by the
observation so that ``ffsr-gym leaderboard verify`` re-runs it exactly). An existing entry is kept.
"""

import argparse
from pathlib import Path

import ffsr_gym
from ffsr_gym.bench.policies import uniform_random_residual
from ffsr_gym.tasks.tiers import ALL_TIERS

CALLABLE = "ffsr_gym.bench.policies:uniform_random_residual"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--leaderboard", required=True, help="leaderboard root; entries go to <root>/v2/<tier>/")
    args = parser.parse_args()
    for tier in ALL_TIERS:
        folder = Path(args.leaderboard) / "v2" / tier
        if (folder / "random_residual.json").exists():
            print("kept", folder / "random_residual.json")
            continue
        report = ffsr_gym.evaluate(uniform_random_residual, "FFSR-Residual-v2", task=tier, name="random_residual",
                                   progress=True)
        report.extra |= {"policy": {"callable": CALLABLE},
                         "method": "uniform random residual in [-1, 1]^12 at every decision (lower reference)"}
        print(tier, f"IQM {report.metrics['score_iqm']:.3f}", "->", report.save(folder))


if __name__ == "__main__":
    main()
