"""Figures of the hand-relative planning study (thesis Figs. 6.5 and 6.6)."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.patches import Ellipse, Rectangle

from experiments.plotting import save_figure
from planning.hand.model import goal_region

COLOURS = {"QMDP": "tab:orange", "POMDP": "tab:blue"}


def plot_problem(model, near, far, path: Path) -> str:
    """The hand, its sensors, the trust region, the goal and the belief points (1 sigma)."""
    world, spec = model.world, model.spec
    fig, ax = plt.subplots(figsize=(8, 5.5))
    ax.fill(*world.hand.outline.exterior.xy, color="0.7", label="hand")
    for segment in world.hand.sensor_segments:
        ax.plot(segment[:, 0], segment[:, 1], lw=4, color="tab:red")
    (x0, x1), (y0, y1) = spec.trust_x_m, spec.trust_y_m
    ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, ls="--", color="0.3",
                           label="trust region"))
    (gx0, gy0), (gx1, gy1) = goal_region(world, spec)
    ax.add_patch(Rectangle((gx0, gy0), gx1 - gx0, gy1 - gy0, color="tab:green", alpha=0.4,
                           label="goal"))
    for beliefs, colour, label in ((near, "tab:blue", "beliefs (post-contact)"),
                                   (far, "tab:purple", "beliefs (full)")):
        for i, b in enumerate(beliefs):
            ax.add_patch(Ellipse(b.mean[:2], 2 * b.std[0], 2 * b.std[1], fill=False,
                                 color=colour, alpha=0.5, label=label if i == 0 else None))
    ax.set_aspect("equal")
    ax.set_xlim(-0.1, 0.6)
    ax.set_ylim(-0.25, 0.25)
    ax.set_xlabel("x ahead of the palm (m)")
    ax.set_ylabel("y (m)")
    ax.legend(loc="upper left", fontsize=7)
    ax.set_title(f"{len(model.pomdp.states)} states: {model.free_count} free, "
                 f"{model.contact_count} contact, 1 outside", fontsize=9)
    return save_figure(fig, path)


def _success_curves(ax, results: dict, title: str, style: str = "-", suffix: str = "") -> None:
    for name, r in results.items():
        rate = np.asarray(r["success_over_time"])
        n = r["trials"]
        half = 1.96 * np.sqrt(rate * (1 - rate) / n)
        t = np.arange(len(rate))
        ax.plot(t, rate, style, color=COLOURS[name], label=name + suffix)
        ax.fill_between(t, rate - half, rate + half, color=COLOURS[name], alpha=0.15)
    ax.set_xlabel("step")
    ax.set_ylabel("Pr(object in goal)")
    ax.set_ylim(0, 1)
    ax.set_title(title, fontsize=10)
    ax.legend(fontsize=8)


def plot_results(summary: dict, out: Path) -> list[str]:
    """Fig. 6.5: (a) discrete value, (b) post-contact success, (c) full success."""
    names = []
    if "post_contact_discrete" in summary:
        fig, ax = plt.subplots(figsize=(3.5, 4))
        results = summary["post_contact_discrete"]
        for i, (name, r) in enumerate(results.items()):
            ax.bar(i, r["discounted_value"], yerr=r["discounted_value_ci95"],
                   color=COLOURS[name], capsize=6)
        ax.set_xticks(range(len(results)), list(results))
        ax.set_ylabel("discounted value, depth 50 (less negative is better)")
        ax.set_title("(a) post-contact, discrete model", fontsize=10)
        names.append(save_figure(fig, out / "post_contact_value.png"))
    for key, title, file in (("post_contact", "(b) post-contact, continuous model",
                              "post_contact_success.png"),
                             ("full", "(c) full policy from 50 cm, continuous model",
                              "full_success.png")):
        if key in summary:
            fig, ax = plt.subplots(figsize=(5, 4))
            _success_curves(ax, summary[key], title)
            names.append(save_figure(fig, out / file))
    return names


def plot_coverage(summary: dict, path: Path) -> str:
    """Fig. 6.6: (a) discrete value and (b) full-policy success, fingertips vs links."""
    coverage = summary["coverage"]
    fig, (ax_v, ax_s) = plt.subplots(1, 2, figsize=(10, 4))
    width = 0.35
    for j, (sensors, alpha) in enumerate((("fingertips", 0.45), ("links", 1.0))):
        results = coverage[sensors]["post_contact_discrete"]
        for i, (name, r) in enumerate(results.items()):
            ax_v.bar(i + (j - 0.5) * width, r["discounted_value"], width,
                     yerr=r["discounted_value_ci95"], color=COLOURS[name], alpha=alpha,
                     capsize=4, label=f"{name}, {sensors}")
        _success_curves(ax_s, coverage[sensors]["full"], "(b) full policy success",
                        style="--" if sensors == "fingertips" else "-", suffix=f", {sensors}")
    ax_v.set_xticks(range(2), list(POLICY_ORDER))
    ax_v.set_ylabel("discounted value (discrete model)")
    ax_v.set_title("(a) post-contact value", fontsize=10)
    ax_v.legend(fontsize=7)
    return save_figure(fig, path)


POLICY_ORDER = ("QMDP", "POMDP")
