"""Machine independence: the numbers that feed the kernel, the task draws and the score do not
depend on which SIMD code numpy or OpenBLAS pick for this CPU (docs/model.md §17), on v2 and on capture-v0."""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
from fractions import Fraction

import numpy as np
import pinocchio as pin
import pytest

from ffsr_gym.model import portable
from ffsr_gym.model import quaternion as quat
from ffsr_gym.tasks.tiers import ALL_TIERS

#: Forces numpy onto its baseline (SSE) loops and OpenBLAS onto its Nehalem kernels, whatever the CPU.
OTHER_MACHINE = {"NPY_DISABLE_CPU_FEATURES": "X86_V3 X86_V4 AVX512_ICL AVX512_SPR", "OPENBLAS_CORETYPE": "Nehalem"}

FINGERPRINT = """
import hashlib, json, sys
import numpy as np
import gymnasium as gym
import ffsr_gym
from ffsr_gym.versions.registry import load_benchmark
from ffsr_gym._native import Method
from ffsr_gym.kernel.planner import settings_fields
from ffsr_gym.kernel.robot import robot_arrays
from ffsr_gym.sim.compiled import KernelRollout
from ffsr_gym.tasks.splits import pool, task_scenario
from ffsr_gym.tasks.tiers import ALL_TIERS


def kernel_inputs(rollout, task, model=True):
    # every number the kernel is given for this task: its state, its settings field by field, the plant's and the
    # robot's arrays
    fields = settings_fields(rollout.setup, method="predefined_time", m=task.certificate.m, T_c=task.certificate.T_c_s)
    arrays = [rollout.x]
    for name in sorted(fields):
        value = fields[name]
        if isinstance(value, tuple):  # the arguments of a set_ method
            arrays += list(value)
        else:  # a number, a flag or the method
            arrays.append(np.array([float(value.value) if isinstance(value, Method) else float(value)]))
    if model:
        arrays += [*rollout.setup.plant_arrays, *robot_arrays(rollout.model).values()]
    digest = hashlib.sha256()
    for array in arrays:
        digest.update(np.ascontiguousarray(array, dtype=float).tobytes())
    return digest.hexdigest()


bench = load_benchmark()
out = {}
for tier in ALL_TIERS:
    tasks = pool(tier, "test")
    for index in (0, len(tasks) // 2, len(tasks) - 1):
        task = tasks[index]
        scenario = task_scenario(tier, task.seed, bench)
        rollout = KernelRollout(scenario, m=task.certificate.m, T_c=task.certificate.T_c_s)
        out[f"{tier}/{index}"] = kernel_inputs(rollout, task)
from ffsr_gym.tasks.capture_family import CAPTURE_TIERS
capture = load_benchmark("capture-v0")
for tier in CAPTURE_TIERS:  # the tumbling body's motion and the approach onto its grasp frame are in the frames
    tasks = pool(tier, "test", version="capture-v0")
    for index in (0, len(tasks) // 2, len(tasks) - 1):
        task = tasks[index]
        rollout = KernelRollout(task_scenario(tier, task.seed, capture), m=task.certificate.m,
                                T_c=task.certificate.T_c_s)
        out[f"capture {tier}/{index}"] = kernel_inputs(rollout, task, model=False)
env = gym.make("FFSR-Capture-v0", task="slow", split="test")
env.reset(seed=0, options={"task_index": 0})
while True:
    *_, terminated, truncated, info = env.unwrapped.step_with_parameters(0.3, 4.0)
    if terminated or truncated:
        break
out["capture slow/0 score, capture ratio"] = [float(info["score"]).hex(), float(info["capture_ratio"]).hex()]
env = gym.make("FFSR-v2", task="hard", split="test")
env.reset(seed=0, options={"task_index": 0})
while True:
    *_, terminated, truncated, info = env.unwrapped.step_with_parameters(0.3, 4.0)
    if terminated or truncated:
        break
out["hard/0 score"] = float(info["score"]).hex()
print(json.dumps(out))
"""


def _fingerprint(extra_env: dict[str, str]) -> dict[str, str]:
    env = {**os.environ, **extra_env}
    done = subprocess.run([sys.executable, "-c", FINGERPRINT], capture_output=True, text=True, env=env, timeout=900)
    assert done.returncode == 0, done.stderr[-2000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


@pytest.mark.skipif(platform.machine().lower() not in ("x86_64", "amd64"), reason="the forced paths are x86 ones")
def test_task_settings_and_score_do_not_depend_on_the_cpu_paths_of_numpy_and_openblas():
    """Three test tasks per tier, v2's and capture-v0's: state, settings (with a tumbling target's motion and
    approach), model and plant arrays bit for bit, and one episode's score of each version (capture-v0's with its
    capture ratio, which the end-effector twist sets)."""
    here, other = _fingerprint({}), _fingerprint(OTHER_MACHINE)
    assert len(here) == 3 * len(ALL_TIERS) + 3 * 2 + 2
    assert here == other, [key for key in here if here[key] != other[key]]


def test_dot_sums_left_to_right():
    # exactly 1, but left to right 1e16 + 1 rounds back to 1e16 and the sum is 0
    a, b = [1e16, 1.0, -1e16], [1.0, 1.0, 1.0]
    assert sum(Fraction(x) * Fraction(y) for x, y in zip(a, b)) == 1
    assert portable.dot(a, b) == 0.0
    assert portable.dot([1e16, -1e16, 1.0], b) == 1.0  # the same terms in another order
    with pytest.raises(ValueError):
        portable.dot([1.0, 2.0], [1.0])


def test_norm_against_exact_rational():
    rng = np.random.default_rng(0)
    for v in rng.normal(size=(200, 3)):
        exact = sum(Fraction(float(c)) ** 2 for c in v)
        assert abs(portable.norm(v) ** 2 - float(exact)) <= 4e-16 * float(exact)


def test_quaternion_product_against_pinocchio():
    rng = np.random.default_rng(1)
    for _ in range(100):
        a, b = rng.normal(size=4), rng.normal(size=4)
        a, b = a / np.sqrt(a @ a), b / np.sqrt(b @ b)
        product = pin.Quaternion(*a) * pin.Quaternion(*b)  # Pinocchio/Eigen: (w, x, y, z) constructor
        expected = np.array([product.w, product.x, product.y, product.z])
        np.testing.assert_allclose(quat.multiply(a, b), expected, rtol=0, atol=1e-15)
