"""The docs site's generated pages: one per registered id (its spaces, reward, episode end, arguments and info
keys, from the live environment and its version's spec) and one per tier (its rule, its pools' counts and
certificates and a GIF), and the README's table of ids and tiers; written by
``ffsr-gym docs pages``, checked by a test to be up to date."""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any

import gymnasium

from ffsr_gym.environments.info import markdown_table
from ffsr_gym.model.scenario import load_scenario
from ffsr_gym.model.spec import BenchmarkSpec
from ffsr_gym.scoring.rules import score_rule
from ffsr_gym.tasks.splits import load_pools
from ffsr_gym.versions.registry import all_specs, ranked_spec

#: What each tier is, in one sentence (the rules are in v2.toml and v2_perturbed.toml; docs/envs.md "Task tiers").
TIER_MEANING = {
    "easy": "tasks the default planner (m, T_c) = (0.3, 4 s) solves, certified in every member of the ensemble",
    "medium": "tasks the default planner fails but another constant (m, T_c) of the tier grid solves",
    "hard": "tasks no constant (m, T_c) of the grid solves and a fading residual of FFSR-Residual-v2 does",
    "debris": "tier tasks whose obstacle drifts, with one to three more drifting spheres crossing the end "
              "effector's way",
    "robust": "tier tasks on a robot whose masses and inertias differ from the planner's model, starting with "
              "momentum, with a noisy, biased target estimate",
    "servo": "tier tasks on a torque-level plant: the planned rates command torque-limited joint velocity servos "
             "that drive the free-floating multibody dynamics at a 1 ms physics step",
    "slow": "capture of a box tumbling at 1-3 deg/s: hold its grasp frame within 5 mm, 1 deg, 5 mm/s and "
            "0.5 deg/s for 1 s, certified in every member of the ensemble",
    "fast": "capture of a box tumbling at 5-10 deg/s, where the handle's speed brings the arms near the rate "
            "limit, certified in every member of the ensemble",
    "sweep": "capture of a handle that sweeps a wide cone: a box symmetric about the grasp axis spinning at 6-12 "
             "deg/s about an axis 60-90 deg off it; the method commands when to close in and when to insert, "
             "and a timed certificate captures in every member of the ensemble",
    "nutation": "capture of a handle on an asymmetric box in torque-free nutation (6-12 deg/s, 45-90 deg off the "
                "grasp axis), whose path does not repeat; the method owns the timing, certified like sweep",
    "capture-v2-sweep": "capture v1's sweep on tasks where the default planner going straight in fails at dt and "
                        "dt/4, so the method must choose when to go, and whose timed certificate also captures with "
                        "the body's spin and drift estimated wrong in every direction",
    "capture-v2-nutation": "capture v1's nutation on tasks where going straight in fails at dt and dt/4, certified "
                           "like capture v2's sweep",
}
#: The README's GIF and the tier pages' GIFs: the reference planner on a test task (index), one frame per 8 decisions.
README_GIF = ("debris", 1)
GIF_EVERY = 8


def id_page(env_id: str) -> str:
    """The page of one registered id, from the environment itself and its version's spec."""
    spec = next(s for s in all_specs().values() if env_id in s.env_ids)
    with warnings.catch_warnings():  # a frozen version's "out of date" notice
        warnings.simplefilter("ignore", DeprecationWarning)
        # a version whose pools are being built plays its family's scenario (a custom task) until then
        env = gymnasium.make(env_id, **({"task": load_scenario(spec.rules.tasks.family)}
                                        if spec.status == "building" else {}))
    try:
        action, observation = env.action_space, env.observation_space
        limit = env.spec.max_episode_steps if env.spec else None
    finally:
        env.close()
    note = {"frozen": " (frozen)", "building": " (its pools are being built)"}.get(spec.status, "")
    lines = [f"# `{env_id}`", "", f"Benchmark {spec.version}{note}: {spec.description}.", "",
             "| | |", "|---|---|",
             f"| action space | `{_space(action)}` |",
             f"| observation space | `{_space(observation)}` |",
             f"| reward | {_reward_text(spec)} |",
             f"| episode end | {_episode_end(spec, limit)} |",
             f"| score | {spec.score.text} |",
             f"| arguments of `gymnasium.make` | {', '.join(f'`{k}`' for k in sorted(spec.env_options()))} |",
             f"| tasks | {_tasks_text(spec)} |",
             f"| batched | `gymnasium.make_vec(\"{env_id}\", num_envs=N, vectorization_mode=\"vector_entry_point\")` |",
             "", "```python", "import gymnasium as gym, ffsr_gym",
             f"env = gym.make(\"{env_id}\"{_example_kwargs(spec)})",
             "obs, info = env.reset(seed=0)",
             "obs, reward, terminated, truncated, info = env.step(env.action_space.sample())",
             "```", "", "## Info keys", "", "Every step's `info` has these keys, with these dtypes (the batched env "
             "gives each as an array with its `_key` mask):", "", markdown_table(score_rule(spec)), "",
             "The meaning of each observation component, the reward and the evaluation protocol: "
             "[Environments](../envs.md)."]
    return "\n".join(lines) + "\n"


def _space(space: Any) -> str:
    """A Box as its shape, dtype and bounds, runs of equal bounds written once ("[-1, 1] x 24, [0, 1] x 1")."""
    if not isinstance(space, gymnasium.spaces.Box):
        return str(space)
    bounds = list(zip(space.low.ravel().tolist(), space.high.ravel().tolist()))
    runs: list[list[Any]] = []
    for pair in bounds:
        if runs and runs[-1][0] == pair:
            runs[-1][1] += 1
        else:
            runs.append([pair, 1])
    text = ", ".join(f"[{lo:g}, {hi:g}]" + (f" x {n}" if len(runs) > 1 else "") for (lo, hi), n in runs)
    return f"Box{tuple(space.shape)}, {space.dtype}, {text}"


def _episode_end(spec: BenchmarkSpec, limit: int | None) -> str:
    text = f"truncated after {limit} decisions of 0.1 s" if limit else "-"
    if "terminate_on_violation" in spec.env_options():
        text += ("; terminated at the first violation (a rate above the limit, a clearance below the keep-out "
                 "distance, self contact) unless `terminate_on_violation=False`")
    elif spec.score.rule == "paper_objective":  # the paper's objective: an infeasible episode ends at once
        text += "; terminated at a rate-limit violation or a collision"
    if spec.score.rule == "capture_quality":
        text += "; terminated at the capture (the sample that completes the hold window)"
    return text


def _reward_text(spec: BenchmarkSpec) -> str:
    if spec.score.rule == "capture_quality":
        q = spec.rules.quality
        return (f"the change of the episode's value {q.time_weight:g} (1 - t / T) + {q.contact_weight:g} + "
                f"{q.smoothness_weight:g} / (1 + C_t) (its score were it captured now, at rest); an episode's "
                "rewards sum to its score minus 1")
    if spec.reward.kind == "score_change":
        return "the change of the episode's value 1 / (1 + C_t); an episode's rewards sum to its score minus 1"
    return spec.reward.kind.replace("_", " ")


def _tasks_text(spec: BenchmarkSpec) -> str:
    if spec.tasks.kind == "tiers" and spec.status == "building":
        return (f"tiers {', '.join(f'`{t}`' for t in spec.tasks.tiers)} (their pools are being built; until then a "
                f"scenario, `{spec.tasks.keyword}=`: a shipped name or a TOML path)")
    if spec.tasks.kind == "tiers":
        tiers = ", ".join(f"[`{t}`](../tiers/{tier_key(spec, t)}.md)" for t in spec.tasks.tiers)
        return f"tiers {tiers}; splits {', '.join(f'`{s}`' for s in spec.tasks.splits)}"
    return _scenario_text(spec)


def _scenario_text(spec: BenchmarkSpec) -> str:
    return f"a scenario (`{spec.tasks.keyword}=`: a shipped name or a TOML path; default `{spec.tasks.default}`)"


def _example_kwargs(spec: BenchmarkSpec) -> str:
    if spec.status == "building":
        return f", {spec.tasks.keyword}=\"{spec.rules.tasks.family}\""
    return f", {spec.tasks.keyword}=\"{spec.tasks.default}\", split=\"train\"" if spec.tasks.kind == "tiers" else ""


def ranked_specs() -> list[BenchmarkSpec]:
    """The live versions with tiers and a ranked leaderboard (each tier has a page), the summary's first."""
    live = [s for s in all_specs().values()
            if s.status == "live" and s.tasks.kind == "tiers" and s.leaderboard.ranking == "ci_separation"]
    return sorted(live, key=lambda s: s.version != ranked_spec().version)


def tier_keys() -> dict[str, tuple[BenchmarkSpec, str]]:
    """Every tier page's key (its page ``tiers/<key>.md`` and GIF ``_static/tiers/<key>.gif``) with its version and
    tier: the tier's name for the first live ranked version that has it (:func:`ranked_specs`' order), and
    ``<version>-<tier>`` for a later one (capture v2's ``sweep`` is ``capture-v2-sweep``: capture v1 has one too)."""
    keys: dict[str, tuple[BenchmarkSpec, str]] = {}
    for spec in ranked_specs():
        for tier in spec.tasks.tiers:
            keys[tier if tier not in keys else f"{spec.version}-{tier}"] = (spec, tier)
    return keys


def tier_key(spec: BenchmarkSpec, tier: str) -> str:
    """The page key of ``spec``'s ``tier`` (:func:`tier_keys`)."""
    return next(key for key, (s, t) in tier_keys().items() if s.version == spec.version and t == tier)


def tier_page(key: str, ranked: list[tuple[str, dict[str, Any]]]) -> str:
    """The page of one tier of a live ranked version (``key``: :func:`tier_keys`): its rule, its pools and its GIF.

    ``ranked``: the tier's verified entries as (rank label, entry), in table order (the GIF's caption reads the
    default planner's row on its task).
    """
    spec, tier = tier_keys()[key]
    data = load_pools(None, (tier,), spec.version)
    index = gif_task(key)
    default = spec.rules.planner
    timed = spec.actions.command  # capture v1: a fixed policy is (m, T_c, go_s); the GIF plays the certificate
    setting = f"({default.m!r}, {default.T_c_s!r}{', 0.0' if timed else ''})"
    parameters, residual = spec.ids.parameters, spec.ids.residual
    capture = spec.rules.capture is not None  # the tumbling body is an obstacle too; the capture's margin
    policy = gif_policy(key)
    shown = (f"The task's timed certificate ({policy.replace(',', ', ')}: m, T_c [s], go_s [s]) on test task "
             f"{index}: captures, score {data['splits']['test']['pools'][tier][index]['certificate_score']:.3f}"
             if timed else f"The reference planner ({default.m:g}, {default.T_c_s:g} s) on test task {index}: "
             f"{_outcome(ranked, index, spec.version)}")
    lines = [f"# Tier `{tier}`" + ("" if key == tier else f" ({spec.version})"), "",
             f"Benchmark {spec.version}: {TIER_MEANING[key]}.", "",
             f"![{'The timed certificate' if timed else 'The reference planner'} on test task {index} of {tier}]"
             f"(../_static/tiers/{key}.gif)", "",
             f"{shown} (`ffsr-gym render --env-id {parameters}{'' if policy == 'reference' else ' --policy ' + policy} "
             f"--task {tier} --split test --task-index {index} --every {GIF_EVERY}`).", "",
             "```python", "import gymnasium as gym, ffsr_gym",
             f"env = gym.make(\"{residual}\", task=\"{tier}\", split=\"train\")   # or {parameters}",
             f"report = ffsr_gym.evaluate({setting}, \"{parameters}\", task=\"{tier}\")   # its test pool"
             + (": straight in" if timed else ""),
             "```", "", "## Pools", "",
             f"| split | seeds | tasks | certificates: {'timed' if timed else 'constant / residual'} | "
             + ("worst clearance, obstacles and body [mm] | largest peak rate [deg/s] | largest capture ratio |"
                if capture else "worst obstacle clearance [mm] | largest peak rate [deg/s] |"),
             "|---" * (7 if capture else 6) + "|"]
    for split, s in data["splits"].items():
        entries = s["pools"][tier]
        kinds = [e["certificate"]["kind"] for e in entries]
        margins = s["pool_margins"][tier]
        first, stop = data["seed_ranges"][split]
        counts = (f"{kinds.count('timed')}" if timed else f"{kinds.count('constant')} / {kinds.count('residual')}")
        lines.append(f"| {split} | [{first:,}, {stop:,}) | {len(entries)} | {counts} | "
                     f"{1000 * margins['min_clearance_m']:.1f} | "
                     f"{margins['peak_rate_deg_s']:.1f} |" + (f" {margins['capture_ratio']:.2f} |" if capture else ""))
    ensemble = spec.rules.tasks.ensemble
    moved = "spin and drift" if ensemble is not None and ensemble.drift_offset_m_s else "spin"
    section, spin = (("Capture of a sweeping handle" if timed else "Capture of a tumbling target",
                      f", with the body's {moved} perturbed") if capture else ("Task tiers", ""))
    action = "a timed action (m, T_c, go_s)" if timed else "an action"
    lines += ["", f"Every task stores a certificate: {action} that succeeds at dt, dt/2 and dt/4, from perturbed "
              f"starts{spin} and on the second backend, with margins (the rule, and the counts of rejected candidates: "
              f"[Environments, {section}](../envs.md)).", "",
              f"Its ranked table, with every entry's scores, compute and verification, and how to submit: "
              f"[Leaderboards](../leaderboards.md) (\"{tier} (test pool)\")."]
    return "\n".join(lines) + "\n"


def gif_policy(key: str) -> str:
    """The ``--policy`` of the GIF of tier page ``key``: ``reference``, or on capture v1 and v2 the GIF task's timed
    certificate (``m,T_c,go_s``: going straight in fails most of their tasks)."""
    spec, tier = tier_keys()[key]
    if not spec.actions.command:
        return "reference"
    tasks = load_pools(None, (tier,), spec.version)["splits"]["test"]["pools"][tier]
    certificate = tasks[gif_task(key)]["certificate"]
    return f"{certificate['m']!r},{certificate['T_c_s']!r},{certificate['go_s']!r}"


def gif_task(key: str) -> int:
    """The test task the GIF of tier page ``key`` shows (the README's on its tier, else the first)."""
    return README_GIF[1] if key == README_GIF[0] else 0


def _outcome(ranked: list[tuple[str, dict[str, Any]]], index: int, version: str) -> str:
    """What the default planner's entry recorded on test task ``index``: its score, or how it failed."""
    row = next((r for _, e in ranked if e["name"] == f"reference_{version}_default" for r in e["episodes"]
                if r["task_index"] == index), None)
    if row is None:
        return "not in the leaderboard"
    return f"succeeds, score {row['score']:.3f}" if row["success"] else f"fails ({row['failure'].replace('_', ' ')})"


def ids_table() -> str:
    """The README's table of registered ids: their actions, tasks and whether their version is ranked, frozen or
    having its pools built."""
    lines = ["| id | action | tasks | status |", "|---|---|---|---|"]
    for spec in sorted(all_specs().values(), key=lambda s: (s.status != "live", s.version != ranked_spec().version)):
        status = {"live": "ranked", "building": "pools being built"}.get(spec.status, "frozen")
        for env_id in spec.env_ids:
            action = ("12 residual joint rates added to the reference planner" if spec.is_residual(env_id)
                      else "the planner's (m, T_c)")
            if spec.actions.command:
                action += ", and the approach's command"
            tasks = (", ".join(f"`{t}`" for t in spec.tasks.tiers) if spec.tasks.kind == "tiers"
                     else _scenario_text(spec))
            lines.append(f"| [`{env_id}`](docs/ids/{env_id}.md) | {action} | {tasks} | {status} |")
    return "\n".join(lines) + "\n"


def page_paths(docs: str | Path) -> dict[Path, str]:
    """Every generated page (path under ``docs``) by what writes it: an id, or a tier page's key (:func:`tier_keys`)."""
    docs = Path(docs)
    pages = {docs / "ids" / f"{env_id}.md": env_id for spec in all_specs().values() for env_id in spec.env_ids}
    pages.update({docs / "tiers" / f"{key}.md": key for key in tier_keys()})
    return pages
