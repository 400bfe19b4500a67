"""Perturbed tiers ``debris``, ``robust`` and ``servo``: zero perturbation is the base task, pools are the first
certified base tier tasks, draws stay in the documented ranges (the servo tier's own checks:
``tests/library/tasks/test_servo_tier.py``). Their certificates are replayed through the
environments and the ensemble with the base tiers' (``tests/library/tasks/test_tasks.py``: a sample in CI, all with ``-m slow``).
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import assert_edited_rule_file_is_named
from test_tasks import CODES
from test_vector_env import lockstep, make_vec

import ffsr_gym  # noqa: F401  (registers the environments)
from ffsr_gym.model.resources import envs_dir
from ffsr_gym.sim.simulate import make_rollout
from ffsr_gym.tasks.generator import draw_task
from ffsr_gym.tasks.perturbation import DRAWN_TIERS, PERTURBED_TIERS, load_perturbed_rule, perturbed_task
from ffsr_gym.tasks.splits import SEED_RANGES, load_pools, pool
from ffsr_gym.tasks.tiers import certify, classify_perturbed
from ffsr_gym.versions.registry import load_benchmark

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

BENCH = load_benchmark("v2")
SPLITS = BENCH.tasks.splits
RANGES = tomllib.loads((envs_dir() / "benchmark" / "v2_perturbed.toml").read_text())
BASE_LABELS = {split: load_pools()["splits"][split] for split in SPLITS}
LOGGED = ("q", "v", "dq_joints", "ee_position_error_m", "ee_attitude_error", "clearance_m", "self_clearance_m", "mu",
          "cdf")


def _trajectory(task, certificate):
    rollout = make_rollout(task, backend="kernel", m=certificate.m, T_c=certificate.T_c_s)
    rollout.advance(task.n_steps, stop_on_violation=True)
    rollout.finish()
    return rollout.trajectory()


@pytest.mark.parametrize("tier", DRAWN_TIERS)
def test_zero_perturbation_reproduces_the_medium_tier_bit_for_bit(tier):
    """With every range collapsed, the perturbed code paths (debris section, plant, momentum, noise)
    find the base task's certificate and its score, and move exactly as the base task."""
    zero = load_perturbed_rule("v2").zero()
    for entry in pool("medium", "test")[:3]:
        task = perturbed_task(tier, entry.seed, BENCH, zero)
        assert (task.debris is not None) == (tier == "debris") and (task.target_noise is not None) == (tier == "robust")
        found = certify(task, entry.seed, BENCH)
        assert found.default_failure is not None  # medium: the default planner fails on it too
        assert found.certificate == entry.certificate
        assert found.result.score == entry.certificate_score
        perturbed = _trajectory(task, entry.certificate)
        plain = _trajectory(draw_task(entry.seed, BENCH), entry.certificate)
        for name in LOGGED:
            assert np.array_equal(getattr(perturbed, name), getattr(plain, name)), name


@pytest.mark.parametrize("tier", PERTURBED_TIERS)
def test_pools_are_the_first_certified_base_tier_tasks_disjoint_and_full(tier):
    data = load_pools(None, (tier,))
    seen: set[int] = set()
    for split in SPLITS:
        summary, base = data["splits"][split], BASE_LABELS[split]
        labels = [CODES[c] for c in summary["labels"]]
        seeds = range(summary["first_seed"], summary["first_seed"] + len(labels))
        assert summary["first_seed"] == SEED_RANGES[split][0] == base["first_seed"]
        for seed, label in zip(seeds, labels):  # candidates are exactly the base tier tasks
            in_base_tier = CODES[base["labels"][seed - base["first_seed"]]] in ("easy", "medium", "hard")
            assert (label != "base_rejected") == in_base_tier, seed
        expected = int(RANGES[f"{split}_tasks"])
        pool_seeds = [t.seed for t in pool(tier, split)]
        assert pool_seeds == [s for s, label in zip(seeds, labels) if label == tier][:expected]
        assert len(pool_seeds) == expected and not seen & set(pool_seeds)
        seen |= set(pool_seeds)


@pytest.mark.parametrize("tier", PERTURBED_TIERS)
def test_the_rule_reruns_to_the_stored_labels(tier):
    summary = load_pools(None, (tier,))["splits"]["test"]
    first, base = summary["first_seed"], BASE_LABELS["test"]["labels"]
    for offset in range(8):
        admitted = CODES[base[offset]] in ("easy", "medium", "hard")
        verdict = classify_perturbed(tier, first + offset, BENCH, base_admitted=admitted)
        assert (verdict.tier or verdict.rejection) == CODES[summary["labels"][offset]], first + offset


def test_debris_draws_stay_in_the_documented_ranges():
    spec = RANGES["debris"]
    for split in SPLITS:
        for entry in pool("debris", split)[:20]:
            task, base = perturbed_task("debris", entry.seed, BENCH), draw_task(entry.seed, BENCH)
            d = task.debris
            assert spec["extra_obstacles"][0] <= len(d.positions_m) <= spec["extra_obstacles"][1]
            speed = np.linalg.norm(d.obstacle_velocity_m_s)
            assert spec["obstacle_speed_m_s"][0] <= speed <= spec["obstacle_speed_m_s"][1]
            for radius, velocity in zip(d.radii_m, d.velocities_m_s):
                assert spec["radius_m"][0] <= radius <= spec["radius_m"][1]
                assert spec["debris_speed_m_s"][0] <= np.linalg.norm(velocity) <= spec["debris_speed_m_s"][1] + 1e-15
            assert dataclasses.replace(task, debris=None, name=base.name, description=base.description) == base
            assert task.target == base.target and task.initial == base.initial  # bit for bit, not normalised again


def test_robust_draws_stay_in_the_documented_ranges():
    spec = RANGES["robust"]
    for entry in pool("robust", "train")[:20]:
        task, base = perturbed_task("robust", entry.seed, BENCH), draw_task(entry.seed, BENCH)
        plant, noise, momentum = task.plant, task.target_noise, np.array(task.initial.momentum)
        assert all(spec["mass_scale"][0] <= x <= spec["mass_scale"][1] for x in plant.mass_scale)
        assert all(spec["inertia_scale"][0] <= x <= spec["inertia_scale"][1] for x in plant.inertia_scale)
        assert np.max(np.abs(plant.com_offset_m)) <= spec["com_offset_m"]
        assert np.max(np.abs(momentum[:3])) <= spec["linear_momentum_kg_m_s"]
        assert np.max(np.abs(momentum[3:])) <= spec["angular_momentum_kg_m2_s"]
        assert np.max(np.abs(noise.position_bias_m)) <= spec["position_bias_m"]
        assert np.max(np.abs(noise.attitude_bias_rad)) <= spec["attitude_bias_rad"]
        assert (noise.position_sigma_m, noise.attitude_sigma_rad, noise.interval_s) == (
            spec["position_sigma_m"], spec["attitude_sigma_rad"], spec["interval_s"])
        assert np.any(momentum != 0.0) and np.any(np.array(plant.mass_scale) != 1.0)
        assert dataclasses.replace(task, plant=None, target_noise=None, initial=base.initial, name=base.name,
                            description=base.description) == base


@pytest.mark.parametrize("tier", PERTURBED_TIERS)
def test_batched_env_on_a_perturbed_tier_equals_single_envs(tier):
    import gymnasium as gym

    n = 2
    venv = make_vec("FFSR-Residual-v2", n, task=tier)
    singles = [gym.make("FFSR-Residual-v2", task=tier) for _ in range(n)]
    obs, info = venv.reset(seed=5)
    resets = [env.reset(seed=5 + i) for i, env in enumerate(singles)]
    np.testing.assert_array_equal(obs, np.stack([r[0] for r in resets]))
    assert list(info["task_seed"]) == [r[1]["task_seed"] for r in resets]
    lockstep(venv, singles, 40, np.random.default_rng(2), lambda a, b: a == b, lambda *args: None)


def test_pool_files_record_the_rule_they_were_built_under():
    from ffsr_gym_lab.pools.build import rule_sha256

    for tier in PERTURBED_TIERS:
        assert load_pools(None, (tier,))["rule_sha256"] == rule_sha256(tier, "v2")
        assert Path(envs_dir() / "benchmark" / f"v2_{tier}_tasks.json").is_file()


@pytest.mark.parametrize("tier", PERTURBED_TIERS)
def test_docs_tables_are_generated_from_the_pool_files(tier):
    from ffsr_gym_lab.pools.tables import tier_table

    text = (Path(__file__).resolve().parents[3] / "docs" / "envs.md").read_text(encoding="utf-8")
    block = text.split(f"<!-- tiers-{tier}:begin -->\n")[1].split(f"<!-- tiers-{tier}:end -->")[0]
    assert block == tier_table(load_pools(None, (tier,)))


def test_robust_task_conserves_the_momentum_it_draws_for_its_own_plant():
    """A robust test task in the kernel: the centroidal momentum of a Pinocchio model built here from
    the task's drawn plant stays at the drawn C to 1e-10 over the certificate's episode."""
    import pinocchio as pin
    from test_plant import _perturbed_pinocchio

    entry = pool("robust", "test")[0]
    task = perturbed_task("robust", entry.seed, BENCH)
    model, data, _, _ = _perturbed_pinocchio(task.plant)
    trajectory = _trajectory(task, entry.certificate)
    momentum = np.array(task.initial.momentum)
    worst = max(float(np.max(np.abs(pin.computeCentroidalMomentum(model, data, q, v).vector - momentum)))
                for q, v in zip(trajectory.q, trajectory.v))
    assert worst <= 1e-10 and np.max(np.abs(momentum)) > 0.1


def test_what_the_perturbations_change_for_the_reference_planner():
    """docs/envs.md: on the test pools, the reference (0.3, 4 s) changes outcome on more than 30 % of the tasks of
    each perturbed tier against their base tasks (v1's robust ranges: at most 10 %), mostly from success to failure."""
    from ffsr_gym.tasks.certificate import planner_episode
    from ffsr_gym.tasks.splits import task_scenario

    def succeeds(task):
        return planner_episode(task, BENCH, method="predefined_time", m=0.3, T_c=4.0).success

    for tier in DRAWN_TIERS:
        pairs = [(succeeds(draw_task(e.seed, BENCH)), succeeds(task_scenario(tier, e.seed, BENCH)))
                 for e in pool(tier, "test")]
        lost, gained = sum(a and not b for a, b in pairs), sum(b and not a for a, b in pairs)
        assert lost + gained > 0.30 * len(pairs) and lost > 3 * gained, (tier, lost, gained)


@pytest.mark.parametrize("old, new, message", [
    ("mass_scale = [0.8, 1.2]", "mass_scale = [0.8, 3.0]",
     "'robust.mass_scale[1]' = 3.0 is out of range; allowed: [0.5, 2.0]"),
    ("extra_obstacles = [1, 3]", "extra_obstacles = [1.5, 3]",
     "'debris.extra_obstacles' = [1.5, 3.0]; allowed: two integers"),
    ("radius_m = [0.02, 0.08]", "radius_m = [0.08, 0.02]", "'debris.radius_m' = [0.08, 0.02]; allowed: [low, high]"),
    ("interval_s = 0.1", "interval_s = 0.1\nspin = 1", "unknown key 'robust.spin'"),
])
def test_malformed_perturbed_rule_is_named(tmp_path, monkeypatch, old, new, message):
    from ffsr_gym.tasks import perturbation

    assert_edited_rule_file_is_named(monkeypatch, tmp_path, "v2_perturbed.toml", "rule_path",
                                     perturbation.load_perturbed_rule, (old, new), message)
