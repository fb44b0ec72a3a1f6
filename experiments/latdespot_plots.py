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
    success_lines(ax, rel, {n: LABELS.get(n, n).replace("\n", " ") for n in names}, COLORS)
    ax.set_ylabel("Pr(object in goal), continuous model")
    ax.legend(loc="upper left", fontsize=8)  # the discrete planners oscillate below
    save_figure(fig, out / "rel_success.png")


def success_lines(ax, entries: dict, labels: dict[str, str], colors: dict[str, str]) -> None:
    """Pr(object in goal) over the steps of an episode, one line per policy in ``labels``
    (entries' ``success_over_time``), the last step's 95 % Wilson interval as a bar."""
    for name, label in labels.items():
        rate = np.asarray(entries[name]["success_over_time"])
        (line,) = ax.plot(np.arange(len(rate)), rate, color=colors.get(name), label=label)
        lo, hi = entries[name]["success_rate_ci95"]
        ax.errorbar([len(rate) - 1], [rate[-1]], yerr=[[rate[-1] - lo], [hi - rate[-1]]],
                    color=line.get_color(), capsize=3)
    ax.set_xlabel("step")
    ax.set_ylim(0, 1)


SCENE_LABELS = {"rel-qmdp": "RM", "rel-sarsop": "RS", "rel-despot": "RD", "lift-qmdp": "LM",
                "lift-sarsop": "LS", "lat-despot": "LD", "lat-despot-pb": "LD-pb",
                "lat-despot-continuous": "LD-c"}
SCENE_COLORS = {"rel-qmdp": "0.55", "rel-sarsop": "tab:blue", "rel-despot": "tab:orange",
                "lift-qmdp": "0.3", "lift-sarsop": "tab:cyan", "lat-despot": "tab:red",
                "lat-despot-pb": "tab:purple", "lat-despot-continuous": "tab:green"}


def plot_scenes(summary: dict, out: Path) -> None:
    """``lat_scenes.png``: the thesis' Fig. 7.4, one column per scene: (top) the value on
    the discrete Lat-POMDP (axis inverted as the thesis'), (middle) the success rate on the
    continuous one with 95 % Wilson intervals, (bottom) the fraction of episodes that took
    an infeasible action; and ``lattice_<scene>.png`` for each saved lattice. A policy
    valued on the continuous model (``value_model``) has a hatched value bar."""
    scenes = summary["scenes"]
    fig, axes = plt.subplots(3, len(scenes), figsize=(3.2 * len(scenes), 7.5),
                             sharey="row", squeeze=False)
    for col, (scene, entries) in enumerate(scenes.items()):
        names = list(entries)
        x = np.arange(len(names))
        colors = [SCENE_COLORS.get(n, "0.4") for n in names]
        value = [entries[n]["discounted_value"] for n in names]
        bars = axes[0, col].bar(x, value, color=colors, capsize=3,
                                yerr=[entries[n]["discounted_value_ci95"] for n in names])
        for bar, name in zip(bars, names, strict=True):
            if entries[name].get("value_model") == "continuous":
                bar.set_hatch("//")
        rate = np.array([entries[n]["success_rate"] for n in names])
        lo = rate - np.array([entries[n]["success_rate_ci95"][0] for n in names])
        hi = np.array([entries[n]["success_rate_ci95"][1] for n in names]) - rate
        axes[1, col].bar(x, rate, yerr=[lo, hi], color=colors, capsize=3)
        axes[2, col].bar(x, [entries[n]["infeasible_rate"] for n in names], color=colors)
        axes[0, col].set_title(scene, fontsize=10)
        for row in range(3):
            axes[row, col].set_xticks(x, [SCENE_LABELS.get(n, n) for n in names], fontsize=7)
    axes[0, 0].invert_yaxis()
    axes[0, 0].set_ylabel("value, discrete model\n(hatched: continuous)")
    axes[1, 0].set_ylabel("Pr(goal), continuous")
    axes[1, 0].set_ylim(0, 1)
    axes[2, 0].set_ylabel("Pr(infeasible action)")
    axes[2, 0].set_ylim(0, 1)
    save_figure(fig, out / "lat_scenes.png")
    plot_scene_success(scenes, out / "lat_success_time.png")
    for scene in scenes:
        path = out / f"lattice_{Path(scene).stem}.npz"
        if path.exists():
            plot_lattice(np.load(path), f"{Path(scene).stem}: the lattice Lat-DESPOT asked for "
                         "in one episode", out / f"lattice_{Path(scene).stem}.png")


def plot_scene_success(scenes: dict, path: Path) -> None:
    """Pr(object in goal) over the episode on the continuous Lat-POMDP, one panel per
    scene (as the thesis' Fig. 6.5b for ch. 6): where Fig. 7.4's success at the last step
    does not show when a policy reached the goal and when an infeasible action or
    un-modelled contact ended its episode (a trial ended so counts as out of the goal from
    then on)."""
    fig, axes = plt.subplots(1, len(scenes), figsize=(3.2 * len(scenes), 3.2), sharey=True,
                             squeeze=False)
    for ax, (scene, entries) in zip(axes[0], scenes.items(), strict=True):
        success_lines(ax, entries, {n: SCENE_LABELS.get(n, n) for n in entries},
                      SCENE_COLORS)
        ax.set_title(Path(scene).stem, fontsize=10)
    axes[0, 0].set_ylabel("Pr(object in goal), continuous")
    axes[0, -1].legend(loc="lower right", fontsize=7)
    save_figure(fig, path)


def plot_lattice(data, title: str, path: Path) -> None:
    """The thesis' Fig. 7.1 for one episode: every lattice point with a configuration
    (grey), the edges the planner asked for (green feasible, red infeasible), the
    obstacles' footprints and the hand's start (world frame, cm)."""
    poses, neighbours = data["poses"] * 100, data["neighbours"]
    fig, ax = plt.subplots(figsize=(6, 6))
    reachable = data["reachable"]
    ax.scatter(poses[reachable, 1], poses[reachable, 0], s=1, color="0.75",
               label="lattice point with IK")
    points, actions = np.nonzero(data["asked"])
    targets = neighbours[points, actions]
    for ok, color, label in ((1, "tab:green", "asked, feasible"),
                             (0, "tab:red", "asked, infeasible")):
        sel = (data["status"][points, actions] == ok) & (targets >= 0)
        segments = np.stack([poses[points[sel]][:, [1, 0]], poses[targets[sel]][:, [1, 0]]],
                            axis=1)
        for k, segment in enumerate(segments):
            ax.plot(segment[:, 0], segment[:, 1], color=color, lw=1.2,
                    label=label if k == 0 else None)
    start = 0
    for size in data["obstacle_sizes"]:
        outline = data["obstacles"][start:start + size] * 100
        ax.fill(outline[:, 1], outline[:, 0], color="tab:brown", alpha=0.6)
        start += size
    ax.plot(data["start"][1] * 100, data["start"][0] * 100, "k^", label="hand start")
    ax.set_xlabel("y (cm, world)")
    ax.set_ylabel("x (cm, world; forward)")
    ax.invert_xaxis()  # HERB's view: its left on the left
    ax.set_aspect("equal")
    ax.set_title(title, fontsize=9)
    ax.legend(loc="lower left", fontsize=7)
    save_figure(fig, path)


def plot_bound(summary: dict, out: Path) -> None:
    """``lat_bound.png`` (sec. 7.3.5): per scene, the best value of any policy on the
    Lat-POMDP beside Rel-SARSOP's and Rel-DESPOT's on Rel-POMDP from the same belief
    (95 % intervals), and the horizon's MDP value there (an upper bound of both) as a
    tick: Theorem 7.2 puts the first below the others."""
    scenes = summary["bound"]["scenes"]
    fig, ax = plt.subplots(figsize=(8, 3.6))
    width = 0.25
    for i, check in enumerate(scenes.values()):
        bars = [("best Lat-POMDP value", check["best_lat_value"], check["best_lat_value_ci95"],
                 "tab:red")]
        bars += [(f"{LABELS.get(name, name)} on Rel-POMDP", e["discounted_value"],
                  e["discounted_value_ci95"], COLORS.get(name, "0.3"))
                 for name, e in check["rel_pomdp"].items()]
        for k, (label, value, half, color) in enumerate(bars):
            ax.bar(i + (k - 1) * width, value, width, yerr=half, color=color, capsize=3,
                   label=label if i == 0 else None)
        ax.plot([i], [check["rel_upper_bounds"]["mdp_horizon"]], "v", color="k",
                markersize=9, label="upper bound (the horizon's MDP value)" if i == 0 else None)
    ax.set_xticks(range(len(scenes)), list(scenes), fontsize=9)
    ax.set_ylabel(f"discounted value over {summary['settings']['horizon']} steps")
    ax.invert_yaxis()  # as Fig. 7.3 and 7.4: less negative is better, drawn shorter
    ax.legend(fontsize=7, loc="lower right")
    ax.set_title("Theorem 7.2: Rel-POMDP's values bound the Lat-POMDP's (sec. 7.3.5)",
                 fontsize=10)
    save_figure(fig, out / "lat_bound.png")
