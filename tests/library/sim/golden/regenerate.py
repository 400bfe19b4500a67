"""Regenerate tests/library/sim/golden/paper.json (run only for an intended change; then bump the env version
in docs/envs.md and add a CHANGELOG line).

    python tests/library/sim/golden/regenerate.py
"""

import json
from pathlib import Path

import ffsr_gym
from ffsr_gym.scoring.objective import objective_terms

RUNS = {"predefined_time_m0.1_Tc3": ("predefined_time", 0.1, 3.0), "predefined_time_m0.2167_Tc2.19": ("predefined_time", 0.2167, 2.19),
        "proportional_m0.1_Tc3": ("proportional", 0.1, 3.0), "no_avoidance_m0.1_Tc3": ("no_avoidance", 0.1, 3.0)}
KEYS = ("max_ee_position_error_m", "convergence_time_s", "avoidance_release_time_s", "max_base_position_error_m",
        "min_clearance_m", "min_self_clearance_m", "min_sigma_J_m", "min_sigma_J_c", "collided")


def compute() -> dict:
    scenario = ffsr_gym.load_scenario("paper")
    out = {"scenario_sha256": scenario.sha256(), "runs": {}}
    for name, (method, m, T_c) in RUNS.items():
        traj = ffsr_gym.simulate(scenario, method=method, m=m, T_c=T_c)
        metrics = traj.metrics()
        row = {key: metrics[key] for key in KEYS}
        row["peak_joint_rate_deg_s"] = metrics["peak_joint_rate_deg_s"]
        row["objective"] = objective_terms(traj, scenario.objective).as_dict()["objective"]
        out["runs"][name] = row
    return out


if __name__ == "__main__":
    path = Path(__file__).with_name("paper.json")
    path.write_text(json.dumps(compute(), indent=2) + "\n")
    print("wrote", path)
