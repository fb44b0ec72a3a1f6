"""``cmanip pomdp write|solve``: models leave and enter the project as .pomdp files."""

import numpy as np
import pytest

from cmanip.cli import main
from planning.pomdp.benchmarks import tag
from planning.pomdp.cassandra import read_pomdp


def test_written_tag_reads_back_as_the_built_in(tmp_path, capsys):
    path = tmp_path / "tag.pomdp"
    assert main(["pomdp", "write", "tag", "--out", str(path)]) == 0
    assert "870 states" in capsys.readouterr().out
    back, original = read_pomdp(path), tag()
    assert back.states == original.states and back.discount == original.discount
    assert all(abs(a - b).max() == 0 for a, b in zip(back.T, original.T, strict=True))
    assert np.array_equal(back.Z, original.Z) and np.array_equal(back.R, original.R)


def test_solve_a_file_and_save_the_policy(tmp_path, capsys):
    model, policy = tmp_path / "tiger.pomdp", tmp_path / "tiger.npz"
    assert main(["pomdp", "write", "tiger", "--out", str(model)]) == 0
    assert main(["pomdp", "solve", str(model), "--seconds", "1", "--out", str(policy)]) == 0
    assert "bounds at the initial belief" in capsys.readouterr().out
    assert policy.exists()


def test_bad_files_are_reported_with_their_line(tmp_path, capsys):
    bad = tmp_path / "bad.pomdp"
    bad.write_text("discount: 0.95\nvalues: reward\nstates: 2\nactions: 1\n"
                   "observations: 1\nT: 0 : 0 : 5 0.5\n")
    assert main(["pomdp", "solve", str(bad)]) == 2
    assert "bad.pomdp:6" in capsys.readouterr().err
    assert main(["pomdp", "solve", str(tmp_path / "missing.pomdp")]) == 2


def test_the_cli_offers_exactly_the_solvers_trial_rules(capsys):
    from cmanip.pomdp import TRIAL_RULES
    from planning.pomdp.point_based import PointBasedSolver

    assert TRIAL_RULES == PointBasedSolver.TRIAL_RULES
    with pytest.raises(SystemExit):
        main(["pomdp", "solve", "x.pomdp", "--trial-rule", "greedy"])
    assert "invalid choice: 'greedy'" in capsys.readouterr().err
