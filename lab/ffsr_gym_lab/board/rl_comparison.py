"""The RL study against the classical entries, per tier: the generated ``rl-study`` table of docs/baselines.md.

Per tier with RL entries (entries with ``extra.training_seeds``): the best RL entry at its
best-on-validation checkpoints, the same agents' last checkpoints, the best (m, T_c) planner (an
untrained entry not on the residual env id), the best entry that is not trained at all, and where the
selected RL entry stands against each: above or below with the 95 % CIs of the spec's statistic apart, or the
CIs overlapping (the leaderboard's ``ci_separation`` rule). It also gives the largest drop from an
RL entry's selected checkpoints to its last ones, and how many of the study's RL entry pairs
(2 algorithms x 2 env ids) the tier has, other trained pairs (Brax's PPO) counted apart. Every cell
is read from the entries; nothing is typed.
"""

from __future__ import annotations

from typing import Any

from ffsr_gym.bench.entry import entry_name
from ffsr_gym.bench.verify import CHECKPOINTS
from ffsr_gym.model.spec import BenchmarkSpec
from ffsr_gym_lab.board.tables import method_name, safe

#: The study's algorithms: its grid per tier is each of them on each of the version's two env ids.
STUDY_ALGOS = ("ppo", "sac")


def _pairs(spec: BenchmarkSpec, tier: str, selected: list[dict[str, Any]]) -> str:
    """How many of the study's entry pairs the tier has, and how many other trained pairs."""
    suffix = CHECKPOINTS["best_on_validation"]
    study = {entry_name(algo, spec, env_id, tier) + suffix for algo in STUDY_ALGOS for env_id in spec.env_ids}
    mine = sum(e["name"] in study for e in selected)
    others = len(selected) - mine
    return f"{mine} of {len(study)}" + (f" (+{others} other{'s' * (others > 1)})" if others else "")


def is_trained(entry: dict[str, Any]) -> bool:
    """Whether an entry is an RL study entry (trained agents, a checkpoint)."""
    return bool(entry.get("extra", {}).get("training_seeds"))


def verdict(spec: BenchmarkSpec, a: dict[str, Any], b: dict[str, Any]) -> str:
    """Where ``a`` stands against ``b``: "above" or "below" when their CIs (of the spec's statistic) are apart, else "CIs overlap"."""
    (a_lo, a_hi), (b_lo, b_hi) = a["metrics"][spec.leaderboard.ci], b["metrics"][spec.leaderboard.ci]
    if a_lo > b_hi:
        return "above"
    if a_hi < b_lo:
        return "below"
    return "CIs overlap"


def _cell(spec: BenchmarkSpec, e: dict[str, Any] | None, tier: str) -> str:
    if e is None:
        return "-"
    m = e["metrics"]
    lo, hi = m[spec.leaderboard.ci]
    return (f"`{safe(method_name(e, tier))}` {m[spec.leaderboard.iqm]:.3f} [{lo:.3f}, {hi:.3f}], "
            f"{m[spec.leaderboard.rate]:.0%}")


def _best(spec: BenchmarkSpec, items: list[dict[str, Any]]) -> dict[str, Any] | None:
    key = spec.leaderboard
    return max(items, key=lambda e: (e["metrics"][key.iqm], e["metrics"][key.rate], e["name"]), default=None)


def table(spec: BenchmarkSpec, entries: dict[str, list[dict[str, Any]]]) -> str:
    """The markdown table (a line saying there is nothing yet when no tier has RL entries)."""
    suffix = CHECKPOINTS["best_on_validation"]
    iqm = spec.leaderboard.iqm
    label = spec.leaderboard.label
    lines = [f"| tier | best RL entry, selected on validation: {label} [95% CI], success | the same agents' last "
             f"checkpoints | best (m, T_c) planner | RL against it | best untrained entry | RL against it | largest "
             f"{label} fall, "
             "selected to last checkpoints | RL entry pairs |", "|---|---|---|---|---|---|---|---|---|"]
    for tier, items in entries.items():
        trained = [e for e in items if is_trained(e)]
        selected = [e for e in trained if e["extra"].get("checkpoint") == "best_on_validation"]
        if not selected:
            continue
        last = {e["name"]: e for e in trained if e["extra"].get("checkpoint") == "last"}
        best = _best(spec, selected)
        planner = _best(spec, [e for e in items if not is_trained(e) and e.get("env_id") != spec.env_ids[1]])
        untrained = _best(spec, [e for e in items if not is_trained(e)])
        pair = {e["name"]: last.get(e["name"].removesuffix(suffix)) for e in selected}  # its last checkpoints
        drops = [(e["metrics"][iqm] - pair[e["name"]]["metrics"][iqm], method_name(pair[e["name"]], tier))
                 for e in selected if pair[e["name"]] is not None]
        drop, dropped = max(drops, default=(None, None))
        lines.append(
            f"| {tier} | {_cell(spec, best, tier)} | {_cell(spec, pair[best['name']], tier)} | "
            f"{_cell(spec, planner, tier)} | {'-' if planner is None else verdict(spec, best, planner)} | "
            f"{_cell(spec, untrained, tier)} | {'-' if untrained is None else verdict(spec, best, untrained)} | "
            f"{'-' if drop is None else f'`{safe(dropped)}` {drop:+.3f}'} | {_pairs(spec, tier, selected)} |")
    if len(lines) == 2:
        return "No RL entries yet.\n"
    return "\n".join(lines) + "\n"
