"""Speed regressions made visible: a new ``bench.py`` run against the committed ``experiments/results.json``.

Every row of a run is compared with the same row of the committed results. Raw times and rates move with the
machine and its load, so both sides are first divided by a **yardstick** measured in the same run: a fixed piece of
numpy and Python work that shares no code with ffsr-gym (:func:`yardstick_s`). A row is flagged when its
yardstick-scaled figure is worse than the committed one by more than :data:`TOLERANCE` (a factor: 1.3 means 30 %
slower); the best of the runs is compared on each side (the fastest run is the one least disturbed by other work).
Committed results without that yardstick are scaled by the Pinocchio rollout every results file times (the
reference of the ``rollout`` row); raw comparison is the last resort, meaningful on the same machine only.
"""

from __future__ import annotations

import time

import numpy as np

#: A row is flagged when it is slower than the committed one by more than this factor (on the 2-core VM of the
#: committed results the batched rows spread 1.13-1.15x over three runs; the single rows and the pool rows spread
#: more, up to 1.5x, so a flag on them wants a second run before it is believed).
TOLERANCE = 1.3
#: Units where more is faster; every other unit is a time (less is faster).
RATE_UNITS = ("physics steps/s", "env steps/s")


def yardstick_s(repeats: int = 5) -> float:
    """Seconds (best of ``repeats``) of a fixed workload that shares no code with ffsr-gym: small numpy solves and
    a Python loop, the mix the package's own Python spends its time on."""
    rng = np.random.default_rng(0)
    matrices, vectors = rng.normal(size=(200, 6, 6)) + 6.0 * np.eye(6), rng.normal(size=(200, 6))
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        total = 0.0
        for a, b in zip(matrices, vectors):
            total += float(np.linalg.solve(a, b)[0])
        for k in range(200_000):
            total += (k % 7) * 0.5
        best = min(best, time.perf_counter() - start)
    return best


def best_values(results: dict) -> dict[str, tuple[float, str, str]]:
    """Per row key: the best value over the runs, its unit and its description."""
    out: dict[str, tuple[float, str, str]] = {}
    for run in results.get("runs", []):
        for row in run:
            value, unit = float(row["value"]), row["unit"]
            if row["key"] in out:
                old = out[row["key"]][0]
                value = max(old, value) if unit in RATE_UNITS else min(old, value)
            out[row["key"]] = (value, unit, row["what"])
    return out


def slowdown(new: float, old: float, unit: str, scale: float) -> float:
    """How many times slower ``new`` is than ``old`` (< 1: faster), the old figure scaled by ``scale`` (the new
    yardstick over the old one: a machine twice as slow makes times twice as long and rates half as high)."""
    if unit in RATE_UNITS:
        return (old / scale) / new if new > 0.0 else float("inf")
    return new / (old * scale) if old > 0.0 else float("inf")


def pinocchio_rollout_s(results: dict) -> float | None:
    """The fastest run's Pinocchio rollout of the ``rollout`` row [s] (its value times its ratio), a yardstick that
    every results file holds: numpy, Pinocchio and Python, none of the compiled kernel."""
    times = [row["value"] * row["ratio"] / 1e3 for run in results.get("runs", []) for row in run
             if row.get("key") == "rollout" and row.get("ratio")]
    return min(times) if times else None


def machine_scale(results: dict, committed: dict) -> tuple[float, str]:
    """This run's yardstick over the committed run's, and how it was taken: the dedicated yardstick when both hold
    one, else the Pinocchio rollout, else 1 (raw)."""
    if results.get("yardstick_s") and committed.get("yardstick_s"):
        return results["yardstick_s"] / committed["yardstick_s"], "yardstick"
    ours, theirs = pinocchio_rollout_s(results), pinocchio_rollout_s(committed)
    if ours and theirs:
        return ours / theirs, "Pinocchio rollout"
    return 1.0, "raw"


def regressions(results: dict, committed: dict, tolerance: float = TOLERANCE) -> list[str]:
    """One line per row of ``results`` slower than in ``committed`` by more than ``tolerance`` (empty: none)."""
    ours, theirs = best_values(results), best_values(committed)
    scale, how = machine_scale(results, committed)
    scaled = ("raw (neither results file holds a yardstick)" if how == "raw"
              else f"scaled by the {how} (this machine {scale:.2f}x the committed run's time)")
    commit = str(committed.get("provenance", {}).get("git_commit") or "?")[:7]
    lines = []
    for key, (value, unit, what) in ours.items():
        if key not in theirs or theirs[key][1] != unit:
            continue
        factor = slowdown(value, theirs[key][0], unit, scale)
        if factor > tolerance:
            lines.append(f"SLOWER {factor:.2f}x: {what}: {value:,.4g} {unit} against {theirs[key][0]:,.4g} at {commit}, "
                         f"{scaled}; tolerance {tolerance:g}x")
    return lines


START = "<!-- speed-guard:start (generated by `python experiments/bench.py --runs 3 --readme docs/speed.md`) -->"
END = "<!-- speed-guard:end -->"


def guard_block(results: dict) -> str:
    """The speed page's lines on this run against the results it replaced (``slower_than_committed``)."""
    against = results.get("compared_with") or {}
    if not against:
        return "No committed results to compare this run with.\n"
    head = (f"Compared with the results it replaced (commit {str(against.get('git_commit'))[:7]}), scaled by the "
            f"{against.get('scaled_by', 'yardstick')} ({against.get('scale', 1.0):.2f}x that run's time on this "
            f"machine): ")
    lines = results.get("slower_than_committed") or []
    if not lines:
        return head + f"no row slower than {TOLERANCE:g}x.\n"
    return head + f"{len(lines)} rows slower than {TOLERANCE:g}x:\n\n" + "\n".join(f"- {line}" for line in lines) + "\n"


def compare_into(results: dict, committed: dict) -> dict:
    """``results`` with ``slower_than_committed`` and ``compared_with`` (commit, scale and how it was taken)."""
    scale, how = machine_scale(results, committed)
    return {**results, "slower_than_committed": regressions(results, committed),
            "compared_with": {"git_commit": committed.get("provenance", {}).get("git_commit"), "scale": scale,
                              "scaled_by": how}}


def main() -> None:
    """Compare results with the ones they replaced after the fact, and splice the page's block."""
    import argparse
    import json
    from pathlib import Path

    from ffsr_gym.provenance import splice_file, write_json_atomic

    parser = argparse.ArgumentParser(description="compare bench results with the ones they replaced")
    parser.add_argument("--results", default="experiments/results.json")
    parser.add_argument("--against", required=True, help="the results file they replaced")
    parser.add_argument("--readme", default=None, help="splice the comparison between its markers in this page")
    args = parser.parse_args()
    results = compare_into(json.loads(Path(args.results).read_text()), json.loads(Path(args.against).read_text()))
    write_json_atomic(args.results, results)
    print(guard_block(results))
    if args.readme:
        splice_file(args.readme, START, END, guard_block(results))


if __name__ == "__main__":
    main()
