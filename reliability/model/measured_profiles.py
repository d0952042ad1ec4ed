"""Measured error profiles: a motion error's systematic part along travel.

A laser-interferometer or ballbar session measures one motion error of one axis at a series
of axis positions. Read as a *mean* of that error along travel, it shifts the comprehensive
errors pose by pose, while the allocated tolerance stays the random part around it
(σ = t/k). FOSM then uses ``P(|y| < I) = Φ((I − μ)/σ) − Φ((−I − μ)/σ)`` with the pose's
output mean μ (the exact model at the error means, Eq. 20), and the grid experiment adds the
mean to every draw at every grid point.

File format (CSV, comment lines start with ``#``)::

    position,value
    0,0.0
    50,0.0011
    ...

``position`` is the axis position in the unit of its stroke (mm for a linear axis, rad for a
rotary one); ``value`` is the measured error in the unit of the error (mm for ``dx dy dz``,
rad for ``ex ey ez``). The profile is interpolated linearly between measured positions,
periodically (period 2π) on a full-turn rotary axis.

Coverage policy (``outside=``): ``"refuse"`` (default) requires the measurement to span the
whole stroke of a linear or limited rotary axis and refuses positions outside the measured
range later; ``"hold"`` holds the first and last measured values beyond it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ..basics.errors import InputError, InputTypeError
from .machine import COMPONENTS

COLUMNS = ("position", "value")
OUTSIDE = ("refuse", "hold")


@dataclass(frozen=True, eq=False)
class MeasuredProfile:
    """One motion error's measured mean along its axis' travel.

    Attributes
    ----------
    error : str
        Machine error name ``"<axis>.<component>"``, e.g. ``"X.dy"``.
    axis : int
        Position of the axis in the chain.
    component : int
        0–5 for ``dx dy dz ex ey ez``.
    positions, values : ndarray
        Measured axis positions (increasing) and values.
    axis_spec : Axis
        The axis the profile was checked against.
    outside : {'refuse', 'hold'}
        What happens beyond the measured range.
    """

    error: str
    axis: int
    component: int
    positions: np.ndarray
    values: np.ndarray
    axis_spec: object
    outside: str = "refuse"

    @property
    def periodic(self) -> bool:
        """True on a full-turn rotary axis (interpolated with period 2π)."""
        return self.axis_spec.full_turn

    def __call__(self, position) -> np.ndarray:
        """The interpolated mean at axis positions ``position`` (any shape)."""
        x = np.asarray(position, dtype=float)
        if self.periodic:
            return np.interp(x, self.positions, self.values, period=2.0 * math.pi)
        if self.outside == "refuse":
            low, high = self.positions[0], self.positions[-1]
            bad = (x < low) | (x > high)
            if np.any(bad):
                raise InputError(f"position {float(x[bad].flat[0])!r} of {self.error!r} lies "
                                 f"outside the measured range [{low:g}, {high:g}]; pass outside='hold' "
                                 f"to hold the end values")
        return np.interp(x, self.positions, self.values)

    def to_frame(self) -> pd.DataFrame:
        """The measured points as a ``position, value`` table."""
        return pd.DataFrame({"position": self.positions, "value": self.values})


def measured_profile(machine, error: str, positions, values, *, sort: bool = False,
                     outside: str = "refuse") -> MeasuredProfile:
    """Validate measured ``(position, value)`` pairs of one motion error.

    Parameters
    ----------
    machine : Machine
    error : str
        A motion-error name of ``machine``, ``"<axis>.<component>"`` (assembly errors do not
        vary along travel).
    positions, values : array_like
        Same length, at least 2, all finite; positions strictly increasing (or any order
        with ``sort=True``), no position measured twice.
    sort : bool
        Sort the pairs by position instead of refusing an unsorted table.
    outside : {'refuse', 'hold'}
        Coverage policy, see the module docstring.

    Returns
    -------
    MeasuredProfile
    """
    axis, component = _motion_error(machine, error)
    if outside not in OUTSIDE:
        raise InputError(f"outside must be one of {OUTSIDE}; got {outside!r}")
    x, y = _pairs(error, positions, values)
    if sort:
        order = np.argsort(x, kind="stable")
        x, y = x[order], y[order]
    steps = np.diff(x)
    if np.any(steps <= 0):
        first = int(np.argmax(steps <= 0)) + 1
        what = "repeats" if steps[first - 1] == 0 else "is smaller than"
        raise InputError(f"positions of {error!r}: row {first} ({x[first]:g}) {what} the one "
                         f"before ({x[first - 1]:g}); give increasing positions or sort=True")
    spec = machine.axis_specs[axis]
    if spec.full_turn:
        if x[0] < 0 or x[-1] >= 2.0 * math.pi:
            raise InputError(f"positions of {error!r} on full-turn axis {spec.name!r} must lie "
                             f"in [0, 2π) rad; got [{x[0]:g}, {x[-1]:g}]")
    elif outside == "refuse":
        _check_coverage(error, spec, x)
    return MeasuredProfile(error=error, axis=axis, component=component, positions=x,
                           values=y, axis_spec=spec, outside=outside)


def read_profile_csv(path, machine, error: str, *, sort: bool = False,
                     outside: str = "refuse") -> MeasuredProfile:
    """Read a ``position,value`` CSV (see the module docstring) as a measured profile.

    Parameters
    ----------
    path : str or Path
    machine, error, sort, outside
        As in :func:`measured_profile`.
    """
    path = Path(path)
    try:
        frame = pd.read_csv(path, comment="#", skipinitialspace=True)
    except (OSError, pd.errors.ParserError, pd.errors.EmptyDataError) as exc:
        raise InputError(f"{path}: cannot read a position,value table: {exc}") from None
    columns = tuple(str(c).strip() for c in frame.columns)
    if columns != COLUMNS:
        raise InputError(f"{path}: columns must be exactly {','.join(COLUMNS)}; "
                         f"got {','.join(columns)}")
    if len(frame) < 2:
        raise InputError(f"{path}: needs at least 2 rows of position,value; got {len(frame)}")
    for column in COLUMNS:
        if not pd.api.types.is_numeric_dtype(frame[column]):
            raise InputError(f"{path}: column {column!r} must hold numbers only")
    return measured_profile(machine, error, frame["position"].to_numpy(float),
                            frame["value"].to_numpy(float), sort=sort, outside=outside)


@dataclass(frozen=True, eq=False)
class SystematicErrors:
    """The systematic (mean) parts of a machine's errors, from measured profiles.

    Parameters
    ----------
    machine : Machine
    profiles : sequence of MeasuredProfile
        At most one per error.
    """

    machine: object
    profiles: tuple

    def __post_init__(self):
        profiles = tuple(self.profiles)
        for p in profiles:
            if not isinstance(p, MeasuredProfile):
                raise InputTypeError(f"profiles must be MeasuredProfile objects; got {p!r}")
        names = [p.error for p in profiles]
        repeated = sorted({n for n in names if names.count(n) > 1})
        if repeated:
            raise InputError(f"error {repeated[0]!r} has more than one measured profile")
        for p in profiles:
            if p.axis >= len(self.machine.axis_specs) or \
                    self.machine.axis_specs[p.axis] != p.axis_spec:
                raise InputError(f"profile of {p.error!r} was built for another machine")
        object.__setattr__(self, "profiles", profiles)

    def means(self, poses) -> np.ndarray:
        """``(..., n_errors)`` error means at poses ``(..., n_axes)``; zero where unmeasured.

        Pass the result as ``means=`` to :func:`reliability.first_order.fosm.fosm`.
        """
        q = self.machine.check_positions(poses)
        out = np.zeros(q.shape[:-1] + (self.machine.n_errors,))
        for p in self.profiles:
            out[..., 6 * p.axis + p.component] = p(q[..., p.axis])
        return out

    def at_grid(self, axis_points) -> np.ndarray:
        """``(n_axes, P, 6)`` motion-error means at each axis' grid points.

        ``axis_points`` is the list of per-axis grid positions of
        :func:`reliability.model.poses.grid_axis_points` (what the grid experiment adds to its
        draws).
        """
        out = np.zeros((len(axis_points), len(axis_points[0]), 6))
        for p in self.profiles:
            out[p.axis, :, p.component] = p(axis_points[p.axis])
        return out

    def to_frame(self) -> pd.DataFrame:
        """All measured points, one row per error and position."""
        frames = [p.to_frame().assign(error=p.error) for p in self.profiles]
        if not frames:
            return pd.DataFrame(columns=["error", *COLUMNS])
        return pd.concat(frames, ignore_index=True)[["error", *COLUMNS]]


def grid_means(systematic, machine, axis_points) -> np.ndarray:
    """``(n_axes, P, 6)`` means of ``systematic`` at a grid of ``machine``, after checking
    that they were measured on this machine (what the grid experiment adds to its draws)."""
    if not isinstance(systematic, SystematicErrors):
        raise InputTypeError(f"systematic must be a SystematicErrors; got {systematic!r}")
    if systematic.machine.axis_specs != machine.axis_specs:
        raise InputError("systematic errors were measured on a machine with other axes "
                         f"({systematic.machine.axes}) than this one ({machine.axes})")
    return systematic.at_grid(axis_points)


def _motion_error(machine, error) -> tuple[int, int]:
    """Axis and component index of a motion-error name, or a named refusal."""
    if not isinstance(error, str):
        raise InputTypeError(f"error must be a motion-error name such as 'X.dy'; got {error!r}")
    owner, _, component = error.partition(".")
    if owner not in machine.axes or component not in COMPONENTS:
        raise InputError(f"error {error!r} is not a motion error of this machine; use "
                         f"'<axis>.<component>' with an axis of {machine.axes} and a component "
                         f"of {COMPONENTS}")
    return machine.axes.index(owner), COMPONENTS.index(component)


def _pairs(error, positions, values) -> tuple[np.ndarray, np.ndarray]:
    x = np.asarray(positions, dtype=float)
    y = np.asarray(values, dtype=float)
    if x.ndim != 1 or x.shape != y.shape or len(x) < 2:
        raise InputError(f"profile of {error!r}: positions and values must be two 1-d arrays "
                         f"of the same length >= 2; got shapes {x.shape} and {y.shape}")
    for name, array in (("positions", x), ("values", y)):
        bad = ~np.isfinite(array)
        if np.any(bad):
            row = int(np.argmax(bad))
            raise InputError(f"profile of {error!r}: {name}[{row}] = {float(array[row])!r} is not "
                             f"finite")
    return x, y


def _check_coverage(error, axis, x) -> None:
    low, high = axis.stroke
    slack = 1e-9 * (high - low)
    if x[0] > low + slack or x[-1] < high - slack:
        raise InputError(f"profile of {error!r} covers [{x[0]:g}, {x[-1]:g}] but axis "
                         f"{axis.name!r} travels [{low:g}, {high:g}]; measure the whole stroke "
                         f"or pass outside='hold' to hold the end values")
