"""``ffsr-gym ga``: the paper's GA study end to end (runs, figures, table, leaderboard entries)."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

from ffsr_gym.bench.evaluation import evaluate
from ffsr_gym.cluster import study_executor
from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.model.scenario import load_scenario
from ffsr_gym.optim import ga
from ffsr_gym.provenance import provenance, write_json_atomic, write_text_atomic
from ffsr_gym.report import plotting
from ffsr_gym.sim.simulate import simulate

#: Where the fitness evaluations run: local processes, a local Dask cluster, or this process.
EXECUTORS = ("process", "dask", "none")
MODES = {"reproduction": 2.19, "full": None}  # T_c fixed at the paper's value, or optimised
BASELINE = (0.1, 2.19)  # the paper's non-optimised setting
PAPER = {"m": 0.2167, "T_c_s": 2.19, "mission_peak_deg_s": (94.12, 198.40), "balance_j4_deg_s": (-110.70, -241.40),
         "balance_j5_deg_s": (-124.00, -231.90), "final_error_m": 2.816e-7, "convergence_s": 1.751}


def run_study(out: str | Path, *, modes: tuple[str, ...] = ("reproduction", "full"), config: ga.GAConfig | None = None,
              executor: str = "process", workers: int | None = None, leaderboard: str | Path | None = None,
              progress: bool = True, scheduler: str | None = None) -> dict[str, Any]:
    """Run the GA in each mode (resuming from ``out/<mode>/checkpoint.json``), then write the report. The fitness
    evaluations run on ``executor`` (one of :data:`EXECUTORS`) with ``workers`` (default: every core), or on the
    Dask cluster ``scheduler`` names (:func:`ffsr_gym.cluster.study_executor`; it overrides ``executor``).

    Returns:
        ``{mode: summary}`` with the optimum, its metrics, the baseline's and the paper's numbers.
    """
    out = Path(out)
    base = config or ga.GAConfig()
    results = {}
    if executor not in EXECUTORS:
        raise InvalidInputError(f"executor {executor!r}; allowed: {list(EXECUTORS)}")
    workers = workers or os.cpu_count() or 1
    if scheduler is None and executor == "dask":  # a local cluster of that many workers
        scheduler = f"local:{workers}"
    with study_executor(scheduler, workers if executor == "process" else 1) as (pool, _):
        for mode in modes:
            cfg = ga.GAConfig(**{**base.__dict__, "T_c_fixed": MODES[mode]})
            state = ga.run(cfg, executor=pool, checkpoint=out / mode / "checkpoint.json", progress=progress)
            results[mode] = _report(out / mode, state, mode, leaderboard)
    write_json_atomic(out / "ga_study.json", results)
    return results


def _report(folder: Path, state: ga.GAState, mode: str, leaderboard: str | Path | None) -> dict[str, Any]:
    m, T_c, score = ga.best(state)
    scenario = load_scenario(state.config.scenario)
    optimum = simulate(scenario, m=m, T_c=T_c)
    baseline = simulate(scenario, m=BASELINE[0], T_c=BASELINE[1])
    prov = provenance(scenarios={scenario.name: scenario.sha256()}, seeds=[state.config.seed], wall_time_s=state.wall_time_s)
    footer = f"GA {mode}, seed {state.config.seed}, commit {(prov['git_commit'] or 'no-git')[:10]}, scenario sha256 {prov['scenario_sha256'][scenario.name][:10]}"
    plotting.plot_ga_history(state.history, folder / "fig7_ga_generations.png", footer, f"GA ({mode} mode)")
    runs = {f"non-optimised m = {BASELINE[0]}, T_c = {BASELINE[1]} s": baseline, f"GA m = {m:.4f}, T_c = {T_c:.3f} s": optimum}
    plotting.plot_joint_rates(runs, 0, folder / "fig8_mission_joint_rates.png", footer)
    plotting.plot_joint_rates(runs, 1, folder / "fig9_balance_joint_rates.png", footer)
    plotting.plot_series({f"m = {m:.4f}, T_c = {T_c:.3f} s": optimum}, "ee_position_error_m",
                         "EE position error ||p_e - p_d|| [m]", "End-effector position error, GA optimum",
                         folder / "fig10_ee_position_error.png", footer)
    summary = {"mode": mode, "optimum": {"m": m, "T_c_s": T_c, "score": None if math.isinf(score) else score},
               "optimum_metrics": optimum.metrics(), "baseline": {"m": BASELINE[0], "T_c_s": BASELINE[1]},
               "baseline_metrics": baseline.metrics(),
               "baseline_score": _json_score(_score(scenario, baseline)), "paper": PAPER,
               "config": state.config.__dict__, "evaluations": len(state.cache), "wall_time_s": state.wall_time_s,
               "provenance": prov}
    write_text_atomic(folder / "ga_table.md", render_table(summary))
    write_json_atomic(folder / "summary.json", summary)
    if leaderboard is not None:
        report = evaluate((m, T_c), "FFSR-v0", name=f"ga_{mode}")
        report.extra = {"method": f"paper GA, {mode} mode", "ga_config": state.config.__dict__, "ga_wall_time_s": state.wall_time_s,
                        "ga_evaluations": len(state.cache), "parameters": {"m": m, "T_c_s": T_c}}
        report.save(Path(leaderboard) / "FFSR-v0", overwrite=True)
    return summary


def _score(scenario, traj) -> float:
    from ffsr_gym.scoring.objective import objective_terms

    return objective_terms(traj, scenario.objective).score


def _json_score(x: float) -> float | None:
    return None if math.isinf(x) else x


def render_table(summary: dict[str, Any]) -> str:
    """Peak rates per joint and arm, final error and convergence, next to the paper's numbers."""
    opt, base, paper = summary["optimum_metrics"], summary["baseline_metrics"], summary["paper"]
    o, b = summary["optimum"], summary["baseline"]
    lines = [f"# GA ({summary['mode']} mode): m = {o['m']:.4f}, T_c = {o['T_c_s']:.3f} s vs non-optimised m = {b['m']}, T_c = {b['T_c_s']} s",
             "", f"Objective B: GA {o['score']} vs non-optimised {summary['baseline_score']} (None = infeasible, +inf). "
             f"{summary['evaluations']} evaluations, {summary['wall_time_s']:.0f} s wall time. Scenario paper, dt = 0.01 s.",
             "", "| joint | GA mission [deg/s] | non-opt. mission | GA balance | non-opt. balance |", "|---|---|---|---|---|"]
    for j in range(6):
        lines.append(f"| {j + 1} | {opt['signed_peak_joint_rate_deg_s']['mission'][j]:.2f} | {base['signed_peak_joint_rate_deg_s']['mission'][j]:.2f} | "
                     f"{opt['signed_peak_joint_rate_deg_s']['balance'][j]:.2f} | {base['signed_peak_joint_rate_deg_s']['balance'][j]:.2f} |")
    lines += ["", "| quantity | ours GA | ours non-opt. | paper GA | paper non-opt. |", "|---|---|---|---|---|",
              f"| mission-arm peak [deg/s] | {opt['max_joint_rate_deg_s']['mission']:.2f} | {base['max_joint_rate_deg_s']['mission']:.2f} | "
              f"{paper['mission_peak_deg_s'][0]} | {paper['mission_peak_deg_s'][1]} |",
              f"| balance-arm peak [deg/s] | {opt['max_joint_rate_deg_s']['balance']:.2f} | {base['max_joint_rate_deg_s']['balance']:.2f} | "
              f"{abs(paper['balance_j5_deg_s'][0])} (joint 5) | {abs(paper['balance_j4_deg_s'][1])} (joint 4) |",
              f"| final EE error [m] | {opt['final_ee_position_error_m']:.3g} | {base['final_ee_position_error_m']:.3g} | {paper['final_error_m']} | – |",
              f"| convergence after avoidance [s] | {opt['convergence_after_release_s']} | {base['convergence_after_release_s']} | {paper['convergence_s']} | – |",
              "", f"Provenance: `{json.dumps({k: summary['provenance'][k] for k in ('git_commit', 'git_dirty', 'versions', 'command')})}`", ""]
    return "\n".join(lines)
