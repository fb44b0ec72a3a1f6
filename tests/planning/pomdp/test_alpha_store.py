"""The two-layout alpha-vector store: products, growth and pruning agree with plain numpy,
and pruning keeps every sub-plan of what it keeps."""

import numpy as np
import pytest

from planning.pomdp.alpha_store import AlphaStore
from planning.pomdp.point_based_kernels import alpha_products, products_at_beliefs


def _filled(rng, count=83, n_states=40):
    """Vector k leads to vectors k // 2 and k // 3 (a sub-plan is always older)."""
    store = AlphaStore(n_states, 2, capacity=16)  # grows three times
    vectors = rng.normal(size=(count, n_states))
    for k, alpha in enumerate(vectors):
        store.add(alpha, k % 5, np.array([k // 2, k // 3]))
        store.written()
    return store, vectors


def test_products_read_both_layouts_and_match_numpy():
    rng = np.random.default_rng(0)
    store, vectors = _filled(rng)
    assert 0 < store.flushed < store.count == len(vectors)  # some vectors only by row
    np.testing.assert_array_equal(store.vectors, vectors)
    columns = np.array([1, 2, 3, 7, 20, 39])
    rows = rng.random((3, len(columns)))
    rows[1] = 0.0  # an all-zero row (an impossible observation) is allowed
    for first in (0, 10, store.flushed, store.count - 1):
        np.testing.assert_allclose(alpha_products(store.view(), first, columns, rows),
                                   rows @ vectors[first:, columns].T, atol=1e-12)


def test_products_at_flat_beliefs():
    rng = np.random.default_rng(1)
    store, vectors = _filled(rng)
    supports = [np.array([0, 5, 6]), np.array([2]), np.arange(10, 40)]
    probs = [rng.dirichlet(np.ones(len(s))) for s in supports]
    offsets = np.cumsum([0] + [len(s) for s in supports])
    values = products_at_beliefs(store.view(), 30, offsets, np.concatenate(supports),
                                 np.concatenate(probs))
    expected = np.stack([vectors[30:, s] @ p for s, p in zip(supports, probs, strict=True)])
    np.testing.assert_allclose(values, expected, atol=1e-12)


def test_keep_compacts_both_layouts_the_actions_and_the_sub_plans():
    rng = np.random.default_rng(2)
    store, vectors = _filled(rng)
    actions = np.arange(len(vectors)) % 5
    index = store.closure(np.array([40, store.flushed, store.count - 1]))
    assert set(index) >= {40, 20, 13, 10, 6, 5, 3, 2, 1, 0, store.count - 1}
    store.keep(index)
    np.testing.assert_array_equal(store.vectors, vectors[index])
    np.testing.assert_array_equal(store.actions, actions[index])
    np.testing.assert_array_equal(index[store.children], np.stack([index // 2, index // 3], 1))
    columns = np.arange(0, 40, 3)
    rows = rng.random((2, len(columns)))
    np.testing.assert_allclose(alpha_products(store.view(), 0, columns, rows),
                               rows @ vectors[index][:, columns].T, atol=1e-12)


def test_a_pruned_sub_plan_becomes_minus_one():
    store, _ = _filled(np.random.default_rng(4))
    store.keep(np.array([0, 1, 40]))  # 40 leads to 20 and 13, both pruned
    np.testing.assert_array_equal(store.children, [[0, 0], [0, 0], [-1, -1]])
    np.testing.assert_array_equal(store.closure(np.array([1])), [0, 1])
    np.testing.assert_array_equal(store.closure(np.array([2])), [2])


@pytest.mark.parametrize("index", [[3, 1], [0, 0], [0, 500]])
def test_keep_rejects_a_bad_index(index):
    store, _ = _filled(np.random.default_rng(3))
    with pytest.raises(ValueError, match="sorted, distinct"):
        store.keep(np.array(index))
