"""The one validation module: each refusal names the value or the field, each accepted value comes
back normalised (float, int, tuple of floats)."""

import math
from dataclasses import dataclass

import numpy as np
import pytest

from neck_sim.validation import (ParameterError, check_array, check_integer, check_positive, finite, indices,
                                 per_item)


@pytest.mark.parametrize("value, kw, message", [
    ("abc", {}, r"delay: not a number \('abc'\)"),
    (math.nan, {}, r"delay: must be finite, got nan"),
    (0.0, {"positive": True}, r"delay: must be > 0, got 0.0"),
    (-1e-3, {"non_negative": True}, r"delay: must be >= 0, got -0.001"),
])
def test_a_value_by_name_is_refused_naming_it(value, kw, message):
    with pytest.raises(ValueError, match=message):
        finite("delay", value, **kw)


def test_values_by_name_come_back_normalised():
    assert finite("delay", np.float32(0.5), non_negative=True) == 0.5 and type(finite("d", 1)) is float
    assert per_item("f_s", [1, 2.5], non_negative=True) == (1.0, 2.5)
    assert per_item("f_s", 3) == 3.0
    with pytest.raises(ValueError, match=r"f_s\[1\]: must be >= 0, got -2.0"):
        per_item("f_s", [1, -2], non_negative=True)
    assert indices("cables", None) is None and indices("cables", 2) == (2,) and indices("cables", [0, 3]) == (0, 3)
    for bad in ([1, 1], [-1], [], ["x"]):
        with pytest.raises(ValueError, match=r"cables: expected (distinct non-negative )?(a list of )?0-based indices"):
            indices("cables", bad)


@dataclass(frozen=True)
class Drum:
    r_d: float = 0.02
    turns: float = 3
    f_s: tuple = (1, 2)

    def __post_init__(self):
        check_positive(self, "r_d")
        check_integer(self, "turns", 1, 10)
        check_array(self, "f_s", 2, non_negative=True)


def test_fields_are_normalised_in_place():
    d = Drum(r_d=1, turns=4.0, f_s=[0, 2])
    assert (d.r_d, d.turns, d.f_s) == (1.0, 4, (0.0, 2.0))
    assert type(d.r_d) is float and type(d.turns) is int


@pytest.mark.parametrize("kw, message", [
    ({"r_d": 0.0}, r"drum\.r_d: must be finite and positive, got 0\.0"),
    ({"r_d": math.inf}, r"drum\.r_d: must be finite and positive, got inf"),
    ({"r_d": "abc"}, r"drum\.r_d: must be a number, got 'abc' \(str\)"),
    ({"r_d": True}, r"drum\.r_d: must be a number, got True \(bool\)"),
    ({"turns": 2.5}, r"drum\.turns: must be an integer between 1 and 10, got 2\.5"),
    ({"turns": 11}, r"drum\.turns: must be an integer between 1 and 10, got 11"),
    ({"f_s": (1, 2, 3)}, r"drum\.f_s: expected 2 values, got 3"),
    ({"f_s": (1, -2)}, r"drum\.f_s: all values must be >= 0"),
    ({"f_s": (1, math.nan)}, r"drum\.f_s: contains NaN or infinity"),
    ({"f_s": ((1, 2), (3, 4))}, r"drum\.f_s: expected a flat list, got shape \(2, 2\)"),
])
def test_a_field_is_refused_naming_its_group_and_field(kw, message):
    with pytest.raises(ParameterError, match=message):
        Drum(**kw)
    assert issubclass(ParameterError, ValueError)
