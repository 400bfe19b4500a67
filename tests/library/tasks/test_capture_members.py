"""Our own ensemble members for capture certificates (experiments/capture_v1_members.py): none is a member a capture
build uses (v1's four drawn spin patterns at 0.3 deg/s; v2's eight at 0.4 deg/s and its drift along the axes), each
moves what its family says by the amount it says, and capture v1's docs block is the one its committed result
generates."""

from __future__ import annotations

import itertools
import json
from pathlib import Path

import numpy as np
import pytest
from conftest import script_module

from ffsr_gym.tasks.certificate import ensemble_members
from ffsr_gym.tasks.splits import pool, task_scenario
from ffsr_gym.versions.registry import load_benchmark

ROOT = Path(__file__).resolve().parents[3]
STUDY = script_module("capture_v1_members")


def _motion(task):
    body = task.tumbling_target
    return np.asarray(body.omega_body_deg_s, dtype=float), np.asarray(body.velocity_m_s, dtype=float)


@pytest.mark.parametrize("version", ["capture-v1", "capture-v2"])
def test_our_members_move_the_target_by_their_amounts_and_are_none_of_the_builds(version):
    benchmark = load_benchmark(version)
    seed = pool("sweep", "train", version="capture-v1")[0].seed  # the same candidate in both versions
    task = task_scenario("sweep", seed, benchmark)
    spin, drift = _motion(task)
    ours = STUDY.members(task, seed)
    built = ensemble_members(task, seed, benchmark.tasks.ensemble, pinocchio=False)
    built_motion = [_motion(m.task) for m in built]
    for family, tasks in ours.items():
        for member in tasks:
            w, v = _motion(member)
            if family.startswith("spin"):
                offset = float(family.split()[1])
                np.testing.assert_allclose(np.abs(w - spin), offset, atol=1e-12)
                np.testing.assert_array_equal(v, drift)
            elif family.startswith("drift"):
                assert np.linalg.norm(v - drift) == pytest.approx(0.001, abs=1e-12)
                assert np.max(np.abs(v - drift)) < 0.001  # not along an axis, where v2's drift members are
                np.testing.assert_array_equal(w, spin)
            else:
                np.testing.assert_array_equal(w, spin)
                np.testing.assert_array_equal(v, drift)
            moved = [(bw, bv) for bw, bv in built_motion
                     if not (np.array_equal(bw, spin) and np.array_equal(bv, drift))]
            assert all(not (np.allclose(w, bw, atol=1e-12) and np.allclose(v, bv, atol=1e-12)) for bw, bv in moved)
    steps = {m.task.simulation.dt_s for m in built}
    assert not steps & {ours["dt/3"][0].simulation.dt_s, ours["dt/8"][0].simulation.dt_s}


def test_capture_v2_builds_spin_members_at_the_corners_of_the_box_ours_lie_inside():
    benchmark = load_benchmark("capture-v2")
    seed = pool("nutation", "train", version="capture-v1")[0].seed
    task = task_scenario("nutation", seed, benchmark)
    spin, _ = _motion(task)
    corners = {tuple(np.sign(_motion(m.task)[0] - spin)) for m in ensemble_members(task, seed, benchmark.tasks.ensemble,
                                                                                 pinocchio=False)
               if np.allclose(np.abs(_motion(m.task)[0] - spin), 0.4, atol=1e-12)}
    assert corners == set(itertools.product((-1.0, 1.0), repeat=3))
    assert all(float(f.split()[1]) < 0.4 for f in STUDY.members(task, seed) if f.startswith("spin"))


def test_capture_v1s_docs_block_is_the_generated_one():
    result = json.loads((ROOT / "experiments" / "capture_v1_members.json").read_text(encoding="utf-8"))
    start, end = STUDY.markers("capture-v1")
    page = (ROOT / "docs" / "model.md").read_text(encoding="utf-8")
    assert f"{start}\n{STUDY.docs_text(result)}{end}" in page
    assert STUDY.default_paths("capture-v1") == ("runs/capture_v1_members.json", "experiments/capture_v1_members.json")
    assert STUDY.markers("capture-v2")[0].startswith("<!-- capture-v2-members:start") and "--version capture-v2" in (
        STUDY.markers("capture-v2")[0])
