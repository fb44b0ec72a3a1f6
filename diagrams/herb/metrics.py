"""What an episode's trace says: distance to the goal and the episode's summary."""

from __future__ import annotations

import numpy as np

from diagrams.herb.controller import Decision
from diagrams.herb.settings import EpisodeSettings
from models.settings import settings_to_dict
from planning.hand.solution import HandSolution


def distance_to_goal(rel: np.ndarray, goal: np.ndarray) -> np.ndarray:
    """(K,) distance (m) from each object centre (K, 3), hand frame, to the goal rectangle."""
    gap = np.maximum(np.maximum(goal[0] - rel[:, :2], rel[:, :2] - goal[1]), 0.0)
    return np.linalg.norm(gap, axis=1)


def summarise_episode(settings: EpisodeSettings, solution: HandSolution,
                      trace: dict[str, np.ndarray], decisions: tuple[Decision, ...],
                      goal: np.ndarray, stop: str, wall_s: float, refused: int) -> dict:
    """The JSON-ready summary of one episode.

    Args:
        settings: the episode's settings.
        solution: the planning model (for the action names).
        trace: the trace (see :class:`~diagrams.herb.episode.Episode`).
        decisions: the controller's decisions.
        goal: (2, 2) the goal rectangle's corners (hand frame, m).
        stop: why the episode ended.
        wall_s: its wall time (s).
        refused: infeasible commands the executor refused (always 0 by design).

    Returns:
        The summary; ``time_to_goal_s`` is the first time the object was in the goal on a
        successful episode and ``None`` on a failed one (an object that passed through
        the goal and left it did not reach it).
    """
    in_goal = trace["in_goal"]
    reached = np.flatnonzero(in_goal)
    executed = [d for d in decisions if d.action >= 0]
    planning_ms = [d.planning_ms for d in decisions]
    names = solution.model.pomdp.actions
    sim_s = float(trace["time_s"][-1])
    return {
        "success": bool(in_goal[-1]),
        "stop_reason": stop,
        "steps": len(executed),
        "time_to_goal_s": (float(trace["time_s"][reached[0]])
                           if len(reached) and in_goal[-1] else None),
        "final_distance_to_goal_m": float(distance_to_goal(trace["true_rel"][-1:], goal)[0]),
        "final_object_pose_hand": trace["true_rel"][-1].tolist(),
        "initial_object_pose_hand": trace["true_rel"][0].tolist(),
        "estimator_rmse_m": {"mean": float(trace["rmse_m"].mean()),
                             "final": float(trace["rmse_m"][-1])},
        "object_rotationally_symmetric": solution.model.world.object_spec.rotationally_symmetric,
        "estimator_rmse_deg": {"mean": float(np.rad2deg(trace["rmse_rad"]).mean()),
                               "final": float(np.rad2deg(trace["rmse_rad"][-1]))},
        "estimator_rmse_over_time": {"time_s": trace["time_s"][::4].tolist(),
                                     "rmse_m": trace["rmse_m"][::4].tolist(),
                                     "rmse_deg": np.rad2deg(trace["rmse_rad"][::4]).tolist()},
        "planning_ms": planning_ms,
        "planning_ms_median": float(np.median(planning_ms)) if planning_ms else None,
        "actions": [names[d.action] for d in executed],
        "phases": [d.phase for d in executed],
        "infeasible_actions": refused,
        "infeasible_rejected": sum(len(d.rejected) for d in decisions),
        "rejections": [{"time_s": d.time_s, "action": names[a], "reason": r}
                       for d in decisions for a, r in d.rejected],
        "post_contact_from_step": next((i for i, d in enumerate(executed)
                                        if d.phase == "post-contact"), None),
        "first_contact_reading_s": (float(trace["time_s"][np.argmax(trace["readings"].any(1))])
                                    if trace["readings"].any() else None),
        "sim_time_s": sim_s,
        "wall_time_s": wall_s,
        "real_time_factor": sim_s / wall_s,
        "goal_region_hand_m": goal.tolist(),
        "settings": settings_to_dict(settings),
    }
