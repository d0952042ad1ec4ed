"""How a built machine's errors change with age (the machine file's ``[drift]`` table).

Two models of the change ``e(τ) − e(0)`` of each error over an age ``τ`` in years, both
given per error in the units of its tolerance per year (mm or rad, whatever the cost units):

- ``"linear"`` (the default): ``e(τ) = e(0) + r·τ`` with a rate ``r`` drawn once per
  built machine, normal with mean 0 and the given standard deviation, independent of
  ``e(0)``; between errors independent, or correlated as the machine's item correlation
  says (the same correlation as the errors at acceptance).
- ``"wear"``: a monotone wear per error, a gamma process ``W(τ)`` added to the error in its
  positive sense, independent between errors and of ``e(0)``, with mean ``μ·τ`` and
  variance ``v·τ``; the file gives ``[μ, √v]`` (the mean wear and the standard deviation of
  the wear in one year).

The table reads like ``[initial_allocation]``::

    [drift]
    kind = "linear"
    translation = 0.001              # mm per year
    rotation = 2e-6                  # rad per year
    items = { "X.dx" = 0.002 }       # per-error overrides, by paper name or ISO symbol

and with ``kind = "wear"`` every value is a pair ``[mean, sd]`` per year.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..basics.errors import InputError, InputTypeError

KINDS = ("linear", "wear")


@dataclass(frozen=True)
class Drift:
    """The drift of every error of a machine with age.

    Attributes
    ----------
    kind : {'linear', 'wear'}
    rate : ndarray, shape (n_errors,)
        ``'linear'``: the standard deviation of the drift rate across built machines;
        ``'wear'``: the mean wear per year. mm or rad per year, ≥ 0.
    spread : ndarray, shape (n_errors,) or None
        ``'wear'`` only: the standard deviation of one year's wear (√ of the variance per
        year), ≥ 0; None for ``'linear'``.
    """

    kind: str
    rate: np.ndarray
    spread: np.ndarray | None = None

    def __post_init__(self):
        if self.kind not in KINDS:
            raise InputError(f"drift kind must be one of {', '.join(map(repr, KINDS))}; "
                             f"got {self.kind!r}")
        rate = _non_negative(self.rate, "drift rate")
        object.__setattr__(self, "rate", rate)
        if (self.spread is None) != (self.kind == "linear"):
            raise InputError("drift spread must be given for kind 'wear' and only for it")
        if self.spread is not None:
            spread = _non_negative(self.spread, "drift spread")
            if spread.shape != rate.shape:
                raise InputError(f"drift spread must have the shape of the rate "
                                 f"{rate.shape}; got {spread.shape}")
            object.__setattr__(self, "spread", spread)

    def __eq__(self, other) -> bool:
        if type(other) is not type(self):
            return NotImplemented
        return (self.kind == other.kind and np.array_equal(self.rate, other.rate)
                and (self.spread is None) == (other.spread is None)
                and (self.spread is None or np.array_equal(self.spread, other.spread)))

    def mean(self, age: float) -> np.ndarray:
        """Mean of ``e(age) − e(0)`` per error: 0 for ``'linear'``, ``μ·age`` for wear."""
        age = checked_age(age)
        return np.zeros_like(self.rate) if self.kind == "linear" else self.rate * age

    def covariance(self, age: float, correlation: np.ndarray | None = None) -> np.ndarray:
        """Covariance of ``e(age) − e(0)``, ``(n_errors, n_errors)``.

        ``'linear'``: ``age² · D R D`` with ``D = diag(rate)`` and ``R`` the machine's item
        ``correlation`` (identity when None); ``'wear'``: ``age · diag(spread²)``
        (independent increments, independent errors).
        """
        age = checked_age(age)
        if self.kind == "wear":
            return np.diag(age * self.spread ** 2)
        scaled = age * self.rate
        if correlation is None:
            return np.diag(scaled ** 2)
        return scaled[:, None] * np.asarray(correlation, dtype=float) * scaled[None, :]

    def to_dict(self, names) -> dict:
        """The ``[drift]`` table: the most common translational and angular value as
        defaults, the rest as items (the reader's inverse)."""
        values = (self.rate if self.spread is None else
                  np.column_stack([self.rate, self.spread]))
        angular = np.array([name.split(".")[1].startswith("e") for name in names])
        table = {"kind": self.kind}
        defaults = {}
        for key, mask in (("translation", ~angular), ("rotation", angular)):
            rows, counts = np.unique(values[mask].reshape(int(mask.sum()), -1), axis=0,
                                     return_counts=True)
            defaults[key] = rows[np.argmax(counts)]
            table[key] = _plain(defaults[key])
        items = {name: _plain(np.atleast_1d(value)) for name, value, is_angular
                 in zip(names, values, angular)
                 if not np.array_equal(np.atleast_1d(value),
                                       defaults["rotation" if is_angular else "translation"])}
        if items:
            table["items"] = items
        return table


def checked_age(age) -> float:
    """``age`` as a finite float ≥ 0 (years), or an InputError naming it."""
    if isinstance(age, bool) or not isinstance(age, (int, float, np.integer, np.floating)):
        raise InputTypeError(f"age must be a number of years; got {type(age).__name__}")
    age = float(age)
    if not np.isfinite(age) or age < 0:
        raise InputError(f"age must be a finite number of years ≥ 0; got {age!r}")
    return age


def _non_negative(values, name: str) -> np.ndarray:
    array = np.array(values, dtype=float)
    if array.ndim != 1:
        raise InputError(f"{name} must be one value per error; got shape {array.shape}")
    bad = np.flatnonzero(~np.isfinite(array) | (array < 0))
    if len(bad):
        raise InputError(f"{name} must be finite and ≥ 0 per error; got {array[bad[0]]!r} "
                         f"at error {bad[0]}")
    array.setflags(write=False)
    return array


def _plain(row) -> float | list[float]:
    """One value as a float, a pair as a list of floats."""
    row = np.atleast_1d(row)
    return float(row[0]) if len(row) == 1 else [float(v) for v in row]
