"""What a leaderboard entry must prove before it is ranked: one function for the renderer, ``--check`` and the tests.

An entry is refused, with every reason named, when

* its name is not a plain file name (a newline or a ``|`` would forge table rows);
* its env id is not of the folder's version (or ``planner`` for planner variants of a pool version);
* a metric is missing, not finite where it must be, out of its range, or differs from the
  aggregate recomputed from its rows by the version's score rule;
* a row's score or success flag is out of range or inconsistent with the rule;
* its rows are not exactly the protocol's episodes: the folder's tier pool on the spec's split,
  each task once per training seed (with the pool file's current hash when the entry records
  one), or (v0) the seeds its protocol names, each once per training seed;
* (a version whose environments take ``dt_s``) it does not record that it ran at the
  benchmark's own step (a sensitivity run at dt/4 is a study, not an entry).
"""

from __future__ import annotations

import hashlib
import math
import re
import unicodedata
from collections import Counter
from functools import lru_cache
from typing import Any

from ffsr_gym.bench.stamp import stamp_problems
from ffsr_gym.model.spec import BenchmarkSpec
from ffsr_gym.scoring.rules import BoundedSmoothness, score_rule
from ffsr_gym.tasks.reference import reference_path, reference_sha256
from ffsr_gym.tasks.splits import pool, pool_path

#: An entry's name: it becomes a file name, and a table cell (no newline, no ``|``).
#: The checkpoints a trained method is entered with, and the suffix each adds to the entry name.
CHECKPOINTS = {"last": "", "best_on_validation": "_valbest"}
ENTRY_NAME = re.compile(r"[A-Za-z0-9_-][A-Za-z0-9._-]{0,127}")
GIT_COMMIT = re.compile(r"[0-9a-f]{7,40}")
TRAINING_POOL = re.compile(r"[a-z0-9_]+/[a-z]+( \([^()]{1,80}\))?")


def entry_problems(entry: Any, spec: BenchmarkSpec, group: str) -> list[str]:
    """Every reason to refuse ``entry`` in the table ``group`` (a tier or an env id) of ``spec``; empty if none."""
    if not isinstance(entry, dict):
        return [f"not a JSON object ({type(entry).__name__})"]
    problems = _name_problems(entry) + _text_problems(entry) + _id_problems(entry, spec, group)
    rows = entry.get("episodes")
    if not isinstance(rows, list) or not rows or not all(isinstance(row, dict) for row in rows):
        return [*problems, "episodes: not a non-empty list of rows"]
    try:
        problems += _row_problems(rows, spec) + _metric_problems(entry, rows, spec)
        problems += _coverage_problems(entry, rows, spec, group)
        problems += stamp_problems(entry, None if spec.rules is None else spec.rules.version)
    except (KeyError, TypeError, ValueError) as exc:
        problems.append(f"malformed rows or metrics ({type(exc).__name__}: {exc})")
    return problems


def _name_problems(entry: dict) -> list[str]:
    name = entry.get("name")
    if not isinstance(name, str) or not ENTRY_NAME.fullmatch(name):
        return [f"name {name!r}: allowed 1-128 letters, digits, '.', '_', '-'"]
    return []


def training_pool_problem(value: Any, spec: BenchmarkSpec) -> str | None:
    """Why ``extra.training_pool`` is refused, or None: it is None, or ``<tier>/train`` or ``<tier>/validation``
    of the version's tiers, optionally followed by a note in brackets (``easy/train (first 20 tasks)``). A test
    pool is never one to train or tune on."""
    if value is None:
        return None
    allowed = [f"{tier}/{split}" for tier in spec.tasks.tiers for split in spec.tasks.splits if split != "test"]
    if isinstance(value, str) and TRAINING_POOL.fullmatch(value) and value.split(" ")[0] in allowed:
        return None
    return (f"training_pool {str(value)[:60]!r}; allowed: None, or <tier>/train or <tier>/validation (optionally "
            "followed by ' (a note)'), never a test pool")


def _text_problems(entry: dict) -> list[str]:
    """Free text on one line: no control or format character, no line break, in any field (a forged row starts with
    one); a commit is hexadecimal."""
    problems, stack = [], [("", entry)]
    while stack and len(problems) < 5:
        where, value = stack.pop()
        if isinstance(value, dict):
            stack += [(f"{where}.{key}" if where else str(key), item) for key, item in value.items()
                      if not (where == "extra" and key == "trace")]  # the trace is checked as a trace
            stack += [(f"{where} key", key) for key in value]
        elif isinstance(value, list):  # numbers hold no text: only the other items are looked into
            stack += [(f"{where}[{k}]", item) for k, item in enumerate(value) if type(item) not in (int, float)]
        elif isinstance(value, str) and not value.isprintable() and any(  # printable text has none of them
                unicodedata.category(c) in ("Cc", "Cf", "Zl", "Zp") for c in value):
            problems.append(f"{where}: a control character or line break in {value[:40]!r}; allowed: one line of text")
    commit = entry.get("provenance", {}).get("git_commit") if isinstance(entry.get("provenance"), dict) else None
    if commit is not None and not (isinstance(commit, str) and GIT_COMMIT.fullmatch(commit)):
        problems.append(f"provenance.git_commit {str(commit)[:40]!r}; allowed: null or 7-40 hexadecimal digits")
    return problems


def _id_problems(entry: dict, spec: BenchmarkSpec, group: str) -> list[str]:
    env_id = entry.get("env_id")
    pooled = spec.evaluation.protocol == "pool"
    allowed = (*spec.env_ids, "planner") if pooled else (group,)
    return [] if env_id in allowed else [f"env_id {env_id!r} does not belong here; allowed: {list(allowed)}"]


def _row_problems(rows: list[dict], spec: BenchmarkSpec) -> list[str]:
    rule = score_rule(spec)
    scores, flags = rule.row_values(rows)
    problems = []
    if isinstance(rule, BoundedSmoothness):  # capture_smoothness too
        if not all(0.0 <= s <= 1.0 for s in scores) or any((s > 0.0) != f for s, f in zip(scores, flags)):
            problems.append("rows: a score outside [0, 1], or a score > 0 without success (or the reverse)")
    elif any(math.isnan(s) or s < 0.0 or (f != math.isfinite(s)) for s, f in zip(scores, flags)):
        problems.append("rows: a negative or NaN B, or a finite B on an infeasible episode (or the reverse)")
    counts = [row["clipped_actions"] for row in rows if "clipped_actions" in row]
    if any(isinstance(c, bool) or not isinstance(c, int) or c < 0 for c in counts):
        problems.append("rows: clipped_actions is not an integer >= 0")
    return problems


def _metric_problems(entry: dict, rows: list[dict], spec: BenchmarkSpec) -> list[str]:
    recomputed = score_rule(spec).aggregate(rows)
    metrics = entry.get("metrics")
    if not isinstance(metrics, dict):
        return ["metrics: not an object"]
    problems = []
    for key, want in recomputed.items():
        if not _same(metrics.get(key), want):
            problems.append(f"metrics.{key} = {metrics.get(key)!r} differs from the rows' {want!r}")
    return problems


def _same(got: Any, want: Any) -> bool:
    if isinstance(want, list):
        return isinstance(got, list) and len(got) == len(want) and all(_same(g, w) for g, w in zip(got, want))
    if isinstance(got, bool) or not isinstance(got, (int, float, type(None))):
        return False
    got = math.inf if got is None else float(got)  # JSON null is +inf
    if math.isinf(want) or math.isinf(got):
        return got == want
    return math.isfinite(got) and math.isclose(got, want, rel_tol=1e-9, abs_tol=1e-12)


def _coverage_problems(entry: dict, rows: list[dict], spec: BenchmarkSpec, group: str) -> list[str]:
    """Whether the rows are exactly the protocol's episodes, once per training seed."""
    copies = max(1, len(entry.get("extra", {}).get("training_seeds") or [None]))
    if spec.evaluation.protocol == "seeds":  # v0 (frozen) ranks any seeds it names, each once per training seed
        got = Counter(row.get("seed") for row in rows)
        named = entry.get("protocol", {}).get("seeds")
        if set(got.values()) != {copies} or named != [row.get("seed") for row in rows]:
            return ["rows: each seed once per training seed, as the entry's protocol names them"]
        return []
    split, extra = spec.evaluation.split, entry.get("extra", {})
    problems = [reason for reason in [training_pool_problem(extra.get("training_pool"), spec)] if reason]
    if extra.get("evaluation_pool") != f"{group}/{split}":
        problems.append(f"evaluation_pool {extra.get('evaluation_pool')!r}: this table ranks {group}/{split}")
    sha = extra.get("pool_file_sha256")
    version = spec.rules.version
    if sha is not None and sha != _pool_sha(group, version):
        problems.append(f"pool_file_sha256 {str(sha)[:12]}...: the {group} pool file has changed since (stale)")
    recorded, frozen = extra.get("reference_sha256"), reference_sha256(version)
    if recorded is not None and recorded != frozen:
        problems.append(f"reference_sha256 {str(recorded)[:12]}...: scored against another reference than this "
                        f"version's frozen one; allowed: {str(frozen)[:12]}... ({reference_path(version).name})")
    if spec.tasks.step_option and extra.get("dt_s") != spec.rules.dt_s:
        problems.append(f"dt_s {extra.get('dt_s')!r}: this table ranks episodes at the benchmark's own step, "
                        f"dt_s = {spec.rules.dt_s} s")
    expected = Counter({task.seed: copies for task in pool(group, split, version=version)})
    if Counter(row.get("task_seed") for row in rows) != expected:
        problems.append(f"rows: not every task of the {group}/{split} pool exactly once per training seed "
                        f"({len(rows)} rows, {sum(expected.values())} expected)")
    return problems


@lru_cache(maxsize=16)
def _pool_sha(tier: str, version: str) -> str:
    return hashlib.sha256(pool_path(tier, version).read_bytes()).hexdigest()
