"""Figures of ``cmanip experiment latdespot`` (thesis Fig. 7.3)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from experiments.plotting import plt, save_figure

LABELS = {"rel-qmdp": "Rel-QMDP", "rel-sarsop": "Rel-SARSOP", "rel-despot": "Rel-DESPOT",
          "rel-despot-continuous": "Rel-DESPOT\n(continuous)"}
COLORS = {"rel-qmdp": "0.5", "rel-sarsop": "tab:blue", "rel-despot": "tab:orange",
          "rel-despot-continuous": "tab:green"}


def plot_rel(summary: dict, out: Path) -> None:
    """``rel_value.png`` (value with 95 % intervals on the discrete model, Fig. 7.3a, for
    the policies that plan on it, and on the continuous model for all) and
    ``rel_success.png`` (success probability over time on the continuous model; Fig.
    7.3b, the last step's 95 % Wilson interval as a bar)."""
    rel = summary["rel"]
    names = list(rel)
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.8), sharey=True)
    panels = (("discrete model (Fig. 7.3a)", "discounted_value",
               [n for n in names if rel[n].get("value_model", "discrete") == "discrete"]),
              ("continuous model", "continuous_discounted_value", names))
    for ax, (title, key, shown) in zip(axes, panels, strict=True):
        ax.bar(range(len(shown)), [rel[n][key] for n in shown],
               yerr=[rel[n][key + "_ci95"] for n in shown],
               color=[COLORS.get(n, "0.3") for n in shown], capsize=4)
        ax.set_xticks(range(len(shown)), [LABELS.get(n, n) for n in shown], fontsize=8)
        ax.set_title(title, fontsize=10)
    axes[0].set_ylabel("discounted value over "
                       f"{summary['settings']['horizon']} steps\n"
                       "(axis inverted, as the thesis: shorter is better)")
    axes[0].invert_yaxis()  # as the thesis: less negative is better, drawn shorter
    save_figure(fig, out / "rel_value.png")

    fig, ax = plt.subplots(figsize=(5.5, 3.5))
    for name in names:
        rate = np.asarray(rel[name]["success_over_time"])
        (line,) = ax.plot(np.arange(len(rate)), rate, color=COLORS.get(name),
                          label=LABELS.get(name, name).replace("\n", " "))
        lo, hi = rel[name]["success_rate_ci95"]
        ax.errorbar([len(rate) - 1], [rate[-1]], yerr=[[rate[-1] - lo], [hi - rate[-1]]],
                    color=line.get_color(), capsize=3)
    ax.set_xlabel("step")
    ax.set_ylabel("Pr(object in goal), continuous model")
    ax.set_ylim(0, 1)
    ax.legend(loc="upper left", fontsize=8)  # the discrete planners oscillate below
    save_figure(fig, out / "rel_success.png")
