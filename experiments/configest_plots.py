"""Figure of the configuration-estimation study: RMSE over time per arm (thesis Fig. 5.3)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from experiments.plotting import plt, save_figure

COLOURS = {"cpf": "tab:gray", "mpf-uniform": "tab:orange", "mpf-particle": "tab:blue",
           "mpf-ball": "tab:green", "mpf-explicit": "tab:purple"}
LABELS = {"cpf": "CPF", "mpf-uniform": "MPF-Uniform", "mpf-particle": "MPF-Particle",
          "mpf-ball": "MPF-Ball", "mpf-explicit": "MPF-Explicit"}
TITLES = {"2dof": "2-DOF arm, point obstacle", "3dof": "3-DOF arm, unstructured obstacle",
          "wam": "7-DOF WAM among boxes"}


def plot_rmse(arms: dict, path: Path) -> str:
    """One panel per arm: each filter's mean joint-space RMSE (rad) after every update,
    with its 95 % interval over trials as a band.

    Args:
        arms: ``{arm: {filter: {"curve_rad": [...], "curve_rad_ci95": [...]}}}``.
    """
    fig, axes = plt.subplots(1, len(arms), figsize=(5 * len(arms), 3.6), squeeze=False)
    for ax, (arm, filters) in zip(axes[0], arms.items(), strict=True):
        for kind, entry in filters.items():
            mean, ci = np.array(entry["curve_rad"]), np.array(entry["curve_rad_ci95"])
            t = np.arange(1, len(mean) + 1)
            ax.plot(t, mean, color=COLOURS.get(kind), label=LABELS.get(kind, kind))
            ax.fill_between(t, mean - ci, mean + ci, color=COLOURS.get(kind), alpha=0.2)
        ax.set_title(TITLES.get(arm, arm))
        ax.set_xlabel("time step")
        ax.set_ylabel("RMSE (rad)")
        ax.set_ylim(bottom=0)
        ax.grid(alpha=0.3)
    axes[0][0].legend(fontsize=8)
    return save_figure(fig, path)
