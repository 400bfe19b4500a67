"""A shortened ``ffsr-gym reproduce``: files, JSON schema and the direction of every claim."""

from __future__ import annotations

import json

import pytest

from ffsr_gym.cli import main

METRIC_KEYS = {"final_ee_position_error_m", "convergence_time_s", "peak_joint_rate_deg_s", "min_clearance_m",
               "collided", "min_sigma_J_m", "min_sigma_J_c", "convergence_after_release_s"}


@pytest.fixture(scope="module")
def reproduction(tmp_path_factory):
    out = tmp_path_factory.mktemp("reproduce")
    assert main(["reproduce", "--out", str(out), "--duration", "12", "--no-progress"]) == 0
    return out, json.loads((out / "reproduction.json").read_text())


def test_files_are_written(reproduction):
    out, _ = reproduction
    for name in ("fig3_desired_trajectory", "fig4_clearance", "fig5_ee_position_error", "fig6_pose_errors",
                 "fig8_mission_joint_rates", "fig9_balance_joint_rates", "fig10_ee_position_error_ga"):
        assert (out / f"{name}.png").stat().st_size > 10_000
    text = (out / "reproduction.md").read_text()
    assert "| claim | paper | ours | holds |" in text and "8.922e-12 m" in text


def test_json_schema(reproduction):
    _, data = reproduction
    assert set(data["methods"]) == {"no_avoidance", "no_feedback", "proportional", "predefined_time"}
    for metrics in data["methods"].values():
        assert METRIC_KEYS <= set(metrics)
        assert len(metrics["peak_joint_rate_deg_s"]["mission"]) == 6
        assert len(metrics["peak_joint_rate_deg_s"]["balance"]) == 6
    prov = data["provenance"]
    assert {"git_commit", "git_dirty", "versions", "platform", "command", "scenario_sha256", "wall_time_s"} <= set(prov)
    assert len(prov["scenario_sha256"]["paper"]) == 64
    assert prov["command"].startswith("ffsr-gym reproduce")
    assert data["settings"]["duration_s"] == 12


def test_direction_of_every_comparison(reproduction):
    _, data = reproduction
    claims = {c["claim"]: c["holds"] for c in data["claims"]}
    printed = [name for name in claims if "printed obstacle" in name]
    assert len(printed) == 1 and claims.pop(printed[0]) is False  # SPEC §10.4: it cannot interact
    failing = [name for name, holds in claims.items() if not holds]
    assert not failing
    methods = data["methods"]
    assert methods["no_avoidance"]["collided"] and not methods["predefined_time"]["collided"]
    assert (methods["proportional"]["final_ee_position_error_m"]
            > methods["predefined_time"]["final_ee_position_error_m"])
