"""Writing one closed-loop episode: ``summary.json``, ``belief.png`` and ``replay.html``."""

from __future__ import annotations

import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from diagrams.herb.episode import Episode  # noqa: E402
from models.se2 import compose  # noqa: E402


def write_episode(episode: Episode, out_dir: Path) -> None:
    """Write the episode's files into ``out_dir`` (created if needed): ``summary.json``,
    ``belief.png``, ``replay.html`` (when recorded), and ``trace.npz`` with the trace and
    the belief at every decision (keys ``trace_<name>`` and ``decision_<name>``, see
    :class:`~diagrams.herb.episode.Episode`)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(out_dir / "trace.npz",
                        **{f"trace_{k}": v for k, v in episode.trace.items()},
                        **{f"decision_{k}": v for k, v in episode.snapshots.items()})
    (out_dir / "summary.json").write_text(json.dumps(episode.summary, indent=2) + "\n")
    if episode.html is not None:
        (out_dir / "replay.html").write_text(episode.html)
    plot_belief(episode, out_dir / "belief.png")


def plot_belief(episode: Episode, path: Path) -> None:
    """Estimation error over time (position cm, orientation deg unless the object is
    rotationally symmetric, when orientation is unobservable; contact readings and
    the time in the goal shaded) beside a top view of the palm, the true object and the
    belief mean in the world."""
    trace, summary = episode.trace, episode.summary
    t = trace["time_s"]
    fig, (ax_err, ax_top) = plt.subplots(1, 2, figsize=(12, 4.8),
                                         gridspec_kw={"width_ratios": [1.4, 1]})
    ax_err.plot(t, 100 * trace["rmse_m"], color="tab:blue", label="position RMSE (cm)")
    if not summary.get("object_rotationally_symmetric", False):  # else unobservable
        ax_err.plot(t, np.rad2deg(trace["rmse_rad"]) / 10, color="tab:orange",
                    label="orientation RMSE (10 deg)")
    touched = trace["readings"].any(axis=1)
    top = max(1.0, float(np.nanmax(100 * trace["rmse_m"])))
    ax_err.fill_between(t, 0, top, where=trace["in_goal"], color="tab:green", alpha=0.12,
                        step="mid", label="object in goal")
    ax_err.scatter(t[touched], np.full(touched.sum(), 0.97 * top), marker="|", color="k",
                   s=30, label="a sensor reads contact")
    ax_err.set_xlabel("simulated time (s)")
    ax_err.set_ylabel("error")
    ax_err.set_ylim(0, top)
    outcome = "success" if summary["success"] else "failure"
    settings = summary["settings"]
    planner = settings["policy"] if settings.get("planner", "hand") == "hand" \
        else settings["planner"]
    ax_err.set_title(f"{planner.upper()} / "
                     f"{summary['settings']['estimator'].upper()}: {outcome} "
                     f"({summary['stop_reason']}, {summary['steps']} steps)")
    ax_err.legend(loc="upper left", fontsize=8, bbox_to_anchor=(0.0, 0.93))

    mean_W = compose(trace["palm"], trace["mean"])
    ax_top.plot(trace["palm"][:, 1], trace["palm"][:, 0], color="0.3", label="palm")
    ax_top.plot(trace["object"][:, 1], trace["object"][:, 0], color="tab:blue",
                label="object (true)")
    ax_top.plot(mean_W[:, 1], mean_W[:, 0], color="tab:red", ls="--", label="belief mean")
    (x0, y0), (x1, y1) = np.array(summary["goal_region_hand_m"])
    corners = compose(trace["palm"][-1], np.array([[x0, y0, 0], [x1, y0, 0], [x1, y1, 0],
                                                   [x0, y1, 0], [x0, y0, 0]]))
    ax_top.plot(corners[:, 1], corners[:, 0], color="tab:green", label="goal at the end")
    ax_top.set_xlabel("world y (m)")
    ax_top.set_ylabel("world x (m)")
    ax_top.set_aspect("equal", adjustable="datalim")
    ax_top.invert_xaxis()  # world y to the left, as seen from behind the robot
    ax_top.legend(loc="lower left", fontsize=8)
    ax_top.set_title("top view")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
