"""Figures of the MPF study (thesis Figs. 4.6-4.9), 95 % confidence intervals throughout."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from experiments.plotting import save_figure as _save

HAND_SPEED_M_PER_S = 0.01


def plot_part(part: str, runs: list, summaries: list[dict], out: Path) -> list[str]:
    """Write the part's PNGs into ``out``; return their file names.

    Args:
        part: the study part.
        runs: (condition, trial results) per condition.
        summaries: the study's summary of each condition, in the order of ``runs``.
        out: the folder.
    """
    if part in ("compare", "representations"):
        names = [_rmse_over_time(runs[0], out / f"{part}_rmse.png")]
        if part == "representations":
            names.append(_failure_rates(runs[0], summaries[0],
                                        out / "representations_failures.png"))
        return names
    if part == "resolution":
        return [_post_contact_by(runs, summaries, "sensors", "sensor layout",
                                 out / "resolution.png")]
    if part == "rate":
        return [_post_contact_by(runs, summaries, "update_interval_m",
                                 "travel between updates (mm)",
                                 out / "rate.png", scale=1000)]
    if part == "mixing":
        return [_mixing(runs[0], summaries[0], out / "mixing.png")]
    raise ValueError(part)


def aligned(results: list, f: int, which: str, before: int = 10):
    """RMSE of filter ``f`` aligned at first contact: offsets (T',), mean and 95 % half-width.

    ``which`` is ``"m"`` or ``"rad"``.
    """
    touched = [r for r in results if r.contact_index is not None]
    if not touched:
        return np.zeros(0), np.zeros(0), np.zeros(0)
    T = touched[0].rmse_m.shape[1]
    offsets = np.arange(-before, T)
    stack = np.full((len(touched), len(offsets)), np.nan)
    for i, r in enumerate(touched):
        series = getattr(r, f"rmse_{which}")[f]
        lo = max(0, r.contact_index - before)
        seg = series[lo:]
        start = before - (r.contact_index - lo)
        stack[i, start:start + len(seg)] = seg
    count = np.sum(np.isfinite(stack), axis=0)
    keep = count >= max(2, len(touched) // 2)
    mean = np.nanmean(stack[:, keep], axis=0)
    std = np.nanstd(stack[:, keep], axis=0, ddof=1)
    return offsets[keep], mean, 1.96 * std / np.sqrt(count[keep])


def plot_world(world, path: Path, thetas_deg=(0.0, 45.0, 90.0)) -> str:
    """The planar hand (outline, sensors numbered from -y) and the contact manifold's
    iso-contours (object-centre positions touching the hand) at a few orientations."""
    from models.planar.cspace import c_obstacle

    fig, ax = plt.subplots(figsize=(6, 6))
    outline = world.hand.outline
    ax.fill(*outline.exterior.xy, color="0.7", label="hand")
    colours = plt.cm.tab20(np.linspace(0, 1, max(world.sensor_count, 2)))
    for segment, sensor in zip(world.hand.sensor_segments, world.hand.sensor_of_segment,
                               strict=True):
        ax.plot(segment[:, 0], segment[:, 1], lw=4, color=colours[sensor])
    for sensor in range(world.sensor_count):
        mid = world.hand.sensor_segments[world.hand.sensor_of_segment == sensor].mean(axis=(0, 1))
        ax.annotate(str(sensor), mid, textcoords="offset points", xytext=(6, 0), fontsize=8)
    shape = world.shape.vertices[0][world.shape.valid[0]]
    for theta in thetas_deg:
        obstacle = c_obstacle(world.hand.parts, shape, np.deg2rad(theta))
        for poly in getattr(obstacle, "geoms", [obstacle]):
            ax.plot(*poly.exterior.xy, lw=0.8, label=f"X_c at {theta:g} deg")
    ax.set_aspect("equal")
    ax.set_xlabel("x, forward (m)")
    ax.set_ylabel("y, towards F3 (m)")
    ax.set_title(f"planar hand, {world.sensor_count} sensors; {world.object_spec.name} "
                 "contact manifold")
    ax.legend(fontsize=8, loc="lower left")
    ax.grid(alpha=0.3)
    return _save(fig, path)


def _rmse_over_time(run, path: Path) -> str:
    condition, results = run
    dt = condition.settings.update_interval_m / HAND_SPEED_M_PER_S
    fig, axes = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
    for f, spec in enumerate(condition.filters):
        for ax, which, scale in ((axes[0], "m", 100.0), (axes[1], "rad", np.rad2deg(1.0))):
            t, mean, ci = aligned(results, f, which)
            style = "--" if spec.kind == "cpf" else "-"
            ax.plot(t * dt, mean * scale, style, label=spec.label)
            ax.fill_between(t * dt, np.maximum(mean - ci, 0.0) * scale, (mean + ci) * scale,
                            alpha=0.2)
    axes[0].set_ylabel("position RMSE (cm)")
    axes[1].set_ylabel("orientation RMSE (deg)")
    axes[1].set_xlabel("time since first contact (s)")
    for ax in axes:
        ax.axvline(0.0, color="k", lw=0.5)
        ax.grid(alpha=0.3)
    axes[0].legend()
    touched = sum(r.contact_index is not None for r in results)
    axes[0].set_title(f"{condition.name}: {touched} of {len(results)} trials made contact "
                      "(95% CI)")
    return _save(fig, path)


def _failure_rates(run, condition_summary: dict, path: Path) -> str:
    condition, results = run
    summary = condition_summary["filters"]
    labels = [k for k, v in summary.items() if "sampling_failure_rate" in v]
    touched = [r for r in results if r.contact_index is not None]
    rates, cis = [], []
    for label in labels:
        f = [s.label for s in condition.filters].index(label)
        per_trial = []
        for r in touched:
            obs = r.contact_observed[f, r.contact_index:]
            if obs.sum():
                per_trial.append(r.sampling_failed[f, r.contact_index:].sum() / obs.sum())
        per_trial = np.array(per_trial)
        rates.append(per_trial.mean() * 100 if len(per_trial) else np.nan)
        cis.append(1.96 * per_trial.std(ddof=1) / np.sqrt(len(per_trial)) * 100
                   if len(per_trial) > 1 else 0.0)
    fig, ax = plt.subplots(figsize=(5, 4))
    ax.bar(labels, rates, yerr=cis, capsize=4, color="tab:orange")
    ax.set_ylabel("dual sampling failures (% of contact updates)")
    ax.set_title("sampling failures (95% CI over trials)")
    ax.grid(axis="y", alpha=0.3)
    return _save(fig, path)


def _post_contact_by(runs, condition_summaries: list[dict], key: str, xlabel: str, path: Path,
                     scale: float = 1.0) -> str:
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    xs = [c.extra[key] for c, _ in runs]
    positions = np.arange(len(xs))
    summaries = [s["filters"] for s in condition_summaries]
    for spec in runs[0][0].filters:
        for ax, field, unit in ((axes[0], "post_contact_rmse_cm", "cm"),
                                (axes[1], "post_contact_rmse_deg", "deg")):
            means = [s[spec.label][field] for s in summaries]
            cis = [s[spec.label][field + "_ci95"] for s in summaries]
            ax.errorbar(positions, means, yerr=cis, marker="o", capsize=4, label=spec.label)
            ax.set_ylabel(f"post-contact RMSE ({unit})")
    for ax in axes:
        ax.set_xticks(positions, [f"{x * scale:g}" if isinstance(x, float) else str(x)
                                  for x in xs])
        ax.set_xlabel(xlabel)
        ax.grid(alpha=0.3)
    axes[0].legend()
    fig.suptitle("post-contact RMSE (95% CI)")
    return _save(fig, path)


def _mixing(run, condition_summary: dict, path: Path) -> str:
    condition, _ = run
    summary = condition_summary["filters"]
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    mixes = [s for s in condition.filters if s.kind != "cpf"]
    phis = [s.mixing_rate for s in mixes]
    for ax, field, unit in ((axes[0], "post_contact_rmse_cm", "cm"),
                            (axes[1], "post_contact_rmse_deg", "deg")):
        means = [summary[s.label][field] for s in mixes]
        cis = [summary[s.label][field + "_ci95"] for s in mixes]
        ax.errorbar(phis, means, yerr=cis, marker="o", capsize=4, label="MPF-AM")
        ax.axhline(summary["cpf"][field], ls=":", color="k", label="CPF (phi = 0)")
        ax.set_xscale("log")
        ax.set_xlabel("mixing rate phi")
        ax.set_ylabel(f"post-contact RMSE ({unit})")
        ax.grid(alpha=0.3)
    axes[0].legend()
    fig.suptitle("MPF-AM against mixing rate (95% CI)")
    return _save(fig, path)
