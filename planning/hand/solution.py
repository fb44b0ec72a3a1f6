"""The hand-relative problem built and solved once, and kept on disk.

Building the tables takes about half a minute and the point-based solver is given minutes
(thesis sec. 6.4: SARSOP for 5 min), while a closed-loop episode needs the answer at once.
:func:`solve_hand_problem` builds the model (:func:`planning.hand.model.build_hand_pomdp`),
solves QMDP and the point-based policy on the thesis' augmented POMDP (the 15 Gaussian
belief points 20 cm ahead, sec. 6.4.2) and, given a cache directory, stores the tables and
both policies under a key made of every setting that changes them. A later call with the
same settings loads them (a second or so). The cache is our own pickle of our own arrays,
written and read by this module only.
"""

from __future__ import annotations

import hashlib
import json
import pickle
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from models.planar.world import PlanarWorld
from models.settings import check_ranges
from planning.hand.beliefs import POST_CONTACT_DISTANCE_M, belief_points
from planning.hand.discretization import HandDiscretization, HandProblemSpec
from planning.hand.model import HandPOMDP, build_hand_pomdp
from planning.hand.policy import qmdp_vectors
from planning.pomdp.point_based import AlphaVectorPolicy, PointBasedSolver
from planning.pomdp.progress import SolverProgressBar
from planning.pomdp.qmdp import solve_mdp

CACHE_VERSION = 2  # 2: the point-based solver samples by SARSOP's rule
POLICIES = ("qmdp", "pomdp")


SOLVE_SECONDS_CEILING = 86400.0
"""The longest point-based solve a settings file may ask for (s): a day; a longer one is
taken for a mistyped exponent."""


@dataclass(frozen=True)
class HandSolveSettings:
    """Attributes:
        object_name: the pushed object (thesis: the 3.5 cm x 5 cm box, ``small_box``).
        sensors: planar sensor layout (``fingertips``: the F1/F2 and F3 fronts).
        spec: discretisation and reward parameters.
        seed: seeds the Monte Carlo tables and the belief points.
        solve_seconds: the point-based solver's wall-time budget (s).
        solve_trials: also stop after this many search trials (machine-independent).
        belief_count: Gaussian belief points of the augmented POMDP (thesis: 15).
        belief_particles: samples that discretise each belief point.
    """

    object_name: str = "small_box"
    sensors: str = "fingertips"
    spec: HandProblemSpec = field(default_factory=HandProblemSpec)
    seed: int = 0
    solve_seconds: float = 60.0
    solve_trials: int | None = None
    belief_count: int = 15
    belief_particles: int = 3000

    def __post_init__(self):
        if self.solve_seconds <= 0 or self.belief_count < 1 or self.belief_particles < 1:
            raise ValueError("solve_seconds must be > 0, belief_count and belief_particles >= 1")
        check_ranges(self, counts=("solve_trials",),
                     at_most={"solve_seconds": SOLVE_SECONDS_CEILING})

    def key(self) -> str:
        """A short hash of every setting (and the cache format)."""
        fields = asdict(self)
        fields["solve_seconds"] = float(self.solve_seconds)  # 60 and 60.0 are one budget
        text = json.dumps({"v": CACHE_VERSION, **fields}, sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


@dataclass
class HandSolution:
    """The model and its two post-contact policies (``"qmdp"``, ``"pomdp"``), with the
    wall times (s) spent building and solving them."""

    model: HandPOMDP
    policies: dict[str, AlphaVectorPolicy]
    timings: dict[str, float]
    loaded_from_cache: bool = False


def solve_hand_problem(settings: HandSolveSettings = HandSolveSettings(), *,
                       cache_dir: Path | None = None, progress: bool = True) -> HandSolution:
    """Build and solve the problem, or load it from ``cache_dir`` (see the module
    docstring)."""
    world = PlanarWorld.load(settings.object_name, sensors=settings.sensors)
    path = None if cache_dir is None else Path(cache_dir) / f"hand_{settings.key()}.pkl"
    if path is not None and path.exists():
        return _load(path, world, settings.spec)
    model = build_hand_pomdp(world, settings.spec, rng=np.random.default_rng([settings.seed, 1]),
                             progress=progress)
    start = time.perf_counter()
    qmdp = qmdp_vectors(solve_mdp(model.pomdp), model.pomdp.actions)
    qmdp_s = time.perf_counter() - start
    points = belief_points(settings.belief_count, POST_CONTACT_DISTANCE_M,
                           rng=np.random.default_rng([settings.seed, 2]))
    initial = np.array([model.belief(b.sample(world, settings.belief_particles,
                                              rng=np.random.default_rng([settings.seed, 3, i])))
                        for i, b in enumerate(points)])
    start = time.perf_counter()
    bar = SolverProgressBar(settings.solve_seconds, settings.solve_trials, disable=not progress)
    pomdp = PointBasedSolver(model.pomdp).solve(
        settings.solve_seconds, initial_beliefs=initial, max_trials=settings.solve_trials,
        callback=bar)
    bar.close()
    timings = {"build_s": model.build_seconds, "qmdp_solve_s": qmdp_s,
               "pomdp_solve_s": time.perf_counter() - start}
    solution = HandSolution(model, {"qmdp": qmdp, "pomdp": pomdp}, timings)
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        payload = {"pomdp": model.pomdp, "kept": model.kept, "timings": timings,
                   "vectors": {k: (v.alphas, v.alpha_actions) for k, v in
                               solution.policies.items()}}
        partial = path.with_suffix(".tmp")
        partial.write_bytes(pickle.dumps(payload, protocol=pickle.HIGHEST_PROTOCOL))
        partial.replace(path)
    return solution


def _load(path: Path, world: PlanarWorld, spec: HandProblemSpec) -> HandSolution:
    payload = pickle.loads(path.read_bytes())
    pomdp = payload["pomdp"]
    model = HandPOMDP(pomdp, HandDiscretization(world, spec), payload["kept"], spec, world,
                      payload["timings"]["build_s"])
    policies = {k: AlphaVectorPolicy(alphas, actions, pomdp.actions)
                for k, (alphas, actions) in payload["vectors"].items()}
    return HandSolution(model, policies, payload["timings"], loaded_from_cache=True)
