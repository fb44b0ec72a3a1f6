"""``cmanip experiment pushval``: the planar pushing model against Drake's hydroelastic
simulation of the same straight pushes.

Cases: the box starts ``gap`` ahead of the fingertips at lateral offsets and orientations
of a grid (default 5 x 4 = 20 cases); HERB's hand pushes it straight for
``push_distance_m``. Drake simulates the whole arm, hand and box on the table
(:func:`diagrams.herb.straight_push.run_straight_push`); the planar model pushes the box with
the friction coefficient Drake uses between hand and box (Drake's combination
``2 mu_h mu_o / (mu_h + mu_o)``) and the limit-surface radius ``c`` of a uniform pressure
over the box's footprint (the mean distance of the footprint from its centre). Reported
per case: the box's final pose relative to the palm in both, their difference, and
whether the rotation direction agrees (same sign, or both turned less than
``still_deg``). Each case is one trial of :mod:`experiments.runner` (any backend; kept in
``trials.jsonl``, so a killed run resumes).
"""

from __future__ import annotations

import json
from dataclasses import replace
from functools import lru_cache
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from experiments.runner import Backend, Job, TrialStore, map_trials  # noqa: E402
from models.contact import HAND_MATERIAL  # noqa: E402
from models.herb.scene import PlanarPose, SceneSpec  # noqa: E402
from models.herb.tactile import TactileLayout, TactileNoise  # noqa: E402
from models.planar.polygon import signed_distances  # noqa: E402
from models.planar.pushing import PushingParameters  # noqa: E402
from models.planar.world import PlanarWorld  # noqa: E402
from models.pose import wrap_angle  # noqa: E402
from models.se2 import compose, inverse  # noqa: E402

LATERAL_OFFSETS_M = (-0.06, -0.03, 0.0, 0.03, 0.06)
ORIENTATIONS_DEG = (0.0, 20.0, -35.0, 60.0)


def uniform_pressure_radius(outline: np.ndarray, samples: int = 200_000,
                            seed: int = 0) -> float:
    """c (m): mean distance of a convex footprint (V, 2) from its centroid (Monte Carlo)."""
    rng = np.random.default_rng(seed)
    lo, hi = outline.min(0), outline.max(0)
    p = lo + (hi - lo) * rng.random((samples, 2))
    edges = np.roll(outline, -1, axis=0) - outline
    rel = p[:, None, :] - outline[None]
    inside = np.all(edges[None, :, 0] * rel[..., 1] - edges[None, :, 1] * rel[..., 0] >= 0, 1)
    return float(np.linalg.norm(p[inside], axis=1).mean())


def combined_friction(mu_a: float, mu_b: float) -> float:
    """Drake's combination of two Coulomb coefficients."""
    return 2 * mu_a * mu_b / (mu_a + mu_b)


@lru_cache(maxsize=2)
def _planar_model(scene_name: str) -> tuple[SceneSpec, PlanarWorld, float, float]:
    """The scene, the planar world pushing with Drake's friction and the footprint's
    uniform-pressure radius, the friction mu and c (m); built once per process."""
    scene = SceneSpec.load(scene_name)
    mu = combined_friction(HAND_MATERIAL.mu_dynamic, scene.object.material.mu_dynamic)
    c = uniform_pressure_radius(scene.object.footprint())
    world = PlanarWorld.load(scene.object.source or scene.object.name, "medium",
                             pushing=PushingParameters(mu_mean=mu, mu_std=0.0, c_mean_m=c,
                                                       c_std_m=0.0))
    return scene, world, mu, c


def push_case(lateral: float, theta_deg: float, push_distance_m: float, gap_m: float,
              still_deg: float, seed: int) -> dict:
    """One case (a trial of the runner): the box ``gap_m`` ahead of the fingertips at
    lateral offset ``lateral`` (m) and orientation ``theta_deg``, pushed straight for
    ``push_distance_m`` in Drake and by the planar model; the final poses in the hand's
    frame, their difference and whether the rotation direction agrees."""
    from diagrams.herb.straight_push import run_straight_push

    scene, world, _, _ = _planar_model("empty")
    hand = scene.hand_start.as_array()
    theta = np.deg2rad(theta_deg)
    start = _start_with_gap(world, lateral, theta, gap_m)
    object_world = compose(hand, start)
    case_scene = replace(scene, object_pose=PlanarPose(*object_world))
    outcome = run_straight_push(case_scene, push_distance_m, layout=TactileLayout(),
                                noise=TactileNoise.noiseless(), seed=seed, progress=False)
    palm_final = compose(hand, np.array([push_distance_m, 0.0, 0.0]))
    drake_rel = compose(inverse(palm_final), np.array(outcome.summary["object_final_pose"]))
    action = np.array([push_distance_m, 0.0, 0.0])
    u = np.full((1, world.uniforms_per_step(action)), 0.5)
    planar_rel = world.step(start[None], action, u)[0]
    turn_drake = float(wrap_angle(drake_rel[2] - start[2]))
    turn_planar = float(wrap_angle(planar_rel[2] - start[2]))
    agree = (np.sign(turn_drake) == np.sign(turn_planar)) or (
        max(abs(turn_drake), abs(turn_planar)) < np.deg2rad(still_deg))
    return {
        "lateral_offset_m": lateral, "orientation_deg": theta_deg,
        "start_in_hand": start.tolist(),
        "drake_final_in_hand": drake_rel.tolist(), "planar_final_in_hand": planar_rel.tolist(),
        "position_difference_m": float(np.linalg.norm(drake_rel[:2] - planar_rel[:2])),
        "rotation_drake_deg": float(np.rad2deg(turn_drake)),
        "rotation_planar_deg": float(np.rad2deg(turn_planar)),
        "rotation_direction_agrees": bool(agree),
    }


def run_push_validation(out: Path, *, push_distance_m: float = 0.15, gap_m: float = 0.02,
                        still_deg: float = 1.0, seed: int = 0, backend: Backend = Backend(),
                        resume: bool = False, progress: bool = True) -> dict:
    """Run every case in Drake and in the planar model on the trial runner (each case a
    trial, kept in ``out/trials.jsonl`` as it finishes; ``resume`` runs only the missing
    ones); write summary.json and a plot."""
    _, _, mu, c = _planar_model("empty")
    settings = {"push_distance_m": push_distance_m, "gap_m": gap_m, "still_deg": still_deg,
                "seed": seed}
    store = TrialStore(out, "pushval", settings, resume=resume)
    jobs = [Job(f"y{y:+.2f}/theta{t:+.0f}", (y, t, push_distance_m, gap_m, still_deg, seed))
            for t in ORIENTATIONS_DEG for y in LATERAL_OFFSETS_M]
    cases = map_trials(push_case, jobs, backend=backend, store=store, desc="pushes",
                       progress=progress)
    diffs = np.array([case["position_difference_m"] for case in cases])
    rot = np.array([[case["rotation_drake_deg"], case["rotation_planar_deg"]] for case in cases])
    summary = {
        "cases": cases,
        "push_distance_m": push_distance_m, "gap_m": gap_m, "mu": mu, "c_m": c,
        "position_difference_m_median": float(np.median(diffs)),
        "position_difference_m_max": float(diffs.max()),
        "rotation_difference_deg_median": float(np.median(np.abs(rot[:, 0] - rot[:, 1]))),
        "rotation_direction_agreement": int(sum(case["rotation_direction_agrees"]
                                                for case in cases)),
        "case_count": len(cases),
    }
    out.mkdir(parents=True, exist_ok=True)
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    _plot(rot, diffs, out / "push_validation.png")
    return summary


def _start_with_gap(world: PlanarWorld, lateral: float, theta: float,
                    gap_m: float) -> np.ndarray:
    """The box at ``lateral``/``theta`` and the x (1 mm grid) where it is ``gap_m`` ahead of
    the hand."""
    xs = np.arange(0.4, 0.0, -0.001)
    states = np.column_stack([xs, np.full_like(xs, lateral), np.full_like(xs, theta)])
    d = signed_distances(world.hand.parts, world.shape, states, exact_within=1.0).min(axis=1)
    return states[int(np.argmax(d <= gap_m))]


def _plot(rot: np.ndarray, diffs: np.ndarray, path: Path) -> None:
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    lim = np.abs(rot).max() * 1.1 + 1
    axes[0].scatter(rot[:, 0], rot[:, 1])
    axes[0].plot([-lim, lim], [-lim, lim], "k:", lw=0.8)
    axes[0].axhline(0, color="k", lw=0.5)
    axes[0].axvline(0, color="k", lw=0.5)
    axes[0].set_xlabel("box rotation, Drake (deg)")
    axes[0].set_ylabel("box rotation, planar model (deg)")
    axes[1].bar(np.arange(len(diffs)), diffs * 100)
    axes[1].set_xlabel("case")
    axes[1].set_ylabel("final position difference (cm)")
    fig.suptitle("planar pushing model vs Drake hydroelastic simulation")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
