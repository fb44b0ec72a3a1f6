"""``cmanip bench pomdp``: the point-based solver on Tag and RockSample(7,8), and what the
hand-relative planning problem costs.

Reports the bounds at the initial belief after 10, 30, 60, 150 and 300 s (``quick``: up
to 30 s) and the simulated discounted value of the final policy, acting by one-step
lookahead on the lower bound (mean and 95 % half-width over ``episodes`` episodes of
``horizon`` steps). For reference, the C++ SARSOP measured on this machine (issue 4),
single-threaded: Tag lower bound -6.16 after 300 s (policy about -5.96); RockSample(7,8)
lower bound 20.82 at 10 s, 21.11 at 60 s, 21.17 at 150 s (policy about 21.8). Our solver
shares each node's actions among numba's threads (both cores here; the report says how
many).

The hand-relative problem (``hand``, thesis sec. 6.4.2): time to build the Monte Carlo
model, to solve QMDP and to run the point-based solver for 60 s (``quick``: 10 s), and the
median time per step of each policy: choosing an action and the discrete Bayes filter
update (thesis: QMDP 7.64 ms and SARSOP 7.62 ms per evaluation). The POMDP policy's time is
also given as a ratio to QMDP's, measured in the same run.
"""

from __future__ import annotations

import itertools
import time

import numba
import numpy as np

from experiments.timing import median_ms
from models.planar.world import PlanarWorld
from planning.hand.beliefs import belief_points
from planning.hand.discretization import HandProblemSpec
from planning.hand.model import build_hand_pomdp
from planning.hand.policy import qmdp_vectors
from planning.pomdp.benchmarks import rock_sample, tag
from planning.pomdp.point_based import LookaheadPolicy, PointBasedSolver
from planning.pomdp.qmdp import solve_mdp
from planning.pomdp.tabular import belief_update, simulate_value

CHECKPOINTS_S = (10, 30, 60, 150, 300)


def run_pomdp_bench(*, quick: bool = False, episodes: int = 200, horizon: int = 100,
                    seed: int = 0, trial_rule: str = "sarsop") -> dict:
    """Solve each problem for the longest checkpoint; print and return the report.
    ``trial_rule`` is the solver's (``"hsvi"``: HSVI2's, for the comparison)."""
    checkpoints = [c for c in CHECKPOINTS_S if not quick or c <= 30]
    report = {}
    for name, build in (("tag", tag), ("rocksample_7_8", rock_sample)):
        model = build()
        start = time.perf_counter()
        solver = PointBasedSolver(model, trial_rule=trial_rule)
        setup_s = time.perf_counter() - start

        shown = [-np.inf]

        def show(elapsed, lower, upper, trials, name=name, shown=shown):
            if elapsed - shown[0] >= 10.0:
                shown[0] = elapsed
                print(f"  {name:15s} {elapsed:7.1f} s  lower {lower:9.3f}  upper {upper:9.3f}",
                      flush=True)

        # bounds recorded every second, so each checkpoint reads the bound of its time
        policy = solver.solve(max(checkpoints), report_every=1.0, callback=show)
        value, half = simulate_value(model, LookaheadPolicy(model, policy), episodes, horizon,
                                     rng=np.random.default_rng(seed))
        bounds = {str(c): solver.report.at(c) for c in checkpoints}
        report[name] = {
            "lower_bound": {k: v[0] for k, v in bounds.items()},
            "upper_bound": {k: v[1] for k, v in bounds.items()},
            "simulated_value": value, "simulated_value_ci95": half,
            "setup_s": setup_s, "trials": solver.report.trials,
            "beliefs_expanded": solver.report.nodes, "backups": solver.report.backups,
            "alpha_vectors": solver.report.alpha_count,
            "upper_points": solver.report.upper_points,
        }
        print(f"{name}: " + ", ".join(f"{k} s: [{lo:.3f}, {up:.3f}]"
                                      for k, (lo, up) in bounds.items())
              + f"; policy simulates at {value:.2f} +- {half:.2f}")
    report["hand"] = hand_problem_bench(quick=quick, seed=seed)
    report["settings"] = {"episodes": episodes, "horizon": horizon, "seed": seed,
                          "checkpoints_s": checkpoints, "trial_rule": trial_rule,
                          "numba_threads": numba.config.NUMBA_NUM_THREADS}
    return report


def hand_problem_bench(*, quick: bool = False, seed: int = 0, repeats: int = 200,
                       spec: HandProblemSpec | None = None,
                       solve_seconds: float | None = None) -> dict:
    """Model building, solving and per-step policy times on the hand-relative problem
    (``spec`` and ``solve_seconds`` override the defaults, for tests)."""
    rng = np.random.default_rng(seed)
    world = PlanarWorld.load("small_box", sensors="fingertips")
    model = build_hand_pomdp(world, spec or HandProblemSpec(), rng=rng, progress=False)
    start = time.perf_counter()
    Q = solve_mdp(model.pomdp)
    qmdp_s = time.perf_counter() - start
    beliefs = np.array([model.belief(b.sample(world, 2000, rng=rng))
                        for b in belief_points(rng=rng)])
    solver = PointBasedSolver(model.pomdp)
    budget = solve_seconds or (10.0 if quick else 60.0)
    start = time.perf_counter()
    policy = solver.solve(budget, initial_beliefs=beliefs)
    solve_s = time.perf_counter() - start
    policies = {"qmdp": qmdp_vectors(Q, model.pomdp.actions), "pomdp": policy}
    cycle = itertools.cycle(beliefs)
    act_ms = {name: median_ms(lambda p=p: p.act(next(cycle)), repeats)
              for name, p in policies.items()}
    actions = itertools.cycle(range(len(model.pomdp.actions)))
    update_ms = median_ms(lambda: belief_update(model.pomdp, next(cycle), next(actions), 0),
                          repeats)
    lower, upper = solver.report.history[-1][1:]
    out = {
        "states": len(model.pomdp.states), "free_states": model.free_count,
        "contact_states": model.contact_count, "build_s": model.build_seconds,
        "qmdp_solve_s": qmdp_s, "pomdp_solve_s": solve_s, "lower_bound": lower,
        "upper_bound": upper, "alpha_vectors": len(policy.alphas),
        "qmdp_act_ms": act_ms["qmdp"], "pomdp_act_ms": act_ms["pomdp"],
        "pomdp_to_qmdp_act_ratio": act_ms["pomdp"] / act_ms["qmdp"],
        "belief_update_ms": update_ms,
    }
    print(f"hand: {out['states']} states ({out['free_states']} free, {out['contact_states']} "
          f"contact); built in {out['build_s']:.1f} s; QMDP solved in {qmdp_s:.2f} s; "
          f"point-based {solve_s:.0f} s -> [{lower:.3f}, {upper:.3f}], "
          f"{out['alpha_vectors']} alpha-vectors; per step: QMDP act {act_ms['qmdp']:.3f} ms, "
          f"POMDP act {act_ms['pomdp']:.3f} ms ({out['pomdp_to_qmdp_act_ratio']:.1f}x), "
          f"Bayes update {out['belief_update_ms']:.3f} ms")
    return out
