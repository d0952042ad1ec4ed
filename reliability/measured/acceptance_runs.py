"""Acceptance runs read from a measurement file, checked, and their ISO values.

A measurement file (docs/measurements.md) with the optional columns ``cycle`` (1, 2, ...)
and ``direction`` (``+``/``-``) holds the runs of a machine's acceptance tests; no machine
file is needed to read them (the axes are the file's ``<axis>_mm`` and ``<axis>_deg``
columns). Each run is one of:

- **positioning** (ISO 230-2): a run with ``cycle`` and ``direction``, in which one linear
  axis moves; it reads one quantity, the deviation along that axis (``dx`` for an X axis
  along x: measured minus target, mm) at the targets given in the axis' column, every target
  in every cycle in both directions of approach (``+`` approaching in the axis' positive
  direction);
- **circular** (ISO 230-4): a ballbar run (``radial``) in which two linear axes trace a
  circle, each reading labelled with the ``direction`` of travel;
- **rotary** (ISO 10791-6): a run in which one rotary axis turns, reading ``dx``, ``dy``,
  ``dz`` of the tool point (the linear axes follow it).

Runs that are none of these (a line run read for identification, without ``cycle`` and
``direction``; a ballbar run without ``direction``) are listed as left out. Every refusal names the file, the row (data rows
counted from 1) and the column, before any work: a missing cycle or direction, a cycle
counted twice, a target read in fewer cycles than the others or than ISO 230-2's two, units
mixed in one column or one run, a circle whose positions are not a circle.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from ..acceptance.evaluation import (DIRECTIONS, ISO_CYCLES, MIN_CYCLES, TARGET_COLUMNS,
                                     circular_values, positioning_table, positioning_values,
                                     radial_deviations, rotary_values)
from ..acceptance.iso_tests import tool_point
from ..basics.errors import InputError
from .measurement_files import (CENTRE_COLUMNS, FIXED_COLUMNS, QUANTITIES, RUN_COLUMNS,
                                column_numbers, measurements_from_frame, refuse_cell)

#: Columns of ``evaluation.csv`` (:meth:`AcceptanceRuns.evaluation_frame`).
EVALUATION_COLUMNS = ("run", "standard", "quantity", "value", "unit")
TRANSLATIONS = ("dx", "dy", "dz")
#: Positions equal to this (mm, deg) are one position; a circle's positions lie on a circle
#: to this share of its radius.
POSITION_RESOLUTION = 1e-6
CIRCLE_RESOLUTION = 1e-7


@dataclass(frozen=True, eq=False)
class PositioningRun:
    """An ISO 230-2 positioning run: ``deviations`` ``(cycles, 2, targets)`` (mm), direction
    0 ``+``, 1 ``−``, at ``targets`` (mm) of ``axis``, read as ``quantity``."""

    name: str
    axis: str
    quantity: str
    targets: np.ndarray
    deviations: np.ndarray
    standard = "ISO 230-2"
    kind = "positioning"

    def values(self) -> dict[str, float]:
        """:func:`reliability.acceptance.evaluation.positioning_values`."""
        return positioning_values(self.deviations)

    def table(self) -> pd.DataFrame:
        """:func:`reliability.acceptance.evaluation.positioning_table`."""
        return positioning_table(self.targets, self.deviations)


@dataclass(frozen=True, eq=False)
class CircularRun:
    """An ISO 230-4 ballbar run: by direction of travel, the nominal ``angles`` (rad) and
    the ``radial`` readings (mm); ``axes`` the two linear axes tracing the circle of nominal
    ``radius`` (mm) about ``centre`` (their positions, mm)."""

    name: str
    axes: tuple[str, str]
    centre: np.ndarray
    radius: float
    angles: dict
    radial: dict
    standard = "ISO 230-4"
    kind = "circular"

    def values(self) -> dict[str, float]:
        """:func:`reliability.acceptance.evaluation.circular_values`."""
        return circular_values(self.angles, self.radial, self.radius)

    def deviations(self) -> dict[str, np.ndarray]:
        """:func:`reliability.acceptance.evaluation.radial_deviations` (mm), by direction."""
        return radial_deviations(self.angles, self.radial, self.radius)


@dataclass(frozen=True, eq=False)
class RotaryRun:
    """An ISO 10791-6 rotary run: ``deviations`` by quantity (mm) as ``axis`` turns."""

    name: str
    axis: str
    deviations: dict
    standard = "ISO 10791-6"
    kind = "rotary"

    def values(self) -> dict[str, float]:
        """:func:`reliability.acceptance.evaluation.rotary_values`."""
        return rotary_values(self.deviations)


@dataclass(frozen=True, eq=False)
class AcceptanceRuns:
    """The acceptance runs of a file, in file order, and what was left out or warned."""

    runs: tuple
    left_out: tuple[str, ...] = ()
    warnings: tuple[str, ...] = field(default=())

    def evaluation_frame(self) -> pd.DataFrame:
        """``evaluation.csv``: :data:`EVALUATION_COLUMNS`, one row per run and quantity."""
        rows = [(run.name, run.standard, quantity, value, "mm")
                for run in self.runs for quantity, value in run.values().items()]
        return pd.DataFrame(rows, columns=list(EVALUATION_COLUMNS))

    def positions_frame(self) -> pd.DataFrame:
        """``positions.csv``: ``run`` and :data:`TARGET_COLUMNS` (mm) of every positioning
        run, one row per target."""
        parts = [run.table().assign(run=run.name) for run in self.runs
                 if isinstance(run, PositioningRun)]
        columns = ["run", *TARGET_COLUMNS]
        return pd.concat(parts, ignore_index=True)[columns] if parts else \
            pd.DataFrame(columns=columns)


def read_acceptance_runs(path, machine=None) -> AcceptanceRuns:
    """Read and check the acceptance runs of a measurement file.

    Parameters
    ----------
    path : str or Path
    machine : Machine, optional
        Also check the file as a measurement file of this machine (axes, strokes, ``u``).

    Returns
    -------
    AcceptanceRuns

    Raises
    ------
    InputError
        Naming the file, the row and the column (module docstring).
    """
    path = Path(path)
    try:
        table = pd.read_csv(path, dtype=str, keep_default_na=False)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: not a CSV measurement file: {exc}") from None
    return acceptance_runs_from_frame(table, str(path), machine)


def has_run_columns(path) -> bool:
    """Whether the measurement file at ``path`` has a ``cycle`` or ``direction`` column (it
    may hold acceptance runs); only its header is read."""
    try:
        header = pd.read_csv(path, nrows=0).columns
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError):
        return False
    return bool(set(RUN_COLUMNS) & set(header))


def acceptance_runs_from_frame(table: pd.DataFrame, source: str = "runs",
                               machine=None) -> AcceptanceRuns:
    """:func:`read_acceptance_runs` on a table already read (strings or numbers)."""
    table = table.astype(str).apply(lambda column: column.str.strip())
    axes = _axis_columns(table, source)
    if table.empty:
        raise InputError(f"{source}: no readings")
    travel = None if machine is None else \
        _travel(machine, measurements_from_frame(table, machine, source).poses)
    for column in ("run", "quantity"):
        blank = np.flatnonzero(table[column].to_numpy() == "")
        if blank.size:
            refuse_cell(source, blank[0], column, "expected a name; got a blank")
    unknown = np.flatnonzero(~table["quantity"].isin(QUANTITIES).to_numpy())
    if unknown.size:
        refuse_cell(source, unknown[0], "quantity", f"unknown quantity "
                    f"{table['quantity'].iloc[unknown[0]]!r}; use one of {', '.join(QUANTITIES)}")
    readings = _Readings(table, source, axes, travel)
    runs, left_out, warnings = [], [], []
    for name in pd.unique(table["run"]):
        rows = np.flatnonzero(table["run"].to_numpy() == name)
        run = readings.run(name, rows, warnings)
        if isinstance(run, str):
            left_out.append(f"run {name!r} reads {', '.join(pd.unique(readings.quantity[rows]))}"
                            f" without {run}: not an acceptance run")
        else:
            runs.append(run)
    if not runs:
        raise InputError(f"{source}: no acceptance run (a positioning run with cycle and "
                         f"direction, a ballbar run with direction, or a rotary run)")
    return AcceptanceRuns(tuple(runs), tuple(left_out), tuple(warnings))


def _axis_columns(table, source) -> dict[str, tuple[str, str]]:
    """Pose column -> (axis, unit); other columns must be the file's own."""
    known = (*FIXED_COLUMNS, *CENTRE_COLUMNS, *RUN_COLUMNS)
    axes = {}
    for column in table.columns:
        if column in known:
            continue
        axis, _, unit = column.rpartition("_")
        if not axis or unit not in ("mm", "deg"):
            raise InputError(f"{source}: column {column!r}: unknown column; the columns are "
                             f"run, <axis>_mm or <axis>_deg per axis, quantity, value, u, "
                             f"cycle, direction and, for ballbar readings, "
                             f"{', '.join(CENTRE_COLUMNS)}")
        twice = [c for c, (a, _) in axes.items() if a == axis]
        if twice:
            raise InputError(f"{source}: column {column!r}: mixed units: axis {axis!r} is "
                             f"also given as {twice[0]!r}; give each axis in one unit")
        axes[column] = (axis, unit)
    for column in ("run", "quantity", "value"):
        if column not in table.columns:
            raise InputError(f"{source}: column {column!r} is missing")
    if not axes:
        raise InputError(f"{source}: no axis column (<axis>_mm or <axis>_deg)")
    return axes


class _Readings:
    """The file's numbers, parsed once, and each run built from its rows."""

    def __init__(self, table, source, axes, travel=None):
        self.source, self.axes, self.travel = source, axes, travel
        self.quantity = table["quantity"].to_numpy()
        self.value = column_numbers(table, "value", source)
        self.poses = {column: column_numbers(table, column, source) for column in axes}
        self.cycle = table["cycle"].to_numpy() if "cycle" in table else \
            np.full(len(table), "", dtype=object)
        self.direction = table["direction"].to_numpy() if "direction" in table else \
            np.full(len(table), "", dtype=object)
        bad = np.flatnonzero(~np.isin(self.direction, ("", *DIRECTIONS)))
        if bad.size:
            refuse_cell(source, bad[0], "direction", f"expected + or -; got "
                                                     f"{self.direction[bad[0]]!r}")

    def refuse(self, row, column, text):
        refuse_cell(self.source, int(row), column, text)

    def moving(self, rows) -> list[str]:
        """The pose columns that move within ``rows``."""
        out = []
        for column, values in self.poses.items():
            span = np.ptp(values[rows])
            if span > POSITION_RESOLUTION * (1.0 + np.abs(values[rows]).max()):
                out.append(column)
        return out

    def run(self, name, rows, warnings):
        """The run of ``rows``; for a run that is no acceptance run, what it lacks."""
        moving = self.moving(rows)
        rotary = [c for c in moving if self.axes[c][1] == "deg"]
        labelled = np.any(self.cycle[rows] != "") or np.any(self.direction[rows] != "")
        if np.any(self.quantity[rows] == "radial"):
            return self._circular(name, rows, moving, rotary) if labelled else "direction"
        if rotary:
            return self._rotary(name, rows, rotary)
        return self._positioning(name, rows, moving, warnings) if labelled else \
            "cycle and direction"

    def _needed(self, rows, column, what):
        blank = rows[getattr(self, column)[rows] == ""]
        if blank.size:
            self.refuse(blank[0], column, f"missing {column}: every reading of {what} "
                                          f"needs one")

    def _positioning(self, name, rows, moving, warnings) -> PositioningRun:
        what = f"positioning run {name!r}"
        self._needed(rows, "cycle", what)
        self._needed(rows, "direction", what)
        quantity = self._one_quantity(name, rows)
        if len(moving) != 1:
            self.refuse(rows[0], moving[1] if moving else "quantity",
                        f"{what} moves {len(moving)} axes "
                        f"({', '.join(moving) or 'none'}); it moves one linear axis")
        column = moving[0]
        if self.axes[column][1] != "mm":
            self.refuse(rows[0], column, f"{what} moves a rotary axis; it moves a linear one")
        self._check_direction(what, rows, column, quantity)
        cycle = self._cycles(rows)
        targets, target = np.unique(np.round(self.poses[column][rows] / POSITION_RESOLUTION),
                                    return_inverse=True)
        if len(targets) < 2:
            self.refuse(rows[0], column, f"{what} reads one target; give two or more")
        cycles, which = np.unique(cycle, return_inverse=True)
        direction = (self.direction[rows] == "-").astype(int)
        cell = (which * 2 + direction) * len(targets) + target.reshape(-1)
        first = np.unique(cell, return_index=True)[1]
        twice = np.setdiff1d(np.arange(len(rows)), first)
        if twice.size:
            row = twice[0]
            self.refuse(rows[row], "cycle", f"cycle {cycle[row]} of {what} at "
                                            f"{self.poses[column][rows[row]]:g} mm in direction "
                                            f"{self.direction[rows[row]]} is counted twice")
        deviations = np.full(len(cycles) * 2 * len(targets), np.nan)
        deviations[cell] = self.value[rows]
        deviations = deviations.reshape(len(cycles), 2, len(targets))
        self._check_cycles(name, rows, column, target, deviations, cycles)
        if len(cycles) < ISO_CYCLES:
            warnings.append(f"{self.source}: {what} has {len(cycles)} cycles; ISO 230-2 asks "
                            f"for {ISO_CYCLES} (its s and R rest on few readings)")
        positions = targets * POSITION_RESOLUTION
        return PositioningRun(name, self.axes[column][0], quantity, positions, deviations)

    def _check_direction(self, what, rows, column, quantity):
        """With a machine: the quantity read is the moving axis' direction of travel."""
        if self.travel is None:
            return
        along = self.travel[self.axes[column][0]][rows[0]]
        if abs(along[TRANSLATIONS.index(quantity)]) < 1.0 - 1e-9:
            expected = [q for q, v in zip(TRANSLATIONS, along) if abs(v) > 1.0 - 1e-9]
            self.refuse(rows[0], "quantity", f"{what} reads {quantity!r}, but axis "
                                             f"{self.axes[column][0]!r} travels along "
                                             f"{expected[0] if expected else along.round(6)} "
                                             f"of the workpiece frame here")

    def _one_quantity(self, name, rows) -> str:
        read = pd.unique(self.quantity[rows])
        angular = [q for q in read if q not in TRANSLATIONS]
        if angular:
            row = rows[np.flatnonzero(np.isin(self.quantity[rows], angular))[0]]
            problem = f"mixed units: {read[0]!r} in mm and {angular[0]!r} in rad" \
                if len(angular) < len(read) else f"reads {angular[0]!r} (rad)"
            self.refuse(row, "quantity", f"positioning run {name!r} {problem}; it reads the "
                                         f"deviation along its axis, one of "
                                         f"{', '.join(TRANSLATIONS)} (mm)")
        if len(read) > 1:
            row = rows[np.flatnonzero(self.quantity[rows] == read[1])[0]]
            self.refuse(row, "quantity", f"positioning run {name!r} reads {read[0]!r} and "
                                         f"{read[1]!r}; it reads one quantity, the deviation "
                                         f"along its axis")
        return str(read[0])

    def _cycles(self, rows) -> np.ndarray:
        text = self.cycle[rows]
        numbers = pd.to_numeric(pd.Series(text), errors="coerce").to_numpy(dtype=float)
        bad = np.flatnonzero(~(np.isfinite(numbers) & (numbers >= 1)
                               & (numbers == np.round(numbers))))
        if bad.size:
            self.refuse(rows[bad[0]], "cycle", f"expected a cycle number 1, 2, ...; got "
                                               f"{text[bad[0]]!r}")
        return numbers.astype(int)

    def _check_cycles(self, name, rows, column, target, deviations, cycles):
        """Every target read in every cycle in both directions, at least two cycles."""
        missing = np.argwhere(np.isnan(deviations))
        if missing.size:
            c, d, t = missing[0]
            row = rows[np.flatnonzero(target == t)[0]]
            self.refuse(row, "cycle", f"positioning run {name!r} reads the target "
                                      f"{self.poses[column][row]:g} mm in direction "
                                      f"{DIRECTIONS[d]} in fewer cycles than the run: cycle "
                                      f"{cycles[c]} is missing")
        if len(cycles) < MIN_CYCLES:
            self.refuse(rows[0], "cycle", f"positioning run {name!r} reads every target in "
                                          f"{len(cycles)} cycle; ISO 230-2 needs at least "
                                          f"{MIN_CYCLES} (and asks for {ISO_CYCLES})")

    def _circular(self, name, rows, moving, rotary) -> CircularRun:
        what = f"ballbar run {name!r}"
        mixed = rows[self.quantity[rows] != "radial"]
        if mixed.size:
            self.refuse(mixed[0], "quantity", f"{what} mixes radial readings with others")
        self._needed(rows, "direction", what)
        if rotary or len(moving) != 2:
            self.refuse(rows[0], (rotary or moving or ["quantity"])[0],
                        f"{what} moves {', '.join(moving) or 'no axis'}; a circle is traced "
                        f"by two linear axes")
        plane = np.column_stack([self.poses[c][rows] for c in moving])
        centre, radius = _fitted_circle(plane)
        miss = np.abs(np.linalg.norm(plane - centre, axis=1) - radius)
        if miss.max() > CIRCLE_RESOLUTION * radius:
            self.refuse(rows[int(np.argmax(miss))], moving[0],
                        f"{what}: the positions of {moving[0]} and {moving[1]} do not lie on "
                        f"a circle (off by {miss.max():.3g} mm)")
        offset = plane - centre
        theta = np.arctan2(offset[:, 1], offset[:, 0])
        angles, radial = {}, {}
        for sign in DIRECTIONS:
            chosen = self.direction[rows] == sign
            if not chosen.any():
                continue
            key = np.round(np.mod(theta[chosen], 2 * np.pi) * radius / POSITION_RESOLUTION)
            _, first = np.unique(key, return_index=True)
            if len(first) < chosen.sum():
                row = rows[chosen][np.setdiff1d(np.arange(chosen.sum()), first)[0]]
                self.refuse(row, moving[0], f"{what} reads this position twice in direction "
                                            f"{sign}; one turn per direction")
            if chosen.sum() < 4:
                self.refuse(rows[chosen][0], "direction", f"{what} reads {chosen.sum()} "
                                                          f"positions in direction {sign}; a "
                                                          f"circle needs 4 or more")
            angles[sign], radial[sign] = theta[chosen], self.value[rows][chosen]
        axes = tuple(self.axes[c][0] for c in moving)
        return CircularRun(name, axes, centre, radius, angles, radial)

    def _rotary(self, name, rows, rotary) -> RotaryRun:
        what = f"rotary run {name!r}"
        if len(rotary) != 1:
            self.refuse(rows[0], rotary[1], f"{what} turns {', '.join(rotary)}; a rotary run "
                                            f"turns one rotary axis")
        other = rows[~np.isin(self.quantity[rows], TRANSLATIONS)]
        if other.size:
            self.refuse(other[0], "quantity", f"{what} reads {self.quantity[other[0]]!r}; it "
                                              f"reads the tool point's deviation, any of "
                                              f"{', '.join(TRANSLATIONS)} (mm)")
        deviations = {}
        for quantity in pd.unique(self.quantity[rows]):
            chosen = rows[self.quantity[rows] == quantity]
            if len(chosen) < 2:
                self.refuse(chosen[0], "quantity", f"{what} reads {quantity!r} once; a range "
                                                   f"needs two readings or more")
            deviations[str(quantity)] = self.value[chosen]
        return RotaryRun(name, self.axes[rotary[0]][0], deviations)


def _travel(machine, poses) -> dict[str, np.ndarray]:
    """Per linear axis ``(N, 3)``: the tool point's displacement in the workpiece frame per
    mm of the axis at each reading's pose (its direction of travel)."""
    out = {}
    for index, axis in enumerate(machine.axis_specs):
        if axis.kind == "linear":
            step = poses.copy()
            step[:, index] += 1.0
            out[axis.name] = tool_point(machine, step) - tool_point(machine, poses)
    return out


def _fitted_circle(points) -> tuple[np.ndarray, float]:
    """Centre and radius of the circle through planar ``points`` (algebraic least squares:
    ``x² + y² = 2 a x + 2 b y + c``, exact for points on a circle)."""
    design = np.column_stack([2.0 * points, np.ones(len(points))])
    solution = np.linalg.lstsq(design, np.square(points).sum(axis=1), rcond=None)[0]
    centre = solution[:2]
    return centre, float(np.sqrt(solution[2] + centre @ centre))
