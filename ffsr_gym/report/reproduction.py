"""One-command reproduction of the paper's Section 5: runs, figures, JSON and a claims table."""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from tqdm.auto import tqdm

from ffsr_gym.model.scenario import Scenario, load_scenario
from ffsr_gym.planning.planner import METHODS
from ffsr_gym.provenance import provenance, splice_generated, write_json_atomic, write_text_atomic
from ffsr_gym.report import plotting
from ffsr_gym.scoring.objective import objective_terms
from ffsr_gym.sim.setup import prepare
from ffsr_gym.sim.simulate import simulate
from ffsr_gym.sim.trajectory import Trajectory

# (label, scenario, method, m, T_c [s]) — the paper's settings (docs/model.md §9).
COMPARISON = {method: ("paper", method, 0.1, 3.0) for method in METHODS}
PARAMETER_STUDY = {
    "predefined_time m=0.1 T_c=2.19": ("paper", "predefined_time", 0.1, 2.19),
    "predefined_time m=0.2167 T_c=2.19": ("paper", "predefined_time", 0.2167, 2.19),
}
AS_PRINTED = {"paper_as_printed predefined_time m=0.1 T_c=3": ("paper_as_printed", "predefined_time", 0.1, 3.0)}
#: Beyond the paper: the proportional planner φ(e) = K e at these gains K [1/s] on ``paper``.
GAIN_SWEEP_PER_S = (0.5, 1.0, 2.0, 3.0, 4.0, 5.0)
RATE_LIMIT_DEG_S = 200.0


@dataclass(frozen=True)
class Claim:
    """One headline statement of the paper next to our number."""

    claim: str
    paper: str
    ours: str
    holds: bool


def _fmt(x: float | None, unit: str = "") -> str:
    return "never" if x is None else f"{x:.3g}{unit}"


def _claims(c: dict[str, dict], p: dict[str, dict], printed: dict[str, Any]) -> list[Claim]:
    pt, prop, nf, na = c["predefined_time"], c["proportional"], c["no_feedback"], c["no_avoidance"]
    slow, fast = p["predefined_time m=0.1 T_c=2.19"], p["predefined_time m=0.2167 T_c=2.19"]
    cdf_min = min(c[m]["min_clearance_m"] for m in ("no_feedback", "proportional", "predefined_time"))
    b_slow, b_fast = slow["signed_peak_joint_rate_deg_s"]["balance"], fast["signed_peak_joint_rate_deg_s"]["balance"]
    return [
        Claim("Without avoidance the mission arm hits the obstacle (Fig. 4)", "collides",
              f"min clearance {_fmt(na['min_clearance_m'], ' m')}", na["collided"]),
        Claim("Every CDF method keeps the arm off the obstacle (Fig. 4)", "no contact",
              f"min clearance {_fmt(cdf_min, ' m')}", cdf_min > 0),
        Claim("Proportional feedback leaves a residual EE position error (Fig. 5)", "0.033 m",
              _fmt(prop["final_ee_position_error_m"], " m"),
              prop["final_ee_position_error_m"] > max(1e-6, 1e3 * pt["final_ee_position_error_m"])),
        Claim("Predefined-time feedback: final EE position error (Fig. 5)", "8.922e-12 m",
              _fmt(pt["final_ee_position_error_m"], " m"), pt["final_ee_position_error_m"] <= 1e-9),
        Claim("Predefined-time: EE error converges within T_c = 3 s after the avoidance (Fig. 5)", "1.198 s",
              f"{_fmt(pt['convergence_after_release_s'], ' s')} after release at {_fmt(pt['avoidance_release_time_s'], ' s')}",
              pt["convergence_after_release_s"] is not None and pt["convergence_after_release_s"] <= 3.0),
        Claim("EE attitude error converges to zero (Fig. 6)", "micron-scale",
              _fmt(pt["final_ee_attitude_error"]), pt["final_ee_attitude_error"] <= 1e-6),
        Claim("Base position error stays at micron scale (Fig. 6)", "micron-scale",
              f"max {_fmt(pt['max_base_position_error_m'], ' m')}, final {_fmt(pt['final_base_position_error_m'], ' m')}",
              pt["max_base_position_error_m"] < 1e-4 and pt["final_base_position_error_m"] <= 1e-6),
        Claim("Without pose feedback the avoidance error is not removed (Fig. 5)", "(implied)",
              _fmt(nf["final_ee_position_error_m"], " m"), nf["final_ee_position_error_m"] > 1e-3),
        Claim("m = 0.1, T_c = 2.19 s exceeds the 200 deg/s joint-rate limit", "241.4 deg/s (balance arm)",
              f"{_fmt(slow['max_joint_rate_deg_s']['balance'], ' deg/s')} (balance arm)",
              slow["max_joint_rate_deg_s"]["balance"] > RATE_LIMIT_DEG_S),
        Claim("GA optimum m = 0.2167 lowers the mission-arm peak rate (Fig. 8)", "94.12 vs 198.40 deg/s",
              f"{_fmt(fast['max_joint_rate_deg_s']['mission'])} vs {_fmt(slow['max_joint_rate_deg_s']['mission'])} deg/s",
              fast["max_joint_rate_deg_s"]["mission"] < slow["max_joint_rate_deg_s"]["mission"]),
        Claim("GA optimum lowers the balance-arm peaks of joints 4 and 5 (Fig. 9)",
              "-110.7/-124.0 vs -241.4/-231.9 deg/s",
              f"{b_fast[3]:.4g}/{b_fast[4]:.4g} vs {b_slow[3]:.4g}/{b_slow[4]:.4g} deg/s",
              abs(b_fast[3]) < abs(b_slow[3]) and abs(b_fast[4]) < abs(b_slow[4])),
        Claim("GA optimum: final EE position error (Fig. 10)", "2.816e-7 m",
              _fmt(fast["final_ee_position_error_m"], " m"), fast["final_ee_position_error_m"] <= 1e-6),
        Claim("GA optimum: converges within T_c = 2.19 s (Fig. 10)", "1.751 s",
              f"{_fmt(fast['convergence_after_release_s'], ' s')} after release",
              fast["convergence_after_release_s"] is not None and fast["convergence_after_release_s"] <= 2.19),
        Claim("The printed obstacle point calls for avoidance (scenario paper_as_printed)", "avoidance acts",
              f"max CDF {printed['max_cdf']:.3g} < Delta = {printed['delta']}; min clearance "
              f"{_fmt(printed['min_clearance_m'], ' m')} (the point lies inside the base cube)", printed["max_cdf"] > printed["delta"]),
    ]


def _run_all(runs: dict[str, tuple], scenarios: dict[str, Scenario], bar: tqdm) -> dict[str, Trajectory]:
    out = {}
    for label, (name, method, m, T_c) in runs.items():
        bar.set_postfix_str(label)
        out[label] = simulate(scenarios[name], method=method, m=m, T_c=T_c)
        bar.update(1)
    return out


def reproduce(out_dir: str | Path, *, duration_s: float | None = None, progress: bool = True,
              command: str | None = None) -> dict[str, Any]:
    """Run the paper's scenarios with all four methods and write figures, JSON and Markdown.

    Args:
        out_dir: output folder (created).
        duration_s: shorten every run to this duration [s] (default: the scenarios' 20 s).
        progress: show a progress bar.
        command: command line recorded in the provenance.

    Returns:
        The content of ``reproduction.json``.
    """
    start = time.perf_counter()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    scenarios = {name: load_scenario(name) for name in ("paper", "paper_as_printed")}
    if duration_s is not None:
        scenarios = {k: s.replace(simulation=dataclasses.replace(s.simulation, duration_s=duration_s))
                     for k, s in scenarios.items()}
    total = len(COMPARISON) + len(PARAMETER_STUDY) + len(AS_PRINTED) + len(GAIN_SWEEP_PER_S)
    with tqdm(total=total, disable=not progress, desc="reproduce", unit="run") as bar:
        comparison = _run_all(COMPARISON, scenarios, bar)
        study = _run_all(PARAMETER_STUDY, scenarios, bar)
        printed_traj = next(iter(_run_all(AS_PRINTED, scenarios, bar).values()))
        sweep = _gain_sweep(scenarios["paper"], bar)
    printed = {"max_cdf": float(printed_traj.cdf[:, 0].max()), "delta": scenarios["paper_as_printed"].planner.cdf_delta,
               "min_clearance_m": printed_traj.metrics()["min_clearance_m"]}
    c_metrics = {k: t.metrics() for k, t in comparison.items()}
    p_metrics = {k: t.metrics() for k, t in study.items()}
    claims = _claims(c_metrics, p_metrics, printed)
    prov = provenance(scenarios={k: s.sha256() for k, s in scenarios.items()}, command=command,
                      wall_time_s=time.perf_counter() - start)
    result = {
        "settings": {"dt_s": scenarios["paper"].simulation.dt_s, "duration_s": scenarios["paper"].simulation.duration_s,
                     "comparison": {"m": 0.1, "T_c_s": 3.0},
                     "ee_position_tolerance_m": scenarios["paper"].objective.ee_position_tolerance_m},
        "methods": c_metrics,
        "parameter_study": p_metrics,
        "paper_as_printed": printed_traj.metrics() | {"max_cdf_mission": printed["max_cdf"]},
        "claims": [dataclasses.asdict(claim) for claim in claims],
        "gain_sweep": sweep,
        "provenance": prov,
    }
    _write_figures(out, scenarios["paper"], comparison, study, _footer(prov))
    plotting.plot_gain_sweep(sweep, {"predefined time, m = 0.1, T_c = 3 s": c_metrics["predefined_time"],
                                     "predefined time, m = 0.2167, T_c = 2.19 s": p_metrics["predefined_time m=0.2167 T_c=2.19"]},
                             scenarios["paper"].objective.ee_position_tolerance_m, RATE_LIMIT_DEG_S,
                             out / "fig11_proportional_gain_sweep.png", _footer(prov))
    write_json_atomic(out / "reproduction.json", result)
    write_text_atomic(out / "reproduction.md", render_markdown(result))
    return result


def _gain_sweep(scenario: Scenario, bar: tqdm) -> list[dict[str, Any]]:
    """The proportional planner at each gain of :data:`GAIN_SWEEP_PER_S`: errors, peak rates, feasibility (the paper's)."""
    rows = []
    for gain in GAIN_SWEEP_PER_S:
        bar.set_postfix_str(f"proportional K={gain:g}/s")
        played = scenario.replace(planner=dataclasses.replace(scenario.planner, proportional_gain_per_s=gain))
        traj = simulate(played, method="proportional")
        metrics, terms = traj.metrics(), objective_terms(traj, played.objective)
        rows.append({"gain_per_s": gain, "final_ee_position_error_m": metrics["final_ee_position_error_m"],
                     "final_ee_attitude_error": metrics["final_ee_attitude_error"],
                     "convergence_after_release_s": metrics["convergence_after_release_s"],
                     "max_joint_rate_deg_s": metrics["max_joint_rate_deg_s"], "min_clearance_m": metrics["min_clearance_m"],
                     "collided": metrics["collided"], "final_errors_ok": terms.final_errors_ok, "feasible": terms.feasible,
                     "paper_B": None if math.isinf(terms.objective) else terms.objective})
        bar.update(1)
    return rows


def _footer(prov: dict[str, Any]) -> str:
    commit = prov["git_commit"][:10] + ("+dirty" if prov["git_dirty"] else "") if prov["git_commit"] else "none (not a git checkout)"
    sha = prov["scenario_sha256"].get("paper", "")[:10]
    return f"ffsr-gym {prov['versions'].get('ffsr-gym', '?')} | commit {commit} | scenario paper sha256 {sha} | {prov['command']}"


def _release_marks(traj: Trajectory, T_c: float) -> dict[str, float]:
    """The avoidance release time t_r [s] and the predefined-time bound t_r + T_c, for Fig. 5."""
    release = traj.avoidance_release_time()
    return {} if release is None else {f"avoidance released, t_r = {release:.2f} s": release,
                                       f"t_r + T_c = {release + T_c:.2f} s (T_c = {T_c:g} s)": release + T_c}


def _write_figures(out: Path, scenario: Scenario, comparison: dict, study: dict, footer: str) -> None:
    path = prepare(scenario).path
    duration = scenario.simulation.duration_s
    danger = scenario.obstacle.danger_radius_m
    jobs: list[Callable[[], Path]] = [
        lambda: plotting.plot_desired_path(path, duration, out / "fig3_desired_trajectory.png", footer),
        lambda: plotting.plot_series(comparison, "clearance_m", "clearance robot-obstacle [m]",
                                     "Closest distance between obstacle and robot (m = 0.1, T_c = 3 s)",
                                     out / "fig4_clearance.png", footer, log=False,
                                     hlines={"contact": 0.0, f"danger radius {danger} m": danger}),
        lambda: plotting.plot_series(comparison, "ee_position_error_m", "EE position error ||p_e - p_d|| [m]",
                                     "End-effector position error (m = 0.1, T_c = 3 s)", out / "fig5_ee_position_error.png", footer,
                                     vlines=_release_marks(comparison["predefined_time"], scenario.planner.T_c_s)),
        lambda: plotting.plot_pose_errors(comparison["predefined_time"], out / "fig6_pose_errors.png", footer),
        lambda: plotting.plot_joint_rates(study, 0, out / "fig8_mission_joint_rates.png", footer),
        lambda: plotting.plot_joint_rates(study, 1, out / "fig9_balance_joint_rates.png", footer),
        lambda: plotting.plot_series({"m = 0.2167, T_c = 2.19 s": study["predefined_time m=0.2167 T_c=2.19"]},
                                     "ee_position_error_m", "EE position error ||p_e - p_d|| [m]",
                                     "End-effector position error with the paper's GA optimum",
                                     out / "fig10_ee_position_error_ga.png", footer),
    ]
    for job in jobs:
        job()


def readme_markers(block: str) -> tuple[str, str]:
    """The markers around a generated block of docs/reproduction.md (``reproduction``: the claims; ``gain-sweep``)."""
    return (f"<!-- {block}:start (generated by `ffsr-gym reproduce --readme docs/reproduction.md`) -->",
            f"<!-- {block}:end -->")


def claims_table(result: dict[str, Any]) -> list[str]:
    """The claims table (Markdown lines): claim, the paper's value, ours, whether it holds."""
    return ["| claim | paper | ours | holds |", "|---|---|---|---|"] + [
        f"| {c['claim']} | {c['paper']} | {c['ours']} | {'yes' if c['holds'] else 'no'} |" for c in result["claims"]]


def gain_table(result: dict[str, Any]) -> list[str]:
    """The proportional gain sweep next to the predefined-time planner (Markdown lines)."""
    def row(name: str, m: dict[str, Any], feasible: bool) -> str:
        rates = m["max_joint_rate_deg_s"]
        return (f"| {name} | {_fmt(m['final_ee_position_error_m'])} | {_fmt(m['convergence_after_release_s'])} | "
                f"{rates['mission']:.1f} / {rates['balance']:.1f} | {_fmt(m['min_clearance_m'])} | {'yes' if feasible else 'no'} |")

    lines = ["| planner | final EE error [m] | converged after release [s] | peak rate mission / balance [deg/s] | "
             "min clearance [m] | feasible |", "|---|---|---|---|---|---|"]
    lines += [row(f"proportional, K = {r['gain_per_s']:g} 1/s", r, r["feasible"]) for r in result["gain_sweep"]]
    for name, m in (("predefined time, m = 0.1, T_c = 3 s", result["methods"]["predefined_time"]),
                    ("predefined time, m = 0.2167, T_c = 2.19 s", result["parameter_study"]["predefined_time m=0.2167 T_c=2.19"])):
        rates = m["max_joint_rate_deg_s"]
        within = m["final_ee_position_error_m"] <= result["settings"]["ee_position_tolerance_m"]
        lines.append(row(name, m, within and not m["collided"] and max(rates.values()) <= RATE_LIMIT_DEG_S))
    return lines


README_BLOCKS: dict[str, Callable[[dict[str, Any]], list[str]]] = {"reproduction": claims_table, "gain-sweep": gain_table}


def splice_readme(text: str, result: dict[str, Any]) -> str:
    """``text`` with every block of :data:`README_BLOCKS` regenerated from ``result`` between its markers.

    Raises:
        FFSRError: a block's markers are missing.
    """
    for block, table in README_BLOCKS.items():
        text = splice_generated(text, *readme_markers(block), "\n".join(table(result)) + "\n", where="the page")
    return text


def _gain_summary(result: dict[str, Any]) -> list[str]:
    """What the gain sweep shows, in words made from its numbers."""
    rows, tolerance = result["gain_sweep"], result["settings"]["ee_position_tolerance_m"]
    assumed = next((r for r in rows if r["gain_per_s"] == 1.0), rows[0])
    feasible = [r["gain_per_s"] for r in rows if r["feasible"]]
    verdict = (f"feasible at K = {', '.join(f'{k:g}' for k in feasible)} 1/s: the final error is within the "
               f"{tolerance:g} m tolerance, with no collision and every joint under {RATE_LIMIT_DEG_S:.0f} deg/s"
               if feasible else "feasible at none of these gains")
    ga_optimum = result["parameter_study"]["predefined_time m=0.2167 T_c=2.19"]
    fastest = [r for r in rows if r["feasible"] and r["convergence_after_release_s"] is not None]
    speed = "" if not fastest or ga_optimum["convergence_after_release_s"] is None else (
        f" Its fastest feasible gain here, K = {fastest[-1]['gain_per_s']:g} 1/s, converges "
        f"{_fmt(fastest[-1]['convergence_after_release_s'], ' s')} after the release, with a balance-arm peak of "
        f"{fastest[-1]['max_joint_rate_deg_s']['balance']:.1f} deg/s; the predefined-time planner at the paper's GA "
        f"optimum converges in {_fmt(ga_optimum['convergence_after_release_s'], ' s')}, with "
        f"{ga_optimum['max_joint_rate_deg_s']['balance']:.1f} deg/s.")
    return [
        f"At K = {assumed['gain_per_s']:g} 1/s (the gain we assume for the paper's comparison; it is not printed) "
        f"proportional feedback leaves a residual error of {_fmt(assumed['final_ee_position_error_m'], ' m')}, as the "
        f"paper reports (0.033 m there). With a tuned gain it is {verdict}. So the paper's claim that proportional "
        f"feedback cannot remove the error accumulated during the avoidance holds only for low gains.{speed}",
        "",
        "What predefined time still buys: its bound holds for any initial error. The error reaches zero within "
        "T_c of the avoidance's release, whatever its size then; proportional feedback decays like exp(-K t), so its "
        "time to a given tolerance grows with log(initial error / tolerance), and a gain tuned for one error is "
        "too slow (or too aggressive) for another.",
    ]


def render_markdown(result: dict[str, Any]) -> str:
    """The ``reproduction.md`` report: claims table, per-method metrics, provenance."""
    s = result["settings"]
    prov = result["provenance"]
    lines = [
        "# Reproduction of Yan & Liu, Section 5",
        "",
        f"Scenario `paper` (obstacle relocated onto the swept path, docs/model.md §9), dt = {s['dt_s']} s, "
        f"duration {s['duration_s']} s, comparison at m = 0.1, T_c = 3 s. The robot is our reconstruction "
        "(the paper's masses and geometry are unpublished), so absolute numbers differ; the claims are "
        "qualitative.",
        "",
        *claims_table(result),
    ]
    lines += ["", "## Metrics per method (m = 0.1, T_c = 3 s)", "",
              "| method | final EE error [m] | convergence after release [s] | max base error [m] | "
              "peak rate mission/balance [deg/s] | min clearance [m] | collided |", "|---|---|---|---|---|---|---|"]
    rows = list(result["methods"].items()) + list(result["parameter_study"].items())
    for name, m in rows:
        lines.append(
            f"| {name} | {m['final_ee_position_error_m']:.3g} | {_fmt(m['convergence_after_release_s'])} | "
            f"{m['max_base_position_error_m']:.3g} | {m['max_joint_rate_deg_s']['mission']:.1f} / "
            f"{m['max_joint_rate_deg_s']['balance']:.1f} | {_fmt(m['min_clearance_m'])} | {m['collided']} |"
        )
    lines += ["", "## Beyond the paper: proportional feedback, gain by gain", "",
              "The proportional planner (φ(e) = K e, same avoidance) on `paper` at each gain, next to the "
              "predefined-time planner (figure `fig11_proportional_gain_sweep.png`). Feasible: the paper's limits "
              f"({RATE_LIMIT_DEG_S:.0f} deg/s on every joint, no collision, final errors within the tolerances).", "",
              *gain_table(result), "", *_gain_summary(result)]
    lines += ["", "## Provenance", "", f"- commit: {prov['git_commit']} (dirty: {prov['git_dirty']}; from {prov.get('git_source')})",
              f"- command: `{prov['command']}`", f"- versions: {prov['versions']}", f"- platform: {prov['platform']}",
              f"- scenario sha256: {prov['scenario_sha256']}", f"- wall time: {prov['wall_time_s']:.1f} s",
              f"- created: {prov['created_utc']}", ""]
    return "\n".join(lines)
