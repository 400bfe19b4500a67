"""The v2 leaderboards regenerated on the current kernel against the previous kernel's (experiments/kernel_change.json).

The record holds, per tier and entry, the IQM and CI before (read from git at the last commit on the
previous kernel) and after; these tests hold it to the entries in the tree and to the rule a kernel
change must keep: every new IQM inside the old entry's CI, and a rank moves only through a pair of
entries that sat at the edge of CI separation before.
"""

from __future__ import annotations

import json
from pathlib import Path

from conftest import script_module

ROOT = Path(__file__).resolve().parents[3]
RECORD = json.loads((ROOT / "experiments" / "kernel_change.json").read_text(encoding="utf-8"))


def test_the_record_is_the_leaderboards_in_the_tree():
    """The 'after' side is what the committed entries hold now (a regenerated entry needs a regenerated record).
    Entries and tiers (servo) added since the kernel change are not in the record; ranks are compared among the
    recorded ones."""
    script = script_module("kernel_change")
    now = script.entries_at(None, RECORD["version"])
    assert set(RECORD["tiers"]) <= set(now) and set(RECORD["tiers"]) >= {"easy", "medium", "hard", "debris", "robust"}
    for tier, data in RECORD["tiers"].items():
        recorded = {row["name"] for row in data["entries"]}
        assert recorded <= set(now[tier]), tier
        cis = {name: now[tier][name]["ci"] for name in recorded}
        ranks = {name: 1 + sum(lo > ci[1] for lo, _ in cis.values()) for name, ci in cis.items()}
        tied = {r for r in ranks.values() if list(ranks.values()).count(r) > 1}
        for row in data["entries"]:
            rank = ranks[row["name"]]
            label = f"{rank}{' (tied)' if rank in tied else ''}"  # the table's rank label, among the recorded entries
            assert (row["iqm_after"], row["ci_after"], row["rank_after"]) == (
                now[tier][row["name"]]["iqm"], now[tier][row["name"]]["ci"], label), (tier, row["name"])
    text = (ROOT / "docs" / "model.md").read_text(encoding="utf-8")
    block = text.split(script.START + "\n")[1].split(script.END)[0]
    assert block == script.table(RECORD), "rerun: python experiments/kernel_change.py --before ... --docs docs/model.md"


def test_every_regenerated_iqm_lies_inside_its_old_ci():
    rows = [(tier, row) for tier, data in RECORD["tiers"].items() for row in data["entries"]]
    assert rows and all(row["ci_before"] is not None for _, row in rows), "every entry existed before the change"
    outside = [(tier, row["name"], row["iqm_after"], row["ci_before"]) for tier, row in rows if not row["inside_old_ci"]]
    assert not outside
    for _, row in rows:  # the flag is what the numbers say
        assert row["inside_old_ci"] == (row["ci_before"][0] <= row["iqm_after"] <= row["ci_before"][1])


def test_ranks_move_only_through_pairs_at_the_edge_of_separation():
    """A rank differs before and after only if a pair involving the entry flipped its CI separation, and each
    flipped pair's old gap was within half the wider of the two old CIs (statistical noise, not a reversal)."""
    for tier, data in RECORD["tiers"].items():
        entries = {row["name"]: row for row in data["entries"]}
        flipped = {name for pair in data["flipped_pairs"] for name in (pair["above"], pair["below"])}
        for name, row in entries.items():
            if row["rank_before"] != row["rank_after"]:
                assert name in flipped, (tier, name)
        for pair in data["flipped_pairs"]:
            widths = [entries[pair[k]]["ci_before"][1] - entries[pair[k]]["ci_before"][0] for k in ("above", "below")]
            assert abs(pair["gap_before"]) <= 0.5 * max(widths), (tier, pair)


def test_the_rebuilt_pools_hold_the_same_tasks():
    """Rebuilt on the new kernel, every pool keeps its tasks, certificates and default failures (only the stored
    certificate scores, margins and nominal figures are re-recorded)."""
    assert set(RECORD["pools"]) == {"easy", "medium", "hard", "debris", "robust"}
    assert all(row["same_tasks"] and row["tasks"] == 350 for row in RECORD["pools"].values())
