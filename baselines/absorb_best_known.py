"""Raise the best known scores with the baselines' own episodes (``ffsr_gym_lab.best_known.build.absorb``).

    python baselines/absorb_best_known.py --leaderboard leaderboards [--version v2] [--models studies/rl-v2]
                                          [--tiers easy hard] [--splits test validation] [--work studies/best-known]

For each tier of ``--version`` with stored best known scores, it plays on each stored pool task the
constant actions of the tier's entries (``<leaderboard>/<version>/<tier>/``): an entry's fixed
residual (``extra.policy.fixed`` on the version's residual id), and a predefined-time planner
entry's constant (m, T_c) (``extra.planner``), as the action of the version's (m, T_c) id that
maps onto it (rounded to float32, as the env rounds actions; an (m, T_c) outside the action box is
skipped, named). On capture v1 a planner entry's (m, T_c, go_s) is offered as the search's one-knot timed
schedule, and the RL study's models are not played (a command is not a timed schedule's decision).
With ``--models``, it also plays every trained model of the RL study for that
tier (``<algo>_<env id>_<tier>_seed<s>/{model.zip, best_on_validation.zip}``). An episode that
beats the stored score of its family and passes the certificate test is kept as that family's
schedule; the file is then assembled again. A policy finished on a pool is recorded with a hash
of its content (the model file, or the constant action), so an interrupted run resumes at the
first policy not finished; ``--only`` plays only the origins matching one of its patterns
(``fnmatch``, e.g. ``'sac_*'``). A closed-loop policy can beat the per-task search's open-loop
schedules, and a constant can beat a search that started elsewhere and stayed in its basin; without
this the normalised scores of such entries exceed 1. A planner that is neither (the proportional
law) cannot be played as an action of the ids, and is not absorbed.
"""

import argparse
import fnmatch
import hashlib
import json
import shlex
import sys
from pathlib import Path

import numpy as np

from ffsr_gym.bench.policies import load_model
from ffsr_gym.scoring.rules import score_rule
from ffsr_gym.tasks.schedule import Schedule
from ffsr_gym.tasks.splits import pool, task_scenario, version_tiers
from ffsr_gym.versions.registry import all_specs, spec_for_version
from ffsr_gym_lab.best_known import build
from ffsr_gym_lab.best_known.records import records
from ffsr_gym_lab.best_known.search import timed_go


def parameters_action(entry: dict, tier: str, version: str) -> tuple[float, float] | None:
    """The (m, T_c) action (float32) of a predefined-time planner entry's constants, or None (no such planner, or
    constants outside the tier's action box)."""
    planner = (entry.get("extra") or {}).get("planner") or {}
    if planner.get("method") != "predefined_time" or planner.get("m") is None or planner.get("T_c_s") is None:
        return None
    rules = score_rule(spec_for_version(version)).benchmark
    box = task_scenario(tier, pool(tier, "test", version=version)[0].seed, rules).env
    (m_lo, m_hi), (t_lo, t_hi) = box.m_bounds, box.T_c_bounds_s
    action = np.float32([2.0 * (planner["m"] - m_lo) / (m_hi - m_lo) - 1.0,
                         2.0 * (planner["T_c_s"] - t_lo) / (t_hi - t_lo) - 1.0])
    if not np.all(np.abs(action) <= 1.0):
        print(f"{tier}: entry {entry['name']}: (m, T_c) = ({planner['m']}, {planner['T_c_s']}) outside the action box "
              f"m in [{m_lo}, {m_hi}], T_c in [{t_lo}, {t_hi}] s: skipped")
        return None
    return tuple(float(x) for x in action)


def timed_schedules(leaderboard: Path, tier: str, version: str) -> list[tuple[str, str, Schedule]]:
    """(origin, key, schedule) of a tier's predefined-time planner entries on a version whose action commands the
    approach (capture v1): each entry's (m, T_c, go_s) as the one-knot ``timed`` schedule the best-known search
    searches (the insertion commanded from the first decision at or after go_s), whatever its go time."""
    benchmark = score_rule(spec_for_version(version)).benchmark
    out = []
    for path in sorted((leaderboard / version / tier).glob("*.json")):
        entry = json.loads(path.read_text())
        planner = (entry.get("extra") or {}).get("planner") or {}
        action = parameters_action(entry, tier, version)
        if action is None or planner.get("go_s") is None:
            continue
        knot = (*action, timed_go(planner["go_s"], benchmark))
        digest = hashlib.sha256(json.dumps(list(knot)).encode()).hexdigest()
        origin = f"entry {entry['name']}"
        out.append((origin, f"{origin} {digest}", Schedule("timed", (tuple(float(x) for x in knot),))))
    return out


def absorb_timed(leaderboard: Path, tier: str, splits: list[str], work: str, version: str,
                 only: list[str] | None) -> None:
    """Offer each timed planner entry's schedule on every stored task of the pools (``build.offer``: kept where it
    beats the stored score and passes the certificate test)."""
    for origin, key, schedule in timed_schedules(leaderboard, tier, version):
        if only and not any(fnmatch.fnmatch(origin, pattern) for pattern in only):
            continue
        for split in splits:
            if build.is_absorbed(work, tier, split, key):
                print(f"{tier}/{split}: {origin}: already absorbed")
                continue
            kept = sum(build.offer(schedule, tier, split, r["index"], work, origin, version=version) is not None
                       for r in records(tier, split, version))
            build.mark_absorbed(work, tier, split, key)
            print(f"{tier}/{split}: {origin}: {kept} tasks improved")


def policies(leaderboard: Path, models: Path | None, tier: str, version: str = "v2",
             only: list[str] | None = None) -> list[tuple[str, str, str, object]]:
    """(origin, key, env id, policy loader) of a tier: constant entries (fixed residuals, planner constants), then
    the RL study's models, those whose origin matches a pattern of ``only`` when given. The key is the origin and
    the sha256 of what the policy is (the constant action's JSON, the model file)."""
    def wanted(origin: str) -> bool:
        return not only or any(fnmatch.fnmatch(origin, pattern) for pattern in only)

    ids = spec_for_version(version).ids
    timed = spec_for_version(version).actions.command  # its planners are absorbed as timed schedules
    out = []
    for path in sorted((leaderboard / version / tier).glob("*.json")):
        entry = json.loads(path.read_text())
        fixed = (entry.get("extra", {}).get("policy") or {}).get("fixed")
        origin = f"entry {entry['name']}"
        if entry["env_id"] == ids.residual and fixed is not None:
            constant, env_id = fixed, ids.residual
        elif (entry["env_id"] == "planner" and not timed
              and (constant := parameters_action(entry, tier, version)) is not None):
            env_id = ids.parameters
        else:
            continue
        if wanted(origin):
            digest = hashlib.sha256(json.dumps(list(constant)).encode()).hexdigest()
            out.append((origin, f"{origin} {digest}", env_id, lambda constant=constant: tuple(constant)))
    if timed and models:  # an action's last entry is a command there, a timed schedule's a decision: not the same
        print(f"{tier}: the RL study's models are not absorbed on {version} (their actions are no timed schedule)")
    for folder in sorted(models.glob(f"*_{tier}_seed*")) if models and not timed else []:
        algo, env_id = folder.name.split("_")[:2]
        for checkpoint in ("model.zip", "best_on_validation.zip"):
            origin = f"{folder.name}/{checkpoint}"
            if (folder / checkpoint).is_file() and wanted(origin):
                digest = hashlib.sha256((folder / checkpoint).read_bytes()).hexdigest()
                out.append((origin, f"{origin} {digest}", env_id,
                            lambda algo=algo, path=folder / checkpoint: load_model(algo, path)))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--leaderboard", required=True, help="leaderboard root (<root>/<version>/<tier>/)")
    parser.add_argument("--version", default="v2", choices=[v for v in sorted(all_specs()) if v != "v0"],
                        help="the benchmark version (default: v2)")
    parser.add_argument("--models", default=None, help="the RL study's work folder with its models (default: none)")
    parser.add_argument("--tiers", nargs="+", default=None, help="default: every tier of the version")
    parser.add_argument("--splits", nargs="+", default=["test", "validation"])
    parser.add_argument("--work", default="studies/best-known", help="the best-known work folder")
    parser.add_argument("--only", nargs="+", default=None, metavar="PATTERN",
                        help="play only the origins matching one of these fnmatch patterns (default: every one)")
    args = parser.parse_args()
    models = Path(args.models) if args.models else None
    tiers = version_tiers(args.version)
    for tier in args.tiers or tiers:
        if tier not in tiers:
            parser.error(f"--tiers: {tier!r} is not a tier of {args.version}; allowed: {', '.join(tiers)}")
        splits = [s for s in args.splits if records(tier, s, args.version)]
        if not splits:
            continue
        if spec_for_version(args.version).actions.command:  # timed planners: schedules of the search's family
            absorb_timed(Path(args.leaderboard), tier, splits, args.work, args.version, args.only)
        for origin, key, env_id, load in policies(Path(args.leaderboard), models, tier, args.version, args.only):
            left = [s for s in splits if not build.is_absorbed(args.work, tier, s, key)]
            policy = load() if left else None
            for split in splits:
                if split not in left:
                    print(f"{tier}/{split}: {origin}: already absorbed")
                    continue
                kept = build.absorb(policy, env_id, tier, split, args.work, origin, version=args.version,
                                    progress=False, key=key)
                print(f"{tier}/{split}: {origin}: {kept} tasks improved")
    for path in build.assemble(args.work, version=args.version, command=shlex.join(["python", *sys.argv]),
                               splits=args.splits, shipped=True):
        print("wrote", path)


if __name__ == "__main__":
    main()
