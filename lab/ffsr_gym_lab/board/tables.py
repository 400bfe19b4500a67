"""Markdown of the leaderboards: a table's header and rows, and the summary across tiers.

The columns follow the spec's ranking rule: ``feasible_then_iqm`` tables show the feasible rate
and B's IQM; ``ci_separation`` tables show the score's IQM (or mean: the spec's statistic) with its CI,
the success rate, the normalised score (mean of score / the task's best known score, :mod:`ffsr_gym_lab.board.normalise`), the
paper's B, peak rates, final error, convergence time, compute and the training pool. Metric
names come from the spec (``[leaderboard]``).
"""

from __future__ import annotations

import json
import math
import unicodedata
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

import ffsr_gym
from ffsr_gym.bench.stamp import stamp_text
from ffsr_gym.bench.verify import CHECKPOINTS
from ffsr_gym.model.spec import BenchmarkSpec
from ffsr_gym.tasks import reference
from ffsr_gym_lab.best_known import records as best_known
from ffsr_gym_lab.board.normalise import normalised_mean, normalised_scores
from ffsr_gym_lab.pools.freeze import records_since


def safe(text: Any) -> str:
    """``text`` as one Markdown table cell: every string an entry brings into a table passes here.

    Control and format characters become spaces, runs of white space (line breaks included) one
    space; ``|`` (a cell border) becomes ``/``, a backtick (a code span) ``'``, ``<`` and ``>`` (HTML,
    the generated-text markers) entities.
    """
    text = "".join(" " if unicodedata.category(char)[0] in "CZ" else char for char in str(text))
    return " ".join(text.split()).replace("|", "/").replace("`", "'").replace("<", "&lt;").replace(">", "&gt;")


#: The most characters of one free-text field a table shows (longer text ends in an ellipsis).
FREE_TEXT_CHARS = 60


def free_text(text: Any, limit: int = FREE_TEXT_CHARS) -> str:
    """Text an entry's author typed (``compute.hardware``, ``training_pool``'s note, v0's ``extra.method``) as an
    inert cell: :func:`safe`, at most ``limit`` characters, inside a code span, where Markdown renders no link,
    image, emphasis or bare URL. ``<`` and ``>`` become ``‹`` and ``›`` (a code span shows entities as typed)."""
    text = safe(text).replace("&lt;", "\u2039").replace("&gt;", "\u203a")
    if len(text) > limit:
        text = text[:limit - 1].rstrip() + "\u2026"
    return f"`{text}`" if text else ""


def header(spec: BenchmarkSpec, group: str) -> list[str]:
    """The title and column lines of one table."""
    if spec.leaderboard.ranking == "feasible_then_iqm":
        return [f"### {group}", "", "| rank | entry | method | feasible rate | score IQM [95% CI] | score mean | episodes "
                "| commit |", "|---|---|---|---|---|---|---|---|"]
    sha = reference.reference_sha256(spec.rules.version)
    ending = ("capture time [s]: median (10-90 %), captures | contact speed [mm/s], captures"
              if spec.rules.quality is not None
              else "capture time [s], captures | capture ratio, captures" if spec.rules.capture is not None
              else "final error [m], successes | convergence [s], successes")
    return [f"### {group} ({spec.evaluation.split} pool)", "",
            (f"| rank | entry | score {spec.leaderboard.label} [95% CI] | {spec.leaderboard.rate_column} | "
             f"normalised{f' (ref. {sha[:8]})' if sha else ''} | paper B (median) | peak rate mission / "
             f"balance [deg/s] | {ending} | compute | trained on | commit |"), "|---|---|---|---|---|---|---|---|---|---|---|---|"]


def commit(entry: dict[str, Any]) -> str:
    """The short commit an entry was made at (``+dirty`` with uncommitted changes), and its verification stamp."""
    prov = entry["provenance"]
    stamp = stamp_text(entry)
    return safe(str(prov.get("git_commit") or "none")[:8] + ("+dirty" if prov.get("git_dirty") else "")
                + (f", {stamp}" if stamp else ""))


def _g4(x: float | None) -> str:
    return "inf" if x is None or math.isinf(x) else f"{x:.4g}"


def _fmt(x: float | None, spec: str = ".3g") -> str:
    return "-" if x is None else format(x, spec)


def _median(rows: list[dict[str, Any]], key: str, index: int | None = None, *, successes: bool = False) -> float | None:
    """Median of a per-episode value over finite values (over successful episodes only, if asked)."""
    values = [row[key] if index is None else row[key][index] for row in rows if row["success"] or not successes]
    finite = [v for v in values if v is not None and math.isfinite(v)]
    return None if not finite else float(np.median(finite))


def compute_text(compute: dict[str, Any]) -> str:
    """The compute column: environment steps (RL) or objective evaluations (optimisers), and wall time."""
    parts = []
    if compute.get("env_steps"):
        parts.append(f"{compute['env_steps']:,} env steps")
    if compute.get("objective_evaluations"):
        parts.append(f"{compute['objective_evaluations']:,} episodes")
    if compute.get("wall_time_s") is not None:
        parts.append(f"{compute['wall_time_s']:.0f} s")
    if compute.get("hardware"):
        parts.append(free_text(compute["hardware"]))
    return ", ".join(parts) or "none (fixed)"


def entry_cell(e: dict[str, Any]) -> str:
    """The entry's name and, when its policy's actions were clipped into the box, how many were."""
    clipped = sum(int(row.get("clipped_actions") or 0) for row in e["episodes"])
    return f"`{safe(e['name'])}`" + (f" ({clipped:,} clipped actions)" if clipped else "")


def row(spec: BenchmarkSpec, label: str, e: dict[str, Any]) -> str:
    """One entry's table line."""
    m, names = e["metrics"], spec.leaderboard
    lo, hi = m[names.ci]
    if names.ranking == "feasible_then_iqm":
        method = free_text(e.get("extra", {}).get("method", ""))
        runs = " (single run)" if m["episodes"] == 1 else ""
        return (f"| {label} | {entry_cell(e)} | {method} | {m[names.rate]:.2f} | "
                f"{_g4(m[names.iqm])} [{_g4(lo)}, {_g4(hi)}] | "
                f"{_g4(m['score_mean'])} | {m['episodes']}{runs} | {commit(e)} |")
    rows, extra = e["episodes"], e.get("extra", {})
    return (f"| {label} | {entry_cell(e)} | {m[names.iqm]:.3f} [{lo:.3f}, {hi:.3f}] | {m[names.rate]:.2f} | "
            f"{_fmt(normalised_mean(e, spec.rules.version), '.3f')} | {_fmt(_median(rows, 'paper_B'))} | {_fmt(_median(rows, 'peak_rate_deg_s', 0), '.0f')} / "
            f"{_fmt(_median(rows, 'peak_rate_deg_s', 1), '.0f')} | "
            f"{_ending(spec, rows)} | {compute_text(extra.get('compute', {}))} | "
            f"{free_text(extra['training_pool']) if extra.get('training_pool') else '-'} | {commit(e)} |")


def _ending(spec: BenchmarkSpec, rows: list[dict[str, Any]]) -> str:
    """The last two metric cells: the capture's time and ratio (a capture version), else final error and
    convergence time; medians over the successful episodes (capture v1: the capture time's median and 10-90 %
    range, and the speed of first contact)."""
    if spec.rules.quality is not None:
        times = [row["capture_time_s"] for row in rows if row["success"]]
        spread = f" ({np.percentile(times, 10):.1f}-{np.percentile(times, 90):.1f})" if times else ""
        contact = _median(rows, "contact_speed_m_s", successes=True)
        return (f"{_fmt(_median(rows, 'capture_time_s', successes=True), '.1f')}{spread} | "
                f"{_fmt(None if contact is None else 1000 * contact, '.0f')}")
    if spec.rules.capture is not None:
        return (f"{_fmt(_median(rows, 'capture_time_s', successes=True), '.1f')} | "
                f"{_fmt(_median(rows, 'capture_ratio', successes=True), '.2g')}")
    return (f"{_fmt(_median(rows, 'final_ee_position_error_m', successes=True), '.1e')} | "
            f"{_fmt(_median(rows, 'convergence_time_s', successes=True), '.1f')}")


def method_name(entry: dict[str, Any], tier: str) -> str:
    """An entry's name without its tier (``ppo_residual_easy`` → ``ppo_residual``, ``ppo_easy_valbest`` →
    ``ppo_valbest``)."""
    name = entry["name"]
    for suffix in CHECKPOINTS.values():
        if name.endswith(f"_{tier}{suffix}"):
            return name[: -len(tier) - 1 - len(suffix)] + suffix
    return name


def summary(spec: BenchmarkSpec, entries: dict[str, list[dict[str, Any]]],
            ranks: Callable[[list[dict[str, Any]], BenchmarkSpec], list[int]]) -> str:
    """One table across tiers (a row per method, IQM [95 % CI] and rank per tier), and the RL study's compute."""
    cells: dict[str, dict[str, str]] = {}
    rank_sum: dict[str, float] = {}
    tiers = [tier for tier, items in entries.items() if items]
    names = spec.leaderboard
    for tier in tiers:
        items = entries[tier]
        for rank, e in zip(ranks(items, spec), items):
            lo, hi = e["metrics"][names.ci]
            method = method_name(e, tier)
            cells.setdefault(method, {})[tier] = f"{e['metrics'][names.iqm]:.3f} [{lo:.3f}, {hi:.3f}] #{rank}"
            rank_sum[method] = rank_sum.get(method, 0.0) + rank
    order = sorted(cells, key=lambda method: (rank_sum[method] / len(cells[method]), method))
    lines = ["| method | " + " | ".join(f"{tier}: {names.label} [95% CI] #rank" for tier in tiers) + " |",
             "|---|" + "---|" * len(tiers)]
    lines += [f"| `{safe(method)}` | " + " | ".join(cells[method].get(tier, "-") for tier in tiers) + " |"
              for method in order]
    lines += ["", headroom(spec, entries)]
    rl = [e for items in entries.values() for e in items if e.get("extra", {}).get("compute", {}).get("env_steps")
          and e["extra"].get("checkpoint") != "best_on_validation"]  # a checkpoint of a training counted once
    if rl:
        lines += ["", _rl_compute(rl), "", *rl_compute_table(entries)]
    return "\n".join(lines) + "\n"


def top_three(spec: BenchmarkSpec, ordered_entries: dict[str, list[tuple[str, dict[str, Any]]]]) -> str:
    """Per tier, the first three entries of its table (IQM [95 % CI] and rank), and how many more share the third
    one's rank. ``ordered_entries``: each tier's (rank label, entry) in table order."""
    names = spec.leaderboard
    lines = [f"| tier | first: {names.label} [95% CI] #rank | second | third |", "|---|---|---|---|"]
    for tier, pairs in ordered_entries.items():
        if not pairs:
            continue
        cells = []
        for label, e in pairs[:3]:
            lo, hi = e["metrics"][names.ci]
            cells.append(f"`{safe(method_name(e, tier))}` {e['metrics'][names.iqm]:.3f} [{lo:.3f}, {hi:.3f}] #{label}")
        third = pairs[min(2, len(pairs) - 1)][0]
        more = sum(label == third for label, _ in pairs[3:])
        if more:
            cells[-1] += f", {more} more at #{third.split()[0]}"
        lines.append(f"| {tier} | " + " | ".join(cells + ["-"] * (3 - len(cells))) + " |")
    return "\n".join(lines) + "\n"


def headroom(spec: BenchmarkSpec, entries: dict[str, list[dict[str, Any]]]) -> str:
    """Per tier, the best normalised score of an entry and the headroom 1 − it left to the best known scores."""
    cells = []
    for tier, items in entries.items():
        pairs = [(e, r) for e in items if (r := normalised_scores(e, spec.rules.version)) is not None]
        if pairs:
            best, name = max((float(r.mean()), e["name"]) for e, r in pairs)  # normalised_mean, from the same scores
            beaten = {row["task_index"] for e, r in pairs for row, x in zip(e["episodes"], r) if x > 1.0}
            top = max(float(r.max()) for _, r in pairs)
            beats = (f"entries beat the reference score on {len(beaten)} test task{'s' * (len(beaten) != 1)}, by up "
                     f"to {top - 1.0:.1%}" if beaten
                     else "no entry beats the reference score on any test task")
            cells.append(f"{tier} {1.0 - best:.3f} (best: `{safe(name)}`, {best:.3f}; {beats})")
        elif items:
            cells.append(f"{tier} - (no reference scores)")
    sha = reference.reference_sha256(spec.rules.version)
    text = ("Headroom (1 − the best entry's normalised score, the mean over test tasks of score / the task's score in "
            f"the frozen reference{f' {sha[:8]}' if sha else ''}, the best known scores when {spec.rules.version} was "
            "released): " + "; ".join(cells) + ". " + records_text(spec.rules.version))
    stored = best_known.load_best_known(spec.rules.version)
    gap = (stored or {}).get("convergence")
    if gap:
        text += (f" Doubling the best-known search to {gap['generations']} generations on {len(gap['tasks'])} random "
                 f"stored tasks raised their best known score on {gap['share_improved']:.0%} of them, by "
                 f"{gap['median_relative_gap']:.1%} in the median and {gap['max_relative_gap']:.1%} at most.")
    cost = best_known_cost(spec.rules.version)
    return text + (" " + cost if cost else "")


def records_text(version: str) -> str:
    """The best known scores found since the reference was frozen: records, shown apart, never the reference."""
    found = records_since(version)
    if not found:
        return "Records since the reference was frozen: none (no test task's best known score has improved)."
    tiers = sorted({r["tier"] for r in found})
    return (f"Records since the reference was frozen (the best-known search improved them; the normalised column "
            f"keeps the reference): {len(found)} test task{'s' * (len(found) != 1)} in {', '.join(tiers)}, by up to "
            f"{max(r['gain'] for r in found):.1%}.")


def best_known_cost(version: str) -> str:
    """What the stored best-known searches cost (their files' ``counts`` and ``compute``): for the test and
    validation pools, and for the training pools, which only the offline datasets read."""
    parts = []
    for split, label in ((None, "the test and validation pools"), ("train", "the training pools (offline datasets)")):
        data = best_known.load_best_known(version, best_known.best_known_path(version, split))
        if not data or not data.get("compute"):
            continue
        tasks = sum(n for splits in data["counts"].values() for n in splits.values())
        compute = data["compute"]
        hours = compute["wall_time_s"] * compute["cores"] / 3600
        episodes = compute["objective_evaluations"]
        parts.append(f"{tasks:,} tasks of {label}, {episodes:,} episodes, {hours:.1f} core-hours")
    return ("The best-known search cost (its episodes; the certificate checks of its results not counted): "
            + "; ".join(parts) + ".") if parts else ""


def rl_compute_table(entries: dict[str, list[dict[str, Any]]]) -> list[str]:
    """Compute per RL entry (its last and best-on-validation checkpoints share one training): seeds x env steps per
    seed, training wall time summed over seeds, cores."""
    cells: dict[str, dict[str, str]] = {}
    for tier, items in entries.items():
        for e in items:
            extra = e.get("extra", {})
            compute = extra.get("compute", {})
            if not compute.get("env_steps") or extra.get("checkpoint") == "best_on_validation":
                continue
            seeds = len(extra.get("runs", [])) or 1
            cells.setdefault(method_name(e, tier), {})[tier] = (
                f"{seeds} x {extra.get('timesteps_per_seed', compute['env_steps'] // seeds):,} steps, "
                f"{compute['wall_time_s'] / 3600:.1f} h, {free_text(compute.get('hardware') or '-')}")
    if not cells:
        return []
    tiers = [t for t in entries if any(t in c for c in cells.values())]
    return ["| RL entry | " + " | ".join(f"{t}: seeds x env steps, training time, cores" for t in tiers) + " |",
            "|---|" + "---|" * len(tiers),
            *[f"| `{safe(m)}` | " + " | ".join(cells[m].get(t, "-") for t in tiers) + " |" for m in sorted(cells)]]


def _rl_compute(rl: list[dict[str, Any]]) -> str:
    steps = sum(e["extra"]["compute"]["env_steps"] for e in rl)
    seconds = sum(e["extra"]["compute"]["wall_time_s"] for e in rl)
    agents = sum(len(e["extra"].get("runs", [])) for e in rl)
    return (f"RL entries: {agents} trained agents, {steps:,} environment steps, {seconds / 3600:.1f} h of training "
            "on one core each (validation scoring included, test-pool scoring not); each training gives a last and a "
            "best-on-validation entry.")


def search_table(folder: Path | None = None) -> str:
    """The RL hyperparameter searches (``ffsr_gym/hyperparams/search/*.json``): tier, trials, pruned, best
    validation mean, and what each cost."""
    folder = folder or Path(ffsr_gym.__file__).resolve().parent / "hyperparams" / "search"
    lines = [("| algorithm, env id | searched on | trials (pruned) | env steps per trial | best validation mean "
              "(trial) | cost: env steps, wall time, cores |"), "|---|---|---|---|---|---|"]
    for path in sorted(folder.glob("*.json")):
        r = json.loads(path.read_text())
        cost = r["cost"]
        lines.append(f"| {r['algo']}, {r['env_id']} | {r['training_pool']} + {r['selection_pool']} | {cost['trials']} "
                     f"({cost['pruned']}) | {r['trial']['env_steps']:,} | {r['best']['value']:.4f} "
                     f"(#{r['best']['number']}) | {cost['env_steps']:,}, {cost['wall_time_s'] / 60:.0f} min, "
                     f"{cost['cores']} |")
    return "\n".join(lines) + "\n"


def headline(spec: BenchmarkSpec, metrics: dict[str, Any]) -> str:
    """An entry's ranking statistic as the baseline scripts print it (``IQM 0.412``, or ``mean 0.123``)."""
    return f"{spec.leaderboard.label} {metrics[spec.leaderboard.iqm]:.3f}"
