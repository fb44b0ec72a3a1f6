"""What every study's figures share: the Agg backend and one way to write a PNG."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def save_figure(fig, path: Path) -> str:
    """Lay out, write (PNG, 120 dpi) and close a figure; return its file name."""
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path.name
