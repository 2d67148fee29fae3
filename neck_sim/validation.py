"""The one place values are validated: finite numbers, signs, integer ranges, per-item arrays, each
refusal a one-line error that names the field.

Two shapes of the same checks serve two kinds of caller:

* **values by name** (:func:`finite`, :func:`per_item`, :func:`indices`) return the normalised
  value or raise :class:`ValueError` naming ``name`` -- what the effects of
  :mod:`neck_sim.effects` use in their ``__post_init__``;
* **fields of a frozen dataclass** (:func:`check_number`, :func:`check_integer`,
  :func:`check_positive`, :func:`check_array`) normalise the field in place (a float, an int, a
  tuple of floats) or raise :class:`ParameterError` naming ``group.field`` (the lower-case class
  name and the field) -- what the parameter groups of :mod:`neck_sim.params` and
  :mod:`neck_sim.routing` use.

Example::

    from dataclasses import dataclass
    from neck_sim.validation import check_positive, finite

    finite("delay", 0.004, non_negative=True)          # -> 0.004
    finite("delay", float("nan"))                       # ValueError: delay: must be finite, got nan

    @dataclass(frozen=True)
    class Drum:
        r_d: float = 0.02                               # m

        def __post_init__(self):
            check_positive(self, "r_d")                 # Drum(r_d=0) -> ParameterError:
                                                        # drum.r_d: must be finite and positive, got 0.0
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

__all__ = ["ParameterError", "param_field", "finite", "indices", "per_item", "is_integer", "check_number", "check_integer",
           "check_positive", "check_array"]


class ParameterError(ValueError):
    """An invalid parameter value; the message names the offending field."""


def param_field(default: Any, unit: str, source: str, **kw: Any) -> Any:
    """A dataclass field carrying its unit and its source in ``metadata`` (what
    :func:`neck_sim.params.describe` prints): every parameter is declared through it."""
    return dataclasses.field(default=default, metadata={"unit": unit, "source": source}, **kw)


# ----------------------------------------------------------------------------- values by name

def finite(name: str, v: Any, *, positive: bool = False, non_negative: bool = False) -> float:
    """``v`` as a float; ValueError naming ``name`` if it is not a finite number (of that sign)."""
    try:
        v = float(v)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: not a number ({v!r})") from None
    if not math.isfinite(v):
        raise ValueError(f"{name}: must be finite, got {v!r}")
    if positive and v <= 0:
        raise ValueError(f"{name}: must be > 0, got {v!r}")
    if non_negative and v < 0:
        raise ValueError(f"{name}: must be >= 0, got {v!r}")
    return v


def indices(name: str, v: Any) -> tuple[int, ...] | None:
    """Distinct non-negative 0-based indices (None = all)."""
    if v is None:
        return None
    try:
        out = tuple(int(i) for i in (v if hasattr(v, "__iter__") else [v]))
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected a list of 0-based indices, got {v!r}") from None
    if any(i < 0 for i in out) or len(set(out)) != len(out) or not out:
        raise ValueError(f"{name}: expected distinct non-negative 0-based indices, got {v!r}")
    return out


def per_item(name: str, v: Any, *, positive: bool = False,
             non_negative: bool = False) -> tuple[float, ...] | float:
    """A scalar or a tuple of values (one per affected cable/joint), each checked by :func:`finite`
    (an item is named ``name[k]``)."""
    if np.ndim(v) == 0:
        return finite(name, v, positive=positive, non_negative=non_negative)
    return tuple(finite(f"{name}[{k}]", x, positive=positive, non_negative=non_negative) for k, x in enumerate(v))


def is_integer(v: Any) -> bool:
    """A whole number (an int, or a finite float without fraction); bools and strings are not."""
    return (not isinstance(v, bool) and isinstance(v, (int, float, np.integer, np.floating))
            and math.isfinite(v) and int(v) == v)


# ------------------------------------------------------------------ fields of a frozen dataclass

def _where(obj: Any, name: str) -> str:
    return f"{type(obj).__name__.lower()}.{name}"


def check_number(obj: Any, name: str) -> float:
    """The field as a float, or ParameterError when it is not a number (a string, a bool, a list)."""
    v = getattr(obj, name)
    if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
        raise ParameterError(f"{_where(obj, name)}: must be a number, got {v!r} ({type(v).__name__})")
    object.__setattr__(obj, name, float(v))
    return float(v)


def check_integer(obj: Any, name: str, minimum: int, maximum: int | None = None) -> None:
    """The field as an int in ``[minimum, maximum]`` (no upper bound when ``maximum`` is None)."""
    v = getattr(obj, name)
    if not (is_integer(v) and v >= minimum and (maximum is None or v <= maximum)):
        limit = f"between {minimum} and {maximum}" if maximum is not None else f">= {minimum}"
        raise ParameterError(f"{_where(obj, name)}: must be an integer {limit}, got {v!r}")
    object.__setattr__(obj, name, int(v))


def check_positive(obj: Any, *names: str, strict: bool = True) -> None:
    """Each field a finite float, > 0 (``strict``) or >= 0."""
    for name in names:
        v = check_number(obj, name)
        bad = (not math.isfinite(v)) or (v <= 0 if strict else v < 0)
        if bad:
            kind = "positive" if strict else "non-negative"
            raise ParameterError(f"{_where(obj, name)}: must be finite and {kind}, got {v!r}")


def check_array(obj: Any, name: str, length: int | None, *, positive: bool = False,
                non_negative: bool = False) -> None:
    """The field as a tuple of finite floats (``length`` of them unless None), all > 0
    (``positive``) or >= 0 (``non_negative``)."""
    v = getattr(obj, name)
    where = _where(obj, name)
    try:
        arr = np.asarray(v, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ParameterError(f"{where}: not a list of numbers ({exc})") from None
    if arr.ndim != 1:
        raise ParameterError(f"{where}: expected a flat list, got shape {arr.shape}")
    if length is not None and arr.shape[0] != length:
        raise ParameterError(f"{where}: expected {length} values, got {arr.shape[0]}")
    if not np.all(np.isfinite(arr)):
        raise ParameterError(f"{where}: contains NaN or infinity")
    if positive and np.any(arr <= 0):
        raise ParameterError(f"{where}: all values must be > 0, got {tuple(arr)}")
    if non_negative and np.any(arr < 0):
        raise ParameterError(f"{where}: all values must be >= 0, got {tuple(arr)}")
    object.__setattr__(obj, name, tuple(float(x) for x in arr))
