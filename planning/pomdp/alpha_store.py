"""The point-based solver's alpha-vectors, kept in two memory layouts.

The search reads every vector at a belief's support, a few hundred states: column-major
storage makes that a run of contiguous reads per state, and the loop over vectors
vectorises. But a new vector is written over all S states, and it is built from a few
whole vectors: in column-major storage each of those S reads and writes falls on its own
cache line (on RockSample(7,8), 12,545 states, about 1.4 ms per backup). So the vectors are
kept row-major (``by_row``: one contiguous row each, where new vectors are built and read
whole), and a column-major copy (``by_column``) holds all but the newest few, which are
transposed into it in blocks of :attr:`AlphaStore.FLUSH_EVERY`. The compiled products
(:func:`planning.pomdp.point_based_kernels.alpha_products`) read the copy up to ``flushed`` and
the rows after it. The price is twice the memory.
"""

from __future__ import annotations

import numpy as np

from planning.pomdp.point_based_kernels import compact_columns, compact_rows


class AlphaStore:
    """Growable storage of (K, S) alpha-vectors, their actions (K,) and their sub-plans
    (K, O): the vector each observation leads to (the conditional plan whose value the
    vector is; a blind policy's vector leads to itself).

    Args:
        n_states: S.
        n_observations: O.
        capacity: initial room, in vectors (doubled when full; each doubling copies both
            layouts, about 60 ms at 1000 vectors of RockSample(7,8)).
    """

    FLUSH_EVERY = 8

    def __init__(self, n_states: int, n_observations: int, capacity: int = 1024):
        self.by_row = np.empty((capacity, n_states))
        self.by_column = np.empty((capacity, n_states), order="F")
        self._actions = np.empty(capacity, dtype=np.int64)
        self._children = np.empty((capacity, n_observations), dtype=np.int64)
        self.count = 0
        self.flushed = 0  # vectors [0, flushed) are also in by_column

    def __len__(self) -> int:
        return self.count

    @property
    def vectors(self) -> np.ndarray:
        """(K, S) the vectors (a contiguous view)."""
        return self.by_row[:self.count]

    @property
    def actions(self) -> np.ndarray:
        """(K,) the action of each vector (a view)."""
        return self._actions[:self.count]

    @property
    def children(self) -> np.ndarray:
        """(K, O) the vector each observation leads to (a view)."""
        return self._children[:self.count]

    def view(self) -> tuple[np.ndarray, int, np.ndarray, int]:
        """What the compiled kernels read: ``(by_column, flushed, by_row, count)``."""
        return self.by_column, self.flushed, self.by_row, self.count

    def add(self, alpha: np.ndarray, action: int, children: np.ndarray) -> None:
        row = self.reserve(action, children)  # may grow, and replace, by_row
        self.by_row[row] = alpha

    def reserve(self, action: int, children: np.ndarray) -> int:
        """The row where a new vector of ``action`` with sub-plans ``children`` (O,) is to
        be written; call :meth:`written` once it is there."""
        if self.count == len(self.by_row):
            self._grow()
        self._actions[self.count] = action
        self._children[self.count] = children
        self.count += 1
        return self.count - 1

    def closure(self, index: np.ndarray) -> np.ndarray:
        """The sorted vectors ``index`` and every vector their sub-plans lead to."""
        kept = np.zeros(self.count, dtype=bool)
        frontier = np.unique(np.asarray(index, dtype=np.int64))
        while len(frontier):
            kept[frontier] = True
            following = np.unique(self._children[frontier].ravel())
            following = following[following >= 0]
            frontier = following[~kept[following]]
        return np.flatnonzero(kept)

    def written(self) -> None:
        """Transpose the newest vectors into the column-major copy once there are enough."""
        if self.count - self.flushed >= self.FLUSH_EVERY:
            self.by_column[self.flushed:self.count] = self.by_row[self.flushed:self.count]
            self.flushed = self.count

    def keep(self, index: np.ndarray) -> None:
        """Keep only the vectors at the sorted ``index``, in that order (in place). A
        sub-plan that is not kept becomes -1 (:meth:`closure` keeps them all)."""
        index = np.asarray(index, dtype=np.int64)
        if len(index) and (np.any(np.diff(index) <= 0) or index[-1] >= self.count):
            raise ValueError("index must be sorted, distinct and below the vector count")
        renumber = np.full(self.count, -1, dtype=np.int64)
        renumber[index] = np.arange(len(index))
        self._children[:len(index)] = renumber[self._children[index]]  # -1: pruned
        compact_rows(self.by_row, index)
        flushed_kept = index[index < self.flushed]
        compact_columns(self.by_column.T, flushed_kept)
        self._actions[:len(index)] = self._actions[index]
        self.count, self.flushed = len(index), len(flushed_kept)
        self.written()

    def _grow(self) -> None:
        capacity, n_states = 2 * len(self.by_row), self.by_row.shape[1]
        by_row = np.empty((capacity, n_states))
        by_row[:self.count] = self.by_row[:self.count]
        by_column = np.empty((capacity, n_states), order="F")
        by_column[:self.flushed] = self.by_column[:self.flushed]
        actions = np.empty(capacity, dtype=np.int64)
        actions[:self.count] = self._actions[:self.count]
        children = np.empty((capacity, self._children.shape[1]), dtype=np.int64)
        children[:self.count] = self._children[:self.count]
        self.by_row, self.by_column, self._actions = by_row, by_column, actions
        self._children = children
