"""The generative models against the tabular models they restate: same rewards, and the
successor and observation distributions that inverse-CDF sampling from the uniforms
produces (evaluated on a fine grid of uniforms, so the tolerance is the grid's)."""

import numpy as np
import pytest

from planning.pomdp.benchmarks import rock_sample, tag, tiger
from planning.pomdp.generative import TabularGenerative
from planning.pomdp.problems import load_problem
from planning.pomdp.qmdp import solve_mdp
from planning.pomdp.rocksample import RockSample, full_information_values, layout
from planning.pomdp.tag import Tag

GRID = 400  # uniforms (i + 0.5) / GRID: probabilities are exact to 1 / GRID



def test_tabular_wrapper_samples_the_rows_of_T_and_Z():
    pomdp = tiger()
    model = TabularGenerative(pomdp)
    rng = np.random.default_rng(0)
    for a in range(3):
        states = np.array([[0], [1]])
        n = 20_000
        u = rng.random((n, 2))
        for s in (0, 1):
            step = model.step(np.full((n, 1), s), a, u)
            successor = np.bincount(step.next_states[:, 0], minlength=2) / n
            np.testing.assert_allclose(successor, pomdp.T[a].toarray()[s], atol=0.015)
            assert np.all(step.rewards == pomdp.R[s, a])
            for s2 in np.unique(step.next_states[:, 0]):
                seen = step.observations[step.next_states[:, 0] == s2]
                np.testing.assert_allclose(np.bincount(seen, minlength=2) / len(seen),
                                           pomdp.Z[a, s2], atol=0.03)
        assert not model.is_terminal(states).any()


def test_tag_restates_the_tabular_tag():
    native, tabular = Tag(), tag()
    rng = np.random.default_rng(1)
    states = np.column_stack([rng.integers(0, 29, 40), rng.integers(0, 30, 40)])
    states[:5, 1] = states[:5, 0]  # some on the same cell
    index = native.state_index(states)
    for a in range(5):
        u = ((np.arange(GRID) + 0.5) / GRID)[:, None]
        for s, i in zip(states, index, strict=True):
            step = native.step(np.repeat(s[None], GRID, axis=0), a, u)
            got = np.bincount(native.state_index(step.next_states), minlength=870) / GRID
            np.testing.assert_allclose(got, tabular.T[a].toarray()[i], atol=1.5 / GRID)
            assert np.all(step.rewards == tabular.R[i, a])
            z = tabular.Z[a, native.state_index(step.next_states)]
            assert np.all(z[np.arange(GRID), step.observations] == 1.0)
    np.testing.assert_allclose(native.upper_bound(states), solve_mdp(tabular).max(axis=1)[index])


def test_rocksample_restates_the_tabular_builder_with_the_reference_penalties():
    native = RockSample(7, 8)
    tabular = rock_sample(wall_reward=-100.0, empty_sample_reward=-100.0)
    rng = np.random.default_rng(2)
    states = np.column_stack([rng.integers(0, 7, 60), rng.integers(0, 7, 60),
                              rng.integers(0, 256, 60)])
    states[:8, :2] = native.rocks  # on every rock
    states[8:12, 0] = 7  # exited
    index = native.state_index(states)
    u = ((np.arange(GRID) + 0.5) / GRID)[:, None]
    for a in range(len(native.actions)):
        for s, i in zip(states, index, strict=True):
            step = native.step(np.repeat(s[None], GRID, axis=0), a, u)
            successor = native.state_index(step.next_states)
            row = tabular.T[a].getrow(i)
            assert row.nnz == 1 and np.all(successor == row.indices[0])  # deterministic
            assert np.all(step.rewards == tabular.R[i, a])
            frequencies = np.bincount(step.observations, minlength=3) / GRID
            np.testing.assert_allclose(frequencies, tabular.Z[a, successor[0]], atol=1.5 / GRID)
        assert np.all(native.is_terminal(states) == (index == len(tabular.states) - 1))


def test_rocksample_upper_bound_is_the_full_information_mdp_value():
    native = RockSample(7, 8)
    tabular = rock_sample(wall_reward=-100.0, empty_sample_reward=-100.0)
    value = solve_mdp(tabular, tolerance=1e-9).max(axis=1)
    rng = np.random.default_rng(3)
    states = np.column_stack([rng.integers(0, 7, 300), rng.integers(0, 7, 300),
                              rng.integers(0, 256, 300)])
    np.testing.assert_allclose(native.upper_bound(states), value[native.state_index(states)],
                               atol=1e-6)


def test_rocksample_layouts_are_the_reference_ones_or_seeded():
    assert layout(7, 8)[0] == (2, 0) and layout(11, 11)[-1] == (9, 9)
    assert layout(15, 15, seed=4) == layout(15, 15, seed=4) != layout(15, 15, seed=5)
    assert len(set(layout(15, 15))) == 15
    with pytest.raises(ValueError, match="RockSample"):
        layout(3, 9)
    values = full_information_values(np.array([[1, 0]]), 3, 0.95)
    assert values.shape == (1, 2) and values[0, 1] == pytest.approx(10 + 0.95 * 10 * 0.95)


def test_problems_by_name(tmp_path):
    from planning.pomdp.cassandra import write_pomdp

    assert isinstance(load_problem("tag"), Tag)
    model = load_problem("rocksample:5:3")
    assert model.rock_count == 3 and len(model.actions) == 8
    path = tmp_path / "tiger.pomdp"
    write_pomdp(tiger(), path)
    assert load_problem(str(path)).actions == tiger().actions
    for bad in ("rocksample:7", "rocksample:a:b", "lasertag"):
        with pytest.raises(ValueError, match="rocksample:N:K|unknown problem"):
            load_problem(bad)
    with pytest.raises(FileNotFoundError, match="missing.pomdp"):
        load_problem(str(tmp_path / "missing.pomdp"))
