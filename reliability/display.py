"""Units and poses for printed results: lengths in mm, angles in rad, poses by axis name."""

from __future__ import annotations

import numpy as np
import pandas as pd

#: Unit of each comprehensive error: translations in mm, rotations in rad.
OUTPUT_UNITS = ("mm", "mm", "mm", "rad", "rad", "rad")


def axis_units(machine) -> tuple[str, ...]:
    """Unit of each axis' position: ``'mm'`` (linear) or ``'rad'`` (rotary)."""
    return tuple("mm" if axis.kind == "linear" else "rad" for axis in machine.axis_specs)


def with_unit(value: float, unit: str, digits: int = 4) -> str:
    """``value`` to ``digits`` significant digits followed by its unit."""
    return f"{value:.{digits}g} {unit}"


def pose_text(positions, axes, units, digits: int = 4) -> str:
    """A pose as ``"C=0 rad, X=400 mm, …"``."""
    return ", ".join(f"{axis}={with_unit(float(q), unit, digits)}"
                     for axis, q, unit in zip(axes, positions, units))


def pose_columns(poses, axes, units) -> pd.DataFrame:
    """Poses as a table with one column per axis, headed ``"<axis> [<unit>]"``."""
    poses = np.atleast_2d(poses)
    return pd.DataFrame({f"{axis} [{unit}]": poses[:, i]
                         for i, (axis, unit) in enumerate(zip(axes, units))})


def output_limits_text(limits, digits: int = 4) -> list[str]:
    """Each output's limit with its unit."""
    return [with_unit(float(limit), unit, digits) for limit, unit in zip(limits, OUTPUT_UNITS)]


def top_contributors(contributions: pd.DataFrame, output: str, n: int = 3) -> str:
    """The ``n`` errors contributing most to an output's variance at its worst pose, as
    ``"X.dx 45%, C.ez 20%, ..."`` (shares in per cent, ties in error order).

    Parameters
    ----------
    contributions : DataFrame
        :attr:`reliability.fosm.FosmResult.contributions` (errors × outputs, per cent).
    output : str
    n : int
    """
    column = contributions[output].sort_values(ascending=False, kind="stable").head(n)
    return ", ".join(f"{name} {share:.0f}%" for name, share in column.items())
