"""``cmanip bench latdespot``: Lat-DESPOT's decisions on the Python and the compiled DESPOT
engine, side by side.

The study's Lat-DESPOT (:mod:`experiments.latdespot_scenes`: the ch. 7 problem, a scene's
discrete Lat-POMDP, Rel-QMDP above, Lift-QMDP rollouts below, K and D of the study, a trial
budget per decision) plans ``decisions`` times along episodes on the discrete model: at
each decision both engines search from the same scenarios (the same seed), the compiled
engine's action is executed, and the discrete belief is updated. The lattice is evaluated
in full first (every edge and contact row, as the lazy lattice would end up after many
episodes), so the times are the searches' own; on a cold lattice each engine pays the
same 1.4 ms of Drake collision checking per new edge on top. Reported per engine: decision
time p50/p99 (ms) and nodes per decision; the ratio of the medians; and how often the two
chose the same action and built trees of the same size (they build the same tree, up to
rounding in the order of sums).
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np
from tqdm import tqdm

from experiments.latdespot_scenes import SceneSettings, scene_lat_pomdp
from experiments.latdespot_study import RelSettings
from planning.lattice.planners import LatDespotPlanner
from planning.pomdp.despot import DespotSettings
from planning.pomdp.tabular import belief_update

ENGINES = ("python", "compiled")


def run_latdespot_bench(scene: str = "cul_de_sac", *, decisions: int = 60,
                        trials: int = 30, horizon: int = 30, seed: int = 0,
                        cache_dir: str | None = "out/cache", progress: bool = True) -> dict:
    """See the module docstring; episodes of at most ``horizon`` decisions until
    ``decisions`` have been timed."""
    rel = RelSettings()
    lat = scene_lat_pomdp(scene, rel, SceneSettings(cache_dir=cache_dir), progress=progress)
    model, lattice = lat.model, lat.lattice
    start = time.perf_counter()
    points, actions = np.divmod(np.arange(lattice.status.size), lattice.status.shape[1])
    lattice.feasible(points, actions)
    lat.cells_touch(np.arange(lattice.spec.size), np.zeros(lattice.spec.size, dtype=np.int64))
    warm_s = time.perf_counter() - start
    settings = DespotSettings(scenarios=rel.despot_scenarios, depth=rel.despot_depth,
                              max_trials=trials, seconds=60.0)
    planners = {engine: LatDespotPlanner(lat, replace(settings, engine=engine))
                for engine in ENGINES}
    initial = lat.model.belief(lat.initial.sample(model.world, rel.belief_particles,
                                                  rng=np.random.default_rng([seed, 1])))
    initial = lat.free_at_start(initial)
    times = {engine: [] for engine in ENGINES}
    nodes = {engine: [] for engine in ENGINES}
    same_action, same_nodes = 0, 0
    bar = tqdm(total=decisions, desc=f"Lat-DESPOT engines, {scene}", disable=not progress)
    episode = 0
    while len(times["compiled"]) < decisions:
        rng = np.random.default_rng([seed, 2, episode])
        cell = rng.choice(len(initial), p=initial)
        state = lat.with_point(lattice.start_point, np.array([[cell]]))
        belief = initial.copy()
        for _ in range(horizon):
            if len(times["compiled"]) >= decisions:
                break
            cells = rng.choice(len(belief), size=rel.despot_particles, p=belief)[:, None]
            key = int(rng.integers(2**31))
            chosen = {}
            for engine in ENGINES:
                result = planners[engine].plan(cells, rng=np.random.default_rng(key),
                                               point=int(state[0, 0]))
                times[engine].append(result.planning_ms)
                nodes[engine].append(result.stats["nodes"])
                chosen[engine] = result.action
            same_action += chosen["python"] == chosen["compiled"]
            same_nodes += nodes["python"][-1] == nodes["compiled"][-1]
            step = lat.step(state, chosen["compiled"], rng.random((1, lat.uniforms_per_step)))
            belief, _ = belief_update(model.pomdp, belief, chosen["compiled"],
                                      int(step.observations[0]))
            state = step.next_states
            bar.update()
            if step.terminal[0]:
                break
        episode += 1
    bar.close()
    report = {"scene": scene, "decisions": decisions, "trials_per_decision": trials,
              "scenarios": rel.despot_scenarios, "depth": rel.despot_depth,
              "episodes": episode, "lattice_warm_up_s": warm_s}
    for engine in ENGINES:
        ms = np.array(times[engine])
        report[engine] = {"decision_ms_p50": float(np.median(ms)),
                          "decision_ms_p99": float(np.percentile(ms, 99)),
                          "nodes_median": float(np.median(nodes[engine]))}
    report["speedup_p50"] = (report["python"]["decision_ms_p50"]
                             / report["compiled"]["decision_ms_p50"])
    report["same_action_fraction"] = same_action / decisions
    report["same_tree_size_fraction"] = same_nodes / decisions
    print(f"Lat-DESPOT on {scene}, {decisions} decisions of {trials} trials: python p50 "
          f"{report['python']['decision_ms_p50']:.1f} ms (p99 "
          f"{report['python']['decision_ms_p99']:.1f}), compiled p50 "
          f"{report['compiled']['decision_ms_p50']:.1f} ms (p99 "
          f"{report['compiled']['decision_ms_p99']:.1f}): {report['speedup_p50']:.1f}x; "
          f"same action {same_action}/{decisions}, same tree size {same_nodes}/{decisions}")
    return report
