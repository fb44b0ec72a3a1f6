"""A progress bar for the point-based solver that knows both of its budgets.

The solver stops at its wall-time budget or its trial budget, whichever comes first, so
the bar measures progress as the larger of the two fractions spent: a run that will stop
at its 400th trial after a minute does not show a ten-minute ETA for its time cap.
"""

from __future__ import annotations

from tqdm import tqdm


class SolverProgressBar:
    """``callback(elapsed_s, lower, upper, trials)`` for
    :meth:`~planning.pomdp.point_based.PointBasedSolver.solve`, drawing a percentage bar
    with the bounds at the initial belief; :meth:`close` when the solve returns.

    Args:
        seconds: the wall-time budget (s).
        max_trials: the trial budget (``None``: none).
        desc: the bar's label.
        disable: draw nothing.
    """

    def __init__(self, seconds: float, max_trials: int | None = None, *,
                 desc: str = "point-based solver", disable: bool = False):
        self._seconds = float(seconds)
        self._max_trials = max_trials
        budget = f"{seconds:g} s" + (f" or {max_trials} trials" if max_trials else "")
        self._bar = tqdm(total=100, desc=f"{desc} ({budget})", unit="%", disable=disable,
                         bar_format="{l_bar}{bar}| {n:.0f}% [{elapsed}<{remaining}{postfix}]")

    def __call__(self, elapsed_s: float, lower: float, upper: float, trials: int) -> None:
        done = elapsed_s / self._seconds
        if self._max_trials:
            done = max(done, trials / self._max_trials)
        percent = min(100.0, 100.0 * done)
        self._bar.update(percent - self._bar.n)
        self._bar.set_postfix(lower=f"{lower:.3f}", upper=f"{upper:.3f}", trials=trials)

    def close(self) -> None:
        self._bar.close()
