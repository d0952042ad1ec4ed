"""Boundary checks shared by the public entry points.

Each check takes the value and the argument's name, returns the value in the form the
computation needs, and otherwise raises a toolkit exception (:mod:`reliability.basics.errors`)
whose message names the argument, the offending item and what was expected. The policy
they implement is described in ``docs/inputs.md``.
"""

from __future__ import annotations

import difflib
import numbers
import operator
from collections.abc import Mapping

import numpy as np
import pandas as pd

from .display import number_text
from .errors import InputError, InputTypeError, SizeBudgetError

#: Bytes a single array built by the toolkit may take unless the caller passes a budget.
DEFAULT_BUDGET = 2**30

#: Relative slack on stroke ends, so that rounding in a grid or a file is not refused.
STROKE_SLACK = 1e-9


def positive_int(value, name: str, minimum: int = 1) -> int:
    """``value`` as an int ``>= minimum``.

    Non-numbers (strings, None) raise :class:`InputTypeError`; numbers that are not
    whole (2.5, even 3.0, True) raise :class:`InputError`.
    """
    expected = f"{name} must be an integer >= {minimum}; got {number_text(value)}"
    if not isinstance(value, (numbers.Number, np.bool_)):
        raise InputTypeError(f"{expected} ({type(value).__name__})")
    if isinstance(value, (bool, np.bool_)):
        raise InputError(expected)
    try:
        value = operator.index(value)
    except TypeError:
        raise InputError(expected) from None
    if value < minimum:
        raise InputError(f"{name} must be an integer >= {minimum}; got {value}")
    return value


def finite_float(value, name: str, low: float | None = None, high: float | None = None,
                 *, low_open: bool = False, high_open: bool = False) -> float:
    """``value`` as a finite float within ``[low, high]`` (ends open when asked)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise InputTypeError(f"{name} must be a real number; got {number_text(value)} "
                             f"({type(value).__name__})")
    try:
        number = float(value)
    except OverflowError:
        raise InputError(f"{name} is too large for a float; got {_short(value)}") from None
    if not np.isfinite(number):
        raise InputError(f"{name} must be finite; got {number_text(value)}")
    below = low is not None and (number <= low if low_open else number < low)
    above = high is not None and (number >= high if high_open else number > high)
    if below or above:
        left = "(" if low_open else "["
        right = ")" if high_open else "]"
        span = f"{left}{'-inf' if low is None else f'{low:g}'}, " \
               f"{'inf' if high is None else f'{high:g}'}{right}"
        raise InputError(f"{name} must lie in {span}; got {number_text(value)}")
    return number


def probability(value, name: str) -> float:
    """A probability strictly between 0 and 1."""
    return finite_float(value, name, 0.0, 1.0, low_open=True, high_open=True)


def one_allocation(machine, tolerances) -> np.ndarray:
    """``tolerances`` checked by the machine as one allocation of shape ``(n_errors,)``."""
    t = machine.check_tolerances(tolerances)
    if t.ndim != 1:
        raise InputError(f"tolerances must be one allocation of shape ({machine.n_errors},); "
                         f"got {t.shape}")
    return t


def choice(value, name: str, allowed) -> str:
    """One of ``allowed`` (compared exactly)."""
    if not isinstance(value, str) or value not in allowed:
        raise InputError(f"unknown {name} {value!r}; use one of {tuple(allowed)}")
    return value


def instance(value, name: str, kind: type):
    """Refuse ``value`` unless it is a ``kind``."""
    if not isinstance(value, kind):
        raise InputTypeError(f"{name} must be a {kind.__name__}; got a {type(value).__name__}")
    return value


def callback(value, name: str):
    """``None`` or a callable (progress and log hooks), checked before the work starts."""
    if value is not None and not callable(value):
        raise InputTypeError(f"{name} must be a function or None; got {value!r}")
    return value


def numeric_array(value, name: str, ndim: int | None = None) -> np.ndarray:
    """``value`` as a float array; strings, objects, bools and mappings are refused."""
    if isinstance(value, (str, bytes)) or isinstance(value, Mapping):
        raise InputTypeError(f"{name} must be an array of numbers; got a "
                             f"{type(value).__name__}")
    raw = np.asarray(value)
    if raw.dtype.kind not in "iuf":
        first = _first_item(raw)
        raise InputTypeError(f"{name} must hold numbers; got dtype {raw.dtype}"
                             + (f", first item {first!r}" if first is not None else ""))
    array = raw.astype(float)
    if ndim is not None and array.ndim != ndim:
        raise InputError(f"{name} must be {ndim}-dimensional; got shape {array.shape}")
    return array


def finite_values(array: np.ndarray, name: str, labels=None) -> np.ndarray:
    """Refuse NaN and ±inf, naming the first offending entry (by label when given)."""
    bad = np.argwhere(~np.isfinite(array))
    if len(bad):
        where = tuple(int(i) for i in bad[0])
        label = labels[where[-1]] if labels is not None else where
        raise InputError(f"{name} must be finite; entry {label!r} is "
                         f"{number_text(array[where])}")
    return array


def labelled(values, names, what: str) -> np.ndarray:
    """Values for ``names``: a Series or mapping is aligned by name, an array taken as is.

    A pandas Series or a mapping must name every entry of ``names`` exactly once and
    nothing else; it is reordered to ``names``, never read by position. A DataFrame is
    aligned by its columns. Arrays and lists are returned as float arrays (their order is
    the caller's responsibility).
    """
    names = tuple(names)
    if isinstance(values, pd.DataFrame):
        _same_names(tuple(values.columns), names, what)
        return numeric_array(values[list(names)].to_numpy(), what)
    if isinstance(values, (pd.Series, Mapping)):
        keys = tuple(values.index) if isinstance(values, pd.Series) else tuple(values)
        _same_names(keys, names, what)
        items = [values[n] for n in names]
        for name, item in zip(names, items):
            if isinstance(item, (bool, np.bool_)) or not isinstance(item, numbers.Real):
                raise InputTypeError(f"{what}[{name!r}] must be a number; got {item!r}")
        return numeric_array(np.array(items, dtype=float), what)
    return numeric_array(values, what)


def require_size(n_items, bytes_per_item, budget, what: str, advice: str) -> None:
    """Refuse a request whose ``n_items × bytes_per_item`` exceeds ``budget`` bytes.

    The product is computed with Python integers, so it cannot overflow.
    """
    budget = DEFAULT_BUDGET if budget is None else positive_int(budget, "budget")
    needed = int(n_items) * int(bytes_per_item)
    if needed > budget:
        raise SizeBudgetError(f"{what} would need {_bytes(needed)} for {int(n_items):,} items, "
                              f"over the budget of {_bytes(budget)}; {advice}")


def poses_in_strokes(machine, poses: np.ndarray, name: str = "poses",
                     allow_outside_stroke: bool = False) -> np.ndarray:
    """Refuse positions outside an axis' stroke unless ``allow_outside_stroke``.

    Full-turn rotary axes accept every finite angle (angles are periodic). Ends are
    compared with a relative slack of ``STROKE_SLACK`` of the stroke's width.
    """
    if allow_outside_stroke or poses.size == 0:
        return poses
    for column, axis in enumerate(machine.axis_specs):
        if axis.full_turn:
            continue
        low, high = axis.stroke
        slack = STROKE_SLACK * (high - low)
        values = poses[..., column]
        outside = np.flatnonzero((values < low - slack) | (values > high + slack))
        if len(outside):
            value = float(values.ravel()[outside[0]])
            raise InputError(
                f"{name}: axis {axis.name!r} position {value!r} (row {int(outside[0])}) is "
                f"outside its stroke [{low}, {high}]; pass allow_outside_stroke=True to "
                f"extrapolate the model beyond the stroke")
    return poses


def close_matches_text(name, known) -> str:
    """``" (did you mean 'X.dx'?)"`` naming the close matches of ``name`` among ``known``
    (:func:`difflib.get_close_matches`), or ``""`` when there are none."""
    matches = difflib.get_close_matches(str(name), [str(k) for k in known], n=3)
    return f" (did you mean {' or '.join(map(repr, matches))}?)" if matches else ""


def independent_errors(machine, what: str) -> None:
    """Refuse a machine with correlated errors where ``what`` draws them independently."""
    if getattr(machine, "correlation", None) is not None:
        raise InputError(f"machine: {what} draws the errors independently, but this machine's "
                         f"errors are correlated (machine.correlation); use "
                         f"sample_random_poses or GridExperiment, which use the correlation")


def _same_names(keys, names, what: str) -> None:
    duplicated = sorted({str(k) for k in keys if keys.count(k) > 1})
    if duplicated:
        raise InputError(f"{what} names {duplicated[0]!r} more than once")
    known = set(names)
    extra = [k for k in keys if k not in known]
    if extra:
        raise InputError(f"{what} has unknown name {extra[0]!r}; expected names like "
                         f"{names[0]!r} ({len(names)} in all)")
    given = set(keys)
    missing = [n for n in names if n not in given]
    if missing:
        raise InputError(f"{what} is missing {len(missing)} name(s), first {missing[0]!r}")


def _first_item(array: np.ndarray):
    return array.ravel()[0] if array.size else None


def _short(value) -> str:
    text = repr(value)
    return text if len(text) <= 40 else f"{text[:20]}…({len(text)} characters)"


def _bytes(n: int) -> str:
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB"):
        if n < 1024 or unit == "PiB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1024
