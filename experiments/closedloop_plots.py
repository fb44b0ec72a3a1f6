"""The closed-loop study's figure: success per policy (with the thesis' real-robot rates),
per initial belief, the final distance to the goal, and the estimator's error over time."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

COLORS = {"qmdp": "tab:orange", "pomdp": "tab:blue", "lat-despot": "tab:red"}


def plot_closedloop(summary: dict, path: Path) -> None:
    policies = summary["policies"]
    fig, axes = plt.subplots(1, 4, figsize=(16, 4))
    ax = axes[0]
    for i, (name, r) in enumerate(policies.items()):
        lo, hi = r["success_rate_ci95"]
        ax.bar(i, r["success_rate"], color=COLORS.get(name, "0.5"),
               yerr=[[r["success_rate"] - lo], [hi - r["success_rate"]]], capsize=6)
        thesis = summary["thesis_real_robot"].get(name)
        if thesis:
            ax.scatter(i, thesis["successes"] / thesis["trials"], marker="*", s=180,
                       color="k", zorder=3, label="thesis, real HERB" if i == 0 else None)
    ax.set_xticks(range(len(policies)), [n.upper() for n in policies])
    ax.set_ylim(0, 1.05)
    ax.set_ylabel("success rate (95 % Wilson interval)")
    ax.set_title("success")
    if ax.get_legend_handles_labels()[1]:  # the thesis has figures only for its policies
        ax.legend(loc="lower right", fontsize=8)

    ax = axes[1]
    width = 0.8 / max(1, len(policies))
    for i, (name, r) in enumerate(policies.items()):
        beliefs = sorted(r["success_by_belief"], key=int)
        rates = [np.mean(r["success_by_belief"][b]) for b in beliefs]
        ax.bar(np.arange(len(beliefs)) + i * width, rates, width, color=COLORS.get(name, "0.5"),
               label=name.upper())
        ax.set_xticks(np.arange(len(beliefs)) + width * (len(policies) - 1) / 2,
                      [f"belief {b}" for b in beliefs])
    ax.set_ylim(0, 1.05)
    ax.set_title("success per initial belief")
    ax.legend(fontsize=8)

    ax = axes[2]
    data = [100 * np.array(r["final_distance_to_goal_m"]) for r in policies.values()]
    ax.boxplot(data, showfliers=True)
    ax.set_xticks(range(1, len(policies) + 1), [n.upper() for n in policies])
    ax.set_ylabel("final distance to the goal (cm)")
    ax.set_title("where the object ends")

    ax = axes[3]
    for name, r in policies.items():
        for k, episode in enumerate(r["episodes"]):
            curve = episode["estimator_rmse_over_time"]
            ax.plot(curve["time_s"], 100 * np.array(curve["rmse_m"]),
                    color=COLORS.get(name, "0.5"), alpha=0.25, lw=0.8,
                    label=name.upper() if k == 0 else None)
    ax.set_xlabel("simulated time (s)")
    ax.set_ylabel("estimator position RMSE (cm)")
    ax.set_title("estimation error, every episode")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
