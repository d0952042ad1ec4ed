"""Units and poses for printed results: poses by axis name, lengths in mm, rotary positions
in degrees.

Results hold rotary positions in rad (the model's unit); everything printed for people,
and every pose column of a table meant for people, shows them in degrees, with the unit in
the heading (``"A [deg]"``, or ``A_deg`` in a CSV column name).

Tolerances, σ and limits are held in mm and rad too. A table for people shows them in the
units the machine file states (``[cost] units``, e.g. µm and arcsec; mm and rad when it
states none: :func:`people_units`), the unit in the heading (``"tolerance [µm]"``) or
beside each number; machine-readable CSV files keep mm and rad.

Every number is printed only to the digits the computation fixes: a position in a pose
text to :data:`POSITION_RESOLUTION` (a search over the continuous workspace fixes no
finer), a probability near 1 by its failure probability to two significant digits, a gap
or a bound to three (:func:`percent_text`, :func:`significant_percent`), and numbers in
messages as plain numbers (:func:`number_text`), never as a numpy repr.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

#: Unit of each comprehensive error: translations in mm, rotations in rad.
OUTPUT_UNITS = ("mm", "mm", "mm", "rad", "rad", "rad")
#: Resolution of a position shown in a pose text: mm for linear axes, degrees for rotary.
POSITION_RESOLUTION = 1e-3
#: Below this failure probability a percentage would round to 100.0000 %.
SHOWN_FAILURE = 5e-7
#: Below this failure probability double precision fixes only one significant digit of it.
ONE_DIGIT_FAILURE = 1e-14
#: How many of each unit one mm (lengths) or one rad (angles) is.
UNIT_SCALES = {"mm": 1.0, "um": 1e3, "rad": 1.0, "urad": 1e6,
               "arcsec": 180.0 * 3600.0 / math.pi}
#: How a unit is written for people, where it differs from its ASCII name.
UNIT_SYMBOLS = {"um": "µm", "urad": "µrad"}


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


def people_units(units) -> tuple[str, str]:
    """The ``(length, angle)`` units tables for people use: the machine file's stated
    units (``machine.cost_coefficients.units``), mm and rad when it states none."""
    return tuple(units) if units else ("mm", "rad")


def unit_symbol(unit: str) -> str:
    """A unit as written for people: ``'um'`` as ``'µm'``, ``'urad'`` as ``'µrad'``."""
    return UNIT_SYMBOLS.get(unit, unit)


def error_units(names, units) -> tuple[str, ...]:
    """The unit of each error (``"<owner>.d*"`` a length, ``"<owner>.e*"`` an angle) in
    ``people_units(units)``, ASCII names."""
    length, angle = people_units(units)
    return tuple(length if name.rpartition(".")[2].startswith("d") else angle
                 for name in names)


def output_people_units(units) -> tuple[str, ...]:
    """The unit of each comprehensive error (dx dy dz in the length unit, ex ey ez in the
    angle unit) in ``people_units(units)``, ASCII names."""
    length, angle = people_units(units)
    return tuple(length if unit == "mm" else angle for unit in OUTPUT_UNITS)


def in_units(values, units) -> np.ndarray:
    """``values`` held in mm or rad converted element-wise to ``units`` (ASCII names)."""
    scales = np.array([UNIT_SCALES[unit] for unit in units])
    return np.asarray(values, dtype=float) * scales


def quantity_text(value: float, unit: str, digits: int = 4) -> str:
    """A length or an angle held in mm or rad, shown in ``unit`` with its symbol:
    ``quantity_text(0.0034, "um")`` is ``"3.4 µm"``."""
    return with_unit(float(value) * UNIT_SCALES[unit], unit_symbol(unit), digits)


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
    degrees), each position rounded to :data:`POSITION_RESOLUTION` and shown to at most
    ``digits`` significant digits (``-0`` as ``0``)."""
    shown, shown_units = shown_positions(positions, units)
    rounded = np.round(shown / POSITION_RESOLUTION) * POSITION_RESOLUTION + 0.0
    return ", ".join(f"{axis}={with_unit(float(q), unit, digits)}"
                     for axis, q, unit in zip(axes, rounded, shown_units))


def number_text(value) -> str:
    """A number for a message, as its author would write it (``-1e-05``, ``0.004``,
    ``300``), whatever its type (a numpy scalar included); anything else as its repr."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.number)):
        return repr(value)
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    return repr(float(value))


def percent_text(probability: float) -> str:
    """A probability in per cent to four decimals; near 1, where that would show
    ``100.0000 %``, as a bound with its failure probability ``1 − p`` beside it to the
    digits double precision fixes: ``> 99.99999999999 % (1 − 2.0e-14)``."""
    probability = float(probability)
    failure = 1.0 - probability
    if failure <= 0.0:
        return "100 % (1 − 0 in double precision)"
    if failure >= SHOWN_FAILURE:
        return f"{100.0 * probability:.4f} %"
    nines = math.ceil(-math.log10(failure)) - 1
    digits = 2 if failure >= ONE_DIGIT_FAILURE else 1
    return f"> 99.{'9' * (nines - 2)} % (1 − {failure:.{digits - 1}e})"


def significant_percent(fraction: float, digits: int = 3) -> str:
    """A fraction in per cent to ``digits`` significant digits (a gap or a bound:
    ``192 %``, ``0.0123 %``)."""
    return f"{100.0 * float(fraction):.{digits}g} %"


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
