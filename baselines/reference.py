"""Leaderboard entries of the reference planner: the scenario defaults and the paper's non-optimised setting.

    python baselines/reference.py --leaderboard leaderboards
"""

import argparse

import ffsr_gym

if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("--leaderboard", required=True)
    args = parser.parse_args()
    planner = ffsr_gym.load_scenario("paper").planner
    entries = {
        "reference_scenario_defaults": ((planner.m, planner.T_c_s), "reference planner, scenario defaults (paper Figs. 4-6)"),
        "reference_non_optimised": ((0.1, 2.19), "reference planner, the paper's non-optimised setting"),
    }
    for name, (params, method) in entries.items():
        report = ffsr_gym.evaluate(params, "FFSR-v0", name=name)
        report.extra = {"method": method, "parameters": {"m": params[0], "T_c_s": params[1]}}
        print(name, report.metrics, "->", report.save(f"{args.leaderboard}/FFSR-v0", overwrite=True))
