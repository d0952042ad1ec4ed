"""Compensation table files: ``<axis>.csv`` per axis and ``assembly.csv``, each opening with
comment lines that name the machine, the units and the spacing (docs/compensation.md).

Numbers are written with 17 significant digits, so a table read back holds the same values.
Every refusal names the file, the row (data rows counted from 1) and the column.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from ..basics.errors import SavedResultError
from ..basics.files import atomic_write_text, check_destination

#: The file of the constant errors, and its columns.
ASSEMBLY_FILE = "assembly.csv"
ASSEMBLY_COLUMNS = ("error", "iso", "value")
#: Digits that make a written number read back to the same double.
EXACT_DIGITS = "%.17g"
#: Spacing keys of the header, and how far a position may lie outside the stroke.
SPACING_KEYS = ("spacing_mm", "spacing_deg")
STROKE_SLACK = 1e-9
#: How an axis' table file opens (the machine's name follows).
TABLE_HEADER = "# compensation table of "


def table_file_names(machine) -> tuple[str, ...]:
    """The files a compensation folder holds for ``machine``."""
    return tuple(f"{axis}.csv" for axis in machine.axes) + (ASSEMBLY_FILE,)


def write_compensation(tables, folder, overwrite: bool = False) -> Path:
    """Write ``tables`` (a :class:`~reliability.compensation.tables.CompensationTables`)
    into ``folder`` (created if absent); returns the folder.

    An earlier compensation folder (its ``assembly.csv`` or a table file opening with
    :data:`TABLE_HEADER`) is refused unless ``overwrite``; with it, the earlier tables this
    write does not replace (those of axes another machine had) are removed, so the folder
    holds these tables only. Other files are left alone.
    """
    machine = tables.machine
    names = table_file_names(machine)
    earlier = earlier_tables(folder)
    folder = check_destination(folder, overwrite, folder=True, markers=names + earlier)
    folder.mkdir(exist_ok=True)
    spacing = f"# spacing_mm: {tables.spacing_mm!r}\n# spacing_deg: {tables.spacing_deg!r}\n"
    for axis in machine.axis_specs:
        table = tables.axes[axis.name]
        header = (f"{TABLE_HEADER}{machine.name!r}, axis {axis.name} ({axis.kind})\n"
                  f"# units: {table.columns[0]} in {table.columns[0].split('_')[1]}; "
                  f"{_units_text(table.columns[1:])}; the correction is minus each value\n")
        atomic_write_text(folder / f"{axis.name}.csv",
                          header + spacing + table.to_csv(index=False,
                                                          float_format=EXACT_DIGITS),
                          overwrite)
    header = (f"# constant errors of {machine.name!r}\n# units: value in mm (translations) "
              f"and rad (rotations); the correction is minus each value\n")
    atomic_write_text(folder / ASSEMBLY_FILE,
                      header + spacing + tables.assembly.to_csv(index=False,
                                                                float_format=EXACT_DIGITS),
                      overwrite)
    for name in set(earlier) - set(names):
        (folder / name).unlink(missing_ok=True)
    return folder


def earlier_tables(folder) -> tuple[str, ...]:
    """Names of the files in ``folder`` that an earlier :func:`write_compensation` wrote:
    ``assembly.csv`` and the CSV files opening with :data:`TABLE_HEADER`."""
    folder = Path(folder)
    if not folder.is_dir():
        return ()
    return tuple(sorted(p.name for p in folder.glob("*.csv")
                        if p.name == ASSEMBLY_FILE or _opens_as_table(p)))


def _opens_as_table(path) -> bool:
    with open(path, encoding="utf-8", errors="replace") as file:
        return file.readline().startswith(TABLE_HEADER)


def internal_positions(axis, column) -> np.ndarray:
    """A table's position column in mm or rad."""
    values = np.asarray(column, dtype=float)
    return np.radians(values) if axis.kind == "rotary" else values


def read_compensation_fields(folder, machine) -> dict:
    """The fields of the :class:`~reliability.compensation.tables.CompensationTables` in a
    compensation folder written by :func:`write_compensation` (or by hand in its format),
    checked against ``machine``: ``machine, spacing_mm, spacing_deg, axes, assembly``
    (``CompensationTables.load`` builds the tables from them); a damaged or foreign file
    raises
    :class:`~reliability.basics.errors.SavedResultError` (an ``InputError``) naming it, the
    row and the column."""
    folder = Path(folder)
    if not folder.is_dir():
        raise SavedResultError(f"{folder}: not a folder of compensation tables")
    known = set(table_file_names(machine))
    unknown = sorted(p.name for p in folder.glob("*.csv") if p.name not in known)
    if unknown:
        raise SavedResultError(f"{folder / unknown[0]}: not a table of this machine; expected "
                               f"{', '.join(sorted(known))}")
    path = folder / ASSEMBLY_FILE
    if not path.exists():
        raise SavedResultError(f"{path}: missing; every compensation folder has one")
    spacing = _spacing(path)
    axes = {axis.name: _read_axis(folder / f"{axis.name}.csv", machine, a)
            for a, axis in enumerate(machine.axis_specs)}
    return {"machine": machine, "spacing_mm": spacing["spacing_mm"],
            "spacing_deg": spacing["spacing_deg"], "axes": axes,
            "assembly": _read_assembly(path, machine)}


def _units_text(symbols) -> str:
    lengths = [s for s in symbols if s[1] in "XYZ"]
    angles = [s for s in symbols if s[1] in "ABC"]
    parts = [f"{' '.join(lengths)} in mm" if lengths else "",
             f"{' '.join(angles)} in rad" if angles else ""]
    return "; ".join(p for p in parts if p) or "no errors tabled"


def _spacing(path) -> dict:
    found = {}
    for line in path.read_text(encoding="utf-8").splitlines():
        if not line.startswith("#"):
            break
        key, _, value = line[1:].partition(":")
        if key.strip() in SPACING_KEYS:
            found[key.strip()] = _number(value.strip(), path, "header", key.strip())
    missing = [key for key in SPACING_KEYS if key not in found]
    if missing:
        raise SavedResultError(f"{path}: the header has no line '# {missing[0]}: <value>'")
    return found


def _read_table(path) -> pd.DataFrame:
    try:
        return pd.read_csv(path, comment="#", dtype=str, keep_default_na=False)
    except (pd.errors.ParserError, pd.errors.EmptyDataError) as exc:
        raise SavedResultError(f"{path}: not a CSV table: {exc}") from None


def _read_axis(path, machine, a) -> pd.DataFrame:
    axis = machine.axis_specs[a]
    column = "position_deg" if axis.kind == "rotary" else "position_mm"
    if not path.exists():
        return pd.DataFrame({column: np.array([], dtype=float)})
    raw = _read_table(path)
    if raw.columns[0] != column:
        raise SavedResultError(f"{path}: the first column of a {axis.kind} axis' table is "
                               f"{column!r}; got {raw.columns[0]!r}")
    own = machine.iso_names[6 * a: 6 * a + 6]
    for symbol in raw.columns[1:]:
        if symbol not in own:
            raise SavedResultError(f"{path}, column {symbol!r}: not a motion error of axis "
                                   f"{axis.name}; expected among {', '.join(own)}")
    table = pd.DataFrame({name: [_number(v, path, row, name) for row, v in
                                 enumerate(raw[name], start=1)] for name in raw.columns})
    _check_positions(path, axis, table[column].to_numpy(), column)
    return table


def _check_positions(path, axis, shown, column) -> None:
    positions = internal_positions(axis, shown)
    low, high = axis.stroke
    slack = STROKE_SLACK * max(1.0, abs(low), abs(high))
    for row, value in enumerate(positions, start=1):
        if not low - slack <= value <= high + slack:
            raise SavedResultError(f"{path}, row {row}, column {column!r}: {shown[row - 1]!r} is "
                                   f"outside the stroke of axis {axis.name}")
    steps = np.diff(positions)
    if np.any(steps <= 0):
        row = int(np.argmax(steps <= 0)) + 2
        raise SavedResultError(f"{path}, row {row}, column {column!r}: positions must increase")


def _read_assembly(path, machine) -> pd.DataFrame:
    raw = _read_table(path)
    if tuple(raw.columns) != ASSEMBLY_COLUMNS:
        raise SavedResultError(f"{path}: expected the columns {', '.join(ASSEMBLY_COLUMNS)}; got "
                               f"{', '.join(raw.columns)}")
    first = 6 * len(machine.axes)
    constant = machine.error_names[first:]
    rows = []
    for row, (name, iso, value) in enumerate(raw.itertuples(index=False), start=1):
        if name not in constant:
            raise SavedResultError(f"{path}, row {row}, column 'error': {name!r} is not a constant "
                                   f"error of this machine (e.g. {constant[0]!r})")
        expected = machine.iso_names[machine.error_index(name)]
        if iso != expected:
            raise SavedResultError(f"{path}, row {row}, column 'iso': {name!r} is {expected!r}; "
                                   f"got {iso!r}")
        rows.append((name, iso, _number(value, path, row, "value")))
    return pd.DataFrame(rows, columns=list(ASSEMBLY_COLUMNS))


def _number(text, path, row, column) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise SavedResultError(f"{path}, row {row}, column {column!r}: expected a finite number; "
                               f"got {text!r}")
    return value
