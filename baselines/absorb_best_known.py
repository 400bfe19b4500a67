"""Raise the best known scores with the baselines' own episodes (``ffsr_gym.optim.best_known_build.absorb``).

    python baselines/absorb_best_known.py --leaderboard leaderboards [--models studies/rl-v2] [--tiers easy hard]
                                          [--splits test validation] [--work studies/best-known]

For each tier with stored best known scores, it plays on each stored pool task the fixed residual
actions of the tier's entries (``extra.policy.fixed`` on ``FFSR-Residual-v2``) and, with
``--models``, every trained model of the RL study for that tier (``<algo>_<env id>_<tier>_seed<s>/
{model.zip, best_on_validation.zip}``). An episode that beats the stored score of its family and
passes the certificate test is kept as that family's schedule; the file is then assembled again.
A policy finished on a pool is recorded with a hash of its content (the model file, or the fixed
action), so an interrupted run resumes at the first policy not finished; ``--only`` plays only the
origins matching one of its patterns (``fnmatch``, e.g. ``'sac_*'``).
A closed-loop policy can beat the per-task search's open-loop schedules, so without this the
normalised scores of such entries exceed 1.
"""

import argparse
import fnmatch
import hashlib
import json
import shlex
import sys
from pathlib import Path

from ffsr_gym.bench.policies import load_model
from ffsr_gym.optim import best_known_build as build
from ffsr_gym.tasks.best_known import records


def policies(leaderboard: Path, models: Path | None, tier: str,
             only: list[str] | None = None) -> list[tuple[str, str, str, object]]:
    """(origin, key, env id, policy loader) of a tier: fixed residual entries, then the RL study's models, those
    whose origin matches a pattern of ``only`` when given. The key is the origin and the sha256 of what the policy
    is (the fixed action's JSON, the model file)."""
    def wanted(origin: str) -> bool:
        return not only or any(fnmatch.fnmatch(origin, pattern) for pattern in only)

    out = []
    for path in sorted((leaderboard / "v2" / tier).glob("*.json")):
        entry = json.loads(path.read_text())
        fixed = (entry.get("extra", {}).get("policy") or {}).get("fixed")
        origin = f"entry {entry['name']}"
        if entry["env_id"] == "FFSR-Residual-v2" and fixed is not None and wanted(origin):
            digest = hashlib.sha256(json.dumps(fixed).encode()).hexdigest()
            out.append((origin, f"{origin} {digest}", entry["env_id"], lambda fixed=fixed: tuple(fixed)))
    for folder in sorted(models.glob(f"*_{tier}_seed*")) if models else []:
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
    parser.add_argument("--leaderboard", required=True, help="leaderboard root (entries under <root>/v2/<tier>/)")
    parser.add_argument("--models", default=None, help="the RL study's work folder with its models (default: none)")
    parser.add_argument("--tiers", nargs="+", default=["easy", "medium", "hard", "debris", "robust"])
    parser.add_argument("--splits", nargs="+", default=["test", "validation"])
    parser.add_argument("--work", default="studies/best-known", help="the best-known work folder")
    parser.add_argument("--only", nargs="+", default=None, metavar="PATTERN",
                        help="play only the origins matching one of these fnmatch patterns (default: every one)")
    args = parser.parse_args()
    models = Path(args.models) if args.models else None
    for tier in args.tiers:
        splits = [s for s in args.splits if records(tier, s, "v2")]
        if not splits:
            continue
        for origin, key, env_id, load in policies(Path(args.leaderboard), models, tier, args.only):
            left = [s for s in splits if not build.is_absorbed(args.work, tier, s, key)]
            policy = load() if left else None
            for split in splits:
                if split not in left:
                    print(f"{tier}/{split}: {origin}: already absorbed")
                    continue
                kept = build.absorb(policy, env_id, tier, split, args.work, origin, progress=False, key=key)
                print(f"{tier}/{split}: {origin}: {kept} tasks improved")
    for path in build.assemble(args.work, command=shlex.join(["python", *sys.argv]), splits=args.splits, shipped=True):
        print("wrote", path)


if __name__ == "__main__":
    main()
