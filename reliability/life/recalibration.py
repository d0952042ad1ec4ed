"""The recalibration interval: the age at which a falling curve (a machine yield over the
life, an output's life reliability) first falls below a level.

On an age grid the crossing is interpolated linearly between the last age at or above the
level and the first below it. The interval of a yield's crossing age comes from the
crossings of its confidence interval's ends: the lower end falls below the level first (the
earliest age consistent with the sample), the upper end last. A curve below the level at
age 0 crosses at 0; one that stays at or above it over the whole grid has no crossing
within the horizon (NaN here, "beyond the horizon" in words).
"""

from __future__ import annotations

import numpy as np

from ..basics.errors import InputError


def crossing_age(ages, values, level) -> np.ndarray:
    """The first age at which ``values`` fall below ``level``, per column.

    Parameters
    ----------
    ages : ndarray (A,)
        Increasing years from 0.
    values : ndarray (A,) or (A, m)
        The curve(s), e.g. a yield over the life.
    level : float or ndarray (m,)
        The level each column is judged against.

    Returns
    -------
    float or ndarray (m,)
        Interpolated age of the first fall below ``level``; 0 when below at age 0; NaN
        when never below on the grid.
    """
    ages = np.asarray(ages, dtype=float)
    values = np.asarray(values, dtype=float)
    single = values.ndim == 1
    values = values.reshape(len(ages), -1)
    level = np.broadcast_to(np.asarray(level, dtype=float), values.shape[1:])
    if np.any(~((level > 0) & (level < 1))):
        raise InputError(f"level must be a probability in (0, 1); got {level.tolist()}")
    below = values < level
    first = np.argmax(below, axis=0)
    found = below.any(axis=0)
    previous = np.maximum(first - 1, 0)
    columns = np.arange(values.shape[1])
    v0, v1 = values[previous, columns], values[first, columns]
    share = np.where(v0 > v1, (v0 - level) / np.where(v0 > v1, v0 - v1, 1.0), 0.0)
    age = ages[previous] + share * (ages[first] - ages[previous])
    age = np.where(first == 0, 0.0, age)
    age = np.where(found, age, np.nan)
    return float(age[0]) if single else age


def crossing_interval(ages, lower, estimate, upper, level) -> np.ndarray:
    """``[earliest, age, latest]``: the crossing ages of a yield's interval ends and of
    the yield itself (NaN: beyond the horizon)."""
    return np.array([crossing_age(ages, curve, level) for curve in (lower, estimate, upper)])


def age_text(age: float, horizon: float) -> str:
    """An age in years to 0.1 year (the grid's interpolation fixes no more), "beyond H
    years" when the curve never falls below the level, or "0 (below already at
    acceptance)" when it starts below it."""
    if np.isnan(age):
        return f"beyond {horizon:g} years"
    if age == 0:
        return "0 (below already at acceptance)"
    return f"{age:.1f} years"
