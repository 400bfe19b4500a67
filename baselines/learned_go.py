"""A timing learned from simulated outcomes on capture v1 or v2 (``learned_go``): supervised learning of when to go in.

    python baselines/learned_go.py --leaderboard leaderboards [--version capture-v2] [--tiers sweep] [--workers 2]

1. **Data** (training and validation pools): for every task, the observations of the episode that holds the start
   pose, at every moment of a 0.5 s grid, and the score that going in at that moment earns (the default planner
   (0.3, 4 s), simulated as the env plays it: ``ffsr_gym.bench.lookahead``). Resumable: one file per task in
   ``--work`` (default ``runs/learned_go`` for capture v1, ``runs/learned_go/<version>`` for a later version).
2. **Fit** a network (76 -> 128 -> 128 -> 1, ReLU; torch, seeded) from observation to that score on the training
   pool's samples (mean squared error, Adam), on inputs standardised by their training mean and spread; a feature
   whose spread is below ``CONSTANT_SPREAD`` (the held start pose, and its joint rates, which are the integrator's
   residue) is centred, not scaled, so that the policy does not read a difference of another time step as a signal
   (scaled, they made its verdicts at dt/4 agree with dt's on 51-74 % of the test tasks).
3. **Tune** the threshold and how many consecutive moments must reach it (1-3) on the validation pool: the policy
   (``ffsr_gym.bench.learned_go.LearnedGo``) decides at the grid's moments, so its validation score for a setting is
   read exactly off the validation data.
4. **Evaluate** the policy on the test pool through ``ffsr_gym.evaluate`` (a trace of its actions is stored, which
   the board replays) and write the entry. An existing entry is kept.

The test pool is never simulated here but by ``evaluate``.
"""

from __future__ import annotations

import argparse
import os
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import gymnasium as gym
import numpy as np
from tqdm.auto import tqdm

import ffsr_gym
from ffsr_gym.bench.learned_go import LearnedGo, Regressor
from ffsr_gym.bench.lookahead import Lookahead
from ffsr_gym.provenance import write_json_atomic
from ffsr_gym.scoring.rules import score_rule
from ffsr_gym.tasks.splits import pool, task_scenario
from ffsr_gym.versions.registry import load_benchmark, spec_for_version
from ffsr_gym_lab.board.tables import headline

#: The capture versions the policy plays (the approach command in the action), the first the default.
VERSIONS = ("capture-v1", "capture-v2")
NAME, STEP_S, SEED = "learned_go", 0.5, 0
HIDDEN, EPOCHS, BATCH, LEARNING_RATE = (128, 128), 60, 512, 1e-3
#: Below this spread over the training samples a feature counts as constant (module docstring, step 2): the held
#: pose's joint rates are the integrator's residue, 4e-5 rad/s at dt = 0.01 s and 2e-6 at dt/4, spread 4e-6 over
#: the samples; scaled by that spread, they were the network's strongest inputs and turned it into a detector of
#: the time step (its predictions at dt/4 fell below any threshold).
CONSTANT_SPREAD = 1e-3
THRESHOLDS = np.round(np.arange(0.05, 0.451, 0.01), 3)
#: Consecutive moments above the threshold before going in, tuned with it.
CONFIRMS = (1, 2, 3)


def task_data(tier: str, split: str, index: int, version: str = VERSIONS[0]) -> tuple[np.ndarray, np.ndarray]:
    """(observations at the grid's moments while holding the start pose, the score of going in at each)."""
    spec = spec_for_version(version)
    benchmark, duration_s = load_benchmark(version), score_rule(spec).duration_s
    lookahead = Lookahead(step_s=STEP_S)
    scores = lookahead.scores(task_scenario(tier, pool(tier, split, version=version)[index].seed, benchmark), benchmark,
                              duration_s)
    env = gym.make(spec.ids.parameters, task=tier, split=split)
    obs, _ = env.reset(seed=0, options={"task_index": index})
    every = int(round(STEP_S / 0.1))
    seen = [obs]
    for _ in range(len(scores) * every - 1):
        obs, _, terminated, truncated, _ = env.unwrapped.step_with_parameters(lookahead.m, lookahead.T_c_s, command=0.0)
        if terminated or truncated:
            break
        seen.append(obs)
    env.close()
    observations = np.asarray(seen[::every], dtype=np.float64)
    return observations, scores[:len(observations)]


def _collect_one(job: tuple[str, str, int, str, str]) -> str:
    tier, split, index, path, version = job
    start = time.perf_counter()
    observations, scores = task_data(tier, split, index, version)
    part = Path(path).with_suffix(".part.npz")
    np.savez(part, observations=observations, scores=scores, seconds=time.perf_counter() - start)
    os.replace(part, path)
    return path


def collect(tier: str, split: str, work: Path, workers: int,
            version: str = VERSIONS[0]) -> tuple[list[tuple[np.ndarray, np.ndarray]], float, int]:
    """Every task's data of a pool, computing what ``work`` does not hold yet; the seconds its simulation took (as
    each task's file records them) and how many files record none (made before files kept their time)."""
    tasks = len(pool(tier, split, version=version))
    paths = [work / f"{tier}-{split}-{index:03d}.npz" for index in range(tasks)]
    jobs = [(tier, split, index, str(path), version) for index, path in enumerate(paths) if not path.exists()]
    with ProcessPoolExecutor(workers) as executor:
        for _ in tqdm(executor.map(_collect_one, jobs), total=len(jobs), desc=f"data {tier}/{split}", unit="task"):
            pass
    out, seconds, untimed = [], 0.0, 0
    for path in paths:
        with np.load(path) as data:
            out.append((data["observations"], data["scores"]))
            if "seconds" in data:
                seconds += float(data["seconds"])
            else:
                untimed += 1
    return out, seconds, untimed


def fit(data: list[tuple[np.ndarray, np.ndarray]]) -> Regressor:
    """The network fitted to every (observation, score) sample of ``data`` (module docstring)."""
    import torch

    torch.manual_seed(SEED)
    x = np.concatenate([obs for obs, _ in data])
    y = np.concatenate([scores for _, scores in data])
    # a feature that barely varies over the training samples (the held pose, its joint rates: CONSTANT_SPREAD) is
    # centred, not scaled: divided by its spread, a difference of another time step would be a large input
    mean, spread = x.mean(axis=0), x.std(axis=0)
    scale = np.where(spread > CONSTANT_SPREAD, spread, 1.0)
    inputs = torch.tensor((x - mean) / scale, dtype=torch.float32)
    targets = torch.tensor(y, dtype=torch.float32)[:, None]
    layers, width = [], x.shape[1]
    for hidden in HIDDEN:
        layers += [torch.nn.Linear(width, hidden), torch.nn.ReLU()]
        width = hidden
    network = torch.nn.Sequential(*layers, torch.nn.Linear(width, 1))
    optimiser = torch.optim.Adam(network.parameters(), lr=LEARNING_RATE)
    generator = torch.Generator().manual_seed(SEED)
    for _ in tqdm(range(EPOCHS), desc="fit", unit="epoch"):
        for batch in torch.randperm(len(inputs), generator=generator).split(BATCH):
            optimiser.zero_grad()
            torch.nn.functional.mse_loss(network(inputs[batch]), targets[batch]).backward()
            optimiser.step()
    linear = [layer for layer in network if isinstance(layer, torch.nn.Linear)]
    return Regressor(mean, scale, tuple(layer.weight.detach().double().numpy().T.copy() for layer in linear),
                     tuple(layer.bias.detach().double().numpy().copy() for layer in linear))


def offline_score(regressor: Regressor, threshold: float, data: list[tuple[np.ndarray, np.ndarray]],
                  late_s: float, confirm: int = 1) -> float:
    """The mean score of the policy over ``data``'s tasks: it goes in at the first grid moment that ends ``confirm``
    consecutive moments whose prediction reaches ``threshold``, else at the first at or after ``late_s``."""
    total = 0.0
    for observations, scores in data:
        moments = np.arange(len(scores)) * STEP_S
        above = (regressor(observations) >= threshold).astype(int)
        confirmed = np.convolve(above, np.ones(confirm, dtype=int))[:len(above)] >= confirm
        chosen = np.flatnonzero(confirmed | (moments >= late_s - 1e-9))
        total += float(scores[chosen[0]]) if len(chosen) else 0.0
    return total / len(data)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--leaderboard", required=True, help="leaderboard root; entries go to <root>/<version>/<tier>/")
    parser.add_argument("--version", default=VERSIONS[0], choices=VERSIONS,
                        help="capture version (default: %(default)s)")
    parser.add_argument("--tiers", nargs="+", default=None, help="tiers (default: every tier of the version)")
    parser.add_argument("--work", default=None, help="the data, one file per task (resumable; default: "
                        "runs/learned_go, and runs/learned_go/<version> for a later version)")
    parser.add_argument("--workers", type=int, default=1, help="processes for the data (default: 1)")
    args = parser.parse_args()
    version = args.version
    spec = spec_for_version(version)
    work = Path(args.work or ("runs/learned_go" if version == VERSIONS[0] else f"runs/learned_go/{version}"))
    work.mkdir(parents=True, exist_ok=True)
    for tier in args.tiers or spec.tasks.tiers:
        folder = Path(args.leaderboard) / version / tier
        if (folder / f"{NAME}.json").exists():
            print("kept", folder / f"{NAME}.json")
            continue
        (train, *timed), (validation, *more) = (collect(tier, split, work, args.workers, version) for split in
                                                 ("train", "validation"))
        start = time.perf_counter()  # the data's simulation is counted from the time each task's file records
        regressor = fit(train)
        policy = LearnedGo(regressor=regressor, threshold=0.0, every_s=STEP_S)
        late_s = policy.duration_s - policy.approach_s
        tuned = {(float(t), c): offline_score(regressor, float(t), validation, late_s, c)
                 for c in CONFIRMS for t in THRESHOLDS}
        threshold, confirm = max(tuned, key=lambda key: (tuned[key], -key[1], -key[0]))
        simulated = sum(len(scores) for _, scores in train + validation)
        untimed = timed[1] + more[1]
        compute = {"objective_evaluations": simulated, "wall_time_s": timed[0] + more[0] + time.perf_counter() - start,
                   "hardware": "1 CPU core per task" + (f"; the wall time leaves out {untimed} tasks' data, simulated "
                                                        "by an earlier run that kept no time" if untimed else "")}
        policy = LearnedGo(regressor=regressor, threshold=threshold, confirm=confirm, every_s=STEP_S)
        report = ffsr_gym.evaluate(policy, spec.ids.parameters, task=tier, name=NAME, progress=True, compute=compute,
                                   training_pool=f"{tier}/train (threshold: {tier}/validation)",
                                   policy_library=f"torch {__import__('torch').__version__}")
        report.extra |= {"method": (
            "learned timing: the default planner, the insertion commanded at the first 0.5 s moment that ends "
            f"{confirm} consecutive moments whose predicted score of going in reaches {threshold:g} (a 76-128-128-1 "
            "network fitted to the simulated outcomes of going in at every moment of the training tasks; the "
            "threshold and the count tuned on the validation pool)"),
            "learned_go": {"threshold": threshold, "confirm": confirm, "hidden": list(HIDDEN), "epochs": EPOCHS,
                           "seed": SEED, "samples": int(sum(len(s) for _, s in train)),
                           "validation_by_setting": [{"threshold": t, "confirm": c, "validation_mean": v}
                                                     for (t, c), v in tuned.items()]}}
        write_json_atomic(work / f"{tier}-regressor.json", {"threshold": threshold, "confirm": confirm,
                                                            **regressor.as_dict()})
        print(tier, f"threshold {threshold:g}, confirm {confirm}: validation {tuned[threshold, confirm]:.3f};",
              headline(spec, report.metrics),
              "->", report.save(folder))


if __name__ == "__main__":
    main()
