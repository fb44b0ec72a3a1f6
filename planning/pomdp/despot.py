"""DESPOT: online POMDP planning over sampled scenarios (Somani, Ye, Hsu and Lee, NIPS 2013;
Ye, Somani, Hsu and Lee, "DESPOT: Online POMDP Planning with Regularization", JAIR 2017).

A *scenario* is a start state drawn from the belief and its own stream of uniforms, one
``u`` per depth; stepping a scenario with the generative model
(:class:`~planning.pomdp.generative.GenerativePOMDP`) is then deterministic, so the K
scenarios (default 500) span a sparse belief tree (the DESPOT): a belief node holds the
indices of the scenarios that reach it, each action node the scenarios' rewards, and each
observation seen by at least one scenario a child.

Bounds (JAIR sec. 4, with the node weight |Phi_b| / K and the discount gamma^Delta(b) folded
in, so the root's bounds are the values of its policies):

- lower ``l0(b) = gamma^Delta / K * sum_phi V_pi0(phi) - lambda``: the return of the model's
  default policy, rolled out over all of the node's scenarios at once;
- upper ``mu0(b) = gamma^Delta / K * sum_phi U(s_phi)``: the model's upper bound (e.g. the
  MDP value), or one passed in;
- backups ``l(b) = max(l0(b), max_a l(b, a))``, ``mu(b) = max(l0(b), max_a mu(b, a))`` with
  ``x(b, a) = rho(b, a) + sum_z x(tau(b, a, z))`` and ``rho(b, a) = gamma^Delta / K *
  sum_phi R(s_phi, a) - lambda`` (eq. 5 and Algorithm 4's BACKUP). Bounds can cross: a
  model's upper bound is an expectation (the MDP value), and one scenario's stream of
  uniforms can beat it; crossed bounds are repaired (``mu = l``) and counted.

Search (AR-DESPOT, Algorithm 3, the default): trials from the root take the action of
largest upper bound, then the observation child of largest weighted excess uncertainty
``E(b) = mu(b) - l(b) - xi |Phi_b| / K (mu(b0) - l(b0))`` (xi = 0.95), expand a leaf (all
its actions and scenarios in one ``step`` call, all its children's rollouts in one batch),
stop at depth D (default 90; the node then keeps its default policy, MAKEDEFAULT) or when
E < 0, and back up along the path. ``variant="r"`` is R-DESPOT within a budget: nodes are
expanded breadth first, and the regularised policy is the one the same backup computes
bottom-up (the dynamic programme of JAIR sec. 4.1). Either way the final policy is pruned
where the default policy is at least as good (``l0(b) >= max_a l(b, a)``), and its size
is reported.

Two engines run the same search: this module's Python objects (every variant and
option), and :mod:`planning.pomdp.despot_kernels`' compiled trials on flat arrays, for AR
without subtree reuse on models that give kernels (Tag, RockSample, tabular models, the
discrete Lat-POMDP); on tabular models and the discrete Lat-POMDP the two build identical
trees (tested). A model whose kernels read lazily computed data (the Lat-POMDP's lattice)
has ``answer_kernel_request()``, called when a trial stops to ask for it. The tree has no
reference cycles, and the cyclic garbage collector is paused during a search (its passes
over tens of thousands of nodes were the budget overruns).

The budget is wall-clock time, checked before every trial, so a decision overruns by at
most one trial (reported, with the longest trial). The reference instead counts CPU time
(``clock()``) of its tree building only, and stops when the next trial is predicted to
overrun. The chosen action has the largest root lower bound ``l(b0, a)`` (ties: the
larger upper bound); when the root was never expanded (no time for a trial, or its
bounds already met) or a bound is not finite, it is the default policy's action. Each
decision builds a new tree (``reuse="none"``, default), or starts from the chosen action
and received observation's subtree when it has at least ``reuse_min_fraction`` of the
scenarios (``reuse="subtree"``, Python engine).

Differences from the reference's defaults, on purpose: Tag's upper bound here is the MDP
value (the reference's default is the shortest-path bound, looser), and lambda is 0 on
every problem (the reference's Tag sets 0.01).
"""

from __future__ import annotations

import gc
import time
from collections import deque
from dataclasses import dataclass, replace

import numpy as np

from planning.pomdp.despot_kernels import GROW, NEED, ArrayTree, make_core
from planning.pomdp.generative import GenerativePOMDP, action_array, rollout_kernel

VARIANTS = ("ar", "r")
ENGINES = ("auto", "compiled", "python")
CROSSING_TOLERANCE = 1e-9
"""Crossings smaller than this are rounding, repaired but not counted."""
REUSE = ("none", "subtree")


@dataclass(frozen=True)
class DespotSettings:
    """Attributes:
        scenarios: K, the sampled scenarios (JAIR: 500).
        depth: D, the search depth (JAIR: 90).
        xi: the excess-uncertainty fraction (JAIR: 0.95).
        regularization: lambda, the cost per policy-tree node (0: DESPOT unregularised).
        seconds: wall-clock budget per decision (s).
        max_trials: also stop after this many trials (None: the time budget alone);
            with a trial budget the search does not depend on the machine's speed.
        variant: ``ar`` (anytime heuristic search) or ``r`` (breadth-first within the
            budget, then the regularised dynamic programme).
        gap_stop: stop when the root's bounds are within this (JAIR's epsilon_0).
        reuse: ``none`` (a new tree per decision) or ``subtree`` (keep the child reached).
        reuse_min_fraction: the reused subtree must hold at least this fraction of K.
        engine: ``compiled`` (the search in :mod:`planning.pomdp.despot_kernels`, for AR
            without reuse, on models with kernels), ``python`` (this module's; every
            variant and option), or ``auto`` (compiled where it applies).
    """

    scenarios: int = 500
    depth: int = 90
    xi: float = 0.95
    regularization: float = 0.0
    seconds: float = 1.0
    max_trials: int | None = None
    variant: str = "ar"
    gap_stop: float = 1e-6
    reuse: str = "none"
    reuse_min_fraction: float = 0.2
    engine: str = "auto"

    def __post_init__(self):
        if self.scenarios < 1 or self.depth < 1:
            raise ValueError("scenarios and depth must be >= 1")
        if not 0.0 <= self.xi <= 1.0:
            raise ValueError(f"xi must be in [0, 1], got {self.xi}")
        if self.regularization < 0 or self.seconds <= 0:
            raise ValueError("regularization must be >= 0 and seconds > 0")
        if self.max_trials is not None and self.max_trials < 0:
            raise ValueError("max_trials must be >= 0 or None")
        if self.variant not in VARIANTS:
            raise ValueError(f"variant must be one of {VARIANTS}, got {self.variant!r}")
        if self.reuse not in REUSE:
            raise ValueError(f"reuse must be one of {REUSE}, got {self.reuse!r}")
        if self.engine not in ENGINES:
            raise ValueError(f"engine must be one of {ENGINES}, got {self.engine!r}")


_CORES: dict = {}


def belief_nodes(root):
    """Every belief node of the (Python engine's) tree below ``root``, parents first."""
    stack = [root]
    while stack:
        b = stack.pop()
        yield b
        for q in b.children or ():
            stack.extend(q.children.values())


def default_is_better(l0: float, action_lowers) -> bool:
    """Whether the root's default policy (value ``l0``) beats every action's lower bound:
    the search found no better policy than the default, and the root's lower bound
    ``max(l0, max_a l(b0, a))`` is the default's, so its action is the answer (JAIR's
    backup; the reference implementation's ``DESPOT::OptimalAction`` takes the root's
    default move then). Without it, a shallow search whose children's lower bounds fall
    below l0 by the noise of K scenarios answers with whichever child fell least."""
    return bool(l0 > np.max(action_lowers))


def compiled_core(functions: tuple):
    """The compiled trial and backup for a model's kernel functions, built once per
    process."""
    if functions not in _CORES:
        _CORES[functions] = make_core(*functions)
    return _CORES[functions]


class _BeliefNode:
    """A belief node: the scenarios that reach it (indices into the K), their states
    (n, d) and terminal flags, its depth, its bounds and its action children."""

    __slots__ = ("depth", "scenarios", "states", "terminal", "l0", "u0", "lower", "upper",
                 "children")

    def __init__(self, depth, scenarios, states, terminal):
        self.depth = depth
        self.scenarios = scenarios
        self.states = states
        self.terminal = terminal
        self.children: list[_ActionNode] | None = None
        self.l0 = self.u0 = self.lower = self.upper = 0.0


class _ActionNode:
    """An action node: its regularised weighted reward rho(b, a) and observation children."""

    __slots__ = ("rho", "children", "lower", "upper")

    def __init__(self, rho: float, children: dict):
        self.rho = rho
        self.children = children
        self.lower = rho + sum(c.lower for c in children.values())
        self.upper = rho + sum(c.upper for c in children.values())


@dataclass(frozen=True)
class DespotTree:
    """What a search leaves: the root, the scenarios' uniforms (K, D + 1, U) and K.
    Kept (in the planner's memory) only for subtree reuse."""

    root: _BeliefNode
    uniforms: np.ndarray
    scenarios: int


@dataclass(frozen=True)
class DespotStats:
    """One decision's search.

    Attributes:
        trials: trials run (AR) or expansions (R).
        nodes: belief nodes in the tree.
        depth_reached: deepest belief node.
        lower, upper: the root's bounds (weighted, regularised).
        action_lower, action_upper: (A,) every action's bounds at the root (nan where
            the root was not expanded).
        crossings_repaired: backups where the upper bound fell below the lower.
        seconds: wall time of the search (s); overrun_ms: beyond the budget (ms, >= 0),
            at most about ``trial_ms_max``, the longest trial (ms; the first one includes
            building the root).
        policy_size: belief nodes of the pruned regularised policy.
        reused: whether the search started from the last decision's subtree.
    """

    trials: int
    nodes: int
    depth_reached: int
    lower: float
    upper: float
    action_lower: tuple[float, ...]
    action_upper: tuple[float, ...]
    crossings_repaired: int
    seconds: float
    overrun_ms: float
    trial_ms_max: float
    policy_size: int
    reused: bool


class Despot:
    """The DESPOT search over one generative model (see the module docstring).

    Args:
        model: the generative POMDP (its ``upper_bound`` and ``default_actions`` are the
            default bounds).
        settings: the search settings.
        upper_bound: optional ``(states (K, d)) -> (K,)`` replacing the model's.
        default_actions: optional ``(states (K, d)) -> (K,)`` rollout policy replacing
            the model's (it may read only what the agent observes).
    """

    def __init__(self, model: GenerativePOMDP, settings: DespotSettings = DespotSettings(), *,
                 upper_bound=None, default_actions=None):
        self.model = model
        self.settings = settings
        self._upper = upper_bound or model.upper_bound
        self._default = default_actions or model.default_actions
        self._compiled_rollout = None if default_actions else rollout_kernel(model)
        kernels = getattr(model, "kernels", None)
        kernels = kernels() if kernels is not None and not (upper_bound or default_actions) \
            else None
        compilable = kernels is not None and settings.variant == "ar" and \
            settings.reuse == "none"
        if settings.engine == "compiled" and not compilable:
            raise ValueError("the compiled engine needs a model with kernels, its own "
                             "bounds, variant 'ar' and reuse 'none'")
        self._core = None
        self._workspace: ArrayTree | None = None  # the compiled tree's arrays, reused
        if compilable and settings.engine != "python":
            functions, self._kernel_params = kernels
            self._core, self._core_backup = compiled_core(functions)
        self._gamma = model.discount
        self._actions = len(model.actions)
        if self._core is not None:
            self._warm_up()

    # -- one decision
    def search(self, particles: np.ndarray, *, rng: np.random.Generator,
               weights: np.ndarray | None = None,
               previous: DespotTree | None = None) -> tuple[int, DespotStats, DespotTree]:
        """Search from the belief ``particles`` (N, d) (optionally ``weights`` (N,)); or,
        when ``previous`` is given and reusable, from its root. Returns the action, the
        search statistics and the tree."""
        if self._core is not None:
            return self._search_compiled(particles, weights, rng)
        s = self.settings
        start = time.perf_counter()
        self._crossings = 0
        reused = previous is not None
        if reused:
            tree = previous
        else:
            tree = self._new_tree(particles, weights, rng)
        self._uniforms, self._k = tree.uniforms, tree.scenarios
        root = tree.root
        frontier = deque([(root,)])  # breadth-first queue of paths, for the R variant

        def trial() -> int | None:
            path = self._trial(root) if s.variant == "ar" else self._expand_next(frontier)
            if path is None:
                return None
            self._backup(path)
            return path[-1].depth

        trials, depth_reached, trial_max = self._run_trials(
            start, trial, lambda: root.upper - root.lower)
        if reused:
            depth_reached = max(depth_reached, self._deepest(root))
        elapsed = time.perf_counter() - start
        action = self._best_action(root)
        stats = DespotStats(
            trials=trials, nodes=self._count(root), depth_reached=depth_reached,
            lower=root.lower, upper=root.upper,
            action_lower=self._action_bounds(root, "lower"),
            action_upper=self._action_bounds(root, "upper"),
            crossings_repaired=self._crossings, seconds=elapsed,
            overrun_ms=max(0.0, (elapsed - s.seconds) * 1e3), trial_ms_max=trial_max * 1e3,
            policy_size=self._policy_size(root), reused=reused)
        return action, stats, tree

    def _run_trials(self, start: float, trial, gap) -> tuple[int, int, float]:
        """Run ``trial()`` until the trial or time budget is spent or ``gap()`` (the root's)
        closes, with the cyclic garbage collector paused. ``trial()`` returns the depth it
        reached, -1 to be run again (not counted), or None to end the search. Returns
        (trials, deepest depth, longest trial (s, the first one from ``start``))."""
        s = self.settings
        deadline = start + s.seconds
        trials, depth_reached = 0, 0
        trial_start, trial_max = start, 0.0
        collecting = gc.isenabled()
        gc.disable()  # the tree is acyclic: reference counts free it
        try:
            while (s.max_trials is None or trials < s.max_trials) and \
                    time.perf_counter() < deadline and gap() > s.gap_stop:
                reached = trial()
                if reached is None:
                    break
                if reached < 0:
                    continue
                depth_reached = max(depth_reached, reached)
                trials += 1
                now = time.perf_counter()
                trial_max = max(trial_max, now - trial_start)
                trial_start = now
        finally:
            if collecting:
                gc.enable()
        return trials, depth_reached, trial_max

    @property
    def workspace_bytes(self) -> int:
        """The compiled engine's reusable tree arrays (bytes; 0 for the Python engine):
        they grow to the largest tree a decision has needed, then stay."""
        return 0 if self._workspace is None else self._workspace.nbytes

    def _warm_up(self) -> None:
        """Compile the core now (a few seconds once per process and model), with a
        one-trial search, rather than inside the first decision's budget; from the model's
        ``warm_up_states(n)`` if it has them (states whose search computes nothing lazily,
        so that building a planner leaves the model as it was), else from its initial
        belief."""
        settings = self.settings
        self.settings = replace(settings, scenarios=2, depth=2, max_trials=1,
                                gap_stop=-np.inf)  # one trial even if the bounds meet
        try:
            rng = np.random.default_rng(0)
            warm_up_states = getattr(self.model, "warm_up_states", None)
            states = (warm_up_states(2) if warm_up_states is not None
                      else self.model.sample_initial(2, rng=rng))
            self._search_compiled(states, None, rng)
        finally:
            self.settings = settings

    def _search_compiled(self, particles, weights, rng) -> tuple[int, DespotStats, DespotTree]:
        """:meth:`search` on the compiled engine (AR-DESPOT, a new tree). The tree's arrays
        are a workspace kept between searches (grown as needed, never shrunk), so memory
        stays flat over a long run and a decision does not pay for allocating it; the
        returned tree is valid until the next search."""
        s = self.settings
        start = time.perf_counter()
        particles = np.asarray(particles)
        p = None if weights is None else np.asarray(weights, dtype=float) / np.sum(weights)
        picks = rng.choice(len(particles), size=s.scenarios, p=p)
        uniforms = rng.random((s.scenarios, s.depth + 1, self.model.uniforms_per_step))
        states = particles[picks]
        tree = self._workspace
        if tree is None or tree.states.shape[1] != states.shape[1]:
            tree = self._workspace = ArrayTree(states.shape[1], self._actions,
                                               capacity=64 * max(1024, s.scenarios))
        tree.scen[:s.scenarios] = np.arange(s.scenarios)
        tree.states[:s.scenarios] = states
        tree.term[:s.scenarios] = self.model.is_terminal(states)
        tree.counts[:] = (1, 0, 0, s.scenarios)
        tree.depth[0], tree.start[0], tree.count[0] = 0, 0, s.scenarios
        tree.first_action[0] = -1
        ended = bool(tree.term[:s.scenarios].all())
        self._uniforms, self._k = uniforms, s.scenarios
        live = ~tree.term[:s.scenarios]
        value = float(self._rollout(states, np.arange(s.scenarios), ~live,
                                    np.zeros(s.scenarios, dtype=np.int64),
                                    np.array([0, s.scenarios])).sum())
        bound = float(np.where(live, self._upper(states), 0.0).sum()) if live.any() else 0.0
        lam = s.regularization
        tree.l0[0] = value / s.scenarios - lam
        tree.u0[0] = tree.l0[0] if ended else max(bound / s.scenarios, tree.l0[0])
        tree.lower[0], tree.upper[0] = tree.l0[0], tree.u0[0]
        crossings = np.zeros(1, dtype=np.int64)
        path = np.zeros(s.depth + 2, dtype=np.int64)
        resume = np.zeros(2)  # a stopped trial's path length and root gap
        grow_after = False

        def trial() -> int | None:
            nonlocal grow_after
            arrays, pool = tree.as_tuples()
            length = self._core(0, arrays, pool, tree.counts, uniforms, self._kernel_params,
                                self._actions, s.depth, self._gamma, lam, float(s.scenarios),
                                s.xi, crossings, path, resume)
            if length == NEED:  # the model computes what its kernels asked for; resume
                self.model.answer_kernel_request()
                return -1
            if length != GROW:
                return int(tree.depth[path[length - 1]])
            # out of room: grow now, or, late in the budget, after the search (copying the
            # pool then would overrun it)
            if time.perf_counter() - start > 0.5 * s.seconds:
                grow_after = True
                return None
            tree.grow(s.scenarios * self._actions)
            return -1

        trials, depth_reached, trial_max = self._run_trials(
            start, trial, lambda: tree.upper[0] - tree.lower[0])
        if resume[0] > 0:  # the budget ran out in a stopped trial: back up what it expanded
            self._core_backup(path, int(resume[0]), tree.as_tuples()[0], self._actions,
                              s.depth, crossings)
        elapsed = time.perf_counter() - start
        self._crossings = int(crossings[0])
        if grow_after:  # for the next decision, outside this one's search budget
            tree.grow(s.scenarios * self._actions)
        ranking = self._array_ranking(tree)
        qs = tree.action_range(0)
        if ranking is not None and not default_is_better(tree.l0[0],
                                                         tree.q_lower[qs.start:qs.stop]):
            action = ranking[0]
        else:
            actions = action_array(self._default(states[live] if live.any() else states),
                                   int(live.sum()) if live.any() else len(states))
            action = int(np.bincount(actions, minlength=self._actions).argmax())
        qs = tree.action_range(0)
        nan = (float("nan"),) * self._actions
        stats = DespotStats(
            trials=trials, nodes=int(tree.counts[0]), depth_reached=depth_reached,
            lower=float(tree.lower[0]), upper=float(tree.upper[0]),
            action_lower=tuple(float(tree.q_lower[q]) for q in qs) or nan,
            action_upper=tuple(float(tree.q_upper[q]) for q in qs) or nan,
            crossings_repaired=self._crossings, seconds=elapsed,
            overrun_ms=max(0.0, (elapsed - s.seconds) * 1e3), trial_ms_max=trial_max * 1e3,
            policy_size=self._array_policy_size(tree), reused=False)
        return action, stats, DespotTree(tree, uniforms, s.scenarios)

    def _array_ranking(self, tree: ArrayTree) -> tuple[int, ...] | None:
        qs = tree.action_range(0)
        if not qs:
            return None
        lows, ups = tree.q_lower[qs.start:qs.stop], tree.q_upper[qs.start:qs.stop]
        if not (np.all(np.isfinite(lows)) and np.all(np.isfinite(ups))):
            return None
        return tuple(int(a) for a in np.lexsort((-ups, -lows)))

    def _array_policy_size(self, tree: ArrayTree) -> int:
        size, stack = 0, [0]
        while stack:
            b = stack.pop()
            size += 1
            qs = tree.action_range(b)
            if not qs:
                continue
            best = max(qs, key=lambda q: tree.q_lower[q])
            if tree.q_lower[best] > tree.l0[b]:
                first = int(tree.q_child_start[best])
                stack.extend(int(c) for c in
                             tree.child_node[first:first + tree.q_child_count[best]])
        return size

    def subtree(self, tree: DespotTree, action: int, observation: int, *,
                rng: np.random.Generator) -> DespotTree | None:
        """The tree below ``action`` and ``observation`` as a tree of its own, when it
        exists and holds at least ``reuse_min_fraction`` of the scenarios; else None.
        Its bounds are recomputed for the new root (weights |Phi_b| / K', depths - 1),
        and the scenarios' uniform streams move up one depth (the deepest drawn anew
        from ``rng``)."""
        root = tree.root
        if root.children is None:
            return None
        child = root.children[action].children.get(int(observation))
        if child is None or len(child.scenarios) < self.settings.reuse_min_fraction * \
                tree.scenarios:
            return None
        k_new = len(child.scenarios)
        scale = tree.scenarios / (k_new * self._gamma)
        self._rescale(child, scale, shift=child.depth)
        fresh = rng.random((tree.uniforms.shape[0], 1, tree.uniforms.shape[2]))
        return DespotTree(child, np.concatenate([tree.uniforms[:, 1:], fresh], axis=1), k_new)

    # -- the tree
    def _new_tree(self, particles, weights, rng) -> DespotTree:
        s = self.settings
        particles = np.asarray(particles)
        p = None if weights is None else np.asarray(weights, dtype=float) / np.sum(weights)
        picks = rng.choice(len(particles), size=s.scenarios, p=p)
        uniforms = rng.random((s.scenarios, s.depth + 1, self.model.uniforms_per_step))
        self._uniforms, self._k = uniforms, s.scenarios
        states = particles[picks]
        root = _BeliefNode(0, np.arange(s.scenarios), states, self.model.is_terminal(states))
        self._initialise([root])
        return DespotTree(root, uniforms, s.scenarios)

    def _initialise(self, nodes: list[_BeliefNode]) -> None:
        """Bounds of new nodes: one batched rollout and one upper-bound call for all."""
        states = np.concatenate([n.states for n in nodes])
        scenarios = np.concatenate([n.scenarios for n in nodes])
        terminal = np.concatenate([n.terminal for n in nodes])
        depths = np.concatenate([np.full(len(n.scenarios), n.depth) for n in nodes])
        offsets = np.cumsum([0] + [len(n.scenarios) for n in nodes])
        values = self._rollout(states, scenarios, terminal, depths, offsets)
        uppers = np.where(terminal, 0.0, self._upper(states))
        value_sums = np.add.reduceat(values, offsets[:-1])
        upper_sums = np.add.reduceat(uppers, offsets[:-1])
        lam, max_depth = self.settings.regularization, self.settings.depth
        for n, v, u in zip(nodes, value_sums.tolist(), upper_sums.tolist(), strict=True):
            weight = self._gamma ** n.depth / self._k
            n.l0 = weight * v - lam
            n.u0 = n.l0 if n.terminal.all() else weight * u  # all ended: the value is known
            if n.u0 < n.l0:
                if n.l0 - n.u0 > CROSSING_TOLERANCE:
                    self._crossings += 1
                n.u0 = n.l0
            n.lower = n.l0
            n.upper = n.lower if n.depth >= max_depth else n.u0  # MAKEDEFAULT at depth D

    def _rollout(self, states, scenarios, terminal, depths, offsets) -> np.ndarray:
        """(M,) discounted returns of the default policy from each row until depth D or
        the row's scenario ends. Rows ``offsets[j]:offsets[j + 1]`` are one node's
        scenarios: the default policy acts on each node's set (it may be open-loop over
        the node's belief, like the reference's particle-set policies). The model's
        compiled rollout runs all nodes at once, if it has one and the default policy is
        its own; otherwise all nodes' rows are stepped in one ``step`` call per depth, each
        node's default action chosen on its own live rows."""
        if self._compiled_rollout is not None:
            return np.where(terminal, 0.0, self._compiled_rollout(
                states, scenarios, depths, offsets, self._uniforms, self.settings.depth))
        value = np.zeros(len(states))
        current = np.array(states, copy=True)
        depth = np.array(depths, dtype=np.int64, copy=True)
        scale = np.ones(len(states))
        node = np.repeat(np.arange(len(offsets) - 1), np.diff(offsets))
        alive = ~np.asarray(terminal, dtype=bool) & (depth < self.settings.depth)
        while alive.any():
            live = np.flatnonzero(alive)  # ascending, so each node's rows are contiguous
            actions = np.empty(len(live), dtype=np.int64)
            cuts = np.flatnonzero(np.diff(node[live])) + 1
            for rows in np.split(np.arange(len(live)), cuts):  # one call per node
                actions[rows] = action_array(self._default(current[live[rows]]), len(rows))
            step = self.model.step(current[live], actions,
                                   self._uniforms[scenarios[live], depth[live]])
            value[live] += scale[live] * step.rewards
            current[live] = step.next_states
            scale[live] *= self._gamma
            depth[live] += 1
            alive[live] = ~step.terminal & (depth[live] < self.settings.depth)
        return value

    def _expand(self, node: _BeliefNode) -> None:
        """Every action's child nodes: one ``step`` call for all actions and all the
        node's live scenarios (n x A rows), the children's bounds in one batch."""
        live = ~node.terminal
        n, count = int(live.sum()), self._actions
        states = np.repeat(node.states[live], count, axis=0)
        scenarios = np.repeat(node.scenarios[live], count)
        actions = np.tile(np.arange(count), n)
        step = self.model.step(states, actions, self._uniforms[scenarios, node.depth])
        weight = self._gamma ** node.depth / self._k
        lam = self.settings.regularization
        rho = weight * np.bincount(actions, weights=step.rewards, minlength=count) - lam
        key = actions * (int(step.observations.max(initial=0)) + 1) + step.observations
        order = np.argsort(key, kind="stable")
        codes, starts = np.unique(key[order], return_index=True)
        children: list[dict] = [{} for _ in range(count)]
        new = []
        width = int(step.observations.max(initial=0)) + 1
        for code, rows in zip(codes, np.split(order, starts[1:]), strict=True):
            child = _BeliefNode(node.depth + 1, scenarios[rows], step.next_states[rows],
                                step.terminal[rows])
            children[int(code) // width][int(code) % width] = child
            new.append(child)
        if new:
            self._initialise(new)
        node.children = [_ActionNode(float(rho[a]), children[a]) for a in range(count)]

    def _trial(self, root: _BeliefNode) -> list[_BeliefNode]:
        """One AR-DESPOT trial (JAIR Algorithm 3); returns the path it took, root first."""
        node, path = root, [root]
        root_gap = root.upper - root.lower
        xi = self.settings.xi
        while node.depth < self.settings.depth and not node.terminal.all():
            if node.children is None:
                self._expand(node)
            action = max(node.children, key=lambda q: q.upper)
            if not action.children:
                break
            node = max(action.children.values(), key=lambda b: self._excess(b, root_gap, xi))
            path.append(node)
            if self._excess(node, root_gap, xi) < 0:
                break
        return path

    def _excess(self, node: _BeliefNode, root_gap: float, xi: float) -> float:
        return node.upper - node.lower - xi * len(node.scenarios) / self._k * root_gap

    def _expand_next(self, frontier: deque) -> tuple[_BeliefNode, ...] | None:
        """R-DESPOT within a budget: expand the oldest unexpanded node (breadth first);
        returns its path from the root."""
        while frontier:
            path = frontier.popleft()
            node = path[-1]
            if node.depth >= self.settings.depth or node.terminal.all():
                continue
            self._expand(node)
            for q in node.children:
                frontier.extend((*path, child) for child in q.children.values())
            return path
        return None

    def _backup(self, path) -> None:
        """Bounds from the end of ``path`` up to the root (JAIR Algorithm 4's BACKUP)."""
        for node in reversed(path):
            self._back_up_node(node)

    def _back_up_node(self, node: _BeliefNode) -> None:
        """One node's bounds from its children's; a crossing is repaired and counted."""
        if node.children:
            for q in node.children:
                q.lower = q.rho + sum(c.lower for c in q.children.values())
                q.upper = q.rho + sum(c.upper for c in q.children.values())
            node.lower = max(node.l0, max(q.lower for q in node.children))
            if node.depth < self.settings.depth:
                node.upper = max(node.l0, max(q.upper for q in node.children))
        if node.upper < node.lower:
            if node.lower - node.upper > CROSSING_TOLERANCE:
                self._crossings += 1
            node.upper = node.lower

    def _rescale(self, node: _BeliefNode, scale: float, shift: int) -> None:
        """Re-root a subtree: depths less ``shift``, and its bounds recomputed with the new
        weights (each weighted sum times ``scale``; lambda stays per node)."""
        lam = self.settings.regularization
        order = list(belief_nodes(node))
        for b in order:
            b.depth -= shift
            b.l0 = (b.l0 + lam) * scale - lam
            b.u0 = b.u0 * scale if not b.terminal.all() else b.l0
            for q in b.children or ():
                q.rho = (q.rho + lam) * scale - lam
        for b in reversed(order):  # leaves first
            b.lower = b.l0
            b.upper = b.lower if b.depth >= self.settings.depth else b.u0
            self._back_up_node(b)

    # -- answers
    def _best_action(self, root: _BeliefNode) -> int:
        """The action of largest lower bound (ties: of largest upper bound); the default
        policy's (the most frequent over the root's scenarios) when the root is not
        expanded, its bounds are not finite, or the default policy's value l0 is above
        every action's lower bound (:func:`default_is_better`)."""
        ranking = self.ranking(root)
        if ranking is not None and not default_is_better(
                root.l0, [q.lower for q in root.children]):
            return ranking[0]
        live = root.states[~root.terminal] if (~root.terminal).any() else root.states
        actions = action_array(self._default(live), len(live))
        return int(np.bincount(actions, minlength=self._actions).argmax())

    def ranking(self, root) -> tuple[int, ...] | None:
        """Every action, best first by (lower, upper) bound at the root; None when the
        root is not expanded or a bound is not finite."""
        if isinstance(root, ArrayTree):
            return self._array_ranking(root)
        if not root.children:
            return None
        lows = np.array([q.lower for q in root.children])
        ups = np.array([q.upper for q in root.children])
        if not (np.all(np.isfinite(lows)) and np.all(np.isfinite(ups))):
            return None
        return tuple(int(a) for a in np.lexsort((-ups, -lows)))

    def _action_bounds(self, root: _BeliefNode, which: str) -> tuple[float, ...]:
        if not root.children:
            return (float("nan"),) * self._actions
        return tuple(float(getattr(q, which)) for q in root.children)

    def _policy_size(self, root: _BeliefNode) -> int:
        """Belief nodes of the regularised policy, pruned where the default is as good."""
        size, stack = 0, [root]
        while stack:
            b = stack.pop()
            size += 1
            if not b.children:
                continue
            best = max(b.children, key=lambda q: q.lower)
            if best.lower > b.l0:
                stack.extend(best.children.values())
        return size

    def _count(self, root: _BeliefNode) -> int:
        return sum(1 for _ in belief_nodes(root))

    def _deepest(self, root: _BeliefNode) -> int:
        return max(b.depth for b in belief_nodes(root))
