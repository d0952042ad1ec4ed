"""Argument types, input files and printing shared by the ``precrel`` subcommands."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from reliability import display
from reliability.errors import InputError
from reliability.machine import load_machine

SIDE_CHOICES = ("one_sided", "two_sided")


# ----- argument types (argparse reports their errors as one line, exit 2) ---------------
def positive_int(text: str) -> int:
    """An integer >= 1."""
    value = _integer(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {text!r}")
    return value


def grid_points(text: str) -> int:
    """Grid points per axis: an integer >= 2 (both stroke ends)."""
    value = _integer(text)
    if value < 2:
        raise argparse.ArgumentTypeError(f"expected at least 2 points per axis, got {text!r}")
    return value


def seed(text: str) -> int:
    """A random seed: an integer >= 0."""
    value = _integer(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected a seed >= 0, got {text!r}")
    return value


def probability(text: str) -> float:
    """A reliability target strictly between 0 and 1."""
    value = _float(text)
    if not 0.0 < value < 1.0:
        raise argparse.ArgumentTypeError(f"expected a probability in (0, 1), got {text!r}")
    return value


def positive_float(text: str) -> float:
    """A finite number > 0."""
    value = _float(text)
    if not value > 0.0:
        raise argparse.ArgumentTypeError(f"expected a number > 0, got {text!r}")
    return value


def _integer(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None


def _float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not np.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return value


def add_machine(parser) -> None:
    parser.add_argument("machine", metavar="MACHINE.toml", help="machine description file")


def add_side(parser) -> None:
    parser.add_argument("--side", choices=SIDE_CHOICES, default="two_sided",
                        help="probability reading: exact two-sided P(|y| < I) (default) or "
                             "the paper's one-sided Phi(beta)")


def add_points(parser, default: int = 5) -> None:
    parser.add_argument("--points", type=grid_points, default=default, metavar="P",
                        help=f"grid points per axis over each stroke (default {default})")


def add_bounds(parser) -> None:
    parser.add_argument("--bounds", type=positive_float, nargs=2, default=(0.5, 1.5),
                        metavar=("LO", "HI"),
                        help="tolerance box as factors of the initial allocation "
                             "(default 0.5 1.5)")


def add_monte_carlo(parser) -> None:
    """``--repeats``, ``--samples`` and ``--seed`` of the Monte-Carlo verification."""
    parser.add_argument("--repeats", type=positive_int, default=20, metavar="N",
                        help="grid experiments per allocation (default 20, as the paper's "
                             "Table 9)")
    parser.add_argument("--samples", type=positive_int, default=20_000, metavar="N",
                        help="random-pose samples and samples per worst pose (default 20000)")
    parser.add_argument("--seed", type=seed, default=0, metavar="S",
                        help="random seed (default 0)")


# ----- checks done before any work ----------------------------------------------------
def check_bounds(bounds) -> tuple[float, float]:
    """``--bounds LO HI``: factors of the reference allocation, 0 < LO <= HI."""
    low, high = bounds
    if low > high:
        raise InputError(f"--bounds: LO = {low:g} exceeds HI = {high:g}; expected "
                         f"0 < LO <= HI (factors of the initial allocation)")
    return float(low), float(high)


def check_new_file(path, overwrite: bool, option: str = "--out") -> Path:
    """A file to be written: its folder exists, it is not a folder, and it is new unless
    ``overwrite``."""
    path = Path(path)
    if path.is_dir():
        raise InputError(f"{option} {path}: is a folder; expected a file name")
    if path.exists() and not overwrite:
        raise InputError(f"{option} {path}: exists; pass --overwrite to replace it")
    if not path.parent.is_dir():
        raise InputError(f"{option} {path}: folder {path.parent} does not exist")
    return path


def machine(args):
    """Load ``args.machine`` (a MachineDescriptionError or OSError names the file)."""
    return load_machine(args.machine)


def read_tolerances(path, machine) -> np.ndarray:
    """Tolerances from a CSV with columns ``error`` and ``allocated`` (what ``allocate``
    writes), aligned to the machine's error names.

    Raises
    ------
    InputError
        A missing column, a name the machine does not have, a name given twice, a missing
        name, or a value that is not a finite positive number.
    """
    try:
        frame = pd.read_csv(path)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise InputError(f"--tolerances {path}: not a readable CSV table "
                         f"({' '.join(str(exc).split())})") from None
    missing_columns = [c for c in ("error", "allocated") if c not in frame.columns]
    if missing_columns:
        raise InputError(f"--tolerances {path}: missing column(s) {missing_columns}; "
                         f"expected columns 'error' and 'allocated'")
    given = frame["error"].astype(str).str.strip()
    unknown = [n for n in given if not _known(machine, n)]
    if unknown:
        raise InputError(f"--tolerances {path}: unknown error name(s) {unknown[:5]}; "
                         f"the machine's errors are named like {machine.error_names[0]!r} "
                         f"(or by their ISO 230-1 symbols, like {machine.iso_names[0]!r})")
    names = pd.Series([machine.error_names[machine.error_index(n)] for n in given])
    repeated = sorted(set(names[names.duplicated()]))
    if repeated:
        raise InputError(f"--tolerances {path}: error(s) given twice: {repeated[:5]}")
    absent = [n for n in machine.error_names if n not in set(names)]
    if absent:
        raise InputError(f"--tolerances {path}: {len(absent)} error(s) missing, e.g. "
                         f"{absent[:5]}; expected one row per error of the machine")
    values = pd.to_numeric(frame["allocated"], errors="coerce").to_numpy(dtype=float)
    bad = np.flatnonzero(~(np.isfinite(values) & (values > 0)))
    if len(bad):
        raise InputError(f"--tolerances {path}: allocated value of {given[bad[0]]!r} is "
                         f"{frame['allocated'][bad[0]]!r}; expected a number > 0")
    return pd.Series(values, index=names).reindex(list(machine.error_names)).to_numpy()


def _known(machine, name: str) -> bool:
    """Whether ``name`` is one of the machine's error names or ISO 230-1 symbols."""
    try:
        machine.error_index(name)
    except KeyError:
        return False
    return True


# ----- printing ------------------------------------------------------------------------
def pose_text(machine, pose) -> str:
    """A pose as axis positions with units, e.g. ``X=-300 mm, C=1.571 rad``."""
    return display.pose_text(pose, machine.axes, display.axis_units(machine), digits=6)


def top_contributors(contributions: pd.DataFrame, output: str, n: int = 3) -> str:
    """The ``n`` errors contributing most to an output's variance at its worst pose."""
    column = contributions[output].sort_values(ascending=False, kind="stable").head(n)
    return ", ".join(f"{name} {share:.0f}%" for name, share in column.items())


def percent(value: float) -> str:
    return f"{100.0 * value:.4f} %"


def progress_bar(total: int, description: str):
    """A tqdm progress bar on stderr, hidden when stderr is not a terminal."""
    from tqdm import tqdm
    return tqdm(total=total, desc=description, file=sys.stderr, leave=False,
                disable=None)


def say(text: str) -> None:
    """A progress line on stderr."""
    print(text, file=sys.stderr, flush=True)
