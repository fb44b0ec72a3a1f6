"""``cmanip bench robustness``: mutated input files end in clear errors naming the file."""

import json
from dataclasses import dataclass

import numpy as np

from cmanip.cli import main
from cmanip.malformed import (
    FileKind,
    classify,
    fingerprint,
    table_mutations,
    yaml_mutations,
)


def test_every_kind_of_mutated_file_ends_in_a_clear_error_or_loads(tmp_path):
    report = tmp_path / "robust.json"
    assert main(["bench", "robustness", "--parts", "malformed", "--limit-per-kind", "40",
                 "--no-progress",
                 "--json", str(report)]) == 0
    result = json.loads(report.read_text())
    assert result["malformed_tried"] >= 500
    assert len(result["kinds"]) >= 15
    assert result["malformed_other"] == 0, result["other_cases"]
    assert result["malformed_clear_error"] + result["malformed_accepted"] == \
        result["malformed_tried"]
    assert result["malformed_ignored"] == 0, result["ignored_cases"]


def test_mutations_cover_fields_and_lines_and_classify_can_fail(tmp_path):
    labels = [label for label, _ in yaml_mutations("a: 1\nb: {c: 2}\n")]
    assert "b.c: removed" in labels and "b: extra field" in labels and "a: nan" in labels
    lines = [label for label, _ in table_mutations("x 1.5\ny 2\n")]
    assert "line 1: 1.5 -> abc" in lines and "line 2: removed" in lines
    path = tmp_path / "f.txt"
    path.write_text("x")

    def crash(p):
        raise KeyError("boom")

    def vague(p):
        raise ValueError("bad value")

    assert classify(FileKind("k", ".txt", (), crash), path)[0] == "other"
    assert classify(FileKind("k", ".txt", (), vague), path)[0] == "other"
    assert classify(FileKind("k", ".txt", (), lambda p: None), path)[0] == "accepted"


@dataclass
class _Loaded:
    source: str
    values: np.ndarray


def test_a_mutation_that_changes_nothing_is_not_tried_and_an_ignored_one_shows(tmp_path):
    labels = [label for label, _ in yaml_mutations("a: 0\nb: [1, 2]\n")]
    assert "a: zero" not in labels and "b: list" not in labels and "a: negative" in labels
    lines = [label for label, _ in table_mutations("x nan\ny -1.0\n")]
    assert "line 1: nan -> nan" not in lines and "line 2: -1.0 -> -1" not in lines
    first, second = tmp_path / "mutant_1.yaml", tmp_path / "mutant_2.yaml"
    # the file's own path is left out; a different array is not
    same = fingerprint(_Loaded(str(first), np.arange(2000.0)), first)
    assert same == fingerprint(_Loaded(str(second), np.arange(2000.0)), second)
    changed = np.arange(2000.0)
    changed[1000] = np.nan  # hidden in the middle of numpy's shortened repr
    assert same != fingerprint(_Loaded(str(second), changed), second)


def test_a_limit_below_one_is_a_clear_error(capsys):
    assert main(["bench", "robustness", "--limit-per-kind", "0"]) == 2
    assert "--limit-per-kind must be >= 1" in capsys.readouterr().err


def test_bad_robustness_options_are_clear_errors(capsys):
    assert main(["bench", "robustness", "--parts", "faults", "--fault-trials", "0"]) == 2
    assert "--fault-trials must be >= 1" in capsys.readouterr().err
    assert main(["bench", "robustness", "--parts", "budgets", "--budget-s", "0"]) == 2
    assert "--budget-s must be > 0" in capsys.readouterr().err
    assert main(["bench", "robustness", "--parts", "budgets", "--fault-figure", "f.png"]) == 2
    assert "add faults to --parts" in capsys.readouterr().err
    assert main(["bench", "robustness", "--parts", "faults", "--fault-figure", "f.svg"]) == 2
    assert "must end in .png" in capsys.readouterr().err
    assert main(["bench", "robustness", "--parts", "memory", "--smoother-updates", "5"]) == 2
    assert "memory: --smoother-updates and five times --decisions must be >= 10" in \
        capsys.readouterr().err
