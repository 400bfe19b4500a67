"""The native kernel against the numba kernel it replaced (experiments/native_agreement.json): the record's summary
is its rows', every certificate's verdict and score are the same on both, and docs/kernel.md shows the record."""

from __future__ import annotations

import json
from pathlib import Path

from conftest import script_module

ROOT = Path(__file__).resolve().parents[3]
RECORD = json.loads((ROOT / "experiments" / "native_agreement.json").read_text(encoding="utf-8"))


def test_every_certificate_replays_the_same_on_both_kernels():
    rows = {kernel: {(r["version"], r["tier"], r["split"], r["index"]): r for r in RECORD["rows"]
                     if r["kernel"] == kernel} for kernel in ("numba", "native")}
    assert rows["numba"].keys() == rows["native"].keys() and len(rows["native"]) == 2800
    for key, old in rows["numba"].items():
        new = rows["native"][key]
        assert (new["success"], new["score"], new["final_ee_position_error_m"]) == (
            old["success"], old["score"], old["final_ee_position_error_m"]), key
    assert {RECORD["runs"][kernel]["provenance"]["git_dirty"] for kernel in ("numba", "native")} == {False}


def test_the_summary_and_the_docs_table_are_the_records():
    script = script_module("native_agreement")
    by_kernel = {kernel: [{k: v for k, v in r.items() if k != "kernel"} for r in RECORD["rows"]
                          if r["kernel"] == kernel] for kernel in ("numba", "native")}
    assert script.summary(by_kernel["numba"], by_kernel["native"]) == RECORD["summary"]
    text = (ROOT / "docs" / "kernel.md").read_text(encoding="utf-8")
    block = text.split(script.START + "\n")[1].split(script.END)[0]
    assert block == script.table(RECORD), "rerun: python experiments/native_agreement.py --merge --docs docs/kernel.md"
