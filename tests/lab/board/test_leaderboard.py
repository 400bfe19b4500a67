"""Leaderboards: entries valid, aggregates recompute from rows, tables up to date, staleness, ranking."""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import jsonschema
import numpy as np
import pytest

import ffsr_gym
from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym_lab.board import leaderboard

ROOT = Path(__file__).resolve().parents[3] / "leaderboards"
ENTRIES = sorted(p for p in ROOT.glob("*/*.json") if p.parent.name != "v2")  # v0 entries


def _close(a, b):
    if a is None or b is None or (isinstance(b, float) and math.isinf(b)):
        return (a is None or math.isinf(a)) and (b is None or math.isinf(b))
    return math.isclose(a, b, rel_tol=1e-12, abs_tol=1e-15)


@pytest.mark.parametrize("path", [p for p in ENTRIES if p.name != "schema.json"], ids=lambda p: p.name)
def test_committed_entries_are_valid_and_recompute(path):
    entry = json.loads(path.read_text())
    jsonschema.validate(entry, json.loads((ROOT / "schema.json").read_text()))
    recomputed = leaderboard.recompute(entry)
    for key in ("score_mean", "score_iqm", "feasible_rate", "episodes"):
        assert _close(entry["metrics"][key], recomputed[key]), key
    for got, want in zip(entry["metrics"]["score_ci95"], recomputed["score_ci95"]):
        assert _close(got, want)
    assert entry["protocol"]["seeds"] == [row["seed"] for row in entry["episodes"]]


def test_committed_tables_are_up_to_date():
    from ffsr_gym_lab.board.leaderboard import splice_summary

    assert leaderboard.render_readme(ROOT) == (ROOT / "README.md").read_text(), "run: ffsr-gym leaderboard render"
    for page in ("README.md", "docs/baselines.md"):
        text = (ROOT.parent / page).read_text(encoding="utf-8")
        assert splice_summary(text, ROOT) == text, "run: ffsr-gym leaderboard render --readme README.md docs/baselines.md"


def test_the_capture_rl_study_block_reads_the_capture_entries():
    """The ``rl-study-capture-v0`` block has a row per capture tier with RL entries, and its best selected entry is
    the tier's best-on-validation entry by IQM, read here from the entry files."""
    from ffsr_gym_lab.board.leaderboard import _page_markers, splice_summary

    start, end = _page_markers("rl-study-capture-v0")
    text = splice_summary(f"{start}\n{end}\n", ROOT)
    rows = [line.split(" | ") for line in text.splitlines() if line.startswith("| slow") or line.startswith("| fast")]
    assert rows and not any(line.startswith(("| easy", "| medium")) for line in text.splitlines())
    for row in rows:
        tier = row[0].removeprefix("| ")
        selected = [json.loads(p.read_text()) for p in (ROOT / "capture-v0" / tier).glob("*_valbest.json")]
        selected = [e for e in selected if e.get("extra", {}).get("training_seeds")]
        best = max(selected, key=lambda e: e["metrics"]["score_iqm"])
        assert row[1].startswith(f"`{best['name'].replace('_' + tier, '')}` ")
        assert f"{best['metrics']['score_iqm']:.3f}" in row[1]


@pytest.fixture()
def board(tmp_path):
    root = tmp_path / "leaderboards"
    root.mkdir()
    shutil.copy(ROOT / "README.md", root / "README.md")
    good = ffsr_gym.evaluate((0.2167, 2.19), "FFSR-v0", seeds=[1, 2], name="good")
    bad = ffsr_gym.evaluate((0.1, 2.19), "FFSR-v0", seeds=[1], name="bad")
    for report in (good, bad):
        report.save(root / "FFSR-v0")
    return root


def test_ranking_stale_and_out_of_date_detection(board):
    assert leaderboard.write_readme(board)
    text = (board / "README.md").read_text()
    assert text.index("`good`") < text.index("`bad`")  # feasible rate first
    assert "| 1 | `good`" in text and "(single run)" in text
    assert not leaderboard.write_readme(board)  # idempotent
    entry_path = board / "FFSR-v0" / "good.json"
    entry = json.loads(entry_path.read_text())
    entry["provenance"]["scenario_sha256"]["family"] = "0" * 64
    entry_path.write_text(json.dumps(entry))
    assert leaderboard.render_readme(board) != text  # the table is now out of date
    assert "| stale | `good`" in leaderboard.render_readme(board)


def test_tampered_aggregate_is_caught(board):
    entry = json.loads((board / "FFSR-v0" / "good.json").read_text())
    entry["metrics"]["score_iqm"] = 0.0
    assert not _close(entry["metrics"]["score_iqm"], leaderboard.recompute(entry)["score_iqm"])


POOL_ENTRIES = sorted((ROOT / "v2").glob("*/*.json"))


@pytest.mark.parametrize("path", POOL_ENTRIES, ids=lambda p: f"{p.parent.name}/{p.stem}")
def test_committed_v2_entries_recompute_and_name_their_pools(path):
    from ffsr_gym.tasks.splits import pool
    from ffsr_gym_lab.board.leaderboard import recompute as recompute_entry

    entry = json.loads(path.read_text())
    recomputed = recompute_entry(entry)
    assert entry["metrics"].keys() == recomputed.keys()
    for key, value in recomputed.items():
        assert entry["metrics"][key] == pytest.approx(value, rel=1e-12), key
    assert entry["extra"]["evaluation_pool"] == f"{path.parent.name}/test" and entry["extra"]["dt_s"] == 0.01
    assert len(entry["episodes"]) % len(pool(path.parent.name, "test")) == 0  # one per test task (per training seed)
    assert all(0.0 <= row["score"] <= 1.0 and (row["score"] > 0) == row["success"] for row in entry["episodes"])


def test_ranks_share_a_rank_when_no_ci_separates_them():
    from ffsr_gym.versions.registry import spec_for_version
    from ffsr_gym_lab.board.leaderboard import ranks, render_tables

    def render_v2_tables(entries):
        return render_tables(spec_for_version("v2"), entries)

    cis = [[0.6, 0.7], [0.55, 0.65], [0.3, 0.5], [0.0, 0.0], [0.0, 0.0]]
    entries = [{"metrics": {"score_iqm_ci95": ci}} for ci in cis]
    assert ranks(entries) == [1, 1, 3, 4, 4]
    full = [{"name": f"e{i}", "episodes": [], "provenance": {}, "extra": {},
             "metrics": {"score_iqm": ci[1], "score_iqm_ci95": ci, "success_rate": 1.0, "score_mean": ci[1]}} for i, ci in enumerate(cis)]
    table = render_v2_tables({"easy": full})
    assert table.count("| 1 (tied) |") == 2 and "| 3 | `e2`" in table and table.count("| 4 (tied) |") == 2


def test_figures_are_drawn_from_entries(tmp_path):
    from ffsr_gym.scoring.rules import score_rule
    from ffsr_gym.versions.registry import spec_for_version

    def aggregate(scores, successes):
        return score_rule(spec_for_version("v2")).aggregate([{"score": s, "success": ok} for s, ok in zip(scores, successes)])
    from ffsr_gym_lab.board.plots import plot_iqm, plot_learning_curves, plot_profiles

    assert plot_iqm(tmp_path) is None and plot_profiles(tmp_path) is None and plot_learning_curves(tmp_path) is None
    rng = np.random.default_rng(0)
    for tier in ("easy", "hard"):
        for name in ("a", "b"):
            scores = list(rng.uniform(0, 1, 20))
            curve = {"split": "validation", "indices": [0, 24, 49], "points": [{"env_steps": k * 100, "scores": list(rng.uniform(0, 1, 3))}
                                                              for k in range(4)]}
            entry = {"name": name, "provenance": {"git_commit": "abc"}, "metrics": aggregate(scores, [True] * 20),
                     "episodes": [{"score": s} for s in scores], "extra": {"runs": [{"curve": curve}] * 3}}
            (tmp_path / "v2" / tier).mkdir(parents=True, exist_ok=True)
            (tmp_path / "v2" / tier / f"{name}.json").write_text(json.dumps(entry))
    for path in (plot_iqm(tmp_path), plot_profiles(tmp_path), plot_learning_curves(tmp_path)):
        assert path.is_file() and path.stat().st_size > 10_000


def test_committed_figures_regenerate_byte_identically_from_the_json(tmp_path):
    from ffsr_gym_lab.board.plots import plot_iqm, plot_learning_curves, plot_pareto, plot_profiles

    shutil.copytree(ROOT / "v2", tmp_path / "v2", ignore=shutil.ignore_patterns("*.png"))
    for plot in (plot_iqm, plot_profiles, plot_learning_curves, plot_pareto):
        path = plot(tmp_path)
        if path is None:  # no RL entries yet: no learning curves
            assert plot is plot_learning_curves and not (ROOT / "v2" / "learning_curves.png").exists()
            continue
        committed = ROOT / "v2" / path.name
        assert path.read_bytes() == committed.read_bytes(), f"{committed} is out of date: run ffsr-gym leaderboard plot"


def test_pareto_points_are_the_env_episodes_and_the_front_is_non_dominated(tmp_path):
    import gymnasium as gym

    from ffsr_gym.scoring.score import score_episode
    from ffsr_gym.tasks.splits import pool
    from ffsr_gym_lab.board.pareto import task_pareto
    from ffsr_gym_lab.board.plots import PARETO_FILE, _front, plot_pareto

    assert plot_pareto(tmp_path) is None
    (tmp_path / "v2" / "easy").mkdir(parents=True)
    for name in ("reference_v2_default.json", "sac_residual_easy.json"):
        shutil.copy(ROOT / "v2" / "easy" / name, tmp_path / "v2" / "easy" / name)
    forged = {"name": "forged", "env_id": "../../x", "extra": {"runs": [{"seed": 0}]}}  # refused: never a point
    (tmp_path / "v2" / "easy" / "forged.json").write_text(json.dumps(forged))
    (tmp_path / "no-models").mkdir()
    with pytest.raises(InvalidInputError, match="--trust-model"):  # unpickling runs code: only with consent
        task_pareto(tmp_path, tmp_path / "v2" / PARETO_FILE, tmp_path / "no-models", load_model=lambda a, p: None)
    data = json.loads(task_pareto(tmp_path, tmp_path / "v2" / PARETO_FILE, tmp_path / "no-models",
                                  load_model=lambda algo, path: None, progress=False, trust_model=True).read_text())
    assert (tmp_path / "v2" / PARETO_FILE).is_file() and len(data["grid"]["points"]) == 120
    assert data["task"] == "easy/test[0]" and data["task_name"] == f"v2-{pool('easy', 'test')[0].seed}"
    env = gym.make("FFSR-v2", task="easy", split="test")  # the same setting through the env, scored independently
    env.reset(seed=0, options={"task_index": 0})
    done = False
    while not done:
        _, _, terminated, truncated, _ = env.unwrapped.step_with_parameters(0.3, 4.0)
        done = terminated or truncated
    played = score_episode(env.unwrapped.trajectory, env.unwrapped.scenario, env.unwrapped.benchmark)
    grid = next(p for p in data["grid"]["points"] if (p["m"], p["T_c_s"]) == (0.3, 4.0))
    reference, sac = data["baselines"]
    for point in (grid, reference["points"][0]):
        assert point["success"] and point["score"] == pytest.approx(played.score, rel=1e-12)
        assert point["convergence_time_s"] == pytest.approx(played.convergence_time_s, abs=1e-12)
    assert sac["points"] == [] and "model missing" in sac["missing"]
    ok = [(p["convergence_time_s"], p["smoothness_cost"]) for p in data["grid"]["points"] if p["success"]]
    front = _front(ok)
    assert all(not (x <= fx and y <= fy and (x, y) != (fx, fy)) for fx, fy in front for x, y in ok)
    assert plot_pareto(tmp_path).stat().st_size > 10_000


def test_iqm_is_the_mean_of_the_middle_half():
    from ffsr_gym.scoring.aggregate import iqm

    assert iqm([4.0, 1.0, 3.0, 2.0]) == 2.5
    assert iqm([0.0, 0.0, 1.0, 1.0, 1.0, 1.0, 9.0, 100.0]) == 1.0
    assert iqm([7.0]) == 7.0


def test_a_version_with_entries_and_no_readme_section_is_refused_by_name(tmp_path):
    """A live version's entries are never left out of the README's tables unsaid (a new version's section must be
    added by hand, once): the render names the version and the two marker lines to add."""
    from ffsr_gym.exceptions import FFSRError
    from ffsr_gym.versions.registry import spec_for_version

    folder = tmp_path / "capture-v1" / "sweep"
    folder.mkdir(parents=True)
    for path in (ROOT / "capture-v1" / "sweep").glob("slowest_pass.*"):  # the entry and its action trace
        shutil.copy(path, folder)
    (tmp_path / "README.md").write_text("# Leaderboards\n")
    start, end = spec_for_version("capture-v1").leaderboard.markers()
    with pytest.raises(FFSRError, match="no section for capture-v1") as raised:
        leaderboard.render_readme(tmp_path)
    assert start in str(raised.value) and end in str(raised.value)
    (tmp_path / "README.md").write_text(f"# Leaderboards\n\n{start}\n{end}\n")
    assert "`slowest_pass`" in leaderboard.render_readme(tmp_path)
