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
finer), a probability near 1 by its failure probability to two significant digits
(:func:`percent_text`), and numbers in messages as plain numbers (:func:`number_text`),
never as a numpy repr. The rules of the printed numbers:

- a tolerance (or limit, σ, correction) in the units the machine file states, to at most
  0.001 µm or 0.001 arcsec (:func:`tolerance_text`, :func:`tolerance_number`), rounded
  down: a printed tolerance is one to meet, so it never reads looser than the computed one;
- a percentage to 0.01 % (:func:`percentage_text`);
- an elasticity, a multiplier or a ratio to :data:`RATIO_DIGITS` significant digits
  (:func:`significant_text`);
- an exact zero as ``0``, and a value zero to the rounding of its computation (below
  :data:`ZERO_RESOLUTION` of its scale) as ``0`` too (:func:`resolved_text`);
- a certified bound to its safe side: an upper bound rounded up, a lower bound down
  (:func:`upper_bound_text`, :func:`lower_bound_text`, :func:`probability_bound_text`,
  ``percentage_text(…, bound=…)``: a gap is an upper bound).
"""

from __future__ import annotations

import math
from decimal import ROUND_CEILING, ROUND_FLOOR, ROUND_HALF_EVEN, Decimal

import numpy as np
import pandas as pd

from .files import SIGNIFICANT, rounded_down, rounded_up
from .ties import decreasing_order

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
#: Finest step of a tolerance shown to people: 0.001 µm for lengths (in mm) and 0.001
#: arcsec for angles (in rad).
TOLERANCE_STEPS = {"length": 1e-6, "angle": 1e-3 / UNIT_SCALES["arcsec"]}
#: Decimals of a percentage: 0.01 %.
PERCENT_DECIMALS = 2
#: Significant digits of an elasticity, a Lagrange multiplier or a ratio.
RATIO_DIGITS = 3
#: A computed value smaller than this fraction of its scale is zero to rounding.
ZERO_RESOLUTION = 1e-12


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


def with_positions(frame: pd.DataFrame, axes, units) -> pd.DataFrame:
    """``frame`` with its axis columns (model units: mm, rad) replaced, after its first
    column, by the positions people read (``X_mm``, ``A_deg``, …; :func:`pose_frame`), and
    without a ``pose`` column of row numbers: a pose is shown by where it is."""
    shown = pose_frame(frame[list(axes)].to_numpy(dtype=float), axes, units, style="csv")
    out = frame.drop(columns=[*axes, *(["pose"] if "pose" in frame else [])])
    for i, column in enumerate(shown):
        out.insert(1 + i, column, shown[column].to_numpy())
    return out


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


def quantity_bound_text(value: float, unit: str, digits: int = SIGNIFICANT) -> str:
    """A certified upper bound on a length or an angle held in mm or rad, shown in ``unit``
    with its symbol to ``digits`` significant digits rounded up
    (:func:`upper_bound_text`): ``quantity_bound_text(2.04831e-5, "mm", 5)`` is
    ``"2.0484e-05 mm"``."""
    return f"{upper_bound_text(float(value) * UNIT_SCALES[unit], digits)} {unit_symbol(unit)}"


def target_text(target: float) -> str:
    """A probability readable near 1: ``0.99``, ``0.999999999`` (never a rounded ``1``):
    enough decimals to show the failure probability ``1 − target`` to three digits."""
    failure = 1.0 - float(target)
    digits = max(6, int(np.ceil(-np.log10(failure))) + 3) if failure > 0 else 17
    return f"{float(target):.{digits}f}".rstrip("0").rstrip(".")


def bound_text(value: float, digits: int = 6) -> str:
    """A lower bound on a probability (Bonferroni's), clipped to [0, 1] and rounded down to
    ``digits`` decimals, so the printed bound still bounds; a bound at 0 or 1 says nothing
    and is marked ``(trivial)``."""
    value = min(max(float(value), 0.0), 1.0)
    text = decimals_text(value, digits, "lower")
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


def percent_text(probability: float, lower: bool = False) -> str:
    """A probability in per cent to four decimals; near 1, where that would show
    ``100.0000 %``, as a bound with its failure probability ``1 − p`` beside it to the
    digits double precision fixes: ``> 99.99999999999 % (1 − 2.0e-14)``. With ``lower``
    the probability is a lower bound (at a certified σ bound, say) and is rounded down:
    four decimals cut, the failure probability rounded up."""
    probability = float(probability)
    failure = 1.0 - probability
    if failure <= 0.0:
        return "100 % (1 − 0 in double precision)"
    if failure >= SHOWN_FAILURE:
        return f"{decimals_text(probability, 4, 'lower' if lower else None, scale=100)} %"
    nines = math.ceil(-math.log10(failure)) - 1
    digits = 2 if failure >= ONE_DIGIT_FAILURE else 1
    shown = upper_bound_text(failure, digits) if lower else f"{failure:.{digits}g}"
    return f"> 99.{'9' * (nines - 2)} % (1 − {float(shown):.{digits - 1}e})"


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
    column = contributions[output]
    column = column.iloc[decreasing_order(column.to_numpy())].head(n)  # ties: error order
    return ", ".join(f"{name} {share:.0f}%" for name, share in column.items())


def tolerance_decimals(unit: str) -> int:
    """Decimals of a tolerance shown in ``unit`` (ASCII name): as many as
    :data:`TOLERANCE_STEPS` allows and no more (µm and arcsec 3, mm 6, rad 8, µrad 2)."""
    kind = "length" if unit in ("mm", "um") else "angle"
    step = TOLERANCE_STEPS[kind] * UNIT_SCALES[unit]
    return max(0, math.floor(-math.log10(step) + 1e-9))


def tolerance_number(value: float, unit: str) -> str:
    """A tolerance held in mm or rad as a number in ``unit`` (ASCII name), rounded DOWN to
    :func:`tolerance_decimals` decimals, trailing zeros dropped: ``6.8178364e-3`` mm in
    ``"um"`` is ``"6.817"``.

    The value is read as the shortest decimal that gives its float (``0.0029`` mm, not the
    binary 0.00289999…) and converted in decimal arithmetic, so a tolerance a file states
    exactly prints exactly; any other is cut, never raised: the tolerance printed is never
    looser than the one computed.
    """
    value = float(value)
    if not math.isfinite(value):
        return repr(value)
    shown = Decimal(repr(value)) * Decimal(repr(UNIT_SCALES[unit]))
    step = Decimal(1).scaleb(-tolerance_decimals(unit))
    return _plain(shown.quantize(step, rounding=ROUND_FLOOR))


def tolerance_text(value: float, unit: str) -> str:
    """:func:`tolerance_number` followed by the unit's symbol: ``"6.817 µm"``."""
    return f"{tolerance_number(value, unit)} {unit_symbol(unit)}"


def tolerance_numbers(values, units) -> list[str]:
    """Each tolerance of ``values`` (held in mm or rad) by :func:`tolerance_number` in its
    unit of ``units`` (ASCII names, one per value)."""
    return [tolerance_number(value, unit) for value, unit in zip(values, units)]


def ratio_columns(frame: pd.DataFrame, digits: int = RATIO_DIGITS) -> pd.DataFrame:
    """``frame`` with every float column (elasticities, multipliers, ratios) shown by
    :func:`significant_text`."""
    shown = frame.copy()
    for column in frame.columns[[kind == "f" for kind in frame.dtypes.map(lambda d: d.kind)]]:
        shown[column] = [significant_text(value, digits) for value in frame[column]]
    return shown


def percentage_text(fraction: float, bound: str | None = None) -> str:
    """A fraction in per cent to 0.01 % (:data:`PERCENT_DECIMALS`), followed by ``%``:
    ``2.2438941`` is ``"224.39 %"`` (:func:`percent_number`)."""
    return f"{percent_number(fraction, bound)} %"


def percent_number(fraction: float, bound: str | None = None,
                   decimals: int = PERCENT_DECIMALS) -> str:
    """A fraction in per cent to ``decimals`` decimals (0.01 %: :data:`PERCENT_DECIMALS`),
    as a number: an exact 0 is ``"0"``. A bound is rounded to its safe side
    (``bound="upper"`` up, ``"lower"`` down: ``0.0012345`` is ``"0.13"`` as an upper bound;
    :func:`decimals_text`); any other value to the nearest, and a non-zero one that would
    show as ``0.00`` as ``"< 0.01"`` (``"> -0.01"`` below 0)."""
    percent = 100.0 * float(fraction)
    if percent == 0.0 or not math.isfinite(percent):
        return f"{percent:g}"
    if bound is not None:
        return decimals_text(fraction, decimals, bound, scale=100)
    step = 10.0 ** -decimals
    if abs(percent) < step / 2:
        return f"< {step:.{decimals}f}" if percent > 0 else f"> -{step:.{decimals}f}"
    return f"{percent:.{decimals}f}"


def decimals_text(value: float, decimals: int, bound: str | None = None,
                  scale: int = 1) -> str:
    """``scale × value`` to ``decimals`` decimals, computed in exact decimal arithmetic and
    rounded to the nearest, or for a bound to its safe side (``bound="upper"`` up,
    ``"lower"`` down): ``decimals_text(0.98765, 3, "lower", scale=100)`` is ``"98.765"``,
    never 98.766."""
    exact = Decimal(float(value)) * scale
    rounding = {None: ROUND_HALF_EVEN, "upper": ROUND_CEILING, "lower": ROUND_FLOOR}[bound]
    return f"{exact.quantize(Decimal(1).scaleb(-decimals), rounding=rounding) + 0:f}"


def significant_text(value: float, digits: int = RATIO_DIGITS) -> str:
    """``value`` to ``digits`` significant digits, positional between 1e-4 and 1e6
    (``12.935616`` is ``"12.9"``, ``1293.4`` is ``"1290"``, ``-1.204667`` is ``"-1.20"``),
    in exponent form outside; an exact zero is ``"0"``."""
    value = float(value)
    if value == 0.0 or not math.isfinite(value):
        return "0" if value == 0.0 else repr(value)
    rounded = float(f"{value:.{digits}g}")
    exponent = math.floor(math.log10(abs(rounded)))
    if -4 <= exponent < 6:
        return f"{rounded:.{max(0, digits - 1 - exponent)}f}"
    return f"{rounded:.{digits - 1}e}"


def resolved_text(value: float, scale: float, digits: int = SIGNIFICANT,
                  resolution: float = ZERO_RESOLUTION) -> str:
    """``value`` to ``digits`` significant digits (:func:`significant_text`), or ``"0"``
    when it is zero to the rounding of its computation: ``|value| <= resolution × scale``.

    ``scale`` is the size the computation works at (an identified mean's prior σ, say);
    double precision fixes a result only to about 1e-16 of it, and a chain of solves and
    products to about :data:`ZERO_RESOLUTION` (1e-12) of it, so ``-1.50314e-15`` mm
    identified with a prior σ of 1e-3 mm prints as ``"0"``.
    """
    if abs(float(value)) <= resolution * abs(float(scale)):
        return "0"
    return significant_text(value, digits)


def upper_bound_text(value: float, digits: int = SIGNIFICANT) -> str:
    """A certified upper bound to ``digits`` significant digits, rounded UP (toward +∞),
    so the printed bound still bounds: ``2.04831e-05`` at 5 digits is ``"2.0484e-05"``."""
    return _bound_text(float(value), digits, upward=True)


def lower_bound_text(value: float, digits: int = SIGNIFICANT) -> str:
    """A certified lower bound to ``digits`` significant digits, rounded DOWN (toward
    −∞), so the printed bound still bounds: ``2.04831e-05`` at 5 digits is
    ``"2.0483e-05"``."""
    return _bound_text(float(value), digits, upward=False)


def probability_bound_text(value: float, upper: bool, digits: int = 2) -> str:
    """An end of an interval on a probability (a yield), rounded to its safe side: a lower
    end down, an upper end up, to at least four decimals and ``digits`` significant digits
    of the smaller of ``value`` and ``1 − value``, as yields are shown
    (``0.99987654`` as a lower end is ``"0.99987"``: the failure probability 1.2e-4 to two
    digits; ``0.25`` is ``"0.2500"``); 0 and 1 as ``0`` and ``1``."""
    value = float(value)
    if not 0.0 < value < 1.0:
        return f"{value:g}"
    smallest = min(value, 1.0 - value)
    decimals = max(4, digits - 1 - math.floor(math.log10(smallest)))
    step = Decimal(1).scaleb(-decimals)
    shown = Decimal(value).quantize(step, rounding=ROUND_CEILING if upper else ROUND_FLOOR)
    return f"{shown:f}"


def interval_text(lower: float, upper: float, digits: int = 2) -> str:
    """A confidence interval on a probability as ``"[0.9812, 0.9950]"``, its ends
    rounded outward (:func:`probability_bound_text`)."""
    return (f"[{probability_bound_text(lower, upper=False, digits=digits)}, "
            f"{probability_bound_text(upper, upper=True, digits=digits)}]")


def _bound_text(value: float, digits: int, upward: bool) -> str:
    if value == 0.0 or not math.isfinite(value):
        return "0" if value == 0.0 else repr(value)
    away = upward == (value > 0)
    size = (rounded_up if away else rounded_down)(abs(value), digits)
    return f"{math.copysign(float(size), value):.{digits}g}"


def _plain(number: Decimal) -> str:
    """A decimal without trailing zeros or exponent (``-0`` as ``0``)."""
    text = f"{number:f}"
    text = text.rstrip("0").rstrip(".") if "." in text else text
    return "0" if text in ("-0", "") else text
