"""PPO / SAC / TD3 on FFSR-v0 and FFSR-Residual-v0 (same as ``ffsr-gym train``).

    python baselines/sb3_train.py --algo ppo --env-id FFSR-v0 --seeds 0 1 2 3 4 --leaderboard leaderboards
"""

import sys

from ffsr_gym.cli.main import main

if __name__ == "__main__":
    raise SystemExit(main(["train", *sys.argv[1:]]))
