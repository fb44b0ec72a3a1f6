"""Lat-POMDP (thesis sec. 7.1.2) as a generative POMDP for DESPOT.

State: a row ``[p, *s_rel]``: the lattice point ``p`` of the robot's configuration
(``q_lat(x_p)``) and the hand-relative state ``s_rel`` of an inner hand-relative model;
``p = -1`` is the absorbing ``s_bad``. The inner model is either

- the discrete Rel-POMDP (:class:`~planning.pomdp.generative.TabularGenerative`, ``s_rel``
  the cell), for the value on the discretised model (thesis Fig. 7.4-Top), or
- the continuous planar model (:class:`~planning.hand.generative.ContinuousHandGenerative`,
  ``s_rel`` the object's pose (x m, y m, theta rad) in the hand frame), for the success
  rate on the continuous model (Fig. 7.4-Middle).

Transition: when template ``a`` is feasible from ``p`` (the lattice's local planner,
evaluated lazily and kept; :class:`~planning.lattice.lattice.ConfigurationLattice`) the
object moves as in the hand-relative model and the robot to ``p``'s neighbour; then, if the
object touches an obstacle or leaves the table
(:class:`~planning.lattice.contact.UnmodelledContact`; for a cell, at its representative
pose), or when ``a`` is infeasible, the state becomes
``s_bad``. Reward: the hand-relative reward, and -1 for an infeasible action, for
un-modelled contact and for every step in ``s_bad``. Because ``s_bad`` is absorbing with
reward -1 whatever the action, its whole future is known: the step into it returns
``-1 / (1 - gamma)`` at once and ends the scenario (terminal). The value is the thesis'
(up to DESPOT's depth limit, where the thesis' sum would stop after ``gamma^D``); the search
no longer steps scenarios that can gain nothing. Observation: the inner model's; in
``s_bad`` it is uniform over the observations (the thesis' ``O_lat``), which only the belief
update sees (:meth:`LatticePOMDP.log_likelihood`).

Bounds (thesis sec. 7.2.2-7.2.3):

- upper: Rel-QMDP's value ``V_MDP`` of the scenario's cell (Theorem 7.2: an upper bound of
  Rel-POMDP, hence of Lat-POMDP); 0 in ``s_bad`` (its value is already counted);
- lower: the return of Lift-QMDP rolled out on the discrete Lat-POMDP from each scenario's
  cell (:meth:`LatticePOMDP.rollout`): at every depth, the action of largest Rel-QMDP value
  summed over the node's live scenarios' cells, replaced by the next-best feasible one when
  the lattice says it is infeasible (the lattice queried in that order, lazily); rows that
  make un-modelled contact go to ``s_bad``.

Outside the trust region (continuous inner model only; beyond the thesis). The discrete
model's sentinel is absorbing, so both bounds value an object outside the trust region at
``-1 / (1 - gamma)``, wherever it lies; the continuous model keeps simulating it and the hand
can bring it back. ``outside="sentinel"`` keeps the discrete model's view (a search whose
scenarios have all left sees every action alike); ``outside="return"`` values such a
scenario as if it returned by the shortest path: ``d`` steps of -1 (``d``: the 1-norm of its
distance to the region, in action steps), then the bound of the nearest cell inside, i.e.
``gamma^d V(clamped) - (1 - gamma^d) / (1 - gamma)``, and starts its rollout there at depth
``+ d`` (a heuristic like the rest of the continuous bounds; measured against the sentinel
in ``experiments/results/latdespot_continuous_return/``: the goal reached more often, ended
in as often).

The robot's configuration is known: every live scenario of a node has the same lattice
point (the actions so far fix it), so the rollout asks the lattice one edge per node and
depth, in one batch per depth.
"""

from __future__ import annotations

import numpy as np

from planning.hand.generative import ContinuousHandGenerative
from planning.hand.model import HandPOMDP
from planning.lattice.contact import UnmodelledContact
from planning.lattice.kernels import BAD, lat_rollout, lat_step, lat_upper, lift_rollouts
from planning.lattice.lattice import ConfigurationLattice
from planning.pomdp.generative import GenerativeStep, TabularGenerative, action_array
from planning.pomdp.point_based import AlphaVectorPolicy

UNKNOWN_CONTACT = -1
OUTSIDE_MODES = ("sentinel", "return")


def cell_poses(model: HandPOMDP) -> np.ndarray:
    """(S, 3) a representative hand-frame pose of each model state (cell centre, contact
    piece midpoint); NaN for the sentinel (outside the planning region)."""
    raw = model.discretization.representative_poses()
    poses = np.full((len(model.pomdp.states), 3), np.nan)
    kept = model.kept[:len(raw)]
    poses[kept[kept >= 0]] = raw[kept >= 0]
    return poses


def lift_choice(values: np.ndarray, feasible) -> np.ndarray:
    """The Lift policies' choice (thesis sec. 7.3.2): per row of ``values`` (J, A) (an
    action value per row, e.g. Rel-QMDP's Q summed over a belief), the best action that
    ``feasible(rows (n,), actions (n,)) -> (n,) bool`` accepts, asking it in order of value
    (so only the actions up to the chosen one are queried); where none is, the best.

    Returns:
        (J,) int64 actions.
    """
    order = np.argsort(-values, axis=1, kind="stable")
    chosen = order[:, 0].copy()
    pending = np.arange(len(values))
    for rank in range(values.shape[1]):
        if not len(pending):
            break
        ok = feasible(pending, order[pending, rank])
        chosen[pending[ok]] = order[pending[ok], rank]
        pending = pending[~ok]
    return chosen


class LatticePOMDP:
    """See the module docstring.

    Args:
        model: the discrete hand-relative POMDP (cells, Rel-QMDP, the continuous world).
        lattice: the scene's configuration lattice.
        contact: the scene's un-modelled contact check.
        inner: ``"discrete"`` (the tabular Rel-POMDP) or ``"continuous"`` (the planar
            model, :class:`~planning.hand.generative.ContinuousHandGenerative`).
        initial: the continuous initial belief (for ``sample_initial`` and the continuous
            inner model).
        upper_values: (S,) an upper bound of Rel-POMDP's value at each cell (default:
            Rel-QMDP's ``V_MDP``; the point-based solver's corner values are tighter).
        rollout_policy: the hand-relative policy lifted in the rollouts (default:
            Rel-QMDP, as the thesis; the point-based solver's alpha-vectors make them
            Lift-SARSOP's).
        outside: ``"sentinel"`` or ``"return"``: how the bounds value a continuous
            scenario outside the trust region (see the module docstring; the discrete
            inner model has only the sentinel).
    """

    def __init__(self, model: HandPOMDP, lattice: ConfigurationLattice,
                 contact: UnmodelledContact, *, inner: str = "discrete", initial=None,
                 upper_values: np.ndarray | None = None,
                 rollout_policy: AlphaVectorPolicy | None = None,
                 outside: str = "sentinel"):
        if inner not in ("discrete", "continuous"):
            raise ValueError(f"inner must be 'discrete' or 'continuous', got {inner!r}")
        if outside not in OUTSIDE_MODES:
            raise ValueError(f"outside must be one of {', '.join(OUTSIDE_MODES)}, got "
                             f"{outside!r}")
        if outside == "return" and inner != "continuous":
            raise ValueError("outside='return' needs the continuous inner model")
        self.outside = outside
        self.model = model
        self.lattice = lattice
        self.contact = contact
        self.tabular = TabularGenerative(model.pomdp, default_policy="qmdp")
        self.continuous = inner == "continuous"
        self.inner = (ContinuousHandGenerative(model, initial) if self.continuous
                      else self.tabular)
        self.initial = initial
        self.discount = model.pomdp.discount
        self.actions = model.pomdp.actions
        self.uniforms_per_step = self.inner.uniforms_per_step
        self.bad_return = -1.0 / (1.0 - self.discount)
        q = self.tabular.q_values
        self._upper_values = q.max(axis=1) if upper_values is None else np.asarray(
            upper_values, dtype=float)
        #: (S, N) the lifted policy's vectors as columns, and (N,) their actions
        if rollout_policy is None:
            self._alphas_t, self._alpha_actions = np.ascontiguousarray(q), np.arange(q.shape[1])
        else:
            self._alphas_t = np.ascontiguousarray(np.asarray(rollout_policy.alphas,
                                                             dtype=float).T)
            self._alpha_actions = np.asarray(rollout_policy.alpha_actions, dtype=np.int64)
        self._cell_poses = cell_poses(model)
        #: (P, S) int8 un-modelled contact of each cell at each point, -1 until asked.
        self._contact = np.full((lattice.spec.size, len(model.pomdp.states)),
                                UNKNOWN_CONTACT, dtype=np.int8)
        self._tabular_params = self.tabular.kernels()[1]
        self._terminal = self._tabular_params[5]
        #: the compiled search's request (point, action; action -1: a contact row)
        self._request = np.full(2, -1, dtype=np.int64)

    # -- the generative model
    def step(self, states: np.ndarray, actions: int | np.ndarray,
             u: np.ndarray) -> GenerativeStep:
        states = np.asarray(states, dtype=float)
        a = action_array(actions, len(states))
        points = states[:, 0].astype(np.int64)
        live = np.flatnonzero(points != BAD)
        next_states = states.copy()
        rewards = np.zeros(len(states))
        terminal = points == BAD
        observations = np.zeros(len(states), dtype=np.int64)
        if len(live):
            feasible = self.lattice.feasible(points[live], a[live])
            inner = self.inner.step(self._inner(states[live]), a[live], u[live])
            targets = self.lattice.neighbours[points[live], a[live]]
            touched = np.zeros(len(live), dtype=bool)
            touched[feasible] = self.touches(targets[feasible],
                                             inner.next_states[feasible])
            bad = ~feasible | touched
            next_states[live, 0] = np.where(bad, BAD, targets)
            next_states[live, 1:] = np.where(bad[:, None], states[live, 1:],
                                             inner.next_states)
            rewards[live] = np.where(bad, self.bad_return, inner.rewards)
            terminal[live] = bad | inner.terminal
            observations[live] = inner.observations
        return GenerativeStep(next_states, rewards, observations, terminal)

    def log_likelihood(self, observation: int, states: np.ndarray,
                       action: int) -> np.ndarray:
        states = np.asarray(states, dtype=float)
        out = np.full(len(states), -np.log(len(self.model.pomdp.observations)))
        live = states[:, 0] != BAD
        if live.any():
            out[live] = self.inner.log_likelihood(observation, self._inner(states[live]),
                                                  action)
        return out

    def sample_initial(self, n: int, *, rng: np.random.Generator) -> np.ndarray:
        """(n, 1 + d) the start point with the inner model's initial states (the
        continuous belief's samples, or their cells)."""
        if self.initial is None:
            raise ValueError("LatticePOMDP needs an initial belief to sample from")
        poses = self.initial.sample(self.model.world, n, rng=rng)
        return self.from_poses(self.lattice.start_point, poses)

    def free_at_start(self, belief: np.ndarray) -> np.ndarray:
        """(S,) the discrete ``belief`` (S,) conditioned on the object touching nothing with
        the robot at the lattice's start (the cells that touch removed, renormalised)."""
        free = ~self.cells_touch(np.full(len(belief), self.lattice.start_point),
                                 np.arange(len(belief)))
        return belief * free / float(np.sum(belief * free))

    def with_point(self, point: int, inner_states: np.ndarray) -> np.ndarray:
        """Rows ``[point, s_rel]`` of the inner model's states (n, d)."""
        inner = np.asarray(inner_states, dtype=float).reshape(len(inner_states), -1)
        return np.column_stack([np.full(len(inner), float(point)), inner])

    def from_poses(self, point: int, poses: np.ndarray) -> np.ndarray:
        """Rows ``[point, s_rel]`` of hand-frame object poses (n, 3): the poses, or their
        cells for the discrete inner model."""
        poses = np.asarray(poses, dtype=float)
        return self.with_point(point, poses if self.continuous else self.model.index(poses))

    def is_terminal(self, states: np.ndarray) -> np.ndarray:
        return np.asarray(states)[:, 0] == BAD

    def upper_bound(self, states: np.ndarray) -> np.ndarray:
        states = np.asarray(states, dtype=float)
        cells, steps = self.bound_cells(states)
        kept = self.discount ** steps
        return np.where(states[:, 0] == BAD, 0.0,
                        kept * self._upper_values[cells] + (1.0 - kept) * self.bad_return)

    def policy_values(self, cells: np.ndarray) -> np.ndarray:
        """(A,) the lifted policy's action values at the histogram of ``cells`` (n,) (its
        best vector's summed value per action; -inf for an action without one)."""
        dots = self._alphas_t[cells].sum(axis=0)
        values = np.full(len(self.actions), -np.inf)
        np.maximum.at(values, self._alpha_actions, dots)
        return values

    def default_actions(self, states: np.ndarray) -> np.ndarray:
        """The lifted policy on the node's live scenarios (they share the lattice point),
        as the rollouts choose."""
        states = np.asarray(states, dtype=float)
        live = states[:, 0] != BAD
        if not live.any():
            return np.zeros(len(states), dtype=np.int64)
        point = int(states[np.flatnonzero(live)[0], 0])
        values = self.policy_values(self.bound_cells(states[live])[0])[None]
        action = lift_choice(values, lambda rows, acts: self.lattice.feasible(
            np.full(len(rows), point), acts))
        return np.full(len(states), int(action[0]), dtype=np.int64)

    def rollout(self, states, scenarios, depths, offsets, uniforms, max_depth) -> np.ndarray:
        """(M,) Lift-QMDP's discounted returns on the discrete Lat-POMDP from each row's
        point and cell, rows ``offsets[j]:offsets[j + 1]`` being node j's scenarios: the
        compiled kernel (:mod:`planning.lattice.kernels`), with the lattice's answers it
        asks for evaluated between its calls, each call's requests in one batch."""
        states = np.asarray(states, dtype=float)
        points = states[:, 0].astype(np.int64)
        cells, steps = self.bound_cells(states)
        depth = np.asarray(depths, dtype=np.int64) + steps
        scale = self.discount ** steps
        value = (1.0 - scale) * self.bad_return
        alive = (points != BAD) & (depth < max_depth) & ~self._terminal[cells]
        offsets = np.asarray(offsets, dtype=np.int64)
        pending = np.empty((len(offsets) - 1, 2), dtype=np.int64)
        indptr, indices, cumulative, _, R, terminal, _, _, _ = self._tabular_params
        while True:
            lift_rollouts(points, cells, depth, scale, value, alive, offsets,
                          np.asarray(scenarios, dtype=np.int64), uniforms, max_depth,
                          self.discount, self.bad_return, indptr, indices, cumulative, R,
                          terminal, self._alphas_t, self._alpha_actions, self.lattice.status,
                          self.lattice.neighbours, self._contact, pending)
            asked = pending[pending[:, 0] >= 0]
            if not len(asked):
                return value
            edges = asked[asked[:, 1] >= 0]
            if len(edges):
                self.lattice.feasible(edges[:, 0], edges[:, 1])
            self._contact_rows(asked[asked[:, 1] < 0, 0])

    # -- the compiled search (planning.pomdp.despot_kernels)
    def kernels(self):
        """The compiled DESPOT's kernels (:mod:`planning.lattice.kernels`) and their
        parameters, for the discrete inner model (None for the continuous one, which has
        no compiled step: DESPOT then runs its Python engine). The parameters hold the
        lattice's and the contact table's arrays themselves, so what
        :meth:`answer_kernel_request` evaluates the kernels see."""
        if self.continuous:
            return None
        return (lat_step, lat_upper, lat_rollout), (
            self._tabular_params, self.lattice.status, self.lattice.neighbours,
            self._contact, self._upper_values, self._alphas_t, self._alpha_actions,
            self.lattice.asked, self._request, self.bad_return)

    def answer_kernel_request(self) -> None:
        """Evaluate what a compiled kernel asked for: an edge, or a point's contact row."""
        point, action = (int(v) for v in self._request)
        if action >= 0:
            self.lattice.feasible([point], [action])
        else:
            self._contact_rows(np.array([point]))

    def warm_up_states(self, n: int) -> np.ndarray:
        """(n, 2) rows in ``s_bad``: a search from them compiles the kernels and asks the
        lattice nothing (see :meth:`planning.pomdp.despot.Despot._warm_up`)."""
        return np.tile([float(BAD), 0.0], (n, 1))

    # -- helpers
    def _inner(self, states: np.ndarray) -> np.ndarray:
        return states[:, 1:] if self.continuous else states[:, 1:].astype(np.int64)

    def cells(self, states: np.ndarray) -> np.ndarray:
        """(K,) the discrete cell of each row's hand-relative state."""
        inner = states[:, 1:]
        return self.model.index(inner) if self.continuous else inner[:, 0].astype(np.int64)

    def bound_cells(self, states: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(cells (K,), steps (K,) int64): the cell whose bounds each row takes and the
        steps it is charged to get there: its own cell and 0, except, with
        ``outside="return"``, a pose outside the trust region: the cell of its nearest
        pose inside and the 1-norm of the distance, in action steps (module docstring)."""
        cells = self.cells(states)
        steps = np.zeros(len(states), dtype=np.int64)
        if self.outside == "sentinel" or not len(states):
            return cells, steps
        trust = self.model.discretization.spec
        lo = np.array([trust.trust_x_m[0], trust.trust_y_m[0]])
        hi = np.array([trust.trust_x_m[1], trust.trust_y_m[1]])
        xy = states[:, 1:3]
        excess = np.maximum(lo - xy, 0.0) + np.maximum(xy - hi, 0.0)
        out = np.flatnonzero((states[:, 0] != BAD) & (excess.sum(axis=1) > 0))
        if len(out):
            margin = 0.5 * trust.free_cell_m  # a cell centre's distance from the edge
            nearest = states[out, 1:].copy()
            nearest[:, :2] = np.clip(xy[out], lo + margin, hi - margin)
            cells[out] = self.model.index(nearest)
            steps[out] = np.ceil(excess[out] / self.model.spec.step_m - 1e-9).sum(axis=1)
        return cells, steps

    def touches(self, points: np.ndarray, inner_states: np.ndarray) -> np.ndarray:
        """(K,) bool: un-modelled contact of inner states at lattice points."""
        if self.continuous:
            return self.contact.touches(self.lattice.poses[points], inner_states)
        return self.cells_touch(points, np.asarray(inner_states)[:, 0].astype(np.int64))

    def cells_touch(self, points: np.ndarray, cells: np.ndarray) -> np.ndarray:
        """(K,) bool: does the representative pose of each cell touch something at its
        lattice point?"""
        points = np.asarray(points, dtype=np.int64)
        self._contact_rows(points)
        return self._contact[points, np.asarray(cells, dtype=np.int64)] == 1

    def _contact_rows(self, points: np.ndarray) -> None:
        """Fill the contact table's rows (every cell) of the points not filled yet."""
        todo = np.unique(points[self._contact[points, 0] == UNKNOWN_CONTACT])
        for point in todo:
            poses = self.lattice.poses[np.full(len(self._cell_poses), point)]
            self._contact[point] = self.contact.touches(poses, self._cell_poses)
