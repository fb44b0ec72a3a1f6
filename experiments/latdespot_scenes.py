"""``cmanip experiment latdespot --part scenes|bound``: the thesis' Lat-POMDP experiments
(sec. 7.3.4, Fig. 7.4) and the upper-bound validation (sec. 7.3.5).

Each scene (``empty``, ``right_obstacles``, ``left_obstacles``, ``cul_de_sac``) is HERB's
right arm with its hand at the scene's start, the ch. 7 problem and belief of part ``rel``
(:mod:`experiments.latdespot_study`: a bottle, two perfect fingertip sensors, four 1 cm
moves), on the scene's configuration lattice (1 cm, the problem's step;
:mod:`planning.lattice`). Policies (thesis sec. 7.3.2):

- ``rel-qmdp``, ``rel-sarsop``, ``rel-despot``: plan on the discrete Rel-POMDP, blind to
  the arm; the action they choose is executed whatever the lattice says;
- ``lift-qmdp``, ``lift-sarsop``: Rel-QMDP's and Rel-SARSOP's choice, replaced by the
  next-best feasible action;
- ``lat-despot``: DESPOT on the discrete Lat-POMDP, Rel-QMDP upper bound, Lift-QMDP
  rollouts (thesis sec. 7.2);
- ``lat-despot-pb`` (beyond the thesis, its sec. 7.4): the same with the point-based
  solver's bounds: its corner values above (the sawtooth upper bound at each state) and
  Lift-SARSOP rollouts below;
- ``lat-despot-continuous`` (beyond the thesis; not in the default set, its decisions take
  about a second): Lat-DESPOT planning on the continuous Lat-POMDP itself (the planar
  pushing model on the lattice, the pose's exact goal reward; the same Rel-QMDP bound and
  Lift-QMDP rollouts from each scenario's cell), the object tracked by the manifold
  particle filter (thesis Alg. 4.2, analytic manifold), as part ``rel``'s
  ``rel-despot-continuous``. It runs on the continuous model only (its value there).

Every other policy plans on the discrete model and tracks the discrete belief (thesis sec.
6.4.1); DESPOT's scenarios are drawn from it. The initial belief is part ``rel``'s
Gaussian conditioned on the object not touching an obstacle at the start (an object does
not start inside the clutter; unconditioned, 11 % of it does in ``right_obstacles`` and
``cul_de_sac``, 13 % in ``left_obstacles``): the true pose is drawn from it by rejection,
and the discrete belief has the cells that touch at the start removed. Each policy is
evaluated on two models, from the same initial belief, ``trials`` episodes of ``horizon``
steps each:

- the discrete Lat-POMDP: its discounted value (Fig. 7.4-Top); an episode that enters
  ``s_bad`` gets -1 for every remaining step;
- the continuous Lat-POMDP (the planar pushing model on the lattice): the success rate,
  Pr(object in the goal) at the last step (Fig. 7.4-Middle), and the fraction of episodes
  that took an infeasible action (Fig. 7.4-Bottom; such an episode ends there and fails) or
  made un-modelled contact (ends likewise).

Episode (scene, policy, model, j) is seeded from (seed, 23, scene, policy, model, j) and
depends on nothing else (the lattice's answers are deterministic, whichever episode asked
first), so episodes run on the trial runner (:mod:`experiments.runner`: any backend, each
kept in ``trials.jsonl`` as it finishes, a killed study resumable), each process building
the problem once, its scenes when first asked, and loading the solved point-based policy
from the study's directory.
DESPOT's budget is a trial count per decision with a wall-clock cap (``lat_despot_trials``,
``lat_despot_seconds``); with the trial count set to none the cap alone is the budget
(the 0.1 s and 1 s figures).

Part ``bound`` (sec. 7.3.5): the discrete-model values of Rel-SARSOP and Rel-DESPOT on
Rel-POMDP against the best value of any policy on each scene's Lat-POMDP. Theorem 7.2
bounds a belief's Lat value by the same belief's Rel value, so the Rel episodes start from
each scene's own initial belief (the conditioned one above; part ``rel``'s unconditioned
belief is another belief: the thesis' scenes had no object inside the clutter, and one
belief served both); they run as the scene's third model, ``rel``, kept in the same
``trials.jsonl``. Beside the policies' values, a guaranteed upper bound at each scene's
belief: the ``horizon``-step value of Rel-POMDP's underlying MDP, ``b . V_H``, which no
policy of either POMDP can exceed in expectation over the same horizon (the
infinite-horizon bounds, QMDP's and the point-based solver's, do not bound a 100-step
value: with rewards at most 0 a shorter horizon is worth more).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace
from functools import lru_cache
from pathlib import Path

import numpy as np

from estimation.hand.manifolds import AnalyticManifold
from estimation.particles.belief import ParticleBelief
from estimation.particles.factory import make_filter
from experiments.latdespot_study import (
    RelSettings,
    build_rel_problem,
)
from experiments.runner import Backend, Job, TrialStore, map_trials
from experiments.statistics import half_width, wilson_interval
from models.herb.scene import SceneSpec
from models.planar.observation import observation_reading
from models.planar.polygon import pose_points
from planning.hand.model import HandPOMDP
from planning.hand.policy import qmdp_vectors
from planning.lattice.contact import UnmodelledContact
from planning.lattice.grid import LatticeSpec
from planning.lattice.ik_table import load_ik_table
from planning.lattice.lattice import ConfigurationLattice
from planning.lattice.planners import LatDespotPlanner, LiftPolicy, check_budget
from planning.lattice.pomdp import BAD, LatticePOMDP
from planning.pomdp.despot import DespotSettings
from planning.pomdp.generative import TabularGenerative
from planning.pomdp.online import DespotPlanner
from planning.pomdp.point_based import AlphaVectorPolicy
from planning.pomdp.qmdp import mdp_horizon_values
from planning.pomdp.tabular import belief_update, simulate_episode

SCENES = ("empty", "right_obstacles", "left_obstacles", "cul_de_sac")
POLICIES = ("rel-qmdp", "rel-sarsop", "rel-despot", "lift-qmdp", "lift-sarsop",
            "lat-despot", "lat-despot-pb", "lat-despot-continuous")
#: The study's policies unless told otherwise (``lat-despot-continuous`` is asked for by
#: name: a 200-trial study of it would take about 16 hours on two cores).
DEFAULT_POLICIES = POLICIES[:-1]
#: Policies that plan on the continuous model and are evaluated on it alone.
CONTINUOUS_ONLY = ("lat-despot-continuous",)
MODELS = ("discrete", "continuous")
#: The models an episode can run on: the two Lat-POMDPs and (part ``bound``) Rel-POMDP from
#: the scene's belief; an episode's seed holds its index here.
KINDS = (*MODELS, "rel")
#: The policies part ``bound`` evaluates on Rel-POMDP (thesis sec. 7.3.5).
BOUND_POLICIES = ("rel-sarsop", "rel-despot")
EPISODE_STREAM = 23


@dataclass(frozen=True)
class SceneSettings:
    """Attributes:
        scenes: which scenes (built-in names or paths).
        policies: which policies (:data:`POLICIES`).
        policy_trials: ``POLICY=N`` entries: that policy's episodes per scene and model,
            when fewer than the study's ``trials`` (the costliest ones: a 200-trial study of
            Rel-DESPOT and Lat-DESPOT-pb would take about 28 hours on two cores; each
            entry's ``trials`` in ``summary.json`` says how many it had).
        lat_despot_trials: DESPOT trials per Lat-DESPOT decision (None: the wall-clock cap
            alone).
        lat_despot_seconds: wall-clock cap per Lat-DESPOT decision (s).
        lattice_x_range_m, lattice_y_range_m: the lattice's extent about the hand's start
            (back, forward) and (right, left) (m); its resolution is the problem's step.
        cache_dir: where the lattice's IK table is kept (None: solved, not kept).
    """

    scenes: tuple[str, ...] = SCENES
    policies: tuple[str, ...] = DEFAULT_POLICIES
    policy_trials: tuple[str, ...] = ()
    lat_despot_trials: int | None = 30
    lat_despot_seconds: float = 5.0
    lattice_x_range_m: tuple[float, float] = (-0.10, 0.40)
    lattice_y_range_m: tuple[float, float] = (-0.40, 0.40)
    cache_dir: str | None = "out/cache"

    def __post_init__(self):
        if not self.scenes:
            raise ValueError("scenes must name at least one scene")
        unknown = set(self.policies) - set(POLICIES)
        if not self.policies or unknown:
            raise ValueError(f"policies must be drawn from {POLICIES}, got {self.policies}")
        check_budget(self.lat_despot_trials, self.lat_despot_seconds)
        self.policy_trial_counts()

    def policy_trial_counts(self) -> dict[str, int]:
        """``policy_trials`` as ``{policy: N}``.

        Raises:
            ValueError: an entry that is not ``POLICY=N`` with a known policy and N >= 2.
        """
        counts = {}
        for entry in self.policy_trials:
            name, _, count = entry.partition("=")
            if name not in POLICIES or not count.strip().isdigit() or int(count) < 2:
                raise ValueError(f"policy_trials entries are POLICY=N with POLICY one of "
                                 f"{POLICIES} and N >= 2, got {entry!r}")
            counts[name] = int(count)
        return counts

    def trials_of(self, policy: str, trials: int) -> int:
        """The episodes of ``policy`` per scene and model in a study of ``trials``."""
        return min(trials, self.policy_trial_counts().get(policy, trials))


@dataclass(frozen=True)
class Solved:
    """What the parent solves once and every worker loads from the study's directory: the
    point-based policy and its corner upper bound (S,)."""

    sarsop: AlphaVectorPolicy
    corner: np.ndarray

    def save(self, path: Path) -> None:
        """Write both as ``.npz`` (the policy's arrays under the names
        :meth:`AlphaVectorPolicy.load` reads, and ``corner``)."""
        np.savez_compressed(path, alphas=self.sarsop.alphas,
                            alpha_actions=self.sarsop.alpha_actions,
                            action_names=np.array(self.sarsop.action_names),
                            corner=self.corner)

    @staticmethod
    def load(path: Path) -> Solved:
        return Solved(AlphaVectorPolicy.load(path), np.load(path)["corner"])


@dataclass(frozen=True)
class LatEpisode:
    """One episode on a Lat-POMDP.

    Attributes:
        in_goal: (horizon + 1,) bool, the object in the goal before each step and after the
            last (False from the step that ends the episode in ``s_bad``).
        discounted_return: sum_t gamma^t R_t over the horizon.
        infeasible: the episode took an infeasible action (and ended).
        unmodelled: the episode made un-modelled contact (and ended).
        planning_ms: wall time of each decision (ms).
        edges_asked: lattice edges the policy asked for in the episode.
        edges_asked_per_decision: median over its decisions.
        asked: (P, A) bool, the asked edges, and status: (P, A) int8 the lattice's
            answers at the end (kept for the lattice figure: Lat-DESPOT's first episode on
            the continuous model).
    """

    in_goal: np.ndarray
    discounted_return: float
    infeasible: bool
    unmodelled: bool
    planning_ms: np.ndarray
    edges_asked: int
    edges_asked_per_decision: float
    asked: np.ndarray | None = None
    status: np.ndarray | None = None


def lattice_spec(scene: SceneSpec, step_m: float, settings: SceneSettings) -> LatticeSpec:
    """The scene's lattice: at the hand's start, the problem's step (m) apart."""
    return LatticeSpec(start=tuple(float(v) for v in scene.hand_start.as_array()),
                       resolution_m=step_m, x_range_m=settings.lattice_x_range_m,
                       y_range_m=settings.lattice_y_range_m)


def scene_lat_pomdp(scene_name: str, rel: RelSettings, scenes: SceneSettings, *,
                    model: HandPOMDP | None = None, belief=None,
                    progress: bool = False) -> LatticePOMDP:
    """The discrete Lat-POMDP of a scene on the study's problem (``model`` and ``belief``:
    :func:`~experiments.latdespot_study.build_rel_problem`'s, built here when not given),
    the lattice's IK table from ``scenes.cache_dir`` (solved into it on first use)."""
    if model is None:
        model, belief, _ = build_rel_problem(rel, progress=progress)
    scene = SceneSpec.load(scene_name, object_override=rel.object_name)
    spec = lattice_spec(scene, model.spec.step_m, scenes)
    cache = None if scenes.cache_dir is None else Path(scenes.cache_dir)
    table = load_ik_table(scene, spec, cache_dir=cache, progress=progress)
    lattice = ConfigurationLattice(scene, table, model.spec.action_vectors())
    return LatticePOMDP(model, lattice, UnmodelledContact(scene), inner="discrete",
                        initial=belief)


class SceneEpisodes:
    """One scene's lattice, models and policies (built in each worker)."""

    def __init__(self, rel: RelSettings, scenes: SceneSettings, solved: Solved,
                 model: HandPOMDP, belief, initial: np.ndarray, scene_name: str):
        self.rel, self.model, self.belief = rel, model, belief
        discrete = scene_lat_pomdp(scene_name, rel, scenes, model=model, belief=belief)
        self.scene, self.lattice = discrete.lattice.scene, discrete.lattice
        self.contact = contact = discrete.contact
        self.models = {"discrete": discrete,
                       "continuous": LatticePOMDP(model, self.lattice, contact,
                                                  inner="continuous", initial=belief,
                                                  outside=rel.continuous_outside)}
        lat_settings = DespotSettings(scenarios=rel.despot_scenarios, depth=rel.despot_depth,
                                      max_trials=scenes.lat_despot_trials,
                                      seconds=scenes.lat_despot_seconds)
        pb = LatticePOMDP(model, self.lattice, contact, inner="discrete", initial=belief,
                          upper_values=solved.corner, rollout_policy=solved.sarsop)
        q = qmdp_vectors(self.models["discrete"].tabular.q_values, model.pomdp.actions)
        rel_despot = DespotPlanner(TabularGenerative(model.pomdp, default_policy="qmdp"),
                                   DespotSettings(scenarios=rel.despot_scenarios,
                                                  depth=rel.despot_depth,
                                                  max_trials=rel.despot_trials,
                                                  seconds=rel.despot_seconds))
        self.vectors = {"rel-qmdp": q, "rel-sarsop": solved.sarsop}
        self.lift = {"lift-qmdp": LiftPolicy(q, self.lattice),
                     "lift-sarsop": LiftPolicy(solved.sarsop, self.lattice)}
        self.lat = {"lat-despot": LatDespotPlanner(self.models["discrete"], lat_settings),
                    "lat-despot-pb": LatDespotPlanner(pb, lat_settings),
                    "lat-despot-continuous": LatDespotPlanner(
                        self.models["continuous"],
                        replace(lat_settings, max_trials=rel.continuous_despot_trials))}
        self.filter = make_filter("mpf", model.world, AnalyticManifold(model.world))
        self.rel_despot = rel_despot
        self.action_vectors = model.spec.action_vectors()
        self.initial = discrete.free_at_start(initial)

    def free_particles(self, rng: np.random.Generator) -> ParticleBelief:
        """The particle belief of ``lat-despot-continuous``: ``despot_particles`` poses of
        the initial Gaussian that touch nothing with the palm at the start (the discrete
        belief's conditioning, sample by sample)."""
        n = self.rel.despot_particles
        return ParticleBelief.uniform(self.contact.free_starts(
            lambda k: self.belief.sample(self.model.world, k, rng=rng), n, batch=n))

    def decide(self, policy: str, point: int, belief,
               rng: np.random.Generator) -> tuple[int, float]:
        """(action, planning ms) of ``policy`` at lattice point ``point``, discrete belief
        (S,) (a particle belief for ``lat-despot-continuous``)."""
        if policy in self.vectors:
            return self.vectors[policy].act(belief), 0.0
        if policy in self.lift:
            result = self.lift[policy].plan(belief, rng=rng, point=point)
            return result.action, result.planning_ms
        if policy in CONTINUOUS_ONLY:  # DESPOT draws its scenarios from the particles
            result = self.lat[policy].plan(belief, rng=rng, point=point)
            return result.action, result.planning_ms
        cells = rng.choice(len(belief), size=self.rel.despot_particles, p=belief)[:, None]
        if policy == "rel-despot":
            result = self.rel_despot.plan(cells, rng=rng)
        else:
            result = self.lat[policy].plan(cells, rng=rng, point=point)
        return result.action, result.planning_ms

    def run(self, policy: str, kind: str, seed_key: tuple[int, ...], *,
            keep_lattice: bool = False) -> LatEpisode:
        """One episode of ``policy`` on the ``kind`` Lat-POMDP (see the module docstring);
        ``keep_lattice``: with the lattice's asked edges and answers (the lattice figure's
        episode; 33,000 entries, so not every episode's)."""
        if policy in CONTINUOUS_ONLY and kind != "continuous":
            raise ValueError(f"{policy} runs on the continuous model only")
        rng = np.random.default_rng(seed_key)
        if kind == "rel":
            return self.run_rel(policy, rng)
        lat, model, horizon = self.models[kind], self.model, self.rel.horizon
        gamma = lat.discount
        if kind == "continuous":
            start = self.contact.free_start(
                lambda n: self.belief.sample(self.model.world, n, rng=rng), batch=64)
            state = lat.from_poses(self.lattice.start_point, start[None])
        else:
            cell = rng.choice(len(self.initial), p=self.initial)
            state = lat.with_point(self.lattice.start_point, np.array([[cell]]))
        particles = policy in CONTINUOUS_ONLY
        belief = self.free_particles(rng) if particles else self.initial.copy()
        in_goal = np.zeros(horizon + 1, dtype=bool)
        in_goal[0] = self._in_goal(lat, state)
        self.lattice.reset_asked()
        planning, asked = [], []
        total, infeasible, unmodelled = 0.0, False, False
        for t in range(horizon):
            point = int(state[0, 0])
            before = int(self.lattice.asked.sum())
            action, ms = self.decide(policy, point, belief, rng)
            planning.append(ms)
            asked.append(int(self.lattice.asked.sum()) - before)
            step = lat.step(state, action, rng.random((1, lat.uniforms_per_step)))
            if step.next_states[0, 0] == BAD:
                infeasible = not bool(self.lattice.feasible([point], [action])[0])
                unmodelled = not infeasible
                total -= float(np.sum(gamma ** np.arange(t, horizon)))
                break
            total += gamma ** t * float(step.rewards[0])
            observation = int(step.observations[0])
            if particles:
                reading = observation_reading(observation, model.world.sensor_count)
                belief, _ = self.filter.update(belief, self.action_vectors[action], reading,
                                               rng=rng)
            else:
                belief, _ = belief_update(model.pomdp, belief, action, observation)
            state = step.next_states
            in_goal[t + 1] = self._in_goal(lat, state)
        return LatEpisode(in_goal, total, infeasible, unmodelled,
                          np.round(planning, 2),  # 0.01 ms: what the summaries read
                          int(self.lattice.asked.sum()),
                          float(np.median(asked)) if asked else 0.0,
                          self.lattice.asked.copy() if keep_lattice else None,
                          self.lattice.status.copy() if keep_lattice else None)

    def run_rel(self, policy: str, rng: np.random.Generator) -> LatEpisode:
        """One episode of ``policy`` (Rel-SARSOP or Rel-DESPOT) on Rel-POMDP from the
        scene's initial belief (part ``bound``): the arm and the clutter play no part."""
        if policy not in BOUND_POLICIES:
            raise ValueError(f"part bound runs {BOUND_POLICIES} on Rel-POMDP, not {policy}")
        planning = []

        def act(belief: np.ndarray) -> int:
            action, ms = self.decide(policy, self.lattice.start_point, belief, rng)
            planning.append(ms)
            return action

        total = simulate_episode(self.model.pomdp, act, self.initial, self.rel.horizon,
                                 rng=rng)
        return LatEpisode(np.zeros(self.rel.horizon + 1, dtype=bool), total, False, False,
                          np.round(planning, 2), 0, 0.0)

    def _in_goal(self, lat: LatticePOMDP, state: np.ndarray) -> bool:
        """The object in the goal (continuous model; the discrete one reports no success)."""
        return bool(lat.continuous and self.model.in_goal(state[:, 1:])[0])


class _Worker:
    """A process's problem (built once) and its scenes (built when first asked)."""

    def __init__(self, rel: RelSettings, scenes: SceneSettings, solved: Solved):
        self.rel, self.scenes, self.solved = rel, scenes, solved
        self.model, self.belief, self.initial = build_rel_problem(rel)
        self._scenes: dict[str, SceneEpisodes] = {}

    def run(self, job: tuple[str, str, str, int]) -> LatEpisode:
        scene, policy, kind, j = job
        if scene not in self._scenes:
            self._scenes[scene] = SceneEpisodes(self.rel, self.scenes, self.solved,
                                                self.model, self.belief, self.initial, scene)
        key = (self.rel.seed, EPISODE_STREAM, self.scenes.scenes.index(scene),
               POLICIES.index(policy), KINDS.index(kind), j)
        figure = policy == "lat-despot" and kind == "continuous" and j == 0
        return self._scenes[scene].run(policy, kind, key, keep_lattice=figure)


@lru_cache(maxsize=2)
def _worker(rel: RelSettings, scenes: SceneSettings, solved_path: str,
            version: int) -> _Worker:
    """A process's worker for the solved policy in ``solved_path`` as of ``version`` (its
    modification time: a study solved again in the same process is not served the old)."""
    return _Worker(rel, scenes, Solved.load(Path(solved_path)))


def scene_episode(rel: RelSettings, scenes: SceneSettings, solved_path: str,
                  job: tuple[str, str, str, int]) -> LatEpisode:
    """Episode ``job`` = (scene, policy, model, j), in whichever process the trial runner
    chose: the problem built and the solved policy loaded from ``solved_path`` once per
    process, each scene when first asked."""
    return _worker(rel, scenes, solved_path, Path(solved_path).stat().st_mtime_ns).run(job)


def trial_store(rel: RelSettings, scenes: SceneSettings, out: Path, *,
                resume: bool) -> TrialStore:
    """``out/trials.jsonl``, keyed by every setting an episode depends on (not the trial
    counts, scenes or policies, which only choose episodes: a resumed study may add some)."""
    relevant = settings_dict(rel, scenes)
    del relevant["trials"], relevant["scenes"]["scenes"], relevant["scenes"]["policies"]
    del relevant["scenes"]["policy_trials"]
    if relevant["continuous_outside"] == "sentinel":  # stores written before the setting
        del relevant["continuous_outside"]  # existed ran the sentinel: they stay resumable
    return TrialStore(out, "latdespot-scenes", relevant, resume=resume)


def summarise(episodes: list[LatEpisode], kind: str) -> dict:
    """One policy's entry on one model."""
    returns = np.array([e.discounted_return for e in episodes])
    planning = np.concatenate([e.planning_ms for e in episodes])
    out = {"discounted_value": float(returns.mean()),
           "discounted_value_ci95": half_width(returns),
           "planning_ms_median": float(np.median(planning)),
           "planning_ms_p99": float(np.percentile(planning, 99)),
           "infeasible_rate": float(np.mean([e.infeasible for e in episodes])),
           "unmodelled_contact_rate": float(np.mean([e.unmodelled for e in episodes])),
           "lattice_edges_asked_per_episode": float(np.median(
               [e.edges_asked for e in episodes])),
           "lattice_edges_asked_per_decision": float(np.median(
               [e.edges_asked_per_decision for e in episodes])),
           "trials": len(episodes)}
    if kind == "continuous":
        success = np.stack([e.in_goal for e in episodes], axis=1)
        lo, hi = wilson_interval(int(success[-1].sum()), len(episodes))
        out.update(success_rate=float(success[-1].mean()), success_rate_ci95=[lo, hi],
                   success_over_time=success.mean(axis=1).tolist())
    return out


def models_of(policy: str) -> tuple[str, ...]:
    """The models ``policy`` is evaluated on."""
    return ("continuous",) if policy in CONTINUOUS_ONLY else MODELS


def scene_entry(discrete: dict | None, continuous: dict) -> dict:
    """A policy's summary entry: the value on the discrete model (Fig. 7.4-Top), success,
    infeasible and un-modelled contact rates on the continuous one (Middle, Bottom), and
    its planning times over both. A policy evaluated on the continuous model alone
    (``discrete`` None) has its value there (``value_model: continuous``)."""
    if discrete is None:
        discrete = {**continuous, "value_model": "continuous"}
    entry = {"discounted_value": discrete["discounted_value"],
             "discounted_value_ci95": discrete["discounted_value_ci95"],
             "value_model": discrete.get("value_model", "discrete"),
             "discrete_infeasible_rate": discrete["infeasible_rate"]}
    for key in ("success_rate", "success_rate_ci95", "success_over_time", "infeasible_rate",
                "unmodelled_contact_rate", "lattice_edges_asked_per_episode",
                "lattice_edges_asked_per_decision", "trials"):
        entry[key] = continuous[key]
    entry["continuous_discounted_value"] = continuous["discounted_value"]
    entry["continuous_discounted_value_ci95"] = continuous["discounted_value_ci95"]
    entry["planning_ms_median"] = float(np.median([discrete["planning_ms_median"],
                                                   continuous["planning_ms_median"]]))
    entry["planning_ms_p99"] = max(discrete["planning_ms_p99"], continuous["planning_ms_p99"])
    return entry


def run_scenes(rel: RelSettings, scenes: SceneSettings, solved_path: Path, out: Path, *,
               bound: bool = False, backend: Backend = Backend(), resume: bool = False,
               progress: bool = True) -> tuple[dict, dict]:
    """Every (scene, policy) pair on both models, and with ``bound`` Rel-SARSOP and
    Rel-DESPOT on Rel-POMDP from each scene's belief; episodes on the trial runner (each
    kept in ``out/trials.jsonl`` as it finishes; ``resume`` runs only the missing ones;
    workers load the solved policy from ``solved_path``). Writes ``lattice_<scene>.npz``
    (the edges Lat-DESPOT's first continuous episode asked for) for the lattice figure.

    Returns:
        ``({scene: {policy: entry}}, {scene: {policy: Rel-POMDP entry}})``, the second
        empty without ``bound``.
    """
    kinds = {policy: models_of(policy) for policy in scenes.policies}
    if bound:
        for policy in BOUND_POLICIES:
            kinds[policy] = (*kinds.get(policy, ()), "rel")
    counts = {policy: scenes.trials_of(policy, rel.trials) for policy in kinds}
    # trial index outermost: a study stopped part-way has its first trials of every scene
    # and policy (summarised by ``--trials N --resume`` with N of them done)
    jobs = [(scene, policy, kind, j) for j in range(rel.trials) for scene in scenes.scenes
            for policy, policy_kinds in kinds.items() if j < counts[policy]
            for kind in policy_kinds]
    results = map_trials(scene_episode,
                         [Job("/".join(map(str, job)), (rel, scenes, str(solved_path), job))
                          for job in jobs],
                         backend=backend, store=trial_store(rel, scenes, out, resume=resume),
                         desc="latdespot scenes", progress=progress)
    episodes = dict(zip(jobs, results, strict=True))

    def entries(policy: str, scene: str) -> dict[str, dict]:
        return {kind: summarise([episodes[(scene, policy, kind, j)]
                                 for j in range(counts[policy])], kind)
                for kind in kinds[policy]}

    result: dict[str, dict] = {}
    on_rel: dict[str, dict] = {}
    for scene in scenes.scenes:
        by_policy = {policy: entries(policy, scene) for policy in kinds}
        result[scene] = {policy: scene_entry(by_policy[policy].get("discrete"),
                                             by_policy[policy]["continuous"])
                         for policy in scenes.policies}
        if bound:
            on_rel[scene] = {policy: by_policy[policy]["rel"] for policy in BOUND_POLICIES}
        first = episodes.get((scene, "lat-despot", "continuous", 0))
        if first is not None:
            save_lattice(out / f"lattice_{Path(scene).stem}.npz", scene, rel, scenes, first)
    return result, on_rel


def lattice_figure_data(lattice: ConfigurationLattice, asked: np.ndarray,
                        status: np.ndarray) -> dict[str, np.ndarray]:
    """The data of the lattice figure (thesis Fig. 7.1,
    :func:`experiments.latdespot_plots.plot_lattice`): every point's world pose and
    whether it has a configuration, the ``asked`` (P, A) edges and their ``status``
    (P, A) answers, the obstacles' footprints and the hand's start."""
    footprints = [pose_points(o.pose.as_array()[None], o.spec.footprint())[0]
                  for o in lattice.scene.obstacles]
    return {"poses": lattice.poses, "neighbours": lattice.neighbours,
            "reachable": lattice.table.reachable, "asked": asked, "status": status,
            "obstacles": np.concatenate(footprints) if footprints else np.zeros((0, 2)),
            "obstacle_sizes": np.array([len(f) for f in footprints], dtype=int),
            "start": np.asarray(lattice.spec.start)}


def save_lattice(path: Path, scene_name: str, rel: RelSettings, scenes: SceneSettings,
                 episode: LatEpisode) -> None:
    """``path`` (.npz): the lattice figure's data of ``episode`` (its asked edges)."""
    from planning.hand.discretization import HandProblemSpec

    scene = SceneSpec.load(scene_name, object_override=rel.object_name)
    problem = HandProblemSpec.load(rel.problem)
    spec = lattice_spec(scene, problem.step_m, scenes)
    cache = None if scenes.cache_dir is None else Path(scenes.cache_dir)
    table = load_ik_table(scene, spec, cache_dir=cache, progress=False)
    lattice = ConfigurationLattice(scene, table, problem.action_vectors())
    np.savez_compressed(path, **lattice_figure_data(lattice, episode.asked, episode.status))


def rel_upper_bounds(rel: RelSettings, scenes: SceneSettings, model: HandPOMDP, belief,
                     initial: np.ndarray) -> dict[str, dict]:
    """``{scene: {"mdp_horizon": b . V_H}}``: the ``horizon``-step value of Rel-POMDP's
    underlying MDP at each scene's initial belief b (the unconditioned ``initial`` (S,)
    conditioned on the scene), an upper bound of every policy's value over the episodes'
    horizon on Rel-POMDP and, by Theorem 7.2, on the scene's Lat-POMDP."""
    values = mdp_horizon_values(model.pomdp, rel.horizon)
    out = {}
    for scene in scenes.scenes:
        b = scene_lat_pomdp(scene, rel, scenes, model=model, belief=belief).free_at_start(
            initial)
        out[scene] = {"mdp_horizon": float(b @ values)}
    return out


def bound_check(on_rel: dict, scenes: dict, upper: dict) -> dict:
    """Theorem 7.2 (sec. 7.3.5): each scene's best Lat-POMDP value against the Rel-POMDP
    values of Rel-SARSOP and Rel-DESPOT from the same belief (``on_rel``: ``{scene:
    {policy: entry}}``, :func:`run_scenes`') and its upper bounds there (``upper``:
    :func:`rel_upper_bounds`'). ``holds``: the best Lat value is at most both Rel values;
    ``holds_within_ci95``: at most them up to the two 95 % half-widths (what a finite number
    of episodes can show); ``below_upper_bounds``: the best Lat value's interval reaches
    below the upper bound."""
    out = {"scenes": {}}
    for scene, entries in scenes.items():
        name = max(entries, key=lambda p: entries[p]["discounted_value"])
        best, half = entries[name]["discounted_value"], entries[name]["discounted_value_ci95"]
        rel = on_rel[scene]
        out["scenes"][scene] = {
            "best_lat_policy": name, "best_lat_value": best, "best_lat_value_ci95": half,
            "rel_pomdp": {policy: {key: e[key] for key in (
                "discounted_value", "discounted_value_ci95", "planning_ms_median",
                "planning_ms_p99", "trials")} for policy, e in rel.items()},
            "rel_upper_bounds": upper[scene],
            "holds": all(best <= e["discounted_value"] for e in rel.values()),
            "holds_within_ci95": all(best - half <= e["discounted_value"]
                                     + e["discounted_value_ci95"] for e in rel.values()),
            "below_upper_bounds": best - half <= min(upper[scene].values())}
    for key in ("holds", "holds_within_ci95", "below_upper_bounds"):
        out[key] = all(s[key] for s in out["scenes"].values())
    return out


def settings_dict(rel: RelSettings, scenes: SceneSettings) -> dict:
    return {**asdict(rel), "scenes": asdict(scenes)}
