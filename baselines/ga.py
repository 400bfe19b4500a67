"""The paper's GA baseline (same as ``ffsr-gym ga``): both modes, figures, table, leaderboard entries.

    python baselines/ga.py --out runs/ga --leaderboard leaderboards
"""

from ffsr_gym.cli.main import main

if __name__ == "__main__":
    raise SystemExit(main(["ga", *__import__("sys").argv[1:]]))
