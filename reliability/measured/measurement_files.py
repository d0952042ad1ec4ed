"""Measurement files: one CSV row per reading (docs/measurements.md).

Columns: ``run``; one pose column per axis, ``<axis>_mm`` (linear) or ``<axis>_deg``
(rotary); ``quantity`` (``dx dy dz ex ey ez`` in the workpiece frame, or ``radial``);
``cx_mm cy_mm cz_mm`` (a ballbar's centre in the workpiece frame, on ``radial`` rows only);
``value`` and ``u`` (mm for ``dx dy dz radial``, rad for ``ex ey ez``); optionally ``cycle``
and ``direction`` of acceptance runs (:mod:`reliability.measured.acceptance_runs`). Every
refusal names the file, the row (data rows counted from 1, the header apart) and the
column, and comes before any work.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ..basics.errors import InputError
from ..basics.files import write_csv

#: The quantities a reading can be of: the six outputs in the workpiece frame, and a ballbar's.
QUANTITIES = ("dx", "dy", "dz", "ex", "ey", "ez", "radial")
#: Columns of a ballbar's centre (mm, workpiece frame).
CENTRE_COLUMNS = ("cx_mm", "cy_mm", "cz_mm")
#: Columns every file has besides the pose columns.
FIXED_COLUMNS = ("run", "quantity", "value", "u")
#: Optional columns of acceptance runs (``precrel evaluate``): the cycle (1, 2, ...) and the
#: direction (``+``/``-``) of approach or travel; identification reads past them.
RUN_COLUMNS = ("cycle", "direction")
#: Significant digits of the numbers a measurement file is written with.
WRITTEN_DIGITS = 12


@dataclass(frozen=True, eq=False)
class Measurements:
    """Readings of one machine, checked against it.

    Attributes
    ----------
    run : ndarray of str (N,)
        Each reading's run.
    poses : ndarray (N, n_axes)
        Positions (mm, rad).
    quantity : ndarray of str (N,)
        One of :data:`QUANTITIES` each.
    centre : ndarray (N, 3)
        Ballbar centres (mm, workpiece frame) on ``radial`` readings, NaN elsewhere.
    value, u : ndarray (N,)
        Reading and its whole standard uncertainty (mm or rad).
    cycle, direction : ndarray (N,) or None
        Of readings of acceptance runs (:data:`RUN_COLUMNS`): the cycle (0 on other
        readings) and the direction ``+``/``-`` (blank on other readings); None when no
        reading has them. Written by :meth:`to_frame`; identification does not use them.
    """

    run: np.ndarray
    poses: np.ndarray
    quantity: np.ndarray
    centre: np.ndarray
    value: np.ndarray
    u: np.ndarray
    cycle: np.ndarray | None = None
    direction: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.value)

    @property
    def runs(self) -> tuple[str, ...]:
        """Run names in order of first appearance."""
        return tuple(pd.unique(self.run))

    def to_frame(self, machine) -> pd.DataFrame:
        """The file's table: rotary positions in degrees, blank centres off ``radial`` rows,
        ``cycle`` and ``direction`` when the readings have them."""
        table = {"run": self.run}
        for index, name in enumerate(pose_columns(machine)):
            positions = self.poses[:, index]
            table[name] = np.degrees(positions) if name.endswith("_deg") else positions
        table["quantity"] = self.quantity
        for index, name in enumerate(CENTRE_COLUMNS):
            table[name] = self.centre[:, index]
        table["value"] = self.value
        table["u"] = self.u
        if self.cycle is not None:
            table["cycle"] = np.where(self.cycle > 0, self.cycle.astype(object), "")
            table["direction"] = self.direction
        return pd.DataFrame(table)


def pose_columns(machine) -> tuple[str, ...]:
    """``<axis>_mm`` or ``<axis>_deg`` for every axis, in chain order."""
    return tuple(f"{a.name}_{'mm' if a.kind == 'linear' else 'deg'}" for a in machine.axis_specs)


def write_measurements(measurements, machine, path, overwrite: bool = False) -> Path:
    """Write ``measurements`` as a measurement file (atomically)."""
    return write_csv(measurements.to_frame(machine), path, overwrite=overwrite, index=False,
                     float_format=f"%.{WRITTEN_DIGITS}g")


def read_measurements(path, machine) -> Measurements:
    """Read and check a measurement file against ``machine``.

    Parameters
    ----------
    path : str or Path
    machine : Machine

    Returns
    -------
    Measurements

    Raises
    ------
    InputError
        Naming the file, the row and the column: an unknown column, axis or quantity, a pose
        outside the strokes, ``u`` missing or <= 0, a non-number, a centre on a row that is
        not ``radial`` (or missing on one that is), a run that mixes ``radial`` with other
        quantities or moves its centre, a quantity read only once in a run.
    """
    path = Path(path)
    try:
        table = pd.read_csv(path, dtype=str, keep_default_na=False)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: not a CSV measurement file: {exc}") from None
    return measurements_from_frame(table, machine, source=str(path))


def measurements_from_frame(table: pd.DataFrame, machine, source: str = "measurements"
                            ) -> Measurements:
    """:func:`read_measurements` on a table of strings (or numbers) already read."""
    table = table.astype(str).apply(lambda column: column.str.strip())
    _check_columns(table, machine, source)
    if table.empty:
        raise InputError(f"{source}: no readings")
    quantity = table["quantity"].to_numpy()
    _check_names(table, "run", source)
    _check_quantities(quantity, source)
    radial = quantity == "radial"
    measurements = Measurements(
        run=table["run"].to_numpy(), quantity=quantity,
        poses=_poses(table, machine, source),
        centre=_centres(table, radial, source),
        value=column_numbers(table, "value", source),
        u=_uncertainties(table, source))
    _check_runs(measurements, source)
    return measurements


def refuse_cell(source, row, column, text):
    """Raise an InputError naming the file, the data row (counted from 1) and the column."""
    raise InputError(f"{source}: row {row + 1}, column {column!r}: {text}")


def _check_columns(table, machine, source) -> None:
    axes = pose_columns(machine)
    known = set(FIXED_COLUMNS) | set(axes) | set(CENTRE_COLUMNS) | set(RUN_COLUMNS)
    for column in table.columns:
        if column not in known:
            what = "unknown axis" if column.endswith(("_mm", "_deg")) else "unknown column"
            raise InputError(f"{source}: column {column!r}: {what}; the columns are "
                             f"{', '.join((*FIXED_COLUMNS[:1], *axes, *FIXED_COLUMNS[1:]))}"
                             f" and, for ballbar readings, {', '.join(CENTRE_COLUMNS)}")
    for column in (*FIXED_COLUMNS, *axes):
        if column not in table.columns:
            raise InputError(f"{source}: column {column!r} is missing; a measurement file "
                             f"has {', '.join((*FIXED_COLUMNS, *axes))}")
    if "radial" in set(table["quantity"]):
        for column in CENTRE_COLUMNS:
            if column not in table.columns:
                raise InputError(f"{source}: column {column!r} is missing; radial readings "
                                 f"need the ballbar's centre in {', '.join(CENTRE_COLUMNS)}")


def _check_names(table, column, source) -> None:
    empty = np.flatnonzero(table[column].to_numpy() == "")
    if empty.size:
        refuse_cell(source, empty[0], column, "expected a name; got a blank")


def _check_quantities(quantity, source) -> None:
    unknown = np.flatnonzero(~np.isin(quantity, QUANTITIES))
    if unknown.size:
        refuse_cell(source, unknown[0], "quantity", f"unknown quantity {quantity[unknown[0]]!r}; "
                                                f"use one of {', '.join(QUANTITIES)}")


def column_numbers(table, column, source, rows=None) -> np.ndarray:
    """Finite numbers of ``column`` of a table of strings on ``rows`` (all rows by default),
    NaN elsewhere; a blank or a non-number is refused naming the row and the column."""
    text = table[column]
    rows = np.ones(len(table), dtype=bool) if rows is None else rows
    values = pd.to_numeric(text.where(rows, "nan"), errors="coerce").to_numpy(dtype=float)
    bad = np.flatnonzero(rows & ~np.isfinite(values))
    if bad.size:
        got = text.iloc[bad[0]]
        refuse_cell(source, bad[0], column, f"expected a finite number; got "
                                        f"{got!r}" if got else "expected a number; got a blank")
    return values


def _uncertainties(table, source) -> np.ndarray:
    u = column_numbers(table, "u", source)
    small = np.flatnonzero(u <= 0)
    if small.size:
        refuse_cell(source, small[0], "u",
                    f"the standard uncertainty must be > 0; got {u[small[0]]:g}")
    return u


def _poses(table, machine, source) -> np.ndarray:
    columns = pose_columns(machine)
    poses = np.column_stack([column_numbers(table, column, source) for column in columns])
    for index, (axis, column) in enumerate(zip(machine.axis_specs, columns)):
        if axis.kind == "rotary":
            poses[:, index] = np.radians(poses[:, index])
        if axis.full_turn:
            continue
        low, high = axis.stroke
        slack = 1e-9 * (high - low)
        outside = np.flatnonzero((poses[:, index] < low - slack) | (poses[:, index] > high + slack))
        if outside.size:
            unit = (lambda v: f"{v:g} mm") if axis.kind == "linear" else \
                (lambda v: f"{math.degrees(v):.6g}°")
            refuse_cell(source, outside[0], column,
                    f"position {unit(poses[outside[0], index])} lies outside the stroke "
                    f"[{unit(low)}, {unit(high)}] of axis {axis.name!r}")
    return poses


def _centres(table, radial, source) -> np.ndarray:
    if not np.any(radial) and not set(CENTRE_COLUMNS) & set(table.columns):
        return np.full((len(table), 3), np.nan)
    centre = np.column_stack([column_numbers(table, column, source, rows=radial)
                              for column in CENTRE_COLUMNS])
    for column in CENTRE_COLUMNS:
        given = np.flatnonzero(~radial & (table[column].to_numpy() != ""))
        if given.size:
            refuse_cell(source, given[0], column, "a centre belongs on radial rows only; leave it "
                                              "blank here")
    return centre


def _check_runs(measurements, source) -> None:
    frame = pd.DataFrame({"run": measurements.run, "quantity": measurements.quantity,
                          "row": np.arange(len(measurements))})
    radial = frame["quantity"] == "radial"
    mixed = frame.groupby("run")["quantity"].transform(
        lambda q: (q == "radial").any() and (q != "radial").any())
    if mixed.any():
        row = int(np.flatnonzero(mixed.to_numpy() & ~radial.to_numpy())[0])
        refuse_cell(source, row, "quantity", f"run {measurements.run[row]!r} mixes radial readings "
                                         f"with others; a ballbar run reads radial only")
    counts = frame.groupby(["run", "quantity"])["row"].transform("size").to_numpy()
    single = np.flatnonzero(counts == 1)
    if single.size:
        row = int(single[0])
        refuse_cell(source, row, "quantity", f"run {measurements.run[row]!r} reads "
                                         f"{measurements.quantity[row]!r} only once; its "
                                         f"set-up needs two readings or more")
    _check_fixed_centres(measurements, np.flatnonzero(radial.to_numpy()), source)


def _check_fixed_centres(measurements, rows, source) -> None:
    if not rows.size:
        return
    frame = pd.DataFrame(measurements.centre[rows], columns=CENTRE_COLUMNS)
    first = frame.groupby(measurements.run[rows]).transform("first").to_numpy()
    moved = np.abs(measurements.centre[rows] - first) > 1e-9 * (1.0 + np.abs(first))
    if moved.any():
        row, column = np.argwhere(moved)[0]
        refuse_cell(source, int(rows[row]), CENTRE_COLUMNS[column],
                f"run {measurements.run[rows[row]]!r} moves its centre; one ballbar run "
                f"has one centre")
