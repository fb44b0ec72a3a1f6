"""The range checks that settings dataclasses share (:func:`models.settings.check_ranges`)."""

from dataclasses import dataclass

import pytest

from models.settings import check_ranges


@dataclass(frozen=True)
class _Example:
    step_s: float = 0.1
    size_m: tuple[float | None, ...] = (0.1, None)
    weight: float = 0.0
    trials: int = 3
    offsets_m: tuple[tuple[float, float], ...] = ((-2.0, 0.5), (1.0, 2.0))


def _check(example):
    check_ranges(example, positive=("step_s", "size_m"), non_negative=("weight",),
                 counts=("trials",), at_most={"step_s": 1.0, "offsets_m": 2.0})


def test_valid_values_and_unset_optional_elements_pass():
    _check(_Example())


@pytest.mark.parametrize("field, value", [
    ("step_s", 0.0), ("step_s", float("nan")), ("size_m", (0.1, -0.2)),
    ("weight", -1e-9), ("weight", float("nan")), ("trials", 0), ("trials", 2.5),
    ("step_s", 1e12), ("offsets_m", ((0.0, 0.0), (0.0, -2.5))),
])
def test_a_wrong_sign_names_the_field_and_value(field, value):
    with pytest.raises(ValueError, match=field) as err:
        _check(_Example(**{field: value}))
    assert repr(value) in str(err.value)
