"""The native kernel (C++, ``ffsr_gym._native``) against the numba kernel it replaces, measured side by side in one
run: a whole closed-loop episode of one copy (paper, and a hard test task: the danger field acting), and batched
decisions of v2 ``easy`` test tasks on threads (numba's ``decide_batch`` inside the batched env, timed alone, against
``EpisodeBatch``). Both give the same bits (tests/test_native_*.py); this measures only time.

    python benchmarks/native_kernel.py [--copies 64] [--decisions 100] [--threads 2] [--repeats 5]

Prints each row with its ratio native / numba (below 1: the native kernel is faster) and writes them with
provenance to ``benchmarks/native_kernel.json``. Run it on an otherwise idle machine.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import gymnasium as gym
import numba
import numpy as np

import ffsr_gym  # noqa: F401 - registers the ids
from ffsr_gym import _native
from ffsr_gym.kernel import loop
from ffsr_gym.model.scenario import load_scenario
from ffsr_gym.model.spec import spec_for_version
from ffsr_gym.native.planner import planner_settings
from ffsr_gym.native.robot import native_plant, native_robot
from ffsr_gym.provenance import provenance, write_json_atomic
from ffsr_gym.scoring.rules import score_rule
from ffsr_gym.sim.compiled import LOG_FIELDS, KernelRollout, settings_vectors
from ffsr_gym.sim.setup import prepare
from ffsr_gym.tasks.splits import pool, task_scenario

sys.path.insert(0, str(Path(__file__).parent))
from timing import _no_gc, best_of, kernel_time  # noqa: E402  (benchmarks/timing.py)

#: The v2 decision settings (envs/benchmark/v2.toml): residual scale, fade, motion, the (m, T_c) box, the rate
#: limit, the violation cost's clearance scale, then α, β, E_ref, V_ref.
DECISION = {"rate_scale": np.radians(20.0), "fade_s": 2.0, "motion_s": 10.0, "m_lo": 0.05, "m_hi": 0.6, "T_lo": 1.0,
            "T_hi": 10.0, "rate_limit_deg_s": 200.0, "clear_scale": 0.01, "alpha": 0.35, "beta": 0.65, "E_ref": 1.0,
            "V_ref": 10.0}


def episode_rows(scenario, repeats: int) -> tuple[float, float]:
    """Microseconds per physics step of one whole episode (no early stop): numba, native."""
    setup, rollout = prepare(scenario), KernelRollout(scenario)
    mdl, n = rollout._mdl, scenario.n_steps
    fp, ip = settings_vectors(setup, method="predefined_time", m=0.3, T_c=4.0)
    logs = [np.zeros((n, *shape)) for shape in LOG_FIELDS.values()]
    robot, settings = native_robot(mdl), planner_settings(setup, method="predefined_time", m=0.3, T_c=4.0)
    plant = native_plant(mdl, rollout.plant)
    numba_s = best_of(lambda: loop.run(mdl, rollout.plant, rollout.x.copy(), 0, n, n, fp, ip, np.zeros(12), False,
                                     False, *logs), repeats)
    native_s = best_of(lambda: _native.run(robot, settings, rollout.x.copy(), 0, n, n, np.zeros(12), False,
                                         plant=plant), repeats)
    return 1e6 * numba_s / n, 1e6 * native_s / n


def batched_numba(copies: int, decisions: int, threads: int) -> float:
    """Physics steps per second of numba's batched decisions alone (``decide_batch``), in the batched env."""
    numba.set_num_threads(threads)
    venv = gym.make_vec("FFSR-v2", num_envs=copies, vectorization_mode="vector_entry_point", task="easy",
                        split="test")
    venv.reset(seed=0, options={"task_index": list(range(copies))})
    actions = np.zeros(venv.action_space.shape, np.float32)
    venv.step(actions)
    steps = 0
    with _no_gc(), kernel_time() as spent:
        for _ in range(decisions):
            venv.step(actions)
            steps += int(venv.engine.out[:, 0].sum())
    venv.close()
    return steps / spent[0]


def batched_native(copies: int, decisions: int, threads: int) -> float:
    """Physics steps per second of ``EpisodeBatch`` on the same tasks (one pass: episodes end at the horizon)."""
    benchmark = score_rule(spec_for_version("v2")).benchmark
    settings = _native.DecisionSettings()
    for name, value in DECISION.items():
        setattr(settings, name, value)
    episodes = []
    for task in pool("easy", "test", version="v2")[:copies]:
        scenario = task_scenario("easy", task.seed, benchmark)
        setup, rollout = prepare(scenario), KernelRollout(scenario)
        episodes.append(_native.Episode(native_robot(rollout._mdl), planner_settings(
            setup, method="predefined_time", m=0.3, T_c=4.0), settings, rollout.x.copy(), scenario.n_steps,
            plant=native_plant(rollout._mdl, rollout.plant)))
    batch, n = _native.EpisodeBatch(episodes, threads), len(episodes)
    k, obs, out = np.zeros(n, np.int64), np.zeros((n, 53), np.float32), np.zeros((n, 7))
    actions, active = np.zeros((n, 2)), np.ones(n, bool)
    batch.decide(actions, active, k, 1, 10, obs, out)
    steps, start = 0, time.perf_counter()
    for _ in range(decisions):
        active = (out[:, 1] == 0) & (k < 200)
        batch.decide(actions, active, k, 1, 10, obs, out)
        steps += int(out[active, 0].sum())
    return steps / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--copies", type=int, default=64)
    parser.add_argument("--decisions", type=int, default=100)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--out", default=str(Path(__file__).with_name("native_kernel.json")))
    args = parser.parse_args()
    benchmark = score_rule(spec_for_version("v2")).benchmark
    hard = task_scenario("hard", pool("hard", "test", version="v2")[0].seed, benchmark)
    rows = []
    for name, scenario in (("paper episode", load_scenario("paper")), ("hard test task 0 episode", hard)):
        numba_us, native_us = episode_rows(scenario, args.repeats)
        rows.append({"what": f"{name}, one copy", "unit": "us per physics step", "numba": numba_us,
                     "native": native_us, "ratio": native_us / numba_us})
    numba_rate = batched_numba(args.copies, args.decisions, args.threads)
    native_rate = batched_native(args.copies, args.decisions, args.threads)
    rows.append({"what": f"batched decisions, {args.copies} easy test tasks, {args.threads} threads",
                 "unit": "physics steps per s", "numba": numba_rate, "native": native_rate,
                 "ratio": numba_rate / native_rate})
    for row in rows:
        print(f"{row['what']}: numba {row['numba']:.4g}, native {row['native']:.4g} {row['unit']}; "
              f"time ratio native / numba {row['ratio']:.3f}")
    write_json_atomic(args.out, {"rows": rows, "settings": vars(args),
                                 "provenance": provenance(command=" ".join(["python", *sys.argv]))})
    print("wrote", args.out)


if __name__ == "__main__":
    main()
