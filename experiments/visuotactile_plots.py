"""Figures of the visuo-tactile study (:mod:`experiments.visuotactile_study`)."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from scipy import stats

from experiments.plotting import save_figure
from models.pose import wrap_angle

UNITS = {"motion": "N m^2", "contact": "mm", "vision": "mm", "stationary": "mm"}


def noise_figures(residuals, folder: Path) -> list[str]:
    """Seed 003 Fig. 7 for every cost: the first axis's histogram with the fitted normal,
    and its normal QQ plot; plus the contact errors' scatter."""
    names = []
    fig, axes = plt.subplots(2, 4, figsize=(15, 7))
    for column, cost in enumerate(("motion", "contact", "vision", "stationary")):
        rows = np.concatenate([getattr(r, cost) for r in residuals])
        values = rows[:, 0] * (1.0 if cost == "motion" else 1e3)
        sigma = float(np.sqrt(np.mean(values ** 2)))
        ax = axes[0, column]
        ax.hist(values, bins=60, density=True, color="0.6")
        grid = np.linspace(values.min(), values.max(), 200)
        ax.plot(grid, stats.norm.pdf(grid, 0.0, sigma), "r-", label=f"N(0, {sigma:.3g})")
        ax.set_title(f"{cost}: first axis ({UNITS[cost]})")
        ax.legend(fontsize=8)
        stats.probplot(values, dist="norm", plot=axes[1, column])
        axes[1, column].set_title(f"{cost}: normal QQ plot")
    names.append(save_figure(fig, folder / "noise_qq.png"))
    contact = np.concatenate([r.contact for r in residuals]) * 1e3
    fig, ax = plt.subplots(figsize=(5, 5))
    ax.scatter(contact[:, 1], contact[:, 2], s=3, alpha=0.4)
    ax.set_xlabel("contact point error, object x (mm)")
    ax.set_ylabel("contact point error, object y (mm)")
    ax.set_aspect("equal")
    ax.set_title("contact cost at the true poses")
    names.append(save_figure(fig, folder / "contact_errors.png"))
    return names


def _bars(ax, labels, means, stds, paper=None, ylabel=""):
    x = np.arange(len(labels))
    ax.bar(x, means, yerr=stds, capsize=3, color="tab:blue", alpha=0.8, label="simulated")
    if paper is not None:
        ax.plot(x, paper, "k*", markersize=10, label="seed 003 (real rig)")
    ax.set_xticks(x, labels, rotation=30, ha="right", fontsize=8)
    ax.set_ylabel(ylabel)
    ax.legend(fontsize=8)


def methods_figures(results: dict, traces: dict, paper: dict, folder: Path) -> list[str]:
    labels = list(results)
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.5))
    for ax, key, unit, index in ((axes[0], "rmse_mm", "translation RMSE (mm)", 0),
                                 (axes[1], "rmse_deg", "rotation RMSE (deg)", 1)):
        means = [results[m][key]["mean"] or np.nan for m in labels]
        stds = [results[m][key]["std"] or 0.0 for m in labels]
        _bars(ax, labels, means, stds, [paper.get(m, (np.nan, np.nan))[index] for m in labels],
              unit)
    fig.suptitle("Estimators on the standard procedure, rect1 on plywood (Table II)")
    names = [save_figure(fig, folder / "methods_rmse.png")]
    names.append(error_figure(traces, "methods", folder))
    names.append(trajectory_figure(traces, folder))
    return names


def error_figure(traces: dict, name: str, folder: Path) -> str:
    """Translation and rotation error over time of trial 0, one line per method."""
    t, truth = traces["t"], traces["truth"]
    fig, axes = plt.subplots(2, 1, figsize=(11, 6), sharex=True)
    for label, estimates in traces.items():
        if label in ("t", "truth"):
            continue
        axes[0].plot(t, 1e3 * np.linalg.norm(estimates[:, :2] - truth[:, :2], axis=1),
                     lw=0.8, label=label)
        axes[1].plot(t, np.rad2deg(np.abs(wrap_angle(estimates[:, 2] - truth[:, 2]))), lw=0.8)
    axes[0].set_ylabel("translation error (mm)")
    axes[1].set_ylabel("rotation error (deg)")
    axes[1].set_xlabel("time (s)")
    axes[0].legend(fontsize=7, ncol=2)
    fig.suptitle("Estimation error over time, trial 0")
    return save_figure(fig, folder / f"{name}_error_over_time.png")


def trajectory_figure(traces: dict, folder: Path) -> str:
    t, truth = traces["t"], traces["truth"]
    fig, ax = plt.subplots(figsize=(6, 6))
    ax.plot(1e3 * truth[:, 0], 1e3 * truth[:, 1], "k-", lw=2, label="truth")
    for label in ("vision only", "EKF", "iSAM 200-step"):
        if label in traces:
            e = traces[label]
            ax.plot(1e3 * e[:, 0], 1e3 * e[:, 1], lw=0.8, label=label)
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_aspect("equal")
    ax.legend(fontsize=8)
    ax.set_title(f"Object centre, trial 0 ({t[-1]:.0f} s)")
    return save_figure(fig, folder / "trajectory.png")


def conditions_figure(results: dict, paper: dict, part: str, folder: Path) -> str:
    conditions = list(results)
    methods = list(next(iter(results.values())))
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.5))
    width = 0.8 / len(methods)
    for ax, key, unit, index in ((axes[0], "rmse_mm", "translation RMSE (mm)", 0),
                                 (axes[1], "rmse_deg", "rotation RMSE (deg)", 1)):
        x = np.arange(len(conditions))
        for j, method in enumerate(methods):
            means = [results[c][method][key]["mean"] or np.nan for c in conditions]
            stds = [results[c][method][key]["std"] or 0.0 for c in conditions]
            ax.bar(x + (j - (len(methods) - 1) / 2) * width, means, width, yerr=stds,
                   capsize=2, label=method)
        ax.plot(x, [paper[c][index] for c in conditions], "k*", markersize=10,
                label="seed 003 iSAM (real rig)")
        ax.set_xticks(x, conditions)
        ax.set_ylabel(unit)
        ax.legend(fontsize=7)
    fig.suptitle(f"RMSE by {part[:-1]} (Table {'III' if part == 'shapes' else 'IV'})")
    return save_figure(fig, folder / f"{part}_rmse.png")


def timing_figure(results: dict, folder: Path) -> str:
    labels = [m for m in results if "timing" in results[m]]
    fig, ax = plt.subplots(figsize=(7, 4))
    x = np.arange(len(labels))
    for offset, key in ((-0.2, "update_ms_mean"), (0.0, "update_ms_p99"),
                        (0.2, "relinearize_ms_mean")):
        ax.bar(x + offset, [results[m]["timing"].get(key, np.nan) for m in labels], 0.2,
               label=key)
    ax.set_yscale("log")
    ax.set_xticks(x, labels)
    ax.set_ylabel("ms")
    ax.legend(fontsize=8)
    ax.set_title("Smoother timing per history length")
    return save_figure(fig, folder / "timing.png")
