"""Benchmark v2's task tiers: certificates replayed through the environments and in every member of the
ensemble, the tier rule re-run, disjoint train, validation and test pools, the screening margins against
Pinocchio, and the fading residual on the easy test pool.

CI replays a sample; ``-m slow`` replays every certificate (in every ensemble member) and re-runs the rule
on more candidates.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from conftest import replay_certificate

import ffsr_gym  # noqa: F401  (registers the environments)
from ffsr_gym import failure_name
from ffsr_gym.exceptions import InvalidInputError, ScenarioError
from ffsr_gym.model.robot import load_robot
from ffsr_gym.sim.setup import initial_configuration
from ffsr_gym.sim.simulate import make_rollout
from ffsr_gym.tasks.certificate import Certificate, Margins, Member, ensemble_members, replay_members
from ffsr_gym.tasks.generator import draw_task, screen
from ffsr_gym.tasks.perturbation import confirmation_member
from ffsr_gym.tasks.splits import LABEL_CODES, SEED_RANGES, load_pools, pool, task_scenario
from ffsr_gym.tasks.tiers import ALL_TIERS, TIERS, classify
from ffsr_gym.versions.registry import load_benchmark

BENCH = load_benchmark("v2")
SPLITS = BENCH.tasks.splits
POOLS = load_pools()
CODES = {code: label for label, code in LABEL_CODES.items()}
IDS = ("FFSR-v2", "FFSR-Residual-v2")


def replay_in_env(tier: str, split: str, index: int) -> dict:
    """Step a certificate through the registered environment; the last step's info."""
    return replay_certificate("v2", tier, split, index)


def certificate_cases(per_pool: int | None) -> list[tuple[str, str, int]]:
    """(tier, split, index) of ``per_pool`` spread tasks (None: all) of every pool, the perturbed tiers' included."""
    cases = []
    for split in SPLITS:
        for tier in ALL_TIERS:
            n = len(pool(tier, split))
            picks = range(n) if per_pool is None else np.linspace(0, n - 1, per_pool).round().astype(int)
            cases += [(tier, split, int(i)) for i in picks]
    return cases


@pytest.mark.parametrize("tier,split,index", certificate_cases(2))
def test_certificate_replays_to_success_in_the_env(tier, split, index):
    info = replay_in_env(tier, split, index)
    assert info["success"], info["failure"]
    assert info["score"] == pytest.approx(pool(tier, split)[index].certificate_score, rel=0, abs=1e-12)


@pytest.mark.slow
def test_every_certificate_replays_to_success():
    failed = [(case, info["failure"]) for case in certificate_cases(None)
              if not (info := replay_in_env(*case))["success"]]
    assert not failed


def ensemble_problems(tier: str, split: str, index: int) -> list[str]:
    """Replay a pool certificate at dt and in every ensemble member (Pinocchio included); what fails, or what
    differs from the worst margins the pool file stores."""
    entry = pool(tier, split)[index]
    task = task_scenario(tier, entry.seed, BENCH)
    members = [Member("dt", task), *ensemble_members(task, entry.seed, BENCH.tasks.ensemble, pinocchio=False),
               confirmation_member(task, "v2")]  # Pinocchio, or a servo task's finer physics step
    failed, results = replay_members(members, entry.certificate, BENCH)
    if failed is not None:
        return [f"{tier}/{split}[{index}]: fails at {failed} ({results[-1].failure})"]
    worst = Margins.worst(results)
    problems = [] if worst.short(BENCH) is None else [f"{tier}/{split}[{index}]: {worst.short(BENCH)}"]
    stored = entry.margins
    if stored is None or stored.episodes != worst.episodes:
        return [*problems, f"{tier}/{split}[{index}]: stored margins {stored} for {worst.episodes} episodes"]
    for key in ("min_clearance_m", "min_self_clearance_m", "peak_rate_deg_s"):
        if getattr(stored, key) != pytest.approx(getattr(worst, key), rel=1e-9):  # Pinocchio's last bits: §17
            problems.append(f"{tier}/{split}[{index}]: stored {key} {getattr(stored, key)} != {getattr(worst, key)}")
    return problems


@pytest.mark.parametrize("tier,split,index", [case if case[1] == "test" else pytest.param(*case, marks=pytest.mark.slow)
                                               for case in certificate_cases(1)])  # CI: the test pools' tasks
def test_certificate_succeeds_in_every_ensemble_member_with_its_stored_margins(tier, split, index):
    assert not ensemble_problems(tier, split, index)


@pytest.mark.slow
def test_every_certificate_succeeds_in_every_ensemble_member():
    problems = [p for case in certificate_cases(None) for p in ensemble_problems(*case)]
    assert not problems, problems[:20]


def test_pools_are_full_disjoint_in_range_and_the_first_of_their_tier():
    rule = BENCH.tasks
    seen: set[int] = set()
    for split in SPLITS:
        summary = POOLS["splits"][split]
        lo, hi = SEED_RANGES[split]
        labels = [CODES[c] for c in summary["labels"]]
        seeds = range(summary["first_seed"], summary["first_seed"] + len(labels))
        assert summary["first_seed"] == lo and seeds[-1] < hi
        for tier in TIERS:
            expected = rule.tasks_in(split)
            pool_seeds = [t.seed for t in pool(tier, split)]
            assert pool_seeds == [s for s, label in zip(seeds, labels) if label == tier][:expected]
            assert not seen & set(pool_seeds)
            seen |= set(pool_seeds)
        counts = {label: labels.count(label) for label in LABEL_CODES}
        assert summary["tier_counts"] == {tier: counts[tier] for tier in TIERS}


@pytest.mark.parametrize("split", SPLITS)
def test_the_tier_rule_reruns_to_the_stored_labels(split):
    summary = POOLS["splits"][split]
    first = summary["first_seed"]
    for offset in range(6):
        verdict = classify(first + offset, BENCH)
        assert (verdict.tier or verdict.rejection) == CODES[summary["labels"][offset]], first + offset


@pytest.mark.slow
def test_the_tier_rule_reruns_on_a_random_sample():
    rng = np.random.default_rng(0)
    for split in SPLITS:
        summary = POOLS["splits"][split]
        for offset in rng.choice(len(summary["labels"]), 40, replace=False):
            verdict = classify(summary["first_seed"] + int(offset), BENCH)
            assert (verdict.tier or verdict.rejection) == CODES[summary["labels"][offset]]


def test_reference_planner_at_its_defaults_defines_the_tiers():
    """Easy tasks succeed at the default (m, T_c); medium and hard ones fail there (replayed)."""
    for tier in TIERS:
        task = pool(tier, "test")[0]
        result = ffsr_gym.tasks.certificate.replay(draw_task(task.seed, BENCH), Certificate("constant", 0.3, 4.0), BENCH)
        assert result.success == (tier == "easy"), (tier, result.failure)


def test_balance_singularity_margin_matches_pinocchio():
    """The kernel's σ_min(J_c²) on a rejected candidate equals Pinocchio's, and the default planner breaks the rate limit there."""
    labels = POOLS["splits"]["train"]["labels"]
    seed = labels.index(LABEL_CODES["balance_singularity"])
    task = draw_task(seed, BENCH)
    nominal = screen(task, BENCH)
    assert nominal.cause == "balance_singularity" and nominal.min_balance_sigma < BENCH.tasks.min_balance_sigma
    rollout = make_rollout(task, method="no_avoidance", backend="kernel")
    rollout.advance(task.n_steps)
    rollout.finish()
    traj = rollout.trajectory()
    k = int(np.argmin(traj.sigma_min[:, 1]))
    robot = load_robot(task.robot)
    H_bm2 = robot.momentum_matrices(traj.q[k]).H_bm[1]
    assert np.linalg.svd(-H_bm2, compute_uv=False)[-1] == pytest.approx(nominal.min_balance_sigma, rel=1e-9)
    default = ffsr_gym.tasks.certificate.replay(task, Certificate("constant", 0.3, 4.0), BENCH)
    assert default.failure == "rate_limit" and default.peak_rate_deg_s[1] > BENCH.score.max_rate_deg_s


def test_candidates_are_deterministic_and_seeds_checked():
    a, b = draw_task(5, BENCH), draw_task(5, BENCH)
    assert a.sha256() == b.sha256() and a.target != draw_task(6, BENCH).target
    assert np.allclose(initial_configuration(load_robot(a.robot), a), initial_configuration(load_robot(a.robot), a))
    for bad in (-1, 1.5, "3", True, 2**63):
        with pytest.raises(InvalidInputError, match="seed"):
            draw_task(bad, BENCH)


def test_reset_never_draws_the_test_pool_unless_asked():
    test_seeds = {t.seed for t in pool("easy", "test")}
    env = gym.make("FFSR-v2", task="easy")
    drawn = {env.reset(seed=s)[1]["task_seed"] for s in range(60)}
    assert not drawn & test_seeds and len(drawn) > 30
    env = gym.make("FFSR-v2", task="easy", split="test")
    assert {env.reset(seed=s)[1]["task_seed"] for s in range(20)} <= test_seeds
    with pytest.raises(InvalidInputError, match="task_index"):
        env.reset(options={"task_index": 10_000})
    with pytest.raises(InvalidInputError, match="options"):
        env.reset(options="task 3")


def test_bad_pool_file_and_certificate_are_named_errors(tmp_path):
    path = tmp_path / "pools.json"
    path.write_text('{"splits": {}}')
    with pytest.raises(ScenarioError, match="splits"):
        pool("easy", "train", path=str(path))
    with pytest.raises(InvalidInputError, match="tier"):
        pool("trivial", "train")
    with pytest.raises(InvalidInputError, match="float32"):
        Certificate("residual", 0.3, 4.0, (0.1,) * 12)
    with pytest.raises(InvalidInputError, match="m in"):
        Certificate.from_dict({"kind": "constant", "m": 1.5, "T_c_s": 4.0})


def random_residual_on_easy_test_pool(indices) -> tuple[int, int]:
    """(successes, episodes without a rate-limit violation or collision) of a uniform random residual."""
    env = gym.make("FFSR-Residual-v2", task="easy", split="test")
    env.action_space.seed(0)
    successes = eligible = 0
    for index in indices:
        env.reset(seed=int(index), options={"task_index": int(index)})
        while True:
            _, _, terminated, truncated, info = env.step(env.action_space.sample())
            if terminated or truncated:
                break
        if failure_name(info["failure"]) not in ("rate_limit", "collision"):
            eligible += 1
            successes += bool(info["success"])
    return successes, eligible


def test_random_residual_succeeds_on_easy_test_tasks_sample():
    successes, eligible = random_residual_on_easy_test_pool(range(0, 100, 5))
    assert eligible >= 4 and successes >= 0.9 * eligible


@pytest.mark.slow
def test_random_residual_succeeds_on_90_percent_of_the_easy_test_pool():
    successes, eligible = random_residual_on_easy_test_pool(range(len(pool("easy", "test"))))
    assert successes >= 0.9 * eligible


def test_docs_tier_table_is_generated_from_the_pool_file():
    from pathlib import Path

    from ffsr_gym_lab.pools.tables import tier_table

    text = (Path(__file__).resolve().parents[3] / "docs" / "envs.md").read_text(encoding="utf-8")
    block = text.split("<!-- tiers:begin -->\n")[1].split("<!-- tiers:end -->")[0]
    assert block == tier_table(POOLS)
    from ffsr_gym_lab.pools.tables import splice_docs_tables

    assert splice_docs_tables(text, "v2") == text, "rerun: ffsr-gym tasks tables --docs docs/envs.md"
    assert splice_docs_tables(text, "capture-v0") == text, \
        "rerun: ffsr-gym tasks tables --version capture-v0 --docs docs/envs.md"


def test_the_capture_tables_count_every_candidate_once():
    from ffsr_gym.tasks.capture_family import CAPTURE_TIERS
    from ffsr_gym.tasks.splits import load_pools

    for tier in CAPTURE_TIERS:
        data = load_pools(None, (tier,), "capture-v0")
        for split, s in data["splits"].items():
            assert len(s["labels"]) == s["candidates"], (tier, split)
            assert s["tier_counts"][tier] + sum(s["rejection_counts"].values()) == s["candidates"], (tier, split)
            codes = data["label_codes"]
            for cause, count in s["rejection_counts"].items():
                assert s["labels"].count(codes[cause]) == count, (tier, split, cause)


def test_training_loss_is_one_minus_the_mean_certified_score():
    """On easy tasks the default planner is the certificate: the optimisers' loss replays the stored scores."""
    from ffsr_gym.bench.planner_scores import training_loss

    stored = [t.certificate_score for t in pool("easy", "train")[:5]]
    assert training_loss(0.3, 4.0, tier="easy", tasks=5) == pytest.approx(1.0 - np.mean(stored), abs=1e-12)
    assert 0.0 <= training_loss(0.1, 3.0, tier="medium", tasks=3) <= 1.0


def test_a_candidate_the_pinocchio_member_fails_is_relabelled_fragile_and_replaced(tmp_path, monkeypatch):
    """The build's second stage: pool candidates are replayed on Pinocchio in seed order (here a stand-in that fails
    one seed); the failed one becomes `fragile`, the next candidate of its tier takes its place, and a rerun resumes
    from the saved confirmations without replaying them."""
    from ffsr_gym_lab.pools import build

    replayed = []

    def fake_confirm(tier, seed, certificate, version):
        replayed.append(seed)
        margins = {"min_clearance_m": 0.1, "min_self_clearance_m": 0.05, "peak_rate_deg_s": 100.0,
                   "final_ee_position_error_m": 1e-8, "final_ee_attitude_error": 1e-8, "episodes": 1}
        return {"seed": seed, "success": seed != 5, "margins": margins}

    monkeypatch.setattr(build, "confirm", fake_confirm)
    monkeypatch.setattr(build, "expected_count", lambda tier, split, version=None: 2)  # per tier
    verdicts = build.build_split(tmp_path, "train", version="v2", chunk=20, progress=False)
    easy = [v for v in verdicts if v.tier == "easy"]
    assert [v.seed for v in easy[:2]] == [8, 9] and next(v for v in verdicts if v.seed == 5).rejection == "fragile"
    assert replayed == [5, 8, 11, 26, 7, 51, 9]  # easy, medium, hard in seed order; then the easy replacement
    assert easy[0].margins.episodes == 6  # dt, dt/2, dt/4, two starts, then Pinocchio
    count = len(replayed)
    again = build.build_split(tmp_path, "train", version="v2", chunk=20, progress=False)
    assert len(replayed) == count and [v.seed for v in again if v.tier == "easy"][:2] == [8, 9]


def test_what_makes_medium_and_hard_tasks():
    """docs/envs.md: the default breaks the rate limit on medium tasks; on hard ones its collisions are contacts of
    the robot's own parts, the obstacle far away (first 20 test tasks of each)."""
    from ffsr_gym.tasks.certificate import planner_episode

    def defaults(tier):
        return [planner_episode(draw_task(t.seed, BENCH), BENCH, method="predefined_time", m=0.3, T_c=4.0)
                for t in pool(tier, "test")[:20]]

    assert sum(r.failure == "rate_limit" for r in defaults("medium")) >= 18
    hard = [r for r in defaults("hard") if r.failure == "collision"]
    assert len(hard) >= 5 and all(r.min_self_clearance_m < 0.0 and r.min_clearance_m > 0.1 for r in hard)
