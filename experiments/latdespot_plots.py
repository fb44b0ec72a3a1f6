"""Figures of ``cmanip experiment latdespot`` (thesis Fig. 7.3)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from experiments.plotting import plt, save_figure

LABELS = {"rel-qmdp": "Rel-QMDP", "rel-sarsop": "Rel-SARSOP", "rel-despot": "Rel-DESPOT"}


def plot_rel(summary: dict, out: Path) -> None:
    """``rel_value.png`` (value on the discrete model, 95 % intervals; Fig. 7.3a) and
    ``rel_success.png`` (success probability over time on the continuous model; Fig.
    7.3b, the last step's 95 % Wilson interval as a bar)."""
    rel = summary["rel"]
    names = list(rel)
    fig, ax = plt.subplots(figsize=(4.5, 3.5))
    values = [rel[n]["discounted_value"] for n in names]
    ax.bar(range(len(names)), values, yerr=[rel[n]["discounted_value_ci95"] for n in names],
           color=["0.6", "tab:blue", "tab:orange"][:len(names)], capsize=4)
    ax.set_xticks(range(len(names)), [LABELS.get(n, n) for n in names])
    ax.set_ylabel("discounted value, discrete model\n"
                  "(axis inverted, as the thesis: shorter is better)")
    ax.invert_yaxis()  # as the thesis: less negative is better, drawn shorter
    ax.set_title(f"Rel-POMDP, {summary['settings']['horizon']} steps")
    save_figure(fig, out / "rel_value.png")

    fig, ax = plt.subplots(figsize=(5.5, 3.5))
    for name in names:
        rate = np.asarray(rel[name]["success_over_time"])
        (line,) = ax.plot(np.arange(len(rate)), rate, label=LABELS.get(name, name))
        lo, hi = rel[name]["success_rate_ci95"]
        ax.errorbar([len(rate) - 1], [rate[-1]], yerr=[[rate[-1] - lo], [hi - rate[-1]]],
                    color=line.get_color(), capsize=3)
    ax.set_xlabel("step")
    ax.set_ylabel("Pr(object in goal), continuous model")
    ax.set_ylim(0, 1)
    ax.legend(loc="lower right")
    save_figure(fig, out / "rel_success.png")
