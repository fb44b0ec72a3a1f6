"""The fault bench's figure: how far each faulty run ends from the recovery rule's bound.

One row per estimator and variant (the thesis' filter, the robust one), one point per
injected fault at ``error_after / recovery_bound`` on a log axis, coloured by fault; a
point right of the line at 1 was not recovered. The shams (no fault) are drawn in grey:
where they fall is the spread the rule allows a run that no fault touched. A run with a
non-finite estimate is drawn as a cross at the axis' right edge. The right panel is the
pooled test (:func:`experiments.fault_bench.lasting_harm`): per row, the mean rank of the
faulty runs' last-quarter error among their clean draws with its 95 % interval, and the
shams' in grey; 0.5 is where one more clean draw falls. At its right edge, the most of the
row's faulty runs that a fault can have left above all their clean draws (one-sided 95 %).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from experiments.fault_bench import SHAM, TOLERANCE, recovery_bound
from experiments.plotting import plt, save_figure


def bound_ratio(outcome: dict) -> float:
    """``error_after`` over the rule's bound for ``outcome`` (a ``fault_outcomes`` entry
    of the report): at most 1 when the rule passes it; inf for a non-finite run."""
    if not outcome["finite"] or not np.isfinite(outcome["error_after"]):
        return float("inf")
    family = outcome["estimator"].split("/", 1)[0]
    bound = recovery_bound(outcome["clean_after"], TOLERANCE[family],
                           outcome["clean_after_worst"])
    return outcome["error_after"] / bound


def plot_fault_recovery(outcomes: list[dict], harm: dict, path: Path) -> str:
    """Draw ``outcomes`` (the report's ``fault_outcomes``) and the pooled test ``harm``
    over them (its ``lasting_harm``) to ``path`` (PNG); its name."""
    if not outcomes:
        raise ValueError("no fault outcomes to plot")
    rows = sorted({(o["estimator"], o["robust"]) for o in outcomes})
    faults = sorted({o["fault"] for o in outcomes if o["fault"] != SHAM})
    palette = plt.get_cmap("tab20").colors
    colours = {f: palette[i % len(palette)] for i, f in enumerate(faults)}
    ratios = np.array([bound_ratio(o) for o in outcomes])
    finite = ratios[np.isfinite(ratios)]
    right = max(2.0, float(finite.max()) * 1.3 if finite.size else 2.0)
    left = min(0.05, float(finite.min()) / 1.3) if finite.size else 0.05
    fig, (ax, rank_ax) = plt.subplots(1, 2, sharey=True, figsize=(10.5, 0.45 * len(rows) + 2.6),
                                      gridspec_kw={"width_ratios": (3, 1)})
    jitter = np.random.default_rng(0).uniform(-0.25, 0.25, len(outcomes))
    for o, ratio, dy in zip(outcomes, ratios, jitter, strict=True):
        y = rows.index((o["estimator"], o["robust"])) + dy
        sham = o["fault"] == SHAM
        colour = "0.6" if sham else colours[o["fault"]]
        if np.isfinite(ratio):
            ax.scatter(ratio, y, s=22, color=colour, marker="s" if sham else "o",
                       edgecolors="k" if ratio > 1 else "none", linewidths=0.6, zorder=3)
        else:
            ax.scatter(right, y, s=40, color=colour, marker="x", zorder=3)
    ax.axvline(1.0, color="k", lw=1, ls="--")
    ax.set_xscale("log")
    ax.set_xlim(left, right * 1.05)
    ax.set_yticks(range(len(rows)))
    ax.set_yticklabels([e if e == "smoother" else f"{e} ({'robust' if r else 'thesis'})"
                        for e, r in rows])
    ax.invert_yaxis()
    ax.set_xlabel("error over the last quarter / recovery bound (right of 1: not recovered)")
    handles = [plt.Line2D([], [], marker="o", ls="", color=colours[f], label=f)
               for f in faults]
    handles.append(plt.Line2D([], [], marker="s", ls="", color="0.6", label="sham (no fault)"))
    ax.legend(handles=handles, fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.09),
              ncol=5)
    ax.set_title("Faults injected into the estimators: where each run ends")
    ax.grid(axis="x", alpha=0.3)
    _draw_ranks(rank_ax, harm, rows)
    return save_figure(fig, Path(path))


def _draw_ranks(ax, harm: dict, rows: list[tuple[str, bool]]) -> None:
    """Per row, the faulty runs' mean clean rank with its 95 % interval and the shams',
    as ``harm`` (:func:`experiments.fault_bench.lasting_harm`) has them."""
    for y, (estimator, robust) in enumerate(rows):
        variant = "robust" if robust else "thesis"
        for grouping, dy, style in (("by_estimator", -0.12, dict(color="k", marker="o")),
                                    ("shams_by_estimator", 0.12,
                                     dict(color="0.6", marker="s"))):
            cell = harm[grouping].get(variant, {}).get(estimator)
            if cell is not None:
                ax.errorbar(cell["mean_rank"], y + dy, xerr=cell["ci95"], ls="",
                            capsize=2, ms=5, **style)
        faults = harm["by_estimator"].get(variant, {}).get(estimator)
        if faults is not None:
            ax.text(0.98, y, f"\u2264{100 * faults['harmed_share_upper95']:.0f} %",
                    ha="right", va="center", fontsize=7)
    ax.axvline(0.5, color="k", lw=1, ls="--")
    ax.set_xlim(0, 1)
    ax.set_xlabel("mean rank among clean draws")
    ax.set_title("faults (black), shams (grey);\nat most this share harmed (95 %)",
                 fontsize=8)
    ax.grid(axis="x", alpha=0.3)
