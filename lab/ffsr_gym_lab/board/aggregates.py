"""Aggregates across a pool version's tiers as rliable reports them (``ffsr-gym leaderboard aggregates``; the
figure: :func:`ffsr_gym_lab.board.plots.plot_aggregates`).

Scores are normalised per task by the task's best known score (:mod:`ffsr_gym_lab.board.normalise`), so
tiers can be pooled. Each method (an entry name without its tier) is a matrix of runs x tasks:
the runs are its training seeds (one for a deterministic method), the tasks every test task of the
tiers that have best known scores. With the rliable package (``pip install "ffsr-gym[analysis]"``):

* IQM of the normalised scores with a 95 % stratified-bootstrap CI (percentile method);
* performance profiles: the fraction of (run, task) scores above each threshold τ, with CIs;
* the probability of improvement of each method over the reference planner: P(X > Y) per task
  (Mann-Whitney over runs; for two deterministic methods 1, 0.5 or 0 as X beats, ties or loses),
  averaged over tasks, with its CI.

The bootstraps resample tasks as well as runs within each task (rliable's ``task_bootstrap``): the
test tasks are a sample of each tier's task distribution, and with runs alone a deterministic
method's CI would have zero width.

rliable's bootstrap draws from NumPy's global generator, seeded per method (:func:`method_seed`) before each of
the method's estimates: a method's numbers depend on its own scores (and the reference's) only, not on which other
methods the board holds or in what order. So a method whose inputs are unchanged keeps its stored numbers
(:func:`write` reuses them): a new entry costs its own bootstraps, not everyone's.
The per-tier tables rank by the entries' own CIs (a bootstrap over episodes), not by these.
"""

from __future__ import annotations

import hashlib
import json
import zlib
from pathlib import Path
from typing import Any

import numpy as np
from tqdm.auto import tqdm

from ffsr_gym.exceptions import FFSRError, InvalidInputError, require
from ffsr_gym.model.spec import BenchmarkSpec
from ffsr_gym.provenance import package_versions, provenance, write_json_atomic
from ffsr_gym.tasks.tiers import ALL_TIERS
from ffsr_gym.user_files import parse_json, read_text
from ffsr_gym_lab.board.normalise import normalised_scores
from ffsr_gym_lab.board.tables import method_name, safe

#: The method every other is compared with (the reference planner at the version's default).
REFERENCE = "reference_{version}_default"
SEED = 0
REPS = 2000
TAUS = np.linspace(0.0, 1.1, 111)


def rliable_modules():
    """(rliable.library, rliable.metrics), or a named error with the install hint."""
    need = ("analysis", "rliable", "the aggregates need")
    return require("rliable.library", *need), require("rliable.metrics", *need)


def improvement(scores_x: np.ndarray, scores_y: np.ndarray) -> float:
    """rliable's probability of improvement of X over Y, vectorised: per task, the share of (run of X, run of Y)
    pairs where X scores higher, ties counted half (the Mann-Whitney U over nx ny), averaged over tasks.
    Equal to ``rliable.metrics.probability_of_improvement`` (tested), which calls SciPy once per task: too slow
    to bootstrap over hundreds of tasks."""
    x, y = scores_x[:, None, :], scores_y[None, :, :]
    return float(np.mean(np.mean((x > y) + 0.5 * (x == y), axis=(0, 1))))


def matrix(entry: dict[str, Any], version: str) -> np.ndarray | None:
    """An entry's normalised scores as runs x tasks (runs: training seeds in order), or None."""
    values = normalised_scores(entry, version)
    if values is None:
        return None
    rows = entry["episodes"]
    seeds = sorted({row.get("train_seed", 0) for row in rows})
    tasks = sorted({row["task_index"] for row in rows})
    out = np.full((len(seeds), len(tasks)), np.nan)
    for value, row in zip(values, rows):
        out[seeds.index(row.get("train_seed", 0)), tasks.index(row["task_index"])] = value
    return None if np.isnan(out).any() else out


def score_matrices(entries: dict[str, list[dict[str, Any]]], version: str) -> tuple[dict[str, np.ndarray], list[str]]:
    """Each method's runs x tasks matrix over the tiers where every method present has one, and those tiers."""
    per_tier: dict[str, dict[str, np.ndarray]] = {}
    for tier in ALL_TIERS:
        found = {method_name(e, tier): matrix(e, version) for e in entries.get(tier, [])}
        if found and all(m is not None for m in found.values()):
            per_tier[tier] = found
    tiers = list(per_tier)
    methods = set.intersection(*(set(v) for v in per_tier.values())) if per_tier else set()
    out = {}
    for method in sorted(methods):
        parts = [per_tier[t][method] for t in tiers]
        if len({p.shape[0] for p in parts}) == 1:
            out[method] = np.concatenate(parts, axis=1)
    return out, tiers


def inputs(entries: dict[str, list[dict[str, Any]]]) -> dict[str, str]:
    """``tier/name`` → SHA-256 of each entry's content: what an aggregates file was computed from (a stale file is
    one whose inputs differ from the entries now, :func:`ffsr_gym_lab.board.leaderboard.check`)."""
    return {f"{tier}/{e['name']}": hashlib.sha256(json.dumps({k: v for k, v in e.items() if not k.startswith("_")},
                                                             sort_keys=True).encode()).hexdigest()
            for tier, items in entries.items() for e in items}


#: How the bootstraps are seeded: a stored method whose ``seeding`` differs is recomputed.
SEEDING = "per method: NumPy's global generator seeded with (seed, crc32 of the method's name) before each estimate"


def method_seed(method: str) -> list[int]:
    """The seed of ``method``'s bootstraps: :data:`SEED` and the CRC-32 of its name."""
    return [SEED, zlib.crc32(method.encode("utf-8"))]


def method_inputs(values: np.ndarray, reference: np.ndarray | None) -> str:
    """SHA-256 of what a method's aggregates are computed from: its runs x tasks matrix, the reference's (for the
    probability of improvement; None for the reference itself), the bootstrap's settings."""
    digest = hashlib.sha256(json.dumps([SEED, REPS, SEEDING, [float(t) for t in TAUS]]).encode())
    for part in (values, reference):
        if part is not None:
            digest.update(repr(part.shape).encode() + np.ascontiguousarray(part, np.float64).tobytes())
    return digest.hexdigest()


def method_aggregates(method: str, values: np.ndarray, reference: np.ndarray | None) -> dict[str, Any]:
    """One method's IQM, performance profile (with 95 % CIs) and, against ``reference`` (runs x tasks of one run),
    its probability of improvement, each bootstrap seeded by :func:`method_seed`."""
    library, metrics = rliable_modules()
    one = {method: values}
    np.random.seed(method_seed(method))
    iqm, iqm_ci = library.get_interval_estimates(one, lambda x: np.array([metrics.aggregate_iqm(x)]), reps=REPS,
                                                 task_bootstrap=True)
    np.random.seed(method_seed(method))
    profiles, profile_ci = library.create_performance_profile(one, TAUS, reps=REPS, task_bootstrap=True)
    out = {"runs": int(values.shape[0]), "tasks": int(values.shape[1]), "iqm": float(iqm[method][0]),
           "iqm_ci95": [float(iqm_ci[method][0][0]), float(iqm_ci[method][1][0])], "mean": float(values.mean()),
           "profile": [float(x) for x in profiles[method]],
           "profile_ci95": [[float(x) for x in profile_ci[method][0]], [float(x) for x in profile_ci[method][1]]]}
    if reference is not None:  # a deterministic Y repeated: P(X > Y) is unchanged
        pair = {method: np.stack([values, np.repeat(reference, values.shape[0], axis=0)], axis=-1)}
        np.random.seed(method_seed(method))
        poi, poi_ci = library.get_interval_estimates(pair, lambda a: np.array([improvement(a[..., 0], a[..., 1])]),
                                                     reps=REPS, task_bootstrap=True)
        out |= {"probability_of_improvement": float(poi[method][0]),
                "probability_of_improvement_ci95": [float(x) for x in np.ravel(poi_ci[method])]}
    return out | {"inputs_sha256": method_inputs(values, reference)}


def compute(entries: dict[str, list[dict[str, Any]]], spec: BenchmarkSpec,
            stored: dict[str, Any] | None = None) -> dict[str, Any] | None:
    """The aggregates as a JSON-ready dict (None without a tier that has best known scores). ``stored``: a previous
    aggregates file's methods by name; a method whose ``inputs_sha256`` is unchanged keeps its numbers."""
    rliable_modules()  # the install hint before any work
    version = spec.rules.version
    scores, tiers = score_matrices(entries, version)
    reference = REFERENCE.format(version=version)
    if not scores or reference not in scores:
        return None
    if scores[reference].shape[0] != 1:
        raise InvalidInputError(f"{reference} has {scores[reference].shape[0]} runs; the comparison needs one "
                                "(a deterministic planner)")
    methods, stored = {}, stored or {}
    for m, values in tqdm(sorted(scores.items()), desc="aggregates (bootstraps of changed methods)", unit="method",
                          leave=False):
        against = None if m == reference else scores[reference]
        kept = stored.get(m)
        if isinstance(kept, dict) and kept.get("inputs_sha256") == method_inputs(values, against):
            methods[m] = kept
        else:
            methods[m] = method_aggregates(m, values, against)
    return {"version": version, "tiers": tiers, "score": "score / the task's best known score",
            "reference": reference, "taus": [float(t) for t in TAUS],
            "bootstrap": {"package": f"rliable {package_versions().get('rliable', '?')}", "method": "percentile",
                          "reps": REPS, "seed": SEED, "seeding": SEEDING,
                          "resampled": "tasks, and runs within each task (rliable's task_bootstrap)"},
            "methods": methods, "inputs": inputs(entries), "provenance": provenance()}


def stored_methods(path: Path) -> dict[str, Any]:
    """The methods of an aggregates file already written (empty when there is none, or it cannot be read)."""
    try:
        data = parse_json(read_text(path), str(path))
    except FFSRError:
        return {}
    methods = data.get("methods") if isinstance(data, dict) else None
    return methods if isinstance(methods, dict) else {}


def up_to_date(root: str | Path, spec: BenchmarkSpec, entries: dict[str, list[dict[str, Any]]]) -> bool:
    """Whether ``<root>/<version>/aggregates.json`` was computed from exactly ``entries``, seeded as now."""
    path = Path(root) / spec.version / "aggregates.json"
    try:
        data = parse_json(read_text(path), str(path)) if path.is_file() else None
    except FFSRError:
        return False
    return (isinstance(data, dict) and data.get("inputs") == inputs(entries)
            and (data.get("bootstrap") or {}).get("seeding") == SEEDING)


def write(root: str | Path, spec: BenchmarkSpec, entries: dict[str, list[dict[str, Any]]]) -> Path | None:
    """Write ``<root>/<version>/aggregates.json`` (None when there is nothing to aggregate), recomputing only the
    methods whose inputs changed since the file there was written."""
    path = Path(root) / spec.version / "aggregates.json"
    data = compute(entries, spec, stored_methods(path) if path.is_file() else None)
    if data is None:
        return None
    write_json_atomic(path, data)
    return path


def markdown(path: str | Path) -> str:
    """The aggregates file as a table (IQM, CI, probability of improvement over the reference)."""
    data = json.loads(Path(path).read_text())
    order = sorted(data["methods"], key=lambda m: -data["methods"][m]["iqm"])
    where = f"the {data['tiers'][0]} tier" if len(data["tiers"]) == 1 else f"the tiers {', '.join(data['tiers'])}"
    lines = [(f"Across {where} (score / the task's best known score; "
              f"{data['bootstrap']['package']}, bootstrap over tasks and runs, {data['bootstrap']['reps']} resamples):"),
             "", f"| method | runs | IQM [95% CI] | mean | P(improves on `{safe(data['reference'])}`) [95% CI] |",
             "|---|---|---|---|---|"]
    for m in order:
        v = data["methods"][m]
        poi = (f"{v['probability_of_improvement']:.2f} [{v['probability_of_improvement_ci95'][0]:.2f}, "
               f"{v['probability_of_improvement_ci95'][1]:.2f}]") if "probability_of_improvement" in v else "-"
        lines.append(f"| `{safe(m)}` | {v['runs']} | {v['iqm']:.3f} [{v['iqm_ci95'][0]:.3f}, {v['iqm_ci95'][1]:.3f}] | "
                     f"{v['mean']:.3f} | {poi} |")
    return "\n".join(lines) + "\n"

