"""``cmanip experiment handplan``: planning by touch, hand-relative (thesis sec. 6.4).

Parts:

- ``post-contact`` (Fig. 6.5a, b; H1, H2): QMDP and the point-based (POMDP) post-contact
  policy, from the 15 Gaussian belief points 20 cm ahead. Value on the discrete model
  (``2 x trials`` episodes, as the thesis' 1000 vs 500) and success on the continuous
  planar model (``trials`` episodes).
- ``full`` (Fig. 6.5c; H3, H4): the same beliefs 50 cm ahead, outside the trust region:
  the weighted A* pre-contact trajectory, then the post-contact policy.
- ``coverage`` (Fig. 6.6; H5, H6): fingertip sensors against every link a sensor, for
  both policies, post-contact and full; with the count of geometrically feasible
  observations on the analytic contact manifold (thesis: 10 of 128 with seven links).
- ``all``: every part (the fingertip model is built and solved once).

Every trial ``j`` starts from belief point ``j mod 15``; random streams are keyed by
(seed, part, policy, trial), so results do not depend on the order of evaluation.
Writes ``summary.json`` (per policy ``success_rate`` with its 95 % Wilson interval,
``discounted_value`` with its 95 % half-width, success over time), PNG plots, the
policies (``.npz``) and the fingertip model in Cassandra's ``.pomdp`` format.

The continuous-model evaluations run on the trial runner (:mod:`experiments.runner`), one
job per (part, sensors, policy): within a job all ``trials`` episodes advance in lockstep,
the true objects pushed in one batch per action (the vectorisation over trials that makes
them cheap), so a job is the unit that runs on a worker and is kept in ``trials.jsonl``
when it finishes. Workers rebuild the model from the settings and load the solved
policies from the study's directory; ``resume`` reuses those policies (not solved again)
and the finished jobs.
"""

from __future__ import annotations

import json
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np
from tqdm import tqdm

from estimation.hand.manifolds import AnalyticManifold
from experiments.runner import Backend, Job, TrialStore, map_trials
from experiments.statistics import half_width, wilson_interval
from experiments.timing import median_ms
from models.planar.world import PlanarWorld
from models.settings import check_ranges
from planning.hand.beliefs import (
    POST_CONTACT_DISTANCE_M,
    PRE_CONTACT_DISTANCE_M,
    GaussianBelief,
    belief_points,
)
from planning.hand.discretization import HandProblemSpec
from planning.hand.model import HandPOMDP, build_hand_pomdp
from planning.hand.policy import HandPolicy, qmdp_vectors
from planning.hand.precontact import PreContactPlan, PreContactPlanner, PreContactSettings
from planning.hand.solution import SOLVE_SECONDS_CEILING
from planning.pomdp.cassandra import write_pomdp
from planning.pomdp.point_based import AlphaVectorPolicy, PointBasedSolver
from planning.pomdp.progress import SolverProgressBar
from planning.pomdp.qmdp import solve_mdp
from planning.pomdp.tabular import simulate_returns

PARTS = ("post-contact", "full", "coverage", "all")
POLICIES = ("QMDP", "POMDP")


@dataclass(frozen=True)
class HandplanSettings:
    """Attributes:
        trials: continuous-model episodes per policy (the discrete model gets twice as many).
        seed: master seed.
        solve_seconds: point-based solver budget (s; the thesis ran SARSOP 5 min).
        solve_trials: also stop the solver after this many search trials; set it for
            results that do not depend on the machine's speed.
        horizon: post-contact episode length (steps; Fig. 6.5a's depth 50). The full policy
            gets 15 more steps for its 30 cm longer way.
        belief_count: number of Gaussian belief points (thesis: 15).
        belief_particles: particles that discretise a Gaussian belief.
        precontact_particles: particles of the pre-contact search and its filter.
        precontact: the A* settings.
        object_name: the pushed object (thesis: the 3.5 cm x 5 cm box).
        spec: the discretisation and reward parameters.
    """

    trials: int = 200
    seed: int = 0
    solve_seconds: float = 300.0
    solve_trials: int | None = None
    horizon: int = 50
    belief_count: int = 15
    belief_particles: int = 3000
    precontact_particles: int = 300
    precontact: PreContactSettings = field(default_factory=PreContactSettings)
    object_name: str = "small_box"
    spec: HandProblemSpec = field(default_factory=HandProblemSpec)

    def __post_init__(self):
        if self.trials < 1 or self.horizon < 1 or self.belief_count < 1:
            raise ValueError("trials, horizon and belief_count must be >= 1")
        if self.solve_seconds <= 0:
            raise ValueError("solve_seconds must be > 0")
        check_ranges(self, counts=("belief_particles", "precontact_particles", "solve_trials"),
                     at_most={"solve_seconds": SOLVE_SECONDS_CEILING})


@dataclass
class SolvedProblem:
    """A model with both post-contact policies, the discrete belief points they were
    solved for ((K, S)), and what they cost."""

    model: HandPOMDP
    initial: np.ndarray
    policies: dict[str, AlphaVectorPolicy]
    timings: dict[str, float]
    bounds: list[tuple[float, float, float]]


def _rng(settings: HandplanSettings, *key: int) -> np.random.Generator:
    return np.random.default_rng([settings.seed, *key])


def _stream(name: str) -> int:
    return sum((i + 1) * ord(c) for i, c in enumerate(name))


def near_and_far(settings: HandplanSettings) -> tuple[list[GaussianBelief],
                                                     list[GaussianBelief]]:
    """The belief points 20 cm ahead (post-contact) and the same 50 cm ahead (full)."""
    near = belief_points(settings.belief_count, POST_CONTACT_DISTANCE_M, rng=_rng(settings, 3))
    far = [GaussianBelief((PRE_CONTACT_DISTANCE_M, *b.mean[1:]), b.std) for b in near]
    return near, far


def build_model(settings: HandplanSettings, sensors: str) -> HandPOMDP:
    world = PlanarWorld.load(settings.object_name, sensors=sensors)
    return build_hand_pomdp(world, settings.spec, rng=_rng(settings, _stream(sensors)))


def policy_path(out: Path, sensors: str, name: str) -> Path:
    return Path(out) / f"policy_{sensors}_{name.lower()}.npz"


def solve_problem(settings: HandplanSettings, sensors: str, beliefs: list[GaussianBelief], *,
                  kept: Path | None = None) -> SolvedProblem:
    """Build the model for ``sensors`` and solve QMDP and the point-based policy (or, with
    ``kept``, load the point-based policy a resumed study saved there)."""
    model = build_model(settings, sensors)
    start = time.perf_counter()
    Q = solve_mdp(model.pomdp)
    qmdp_s = time.perf_counter() - start
    initial = discretise(model, beliefs, settings)
    history: list = []
    saved = None if kept is None else policy_path(kept, sensors, "POMDP")
    if saved is not None and saved.is_file():
        pomdp_policy, solve_s = AlphaVectorPolicy.load(saved), None
    else:
        solver = PointBasedSolver(model.pomdp)
        bar = SolverProgressBar(settings.solve_seconds, settings.solve_trials,
                                desc=f"point-based solver ({sensors})")
        start = time.perf_counter()
        pomdp_policy = solver.solve(settings.solve_seconds, initial_beliefs=initial,
                                    callback=bar, max_trials=settings.solve_trials)
        bar.close()
        solve_s = time.perf_counter() - start
        history = list(solver.report.history)
    policies = {"QMDP": qmdp_vectors(Q, model.pomdp.actions), "POMDP": pomdp_policy}
    timings = {"build_s": model.build_seconds, "qmdp_solve_s": qmdp_s,
               "pomdp_solve_s": solve_s}
    for name, policy in policies.items():
        timings[f"{name.lower()}_act_ms"] = median_ms(lambda p=policy: p.act(initial[0]), 20)
    return SolvedProblem(model, initial, policies, timings, history)


def discretise(model: HandPOMDP, beliefs: list[GaussianBelief],
               settings: HandplanSettings) -> np.ndarray:
    """(K, S) discrete versions of the Gaussian beliefs (histograms of their samples)."""
    return np.array([model.belief(b.sample(model.world, settings.belief_particles,
                                           rng=_rng(settings, 7, i)))
                     for i, b in enumerate(beliefs)])


def evaluate_discrete(problem: SolvedProblem, settings: HandplanSettings, *,
                      episodes: int | None = None) -> dict[str, dict]:
    """H1: discounted value of each policy on the discrete model, over ``episodes``
    episodes (default ``2 x trials``, as the thesis' 1000 against 500 in ch. 6)."""
    out = {}
    for name, policy in problem.policies.items():
        returns = simulate_returns(problem.model.pomdp, policy, problem.initial,
                                   episodes or 2 * settings.trials, settings.horizon,
                                   rng=_rng(settings, 11, _stream(name)),
                                   progress=f"value on the discrete model, {name}")
        out[name] = {"discounted_value": float(returns.mean()),
                     "discounted_value_ci95": half_width(returns),
                     "episodes": len(returns)}
    return out


def continuous_batch(problem: SolvedProblem, name: str, beliefs: list[GaussianBelief],
                     settings: HandplanSettings, *, precontact: bool, label: str) -> dict:
    """H2 (and H3, H4 with ``precontact``): policy ``name`` on the continuous planar model,
    ``trials`` episodes. Without ``precontact``, ``beliefs`` are the problem's own belief
    points and the policy starts from their discrete versions (``problem.initial``).

    All trials advance together: the true objects are pushed in one batch per action, and
    each trial's policy updates its own belief from its own reading.
    """
    model, world = problem.model, problem.model.world
    vectors = problem.policies[name]
    horizon = settings.horizon + (15 if precontact else 0)
    planner = PreContactPlanner(model, vectors, settings.precontact) if precontact else None
    plans: dict[int, PreContactPlan] = {}
    trials = settings.trials
    rngs = [_rng(settings, 13, _stream(label + name), j) for j in range(trials)]
    states = np.vstack([beliefs[j % len(beliefs)].sample(world, 1, rng=rngs[j])
                        for j in range(trials)])
    policies = []
    for j in tqdm(range(trials), desc=f"{label} {name}: start", unit="trial", leave=False):
        k = j % len(beliefs)
        policy = HandPolicy(model, vectors, planner)
        if precontact:
            particles = beliefs[k].sample(world, settings.precontact_particles, rng=rngs[j])
            if k not in plans:
                plans[k] = planner.plan(particles, rng=_rng(settings, 17, k))
            policy.reset(particles, plan=plans[k], rng=rngs[j])
        else:
            policy.reset(problem.initial[k], rng=rngs[j])
        policies.append(policy)
    success = np.zeros((horizon + 1, trials), dtype=bool)
    success[0] = model.in_goal(states)
    returns = np.zeros(trials)
    actions_vec = settings.spec.action_vectors()
    for t in tqdm(range(horizon), desc=f"{label} {name}", unit="step", leave=False):
        actions = np.array([p.act() for p in policies])
        returns -= settings.spec.discount ** t * (~model.in_goal(states))
        for a in np.unique(actions):
            sel = np.flatnonzero(actions == a)
            u = np.vstack([rngs[j].random(world.uniforms_per_step(actions_vec[a]))
                           for j in sel])
            states[sel] = world.step(states[sel], actions_vec[a], u)
        u_obs = np.vstack([rngs[j].random(2) for j in range(trials)])
        readings = world.sample_observation(states, u_obs)
        for j, policy in enumerate(policies):
            policy.observe(int(actions[j]), readings[j], rng=rngs[j])
        success[t + 1] = model.in_goal(states)
    rate = success.mean(axis=1)
    lo, hi = wilson_interval(success[-1].sum(), trials)
    out = {
        "success_rate": float(rate[-1]), "success_rate_ci95": [lo, hi],
        "success_over_time": rate.tolist(),
        "discounted_value": float(returns.mean()),
        "discounted_value_ci95": half_width(returns),
        "trials": trials,
    }
    if precontact:
        out["plans"] = {str(k): {"actions": list(p.actions), "reason": p.reason,
                                 "expansions": p.expansions, "seconds": p.seconds}
                        for k, p in sorted(plans.items())}
    return out


_PROBLEMS: dict[tuple, SolvedProblem] = {}
"""This process' problems, keyed by (settings, sensors, the policies' file and its version);
the study's own process registers the ones it solved, so a serial run builds nothing
twice."""


def _problem_key(settings: HandplanSettings, sensors: str, directory: str) -> tuple:
    path = policy_path(Path(directory), sensors, "POMDP")
    return settings, sensors, str(path), path.stat().st_mtime_ns


def _worker_problem(settings: HandplanSettings, sensors: str, directory: str) -> SolvedProblem:
    """A worker's problem: the model rebuilt from the settings (deterministic), the
    policies loaded from the study's directory."""
    key = _problem_key(settings, sensors, directory)
    if key not in _PROBLEMS:
        model = build_model(settings, sensors)
        initial = discretise(model, near_and_far(settings)[0], settings)
        policies = {name: AlphaVectorPolicy.load(policy_path(Path(directory), sensors, name))
                    for name in POLICIES}
        _PROBLEMS.clear()  # one study at a time
        _PROBLEMS[key] = SolvedProblem(model, initial, policies, {}, [])
    return _PROBLEMS[key]


def continuous_job(settings: HandplanSettings, sensors: str, directory: str, name: str,
                   precontact: bool, label: str) -> dict:
    """One (part, sensors, policy) evaluation, in whichever process the runner chose."""
    problem = _worker_problem(settings, sensors, directory)
    near, far = near_and_far(settings)
    return continuous_batch(problem, name, far if precontact else near, settings,
                            precontact=precontact, label=label)


def feasible_observations(sensors: str, settings: HandplanSettings) -> dict[str, int]:
    """How many of the 2^S - 1 contact readings (some sensor fires) a contact state produces
    without noise, on the analytic manifold (iso-contours every 1.15 deg, 1 mm pieces);
    the thesis counts 3 with fingertip sensors and 10 of 2^7 = 128 with seven links."""
    world = PlanarWorld.load(settings.object_name, sensors=sensors)
    keys = np.unique(AnalyticManifold(world).keys)
    keys = keys[keys > 0]
    return {"sensors": world.sensor_count, "possible": 2 ** world.sensor_count - 1,
            "feasible": int(len(keys)), "feasible_keys": keys.tolist()}


def run_study(part: str, settings: HandplanSettings, out: Path, *,
              backend: Backend = Backend(), resume: bool = False,
              progress: bool = True) -> dict:
    """Run ``part`` (see the module docstring); write summary.json and the plots. The
    continuous-model evaluations run on ``backend``, each kept in ``out/trials.jsonl``;
    ``resume`` reuses the policies saved in ``out`` and the finished evaluations."""
    from experiments.handplan_plots import plot_coverage, plot_problem, plot_results

    if part not in PARTS:
        raise ValueError(f"part must be one of {PARTS}, got {part!r}")
    out.mkdir(parents=True, exist_ok=True)
    near, far = near_and_far(settings)
    summary: dict = {"part": part, "settings": _settings_dict(settings),
                     "belief_means": [list(b.mean) for b in near]}
    sensor_sets = (("fingertips",) if part in ("post-contact", "full")
                   else ("fingertips", "links"))
    solved: dict[str, SolvedProblem] = {}
    for sensors in sensor_sets:
        p = solved[sensors] = solve_problem(settings, sensors, near,
                                            kept=out if resume else None)
        for name, policy in p.policies.items():
            policy.save(policy_path(out, sensors, name))
        _PROBLEMS[_problem_key(settings, sensors, str(out))] = p
        summary.setdefault("models", {})[sensors] = {
            "states": len(p.model.pomdp.states), "free_states": p.model.free_count,
            "contact_states": p.model.contact_count,
            "observations": len(p.model.pomdp.observations),
            "timings": p.timings,
            "solver_bounds": p.bounds[-1][1:] if p.bounds else None,
            "solver_reused": p.timings["pomdp_solve_s"] is None,
            "alpha_vectors": len(p.policies["POMDP"].alphas)}

    # (summary path, sensors, precontact, label) of each continuous evaluation
    evaluations = []
    if part in ("post-contact", "all"):
        evaluations.append((("post_contact",), "fingertips", False, "post-contact"))
    if part in ("full", "all"):
        evaluations.append((("full",), "fingertips", True, "full"))
    if part in ("coverage", "all"):
        for sensors in ("fingertips", "links"):
            evaluations.append((("coverage", sensors, "post_contact"), sensors, False,
                                f"coverage {sensors}"))
            evaluations.append((("coverage", sensors, "full"), sensors, True,
                                f"coverage {sensors} full"))
    jobs = [Job(f"{label}/{name}", (settings, sensors, str(out), name, precontact, label))
            for _, sensors, precontact, label in evaluations for name in POLICIES]
    store = TrialStore(out, "handplan", _settings_dict(settings), resume=resume)
    results = iter(map_trials(continuous_job, jobs, backend=backend, store=store,
                              desc="handplan evaluations", progress=progress))

    if part in ("post-contact", "all"):
        p = solved["fingertips"]
        write_pomdp(p.model.pomdp, out / "hand_fingertips.pomdp")
        plot_problem(p.model, near, far, out / "problem.png")
        summary["post_contact_discrete"] = evaluate_discrete(p, settings)
    if part in ("coverage", "all"):
        summary["coverage"] = {sensors: {
            "observations": feasible_observations(sensors, settings),
            "post_contact_discrete": evaluate_discrete(solved[sensors], settings)}
            for sensors in ("fingertips", "links")}
    for path, *_ in evaluations:
        entry = summary
        for key in path[:-1]:
            entry = entry[key]
        entry[path[-1]] = {name: next(results) for name in POLICIES}
    if part in ("coverage", "all"):
        plot_coverage(summary, out / "coverage.png")
    plot_results(summary, out)
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    return summary


def _settings_dict(settings: HandplanSettings) -> dict:
    d = asdict(settings)
    d["spec"]["cell_theta_deg"] = float(np.rad2deg(d["spec"].pop("cell_theta_rad")))
    return d


def quick_settings(settings: HandplanSettings) -> HandplanSettings:
    """A small problem for tests and smoke runs (coarse cells, few samples)."""
    spec = replace(settings.spec, trust_x_m=(0.0, 0.30), trust_y_m=(-0.10, 0.10),
                   samples_per_state=8)
    return replace(settings, spec=spec, belief_particles=500, precontact_particles=100,
                   precontact=replace(settings.precontact, time_limit_s=5.0))
