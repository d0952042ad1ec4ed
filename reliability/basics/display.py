"""Units and poses for printed results: poses by axis name, lengths in mm, rotary positions
in degrees.

Results hold rotary positions in rad (the model's unit); everything printed for people,
and every pose column of a table meant for people, shows them in degrees, with the unit in
the heading (``"A [deg]"``, or ``A_deg`` in a CSV column name). Output errors keep their
model units (mm and rad), always named.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

#: Unit of each comprehensive error: translations in mm, rotations in rad.
OUTPUT_UNITS = ("mm", "mm", "mm", "rad", "rad", "rad")


def axis_units(machine) -> tuple[str, ...]:
    """Unit of each axis' position: ``'mm'`` (linear) or ``'rad'`` (rotary)."""
    return tuple("mm" if axis.kind == "linear" else "rad" for axis in machine.axis_specs)


def shown_positions(positions, units):
    """Positions as shown to people, and their units: rad converted to degrees."""
    positions = np.asarray(positions, dtype=float)
    rotary = np.array([unit == "rad" for unit in units])
    shown = np.where(rotary, np.degrees(positions), positions)
    return shown, tuple("deg" if unit == "rad" else unit for unit in units)


def pose_frame(poses, axes, units, *, style: str = "bracket") -> pd.DataFrame:
    """Poses as a table for people: one column per axis, rotary positions in degrees,
    headed ``"A [deg]"`` (``style="bracket"``) or ``"A_deg"`` (``style="csv"``)."""
    shown, shown_units = shown_positions(np.atleast_2d(poses), units)
    heading = "{axis} [{unit}]" if style == "bracket" else "{axis}_{unit}"
    return pd.DataFrame({heading.format(axis=axis, unit=unit): shown[:, i]
                         for i, (axis, unit) in enumerate(zip(axes, shown_units))})


def target_text(target: float) -> str:
    """A probability readable near 1: ``0.99``, ``0.999999999`` (never a rounded ``1``):
    enough decimals to show the failure probability ``1 − target`` to three digits."""
    failure = 1.0 - float(target)
    digits = max(6, int(np.ceil(-np.log10(failure))) + 3) if failure > 0 else 17
    return f"{float(target):.{digits}f}".rstrip("0").rstrip(".")


def bound_text(value: float, digits: int = 6) -> str:
    """A probability bound, clipped to [0, 1]; a bound at 0 or 1 says nothing and is marked
    ``(trivial)``."""
    value = min(max(float(value), 0.0), 1.0)
    text = f"{value:.{digits}f}"
    return f"{text} (trivial)" if value in (0.0, 1.0) else text


def with_unit(value: float, unit: str, digits: int = 4) -> str:
    """``value`` to ``digits`` significant digits followed by its unit."""
    return f"{value:.{digits}g} {unit}"


def pose_text(positions, axes, units, digits: int = 4) -> str:
    """A pose as ``"C=90 deg, X=400 mm, …"`` (positions in ``units``, rad shown in
    degrees)."""
    shown, shown_units = shown_positions(positions, units)
    return ", ".join(f"{axis}={with_unit(float(q), unit, digits)}"
                     for axis, q, unit in zip(axes, shown, shown_units))


def pose_columns(poses, axes, units) -> pd.DataFrame:
    """Poses as a table with one column per axis, headed ``"<axis> [<unit>]"``, rotary
    positions in degrees (:func:`pose_frame`)."""
    return pose_frame(poses, axes, units)


def output_limits_text(limits, digits: int = 4) -> list[str]:
    """Each output's limit with its unit."""
    return [with_unit(float(limit), unit, digits) for limit, unit in zip(limits, OUTPUT_UNITS)]


def top_contributors(contributions: pd.DataFrame, output: str, n: int = 3) -> str:
    """The ``n`` errors contributing most to an output's variance at its worst pose, as
    ``"X.dx 45%, C.ez 20%, ..."`` (shares in per cent, ties in error order).

    Parameters
    ----------
    contributions : DataFrame
        :attr:`reliability.first_order.fosm.FosmResult.contributions` (errors × outputs, per cent).
    output : str
    n : int
    """
    column = contributions[output].sort_values(ascending=False, kind="stable").head(n)
    return ", ".join(f"{name} {share:.0f}%" for name, share in column.items())
