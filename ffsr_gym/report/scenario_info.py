"""What ``ffsr-gym info`` prints of a scenario's initial state, and ``ffsr-gym list`` of the registry."""

from __future__ import annotations

from typing import Any

import numpy as np

from ffsr_gym.model.quaternion import from_rotation
from ffsr_gym.model.resources import envs_dir, scenario_names
from ffsr_gym.model.scenario import Scenario
from ffsr_gym.sim.setup import prepare
from ffsr_gym.tasks.splits import pool
from ffsr_gym.versions.registry import all_specs, registered_ids


def initial_state_rows(scenario: Scenario) -> list[tuple[str, Any]]:
    """(label, value) rows: hashes, masses, centres of mass, end-effector pose, singular values, clearance."""
    setup = prepare(scenario)
    robot, q = setup.robot, setup.q0
    ee = robot.transform_ee_to_world(q, 0)
    robot.update_kinematics(q)
    mats = robot.momentum_matrices(q)
    clearance = setup.assets.collision.clearance(q, setup.obstacles.spheres(0.0))
    return [
        ("scenario", f"{scenario.name} ({scenario.source})"),
        ("scenario sha256", scenario.sha256()[:16]),
        ("robot", f"{scenario.robot}, total mass {robot.total_mass:.1f} kg"),
        ("base CoM [m]", np.round(q[:3], 4)),
        ("system CoM [m]", np.round(robot.system_com(q), 4)),
        ("mission EE position [m]", np.round(ee.translation, 4)),
        ("mission EE attitude [w x y z]", np.round(from_rotation(ee.rotation), 4)),
        ("target position [m]", np.round(scenario.target.position_m, 4)),
        ("sigma(J_m mission)", np.round(np.linalg.svd(robot.arm_jacobian(0), compute_uv=False), 4)),
        ("sigma(H_bm balance)", np.round(np.linalg.svd(mats.H_bm[1], compute_uv=False), 3)),
        ("clearance [m]", f"{clearance.distance_m:.4f} ({clearance.pair[0]} - {clearance.pair[1]})"),
    ]


def registry_lines() -> list[str]:
    """Every id, each version's tasks and pools, the shipped scenarios and robots."""
    lines = ["environment ids: " + ", ".join(registered_ids())]
    for spec in all_specs().values():
        tasks = spec.tasks
        lines.append(f"{spec.version} ({spec.status}): {', '.join(spec.env_ids)}; {spec.description}")
        lines.append(f"  tasks ({tasks.keyword}=): " + ", ".join([*tasks.scenarios, *tasks.tiers] or ["a scenario"])
                     + ("; its pools are being built: a scenario (task=) until then" if spec.status == "building"
                        else ""))
        for tier in tasks.tiers if spec.status != "building" else ():
            sizes = (f"{split} pool {len(pool(tier, split, version=spec.rules.version))} tasks" for split in tasks.splits)
            lines.append(f"    {tier}: " + ", ".join(sizes))
    lines.append("scenarios (scenario=): " + ", ".join(scenario_names()))
    lines.append("robots: " + ", ".join(sorted(p.name for p in (envs_dir() / "robots").iterdir() if p.is_dir())))
    return lines
