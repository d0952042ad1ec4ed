"""Compensation tables: per axis the identified motion errors along its stroke, and the
constant errors (docs/compensation.md).

A controller subtracts each table's value, interpolated linearly between its positions, from
the error it describes: the table holds the identified error, the correction is its negative.
An item outside the table is not corrected; a value beyond ``max_correction`` is held at it
(the table's range).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..basics.errors import InputError
from .compensation_files import internal_positions, read_compensation_fields, write_compensation

#: Default spacing of the table positions (mm along a linear axis, degrees about a rotary one).
DEFAULT_SPACING_MM = 10.0
DEFAULT_SPACING_DEG = 1.0
#: Components of an error whose value is a length (mm); the others are angles (rad).
LENGTH_COMPONENTS = ("dx", "dy", "dz")


@dataclass(frozen=True, eq=False)
class CompensationTables:
    """A machine's compensation tables.

    Attributes
    ----------
    machine : Machine
    spacing_mm, spacing_deg : float
        Spacing of the positions along linear and about rotary axes.
    axes : dict of str to DataFrame
        Per axis: ``position_mm`` or ``position_deg`` and one column per tabled motion
        error, named by its ISO 230-1 symbol (mm, rad).
    assembly : DataFrame
        ``error, iso, value`` of the tabled constant errors (mm, rad).
    """

    machine: object
    spacing_mm: float
    spacing_deg: float
    axes: dict
    assembly: pd.DataFrame

    @property
    def items(self) -> tuple[str, ...]:
        """The error names the tables correct, in the machine's order."""
        symbols = set(self.assembly["iso"])
        for table in self.axes.values():
            symbols.update(table.columns[1:])
        return tuple(n for n, s in zip(self.machine.error_names, self.machine.iso_names)
                     if s in symbols)

    def values_at(self, poses) -> np.ndarray:
        """``(..., n_errors)``: the tabled error at each pose ``(..., n_axes)``, linear
        between table positions (0 for an item outside the tables); a controller subtracts
        it."""
        poses = self.machine.check_positions(poses)
        out = np.zeros(poses.shape[:-1] + (self.machine.n_errors,))
        for a, axis in enumerate(self.machine.axis_specs):
            table = self.axes.get(axis.name)
            if table is None or table.shape[1] == 1:
                continue
            where = _table_coordinate(axis, poses[..., a])
            knots = internal_positions(axis, table.iloc[:, 0])
            for symbol in table.columns[1:]:
                index = self.machine.error_index(symbol)
                out[..., index] = np.interp(where, knots, table[symbol].to_numpy())
        for name, value in zip(self.assembly["error"], self.assembly["value"]):
            out[..., self.machine.error_index(name)] = value
        return out

    def to_frame(self) -> pd.DataFrame:
        """Every tabled value, one row each: ``table`` (an axis or ``assembly``),
        ``position`` (mm or degrees; NaN for a constant error), ``error`` (ISO 230-1
        symbol) and ``value`` (mm, rad)."""
        parts = [pd.DataFrame({"table": name, "position": table.iloc[:, 0].to_numpy()
                               .repeat(table.shape[1] - 1),
                               "error": np.tile(table.columns[1:], len(table)),
                               "value": table.iloc[:, 1:].to_numpy().ravel()})
                 for name, table in self.axes.items()]
        parts.append(pd.DataFrame({"table": "assembly", "position": np.nan,
                                   "error": self.assembly["iso"].to_numpy(),
                                   "value": self.assembly["value"].to_numpy()}))
        return pd.concat(parts, ignore_index=True)

    def summary(self) -> str:
        """What the tables correct, their spacing and their largest value."""
        frame = self.to_frame()
        lines = [f"Compensation tables of {self.machine.name!r}: {len(self.items)} errors "
                 f"corrected, every {self.spacing_mm:g} mm and {self.spacing_deg:g} degrees"]
        for name, table in self.axes.items():
            values = frame[frame["table"] == name]["value"].abs()
            largest = f"largest |value| {values.max():.3g}" if len(values) else "no error"
            lines.append(f"  axis {name}: {len(table)} positions, {table.shape[1] - 1} "
                         f"errors, {largest}")
        lines.append(f"  constant errors: {len(self.assembly)} "
                     f"({', '.join(self.assembly['iso']) or 'none'})")
        return "\n".join(lines)

    def save(self, folder, overwrite: bool = False):
        """Write the folder of tables
        (:func:`reliability.compensation.compensation_files.write_compensation`; with
        ``overwrite`` earlier tables it does not replace are removed). Returns the
        folder."""
        return write_compensation(self, folder, overwrite)

    @classmethod
    def load(cls, folder, machine) -> "CompensationTables":
        """The tables saved in ``folder`` for ``machine`` (which the folder names but does
        not hold), checked
        (:func:`reliability.compensation.compensation_files.read_compensation_fields`);
        every value comes back to the last digit."""
        return cls(**read_compensation_fields(folder, machine))


def read_compensation(folder, machine) -> CompensationTables:
    """The compensation tables in ``folder`` for ``machine``: :meth:`CompensationTables.load`."""
    return CompensationTables.load(folder, machine)


def compensation_tables(identification, *, spacing_mm: float = DEFAULT_SPACING_MM,
                        spacing_deg: float = DEFAULT_SPACING_DEG, items=None,
                        max_correction_mm: float | None = None,
                        max_correction_rad: float | None = None) -> CompensationTables:
    """Tables of the identified errors of a measured machine.

    Parameters
    ----------
    identification : Identification
        From :func:`reliability.identify`; its ``mean_at`` gives each error as it acts along
        travel.
    spacing_mm, spacing_deg : float
        Spacing of the positions along linear (mm) and rotary (degrees) axes; the stroke's
        ends are always positions.
    items : iterable of str, optional
        Errors to table (names or ISO symbols); default every error.
    max_correction_mm, max_correction_rad : float, optional
        The table's range: values beyond ± this are held at it.

    Returns
    -------
    CompensationTables
    """
    machine = identification.machine
    spacing_mm = _positive(spacing_mm, "spacing_mm")
    spacing_deg = _positive(spacing_deg, "spacing_deg")
    chosen = tabled_mask(machine, items)
    limits = correction_limits(machine, max_correction_mm, max_correction_rad)
    axes = {}
    for a, axis in enumerate(machine.axis_specs):
        positions = table_positions(axis, spacing_mm, spacing_deg)
        poses = np.broadcast_to(_middle_pose(machine), (len(positions), len(machine.axes))).copy()
        poses[:, a] = positions % (2 * math.pi) if axis.full_turn else positions
        values = np.clip(identification.mean_at(poses), -limits, limits)
        column = "position_deg" if axis.kind == "rotary" else "position_mm"
        table = {column: np.degrees(positions) if axis.kind == "rotary" else positions}
        for index in range(6 * a, 6 * a + 6):
            if chosen[index]:
                table[machine.iso_names[index]] = values[:, index]
        axes[axis.name] = pd.DataFrame(table)
    constant = np.clip(identification.mean_at(_middle_pose(machine)), -limits, limits)
    assembly = [(machine.error_names[i], machine.iso_names[i], constant[i])
                for i in range(6 * len(machine.axes), machine.n_errors) if chosen[i]]
    return CompensationTables(machine, spacing_mm, spacing_deg, axes,
                              pd.DataFrame(assembly, columns=["error", "iso", "value"]))


def tabled_mask(machine, items=None) -> np.ndarray:
    """Boolean ``(n_errors,)``: the items a table corrects (all when ``items`` is None)."""
    if items is None:
        return np.ones(machine.n_errors, dtype=bool)
    if isinstance(items, str):
        items = (items,)
    mask = np.zeros(machine.n_errors, dtype=bool)
    for name in items:
        mask[machine.error_index(name)] = True
    return mask


def correction_limits(machine, max_correction_mm=None, max_correction_rad=None) -> np.ndarray:
    """``(n_errors,)``: the largest value a table holds of each error (inf: no limit)."""
    length = math.inf if max_correction_mm is None else \
        _positive(max_correction_mm, "max_correction_mm")
    angle = math.inf if max_correction_rad is None else \
        _positive(max_correction_rad, "max_correction_rad")
    return np.array([length if name.rpartition(".")[2] in LENGTH_COMPONENTS else angle
                     for name in machine.error_names])


def table_positions(axis, spacing_mm: float, spacing_deg: float) -> np.ndarray:
    """Positions of an axis' table (mm, rad): from the stroke's start at the spacing, its
    end included; a full turn runs from 0 to 2π."""
    low, high = axis.stroke
    step = spacing_mm if axis.kind == "linear" else math.radians(spacing_deg)
    count = max(int(math.ceil((high - low) / step - 1e-9)), 1)
    return np.minimum(low + step * np.arange(count + 1), high)


def _table_coordinate(axis, positions) -> np.ndarray:
    """Positions as a table reads them: a full turn's wrapped into [0, 2π)."""
    positions = np.asarray(positions, dtype=float)
    return positions % (2 * math.pi) if axis.full_turn else positions


def _middle_pose(machine) -> np.ndarray:
    return np.array([0.5 * (axis.stroke[0] + axis.stroke[1]) for axis in machine.axis_specs])


def _positive(value, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or \
            not math.isfinite(value) or value <= 0:
        raise InputError(f"{name}: expected a number > 0; got {value!r}")
    return float(value)
