"""The planner seam of DESIGN.md: ``plan(belief, *, rng, **context) -> PlanResult``.

QMDP, the point-based policy, the hand planners, DESPOT and Lat-DESPOT answer it, so a
controller swaps them by configuration. A planner is an immutable core; whatever it must
remember between decisions (a trajectory and its position, a phase, its own belief) goes
out in :attr:`PlanResult.memory` and comes back as the ``memory`` keyword of the next call,
so the closed-loop diagram keeps it in its Context like any other state.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import numpy as np


@dataclass(frozen=True)
class PlanResult:
    """One decision.

    Attributes:
        action: the chosen action's index (the first of ``ranking``).
        ranking: every action's index, best first (a controller that finds the best
            infeasible falls back along it).
        phase: the planner's phase when it chose (e.g. ``pre-contact``, ``post-contact``).
        planning_ms: wall time of the call (ms), including any search it ran.
        stats: solver statistics of this call (e.g. ``search``: the pre-contact search's
            actions, expansions, seconds and stop reason, on the call that searched).
        memory: the planner's state after this decision, to pass back as ``memory=``
            (``None`` for a planner that remembers nothing); an immutable value.
    """

    action: int
    ranking: tuple[int, ...]
    phase: str
    planning_ms: float
    stats: Mapping[str, Any] = field(default_factory=dict)
    memory: Any = None

    def __post_init__(self):
        if not self.ranking or self.ranking[0] != self.action:
            raise ValueError(f"the ranking {self.ranking} must start with the action "
                             f"{self.action}")


@runtime_checkable
class Planner(Protocol):
    """Anything that chooses an action for a belief."""

    def plan(self, belief: Any, *, rng: np.random.Generator, **context: Any) -> PlanResult:
        """The decision for ``belief``; ``context`` carries what the planner asks for
        (e.g. ``memory``, ``contact_seen``, ``last_action``, ``reading``)."""
