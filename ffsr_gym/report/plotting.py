"""Figures of a reproduction run: analogues of the paper's Figs. 3-6 and 8-10.

Every figure has labelled axes with units; errors are drawn on log scales (values below 1e-17
are drawn at 1e-17). matplotlib is imported here only, with the Agg backend.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ffsr_gym.planning.desired_path import DesiredPath, trapezoid
from ffsr_gym.sim.trajectory import Trajectory

_FLOOR = 1e-17
_FLOOR_NOTE = "values below 1e-17, exact zeros included, are drawn at 1e-17"
#: Readable names of the planning methods in legends and titles.
METHOD_NAMES = {"predefined_time": "predefined-time (the paper's method)", "no_avoidance": "predefined-time, no avoidance",
                "no_feedback": "no pose feedback", "proportional": "proportional feedback"}
ARM_NAMES = ("mission arm (arm 1)", "balance arm (arm 2)")


def readable(label: str) -> str:
    """A legend label of the form ``<method>[ m=<m> T_c=<T_c>]`` in words, with units."""
    method, _, rest = label.partition(" ")
    if method not in METHOD_NAMES:
        return label
    name = METHOD_NAMES[method]
    if not rest:
        return name
    values = dict(part.split("=", 1) for part in rest.split() if "=" in part)
    return f"{name}, m = {values.get('m', '?')}, T_c = {values.get('T_c', '?')} s"


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig, path: Path, footer: str) -> Path:
    fig.text(0.01, 0.005, footer, fontsize=6, color="0.4", ha="left", va="bottom")
    fig.tight_layout(rect=(0, 0.03, 1, 1))
    fig.savefig(path, dpi=110)
    _pyplot().close(fig)
    return path


def plot_desired_path(path: DesiredPath, duration: float, out: Path, footer: str) -> Path:
    """Fig. 3: trapezoidal speed profile and desired end-effector position."""
    plt = _pyplot()
    t = np.linspace(0.0, duration, 1001)
    s_dot = np.array([trapezoid(x, path.motion_time, path.accel_time)[1] for x in t])
    positions = np.array([path.at(x)[0] for x in t])
    speed = s_dot * np.linalg.norm(path.target_position - path.start_position)
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 3.8))
    ax1.plot(t, speed * 1e3)
    ax1.set(xlabel="time t [s]", ylabel="desired EE speed [mm/s]", title="Trapezoidal velocity profile")
    for i, axis in enumerate("xyz"):
        ax2.plot(t, positions[:, i], label=f"p_d,{axis}")
    ax2.set(xlabel="time t [s]", ylabel="desired EE position [m]", title="Desired EE position")
    ax2.legend()
    return _save(fig, out, footer)


def plot_series(runs: dict[str, Trajectory], attribute: str, ylabel: str, title: str, out: Path, footer: str,
                *, log: bool = True, hlines: dict[str, float] | None = None, vlines: dict[str, float] | None = None) -> Path:
    """One time series per run (Figs. 4, 5, 10); ``vlines``: labelled instants [s] (release, release + T_c)."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(8, 4.2))
    for label, traj in runs.items():
        values = getattr(traj, attribute)
        ax.plot(traj.t, np.maximum(values, _FLOOR) if log else values, label=readable(label))
    for label, value in (hlines or {}).items():
        ax.axhline(value, color="0.3", ls="--", lw=0.8)
        ax.annotate(label, (0.0, value), fontsize=7, va="bottom")
    for label, value in (vlines or {}).items():
        ax.axvline(value, color="0.3", ls=":", lw=0.9)
        ax.annotate(label, (value, 0.02), xycoords=("data", "axes fraction"), fontsize=7, rotation=90, ha="right")
    if log:
        ax.set_yscale("log")
        ax.annotate(_FLOOR_NOTE, (0.99, 0.01), xycoords="axes fraction", fontsize=6, color="0.4", ha="right")
    ax.set(xlabel="time t [s]", ylabel=ylabel, title=title)
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(fontsize=8)
    return _save(fig, out, footer)


def plot_pose_errors(traj: Trajectory, out: Path, footer: str) -> Path:
    """Fig. 6: EE attitude error, base position and base attitude error (log scale)."""
    plt = _pyplot()
    panels = (("ee_attitude_error", "EE attitude error ||e_o|| [-]"),
              ("base_position_error_m", "base position error [m]"),
              ("base_attitude_error", "base attitude error ||e_o|| [-]"))
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.8))
    for ax, (attribute, label) in zip(axes, panels):
        ax.plot(traj.t, np.maximum(getattr(traj, attribute), _FLOOR))
        ax.set_yscale("log")
        ax.set(xlabel="time t [s]", ylabel=label)
        ax.grid(True, alpha=0.3)
        ax.annotate(_FLOOR_NOTE, (0.99, 0.01), xycoords="axes fraction", fontsize=5, color="0.4", ha="right")
    fig.suptitle(f"Pose errors, {METHOD_NAMES.get(traj.info.get('method'), traj.info.get('method'))} "
                 f"(m = {traj.info.get('m')}, T_c = {traj.info.get('T_c_s')} s)")
    return _save(fig, out, footer)


def plot_joint_rates(runs: dict[str, Trajectory], arm: int, out: Path, footer: str, *, limit_deg_s: float = 200.0) -> Path:
    """Figs. 8-9: joint rates [deg/s] of one arm for each run; a peak over the limit is marked with its time."""
    plt = _pyplot()
    fig, axes = plt.subplots(1, len(runs), figsize=(6 * len(runs), 3.8), sharey=True, squeeze=False)
    for ax, (label, traj) in zip(axes[0], runs.items()):
        rates = np.degrees(traj.dq_joints[:, 6 * arm:6 * arm + 6])
        for j in range(6):
            ax.plot(traj.t, rates[:, j], label=f"joint {j + 1}", lw=0.9)
        for sign in (1, -1):
            ax.axhline(sign * limit_deg_s, color="r", ls="--", lw=0.8)
        k, j = np.unravel_index(int(np.argmax(np.abs(rates))), rates.shape)
        if abs(rates[k, j]) > limit_deg_s:
            window = rates[max(0, k - 25):k + 25, j]
            flips = int(np.sum(np.diff(np.sign(window)) != 0))
            kind = f", {flips} sign flips within +-0.25 s (chatter)" if flips >= 10 else ""
            ax.annotate(f"peak {rates[k, j]:.0f} deg/s, joint {j + 1}, t = {traj.t[k]:.2f} s{kind}", (traj.t[k], rates[k, j]),
                        fontsize=7, color="r", xytext=(0.3, 0.04), textcoords="axes fraction",
                        arrowprops={"arrowstyle": "->", "color": "r", "lw": 0.6})
        ax.set(xlabel="time t [s]", ylabel="joint rate [deg/s]", title=readable(label))
        ax.grid(True, alpha=0.3)
    axes[0][0].legend(fontsize=7, ncol=2)
    fig.suptitle(f"Joint rates of the {ARM_NAMES[arm]}; dashed: the {limit_deg_s:.0f} deg/s limit")
    return _save(fig, out, footer)


def plot_ga_history(history: list[dict], out: Path, footer: str, title: str) -> Path:
    """Fig. 7: best and mean (feasible individuals) objective B per generation, feasible fraction."""
    plt = _pyplot()
    gen = [h["generation"] for h in history]
    best = [np.nan if h["best_score"] is None else h["best_score"] for h in history]
    mean = [np.nan if h["mean_finite_score"] is None else h["mean_finite_score"] for h in history]
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 3.8))
    ax1.plot(gen, best, label="best B")
    ax1.plot(gen, mean, label="mean B of feasible individuals")
    ax1.set(xlabel="generation", ylabel="objective B [-]", title=title)
    ax1.legend(fontsize=8)
    ax1.grid(True, alpha=0.3)
    ax2.plot(gen, [h["feasible_fraction"] for h in history])
    ax2.set(xlabel="generation", ylabel="feasible fraction [-]", ylim=(0, 1.05), title="Feasible individuals")
    ax2.grid(True, alpha=0.3)
    return _save(fig, out, footer)


def plot_gain_sweep(sweep: list[dict], references: dict[str, dict], tolerance_m: float, limit_deg_s: float, out: Path,
                    footer: str) -> Path:
    """Fig. 11 (beyond the paper): final EE error and peak rate per arm of proportional feedback against its gain K,
    with the predefined-time planner's values as horizontal lines."""
    plt = _pyplot()
    gains = [r["gain_per_s"] for r in sweep]
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.0))
    ax1.semilogy(gains, [max(r["final_ee_position_error_m"], _FLOOR) for r in sweep], "o-", label="proportional feedback")
    ax1.axhline(tolerance_m, color="r", ls="--", lw=0.8, label=f"tolerance {tolerance_m:g} m")
    for (name, m), style in zip(references.items(), (":", "-.")):
        ax1.axhline(max(m["final_ee_position_error_m"], _FLOOR), color="k", ls=style, lw=0.8, label=name)
    ax1.set(xlabel="proportional gain K [1/s]", ylabel="final EE position error [m]", title="Final end-effector error")
    ax1.legend(fontsize=7)
    ax1.grid(True, alpha=0.3, which="both")
    for arm, key, marker in ((0, "mission", "o"), (1, "balance", "s")):
        ax2.plot(gains, [r["max_joint_rate_deg_s"][key] for r in sweep], marker + "-", label=f"proportional, {ARM_NAMES[arm]}")
    for m, style in zip(references.values(), (":", "-.")):
        for key, color in (("mission", "C0"), ("balance", "C1")):
            ax2.axhline(m["max_joint_rate_deg_s"][key], color=color, ls=style, lw=0.8)
    ax2.axhline(limit_deg_s, color="r", ls="--", lw=0.8, label=f"limit {limit_deg_s:.0f} deg/s")
    ax2.set(xlabel="proportional gain K [1/s]", ylabel="peak joint rate [deg/s]",
            title="Peak joint rate per arm (lines: predefined time, styles as left)")
    ax2.legend(fontsize=7)
    ax2.grid(True, alpha=0.3)
    fig.suptitle(f"Proportional feedback on the paper scenario, gain by gain ({_FLOOR_NOTE})", fontsize=9)
    return _save(fig, out, footer)
