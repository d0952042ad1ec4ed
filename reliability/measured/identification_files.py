"""An identification's folder read back (docs/measurements.md).

``precrel identify --out DIR`` writes ``errors.csv``, ``setup.csv``, ``residuals.csv``,
``summary.json`` and ``covariance.npy`` (the posterior covariance of the errors, every digit
kept). :func:`read_identification` rebuilds the :class:`Identification` from them and checks
them first: the errors must be the machine's, in its order; the covariance square, finite,
symmetric and positive semi-definite, its diagonal the ``posterior_sd`` of ``errors.csv``.
"""

from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np
import pandas as pd

from ..basics.errors import InputError
from ..basics.files import SIGNIFICANT, atomic_write_bytes
from .identification import Identification

COVARIANCE_FILE = "covariance.npy"
ERROR_COLUMNS = ("error", "prior_sd", "posterior_mean", "posterior_sd", "lower", "upper")
SUMMARY_KEYS = ("rank", "condition", "chi2", "dof", "profile", "combinations", "prior_like")
#: Relative disagreement allowed between ``posterior_sd`` (written to :data:`SIGNIFICANT`
#: digits) and the root of the covariance's diagonal.
SD_AGREEMENT = 10.0 ** (1 - SIGNIFICANT)
#: Relative asymmetry, and negative eigenvalue against the largest, still read as rounding.
SYMMETRY_TOLERANCE = 1e-9
PSD_TOLERANCE = 1e-9


def write_covariance(identification, path, overwrite: bool = False) -> Path:
    """Write the posterior covariance of the errors as ``.npy`` (atomically)."""
    buffer = io.BytesIO()
    np.save(buffer, np.asarray(identification.covariance, dtype=float), allow_pickle=False)
    return atomic_write_bytes(path, buffer.getvalue(), overwrite)


def read_identification(folder, machine) -> Identification:
    """The identification written by ``precrel identify --out folder``, checked.

    Parameters
    ----------
    folder : str or Path
    machine : Machine
        The machine it was identified on.

    Raises
    ------
    InputError
        Naming the file and what is wrong: a missing file or column, errors that are not the
        machine's, a covariance of the wrong shape, not symmetric, not positive
        semi-definite or not matching ``posterior_sd``, a profile other than ``constant``.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(f"identification {folder}: not a folder (expected what precrel "
                         f"identify --out writes)")
    errors = _read_errors(folder / "errors.csv", machine)
    summary = _read_summary(folder / "summary.json")
    covariance = _read_covariance(folder / COVARIANCE_FILE, errors)
    return Identification(
        machine=machine, profile=summary["profile"],
        prior_sd=errors["prior_sd"].to_numpy(dtype=float),
        mean=errors["posterior_mean"].to_numpy(dtype=float), covariance=covariance,
        setup=_read_table(folder / "setup.csv", ("setup", "estimate", "sd")),
        rank=int(summary["rank"]), condition=float(summary["condition"]),
        combinations=tuple(summary["combinations"]), prior_like=tuple(summary["prior_like"]),
        residuals=_read_table(folder / "residuals.csv",
                              ("row", "run", "quantity", "value", "fitted", "normalised")),
        chi2=float(summary["chi2"]), dof=int(summary["dof"]))


def _read_table(path, columns) -> pd.DataFrame:
    if not path.is_file():
        raise InputError(f"{path}: missing; an identification folder holds it")
    table = pd.read_csv(path)
    missing = [c for c in columns if c not in table.columns]
    if missing:
        raise InputError(f"{path}: missing column {missing[0]!r}; expected {', '.join(columns)}")
    return table


def _read_errors(path, machine) -> pd.DataFrame:
    table = _read_table(path, ERROR_COLUMNS)
    names = tuple(table["error"].astype(str))
    if names != machine.error_names:
        extra = [n for n in names if n not in machine.error_names]
        missing = [n for n in machine.error_names if n not in names]
        what = (f"error {extra[0]!r} is not one of the machine's" if extra else
                f"error {missing[0]!r} of the machine is missing" if missing else
                "the errors are not in the machine's order")
        raise InputError(f"{path}: {what}; identify this machine ({machine.name!r}) to read "
                         f"its identification")
    numbers = table[list(ERROR_COLUMNS[1:])].apply(pd.to_numeric, errors="coerce")
    bad = np.argwhere(~np.isfinite(numbers.to_numpy(dtype=float)))
    if bad.size:
        row, column = bad[0]
        raise InputError(f"{path}: row {row + 1}, column {numbers.columns[column]!r}: "
                         f"expected a finite number")
    if np.any(numbers["prior_sd"] <= 0):
        row = int(np.flatnonzero(numbers["prior_sd"].to_numpy() <= 0)[0])
        raise InputError(f"{path}: row {row + 1}, column 'prior_sd': expected a number > 0")
    return pd.concat([table[["error"]], numbers], axis=1)


def _read_summary(path) -> dict:
    if not path.is_file():
        raise InputError(f"{path}: missing; an identification folder holds it")
    try:
        summary = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise InputError(f"{path}: not valid JSON: {exc}") from None
    missing = [key for key in SUMMARY_KEYS if key not in summary]
    if missing:
        raise InputError(f"{path}: missing key {missing[0]!r}")
    if summary["profile"] != "constant":
        raise InputError(f"{path}: profile {summary['profile']!r}: only an identification "
                         f"under 'constant' is read back")
    return summary


def _read_covariance(path, errors) -> np.ndarray:
    if not path.is_file():
        raise InputError(f"{path}: missing; precrel identify --out writes it")
    try:
        covariance = np.load(path, allow_pickle=False)
    except (ValueError, OSError) as exc:
        raise InputError(f"{path}: not a numpy array file: {exc}") from None
    n = len(errors)
    if covariance.shape != (n, n) or not np.issubdtype(covariance.dtype, np.floating):
        raise InputError(f"{path}: expected a ({n}, {n}) float array, one row and column per "
                         f"error; got {covariance.dtype} {covariance.shape}")
    if not np.all(np.isfinite(covariance)):
        raise InputError(f"{path}: holds numbers that are not finite")
    scale = np.abs(covariance).max()
    if np.abs(covariance - covariance.T).max() > SYMMETRY_TOLERANCE * scale:
        raise InputError(f"{path}: the covariance is not symmetric")
    values = np.linalg.eigvalsh(covariance)
    if values[0] < -PSD_TOLERANCE * max(values[-1], 0.0):
        raise InputError(f"{path}: the covariance is not positive semi-definite (eigenvalue "
                         f"{values[0]:.3g})")
    _check_sd(path, errors, covariance)
    return covariance


def _check_sd(path, errors, covariance) -> None:
    sd = np.sqrt(np.maximum(np.diag(covariance), 0.0))
    written = errors["posterior_sd"].to_numpy()
    off = np.abs(sd - written) > SD_AGREEMENT * np.maximum(np.abs(written), 1e-300)
    if off.any():
        row = int(np.flatnonzero(off)[0])
        raise InputError(f"{path}: the covariance gives error {errors['error'].iloc[row]!r} "
                         f"sd {sd[row]:.6g}, errors.csv says {written[row]:.6g}; the files "
                         f"are not of one identification")
