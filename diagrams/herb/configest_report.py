"""The configuration-estimation episode's figure: joint-space error over time."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

LABELS = {"cpf": ("CPF", "tab:gray"), "mpf-ball": ("MPF-Ball", "tab:blue")}


def plot_joint_error(times: np.ndarray, errors: dict[str, np.ndarray], contact: np.ndarray,
                     path: Path) -> str:
    """Each estimate's joint-space error |q_hat - q| (rad) over time (s), with the times of
    contact readings marked below the curves; returns the file name."""
    fig, ax = plt.subplots(figsize=(8, 3.6))
    for kind, error in errors.items():
        label, colour = LABELS.get(kind, (kind, None))
        ax.plot(times, error, label=label, color=colour)
    touching = contact.any(axis=1)
    top = max(float(max(e.max() for e in errors.values())), 1e-3)
    ax.fill_between(times, 0, top * 1.05, where=touching, color="gold", alpha=0.25,
                    step="mid", label="contact reading")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("joint-space error (rad)")
    ax.set_ylim(0, top * 1.05)
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path.name
