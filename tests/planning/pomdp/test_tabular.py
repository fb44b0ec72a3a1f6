"""The tabular POMDP, its .pomdp exchange format, the benchmarks, QMDP and the Bayes filter."""

import numpy as np
import pytest

from planning.pomdp.benchmarks import rock_sample, tag, tiger
from planning.pomdp.cassandra import PomdpFormatError, read_pomdp, write_pomdp
from planning.pomdp.qmdp import mdp_horizon_values, qmdp_policy
from planning.pomdp.tabular import belief_update, simulate_value

CLASSIC_TIGER = """# the classic layout: matrices, identity, uniform, wildcards
discount: 0.95
values: reward
states: tiger-left tiger-right
actions: listen open-left open-right
observations: tiger-left tiger-right
T: listen
identity
T: open-left
uniform
T: open-right
uniform
O: listen
0.85 0.15
0.15 0.85
O: open-left
uniform
O: open-right
uniform
R: listen : * : * : * -1
R: open-left : tiger-left : * : * -100
R: open-left : tiger-right : * : * 10
R: open-right : tiger-left : * : * 10
R: open-right : tiger-right : * : * -100
"""


def _same(p, q):
    return (p.states == q.states and p.actions == q.actions and p.observations ==
            q.observations and all((a != b).nnz == 0 for a, b in zip(p.T, q.T, strict=True))
            and np.array_equal(p.Z, q.Z) and np.array_equal(p.R, q.R)
            and np.array_equal(p.initial, q.initial) and p.discount == q.discount)


@pytest.mark.parametrize("build", [tiger, tag])
def test_written_files_load_back_identically(build, tmp_path):
    model = build()
    write_pomdp(model, tmp_path / "m.pomdp")
    assert _same(model, read_pomdp(tmp_path / "m.pomdp"))


def test_the_classic_tiger_file_reads_as_the_built_in_tiger(tmp_path):
    path = tmp_path / "tiger.pomdp"
    path.write_text(CLASSIC_TIGER)
    model, builtin = read_pomdp(path), tiger()
    assert np.array_equal(model.R, builtin.R) and np.allclose(model.Z, builtin.Z)
    assert all(np.allclose(a.toarray(), b.toarray())
               for a, b in zip(model.T, builtin.T, strict=True))


@pytest.mark.parametrize("text, line, words", [
    (CLASSIC_TIGER.replace("0.85 0.15", "0.85 oops"), 14, "expected a number"),
    (CLASSIC_TIGER.replace("T: open-left\n", "T: open-middle\n"), 9, "unknown action"),
    (CLASSIC_TIGER.replace("0.85 0.15", "0.85 0.25"), None, "sums to"),
    (CLASSIC_TIGER.replace("discount: 0.95\n", ""), 6, "missing preamble"),
])
def test_malformed_files_name_the_line(tmp_path, text, line, words):
    path = tmp_path / "bad.pomdp"
    path.write_text(text)
    with pytest.raises(PomdpFormatError, match=words) as err:
        read_pomdp(path)
    where = "bad.pomdp:" if line is None else f"bad.pomdp:{line}:"
    assert where in str(err.value)


def test_benchmark_sizes():
    assert tag().shape == (870, 5, 30)
    assert rock_sample().shape == (12545, 13, 3)


def test_tag_opponent_runs_away_and_tagging_ends_the_episode():
    model = tag()
    n = 29
    # robot at cell 0 (bottom-left), opponent at cell 2 (two to the east): the opponent
    # moves east with 0.4, north/south split 0.2 + 0.2 (same row) and stays otherwise
    s = 0 * (n + 1) + 2
    row = model.T[4].getrow(s)  # tag (fails): robot stays
    probs = dict(zip((row.indices % (n + 1)).tolist(), row.data.tolist(), strict=True))
    assert probs[3] == pytest.approx(0.4) and probs[12] == pytest.approx(0.2)
    assert probs[2] == pytest.approx(0.4)  # 0.2 stay + 0.2 south into the wall
    assert model.R[s, 4] == -10.0
    same = 5 * (n + 1) + 5
    assert model.R[same, 4] == 10.0
    assert model.T[4].getrow(same).indices.tolist() == [5 * (n + 1) + n]


def test_rock_sample_checks_are_exact_on_the_rock():
    model = rock_sample()
    # robot on rock 0 at (2, 0) with every rock good: check0 reports "good" surely
    s = (0 * 7 + 2) * 256 + 255
    assert model.Z[5, s].tolist() == [0.0, 1.0, 0.0]
    assert model.R[s, 4] == 10.0  # sampling a good rock


def test_bayes_filter_on_tiger():
    model = tiger()
    belief, p = belief_update(model, model.initial, 0, 0)
    assert np.allclose(belief, [0.85, 0.15]) and p == pytest.approx(0.5)
    belief, _ = belief_update(model, belief, 0, 0)
    assert belief[0] == pytest.approx(0.85**2 / (0.85**2 + 0.15**2))


def test_qmdp_on_tiger_and_tag():
    model = tiger()
    policy = qmdp_policy(model)
    # fully observed tiger: open the right door for ever, 10 / (1 - 0.95) = 200
    assert policy.Q[0].max() == pytest.approx(200.0, abs=1e-3)
    assert policy.act(np.array([0.99, 0.01])) == 2
    value, half = simulate_value(tag(), qmdp_policy(tag()), 100, 60,
                                 rng=np.random.default_rng(0))
    assert -25.0 < value < -5.0 and half < 3.0


def test_the_mdp_horizon_values_are_the_finite_sums_and_tend_to_the_infinite_value():
    model = tiger()
    # fully observed tiger: 10 a step for h steps, discounted
    assert mdp_horizon_values(model, 1) == pytest.approx([10.0, 10.0])
    assert mdp_horizon_values(model, 3)[0] == pytest.approx(10 * (1 + 0.95 + 0.95**2))
    assert mdp_horizon_values(model, 2000)[0] == pytest.approx(
        qmdp_policy(model).Q[0].max(), abs=1e-3)
    assert not mdp_horizon_values(model, 0).any()
