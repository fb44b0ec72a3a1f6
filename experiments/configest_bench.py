"""``cmanip bench configest``: what a configuration-estimation update costs, and where the
time goes (issue: an MPF-Ball update on the WAM under 100 ms at n = 250).

Per arm, one simulated experiment filtered by the CPF and by MPF-Ball (n = 250): the
median update time over the run's updates, and for MPF-Ball over the updates with a
contact reading (the only ones that project) and the share of those spent projecting;
the same for MPF-Ball with the exact history dual density (``--dual-density history``) and
what evaluating that density costs at the end of the run, every reading so far weighed;
the projection's cost per seed; the root finders side by side (the thesis' gradient
descent and Levenberg-Marquardt on the same seeds: iterations, failures, time); and the
environment's signed distance per point, Drake's ``ComputeSignedDistanceToPoint`` (one
call per point) against the compiled closed forms (a batch of points), measured in the
same run.
"""

from __future__ import annotations

import time
from functools import partial

import numpy as np

from estimation.configuration.history import ReadingHistory
from estimation.configuration.lift import NormalLift
from estimation.configuration.projection import project
from experiments.configest_study import ConfigestSettings, arm_world, run_filter
from models.arms.environment import drake_signed_distance


def _timed(fn, *args, **kwargs):
    start = time.perf_counter()
    out = fn(*args, **kwargs)
    return out, time.perf_counter() - start


def bench_arm(arm: str, seed: int) -> dict:
    """The figures of one arm (times in ms unless named otherwise).

    Raises:
        ValueError: the arm file's trajectory never touches anything.
    """
    settings = ConfigestSettings(arms=(arm,))
    world = arm_world(arm, settings.process_noise_radius_rad)
    trajectory = world.simulate(rng=np.random.default_rng((seed, 0)))
    touching = trajectory.contacts[1:].any(axis=1)
    if not touching.any():
        raise ValueError(f"{arm}: the commanded trajectory never touches anything")
    cpf = run_filter(world, trajectory, "cpf", settings, rng=np.random.default_rng((seed, 1)))
    ball = run_filter(world, trajectory, "mpf-ball", settings,
                      rng=np.random.default_rng((seed, 2)))
    history_ball = run_filter(world, trajectory, "mpf-ball",
                              ConfigestSettings(arms=(arm,), dual_density="history"),
                              rng=np.random.default_rng((seed, 2)))
    stats = ball.projection
    contact_ms = ball.update_ms[touching]
    history_contact_ms = history_ball.update_ms[touching]
    # the root finders on the same seeds: the truth at the first touch, perturbed by 0.1 rad
    first = int(np.flatnonzero(trajectory.contacts.any(axis=1))[0])
    seeds = world.normalise(np.array(trajectory.q_true[first])[None] + np.random.default_rng(
        (seed, 3)).normal(0.0, 0.1, (250, world.dof)))
    active = np.flatnonzero(trajectory.contacts[first])
    finders = {}
    for method in ("gd", "lm"):
        result, seconds = _timed(project, world, seeds, active, method=method)
        finders[method] = {"ms_per_seed": seconds * 1e3 / len(seeds),
                           "iterations_mean": float(result.iterations.mean()),
                           "failure_rate": float(1.0 - result.success.mean())}
    # the history density of n_d duals at the last step, every reading of the run recorded
    commanded = np.cumsum(trajectory.commanded, axis=0)
    history = ReadingHistory.begin(trajectory.encoders[0], np.zeros(world.dof),
                                   world.sensor_count)
    for t in range(len(commanded) - 1):
        history = history.appended(commanded[t], trajectory.contacts[t + 1])
    duals = seeds[:settings.dual_particles]
    history.log_density(world, duals, commanded[-1])  # compiled before timing
    _, history_s = _timed(history.log_density, world, duals, commanded[-1])
    # the normal lift of the same number of duals, projected onto the first touch's manifold
    lift = NormalLift(world)
    surface = project(world, duals, active).states
    _, path_s = _timed(lift.path, surface, active)
    density = partial(history.log_density, world, commanded=commanded[-1])
    _, surface_density_s = _timed(density, surface)
    _, lift_s = _timed(lift, surface, trajectory.contacts[first], density)
    # signed distance: Drake per point against the compiled batch
    centres, _ = world.chain.centers(seeds[:20])
    points = centres.reshape(-1, 3)
    scene_graph = world.model.diagram.scene_graph()
    world.model.diagram.plant().SetPositions(world.plant_context, world.model.q_default)
    query = scene_graph.get_query_output_port().Eval(
        scene_graph.GetMyContextFromRoot(world.context))
    ids = set(world.model.environment_ids)
    _, drake_s = _timed(lambda: [drake_signed_distance(query, ids, p) for p in points])
    world.environment.signed_distance(points)  # compiled before timing
    _, batch_s = _timed(world.environment.signed_distance, points)
    return {
        "cpf_update_ms": float(np.median(cpf.update_ms)),
        "mpf_ball_update_ms": float(np.median(ball.update_ms)),
        "mpf_ball_contact_update_ms": float(np.median(contact_ms)),
        "mpf_ball_contact_update_ms_p90": float(np.percentile(contact_ms, 90)),
        "projection_share_of_contact_updates": float(stats.seconds * 1e3 / contact_ms.sum()),
        "mpf_ball_history_update_ms": float(np.median(history_ball.update_ms)),
        "mpf_ball_history_contact_update_ms": float(np.median(history_contact_ms)),
        "mpf_ball_history_contact_update_ms_p90": float(np.percentile(history_contact_ms, 90)),
        "history_density_ms_last_step": history_s * 1e3,
        "history_density_steps": len(history.readings),
        "lift_ms_last_step": lift_s * 1e3,
        "lift_path_ms_last_step": path_s * 1e3,
        "lift_cost_ratio_to_density": lift_s / surface_density_s,
        "projection_ms_per_seed": float(stats.seconds * 1e3 / max(stats.seeds, 1)),
        "projection_iterations_per_seed": stats.iterations / max(stats.seeds, 1),
        "projection_failure_rate": stats.failure_rate,
        "projection_short_draws": stats.short_draws,
        "root_finders": finders,
        "drake_signed_distance_us_per_point": drake_s * 1e6 / len(points),
        "compiled_signed_distance_us_per_point": batch_s * 1e6 / len(points),
        "signed_distance_speedup": drake_s / batch_s,
        "updates": len(ball.update_ms), "contact_updates": int(touching.sum()),
    }


def run_configest_bench(arms: tuple[str, ...], *, seed: int = 0) -> dict:
    """``{arm: {...}}`` for every arm, printed as it goes."""
    report = {}
    for arm in arms:
        report[arm] = entry = bench_arm(arm, seed)
        print(f"{arm}: CPF {entry['cpf_update_ms']:.1f} ms/update, MPF-Ball "
              f"{entry['mpf_ball_update_ms']:.1f} ms/update "
              f"({entry['mpf_ball_contact_update_ms']:.1f} ms with contact, "
              f"{entry['projection_share_of_contact_updates']:.0%} projecting); with the "
              f"history density {entry['mpf_ball_history_contact_update_ms']:.1f} ms with "
              f"contact ({entry['history_density_ms_last_step']:.1f} ms for the density at "
              f"step {entry['history_density_steps']}; the normal lift "
              f"{entry['lift_ms_last_step']:.1f} ms there, "
              f"{entry['lift_cost_ratio_to_density']:.1f} x the density); "
              f"signed distance {entry['drake_signed_distance_us_per_point']:.1f} us/point "
              f"in Drake, {entry['compiled_signed_distance_us_per_point']:.2f} compiled; "
              f"GD {entry['root_finders']['gd']['ms_per_seed']:.2f} ms/seed "
              f"({entry['root_finders']['gd']['failure_rate']:.0%} fail), LM "
              f"{entry['root_finders']['lm']['ms_per_seed']:.2f} ms/seed "
              f"({entry['root_finders']['lm']['failure_rate']:.0%} fail)", flush=True)
    return report
