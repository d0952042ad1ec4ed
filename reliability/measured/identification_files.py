"""An identification's folder, written and read back (docs/measurements.md).

:func:`write_identification` (``Identification.save``, ``precrel identify --out DIR``)
writes ``errors.csv``, ``setup.csv``, ``residuals.csv``, ``summary.json`` and
``covariance.npy`` (the posterior covariance of the errors, every digit kept); under a
profile along travel (``gp:<ℓ>``) also ``profiles.csv`` and ``coefficients.npz``: the prior
σ = t/3 of every error, the posterior mean and covariance of the coefficients, and per axis
the grid, the Karhunen–Loève loadings and the positions read, every digit kept; the tables
are written to :data:`~reliability.basics.files.SIGNIFICANT` digits.
:func:`read_identification_fields` (``Identification.load``) reads the identification back
from them and checks them first: the errors must be the machine's, in its order; the
covariances square, finite, symmetric and positive semi-definite, the errors' diagonal the
``posterior_sd`` of ``errors.csv``; the profile one an identification takes. Under ``gp``
the basis is built again from the machine and the profile
(:func:`reliability.measured.travel_bases.travel_bases`): the saved grid must be its grid
and the saved loadings must give the process' correlation on it as the rebuilt ones do
(:data:`BASIS_AGREEMENT`; the saved loadings are used, so that a platform whose eigenvectors
differ in sign reads the same machine), and the coefficients must give the rows of
``errors.csv`` and ``covariance.npy``.
"""

from __future__ import annotations

import io
import json
import zipfile
from pathlib import Path

import numpy as np
import pandas as pd

from ..basics.display import ZERO_RESOLUTION
from ..basics.errors import InputError, SavedResultError
from ..basics.files import (SIGNIFICANT, atomic_write_bytes, atomic_write_text,
                            check_destination, write_csv)
from ..basics.saved_results import PayloadReader
from .travel_bases import Coefficients, GaussianBasis, cross_correlation, travel_bases

COVARIANCE_FILE = "covariance.npy"
COEFFICIENTS_FILE = "coefficients.npz"
#: Every file an identification folder may hold (``profiles.csv`` and ``coefficients.npz``
#: only under ``gp``).
IDENTIFICATION_FILES = ("errors.csv", "profiles.csv", "setup.csv", "residuals.csv",
                        "summary.json", COVARIANCE_FILE, COEFFICIENTS_FILE)
ERROR_COLUMNS = ("error", "prior_sd", "posterior_mean", "posterior_sd", "lower", "upper")
SUMMARY_KEYS = ("rank", "condition", "chi2", "dof", "profile", "combinations", "prior_like")
#: Relative disagreement allowed between ``posterior_sd`` (written to :data:`SIGNIFICANT`
#: digits) and the root of the covariance's diagonal.
SD_AGREEMENT = 10.0 ** (1 - SIGNIFICANT)
#: Relative asymmetry, and negative eigenvalue against the largest, still read as rounding.
SYMMETRY_TOLERANCE = 1e-9
PSD_TOLERANCE = 1e-9
#: Largest difference allowed between the correlation on an axis' grid given by the saved
#: loadings and by the rebuilt ones (both reproduce the kernel to about 1e-9).
BASIS_AGREEMENT = 1e-6
#: Relative disagreement allowed between ``covariance.npy`` and the covariance the
#: coefficients give (both every digit, formed in a different order).
COVARIANCE_AGREEMENT = 1e-9
#: Keys of ``summary.json`` that pass into the identification when present.
STATUS_KEYS = ("iterations", "change", "settled")


def write_identification(identification, folder, overwrite: bool = False) -> tuple:
    """Write ``identification`` into ``folder`` (made if missing): the files of
    :data:`IDENTIFICATION_FILES` it holds, ``profiles.csv`` and ``coefficients.npz`` only
    under a profile along travel.

    With ``overwrite`` an earlier identification in the folder is replaced, and those of
    its files this one does not write (``profiles.csv`` and ``coefficients.npz`` of an
    earlier ``gp`` run under ``constant``) are removed, so the folder holds this run only;
    other files in the folder are left alone. Returns the names written, in the order of
    :data:`IDENTIFICATION_FILES`.

    Raises
    ------
    FileExistsError
        The folder holds an identification's file and not ``overwrite``.
    """
    folder = check_destination(folder, overwrite, folder=True, markers=IDENTIFICATION_FILES)
    folder.mkdir(exist_ok=True)
    digits = f"%.{SIGNIFICANT}g"
    varies = identification.coefficients.varies
    tables = {"errors.csv": identification.errors, "setup.csv": identification.setup,
              "residuals.csv": identification.residuals}
    if varies:
        tables["profiles.csv"] = identification.profiles
    for name, table in tables.items():
        write_csv(table, folder / name, overwrite=overwrite, index=False, float_format=digits)
    atomic_write_text(folder / "summary.json",
                      json.dumps(identification.summary_dict(), indent=2) + "\n", overwrite)
    write_covariance(identification, folder / COVARIANCE_FILE, overwrite)
    if varies:
        write_coefficients(identification, folder / COEFFICIENTS_FILE, overwrite)
    written = tuple(name for name in IDENTIFICATION_FILES
                    if varies or name not in ("profiles.csv", COEFFICIENTS_FILE))
    for name in set(IDENTIFICATION_FILES) - set(written):
        (folder / name).unlink(missing_ok=True)
    return written


def write_covariance(identification, path, overwrite: bool = False) -> Path:
    """Write the posterior covariance of the errors as ``.npy`` (atomically)."""
    buffer = io.BytesIO()
    np.save(buffer, np.asarray(identification.covariance, dtype=float), allow_pickle=False)
    return atomic_write_bytes(path, buffer.getvalue(), overwrite)


def write_coefficients(identification, path, overwrite: bool = False) -> Path:
    """Write what rebuilds an identification under a profile along travel as ``.npz``
    (atomically): ``prior_sd`` (σ = t/3 of every error), ``theta`` and
    ``theta_covariance`` (the coefficients' posterior), and per axis ``a`` its grid
    ``points_a``, loadings ``loadings_a`` and the positions read ``positions_a`` (mm,
    rad)."""
    coefficients = identification.coefficients
    arrays = {"prior_sd": coefficients.prior_sd, "theta": identification.theta,
              "theta_covariance": identification.theta_covariance}
    for a, basis in enumerate(coefficients.bases):
        arrays[f"points_{a}"] = basis.points
        arrays[f"loadings_{a}"] = basis.loadings
        arrays[f"positions_{a}"] = identification.positions[a]
    buffer = io.BytesIO()
    np.savez(buffer, **{key: np.asarray(value, dtype=float) for key, value in arrays.items()})
    return atomic_write_bytes(path, buffer.getvalue(), overwrite)


def read_identification_fields(folder, machine) -> dict:
    """The fields of the :class:`~reliability.measured.identification.Identification`
    written into ``folder`` by :func:`write_identification` (``precrel identify --out
    folder``), checked; ``Identification.load`` builds the identification from them.

    Parameters
    ----------
    folder : str or Path
    machine : Machine
        The machine it was identified on.

    Raises
    ------
    SavedResultError
        (an :class:`~reliability.basics.errors.InputError`) Naming the file and what is
        wrong: a missing file, column or array, errors that
        are not the machine's, a covariance of the wrong shape, not symmetric, not positive
        semi-definite or not matching ``posterior_sd``, a profile an identification does
        not take, coefficients whose basis is not the profile's or that do not give
        ``errors.csv`` and ``covariance.npy``.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise SavedResultError(f"identification {folder}: not a folder (expected what precrel "
                               f"identify --out writes)")
    errors = _read_errors(folder / "errors.csv", machine)
    summary = _read_summary(folder / "summary.json")
    bases = _profile_bases(folder / "summary.json", machine, summary["profile"])
    covariance = _read_covariance(folder / COVARIANCE_FILE, errors)
    posterior = {"prior_sd": errors["prior_sd"].to_numpy(dtype=float),
                 "mean": errors["posterior_mean"].to_numpy(dtype=float),
                 "covariance": covariance}
    if any(isinstance(basis, GaussianBasis) for basis in bases):
        posterior = _read_coefficients(folder / COEFFICIENTS_FILE, machine, bases, errors,
                                       covariance)
    status = {key: summary[key] for key in STATUS_KEYS if key in summary}
    return dict(
        machine=machine, profile=summary["profile"], **posterior,
        setup=_read_table(folder / "setup.csv", ("setup", "estimate", "sd")),
        rank=summary["rank"], condition=summary["condition"],
        combinations=summary["combinations"], prior_like=summary["prior_like"],
        residuals=_read_table(folder / "residuals.csv",
                              ("row", "run", "quantity", "value", "fitted", "normalised")),
        chi2=summary["chi2"], dof=summary["dof"], **status)


def _read_table(path, columns) -> pd.DataFrame:
    if not path.is_file():
        raise SavedResultError(f"{path}: missing; an identification folder holds it")
    table = pd.read_csv(path)
    missing = [c for c in columns if c not in table.columns]
    if missing:
        raise SavedResultError(f"{path}: missing column {missing[0]!r}; expected "
                               f"{', '.join(columns)}")
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
        raise SavedResultError(f"{path}: {what}; identify this machine ({machine.name!r}) to read "
                               f"its identification")
    numbers = table[list(ERROR_COLUMNS[1:])].apply(pd.to_numeric, errors="coerce")
    bad = np.argwhere(~np.isfinite(numbers.to_numpy(dtype=float)))
    if bad.size:
        row, column = bad[0]
        raise SavedResultError(f"{path}: row {row + 1}, column {numbers.columns[column]!r}: "
                               f"expected a finite number")
    if np.any(numbers["prior_sd"] <= 0):
        row = int(np.flatnonzero(numbers["prior_sd"].to_numpy() <= 0)[0])
        raise SavedResultError(f"{path}: row {row + 1}, column 'prior_sd': expected a number > 0")
    return pd.concat([table[["error"]], numbers], axis=1)


def _read_summary(path) -> dict:
    if not path.is_file():
        raise SavedResultError(f"{path}: missing; an identification folder holds it")
    try:
        summary = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise SavedResultError(f"{path}: not valid JSON: {exc}") from None
    missing = [key for key in SUMMARY_KEYS if key not in summary]
    if missing:
        raise SavedResultError(f"{path}: missing key {missing[0]!r}")
    data = PayloadReader(path, summary, "")
    checked = {"rank": data.integer("rank", low=0),
               "condition": data.number("condition", finite=False),
               "chi2": data.number("chi2"), "dof": data.integer("dof"),
               "profile": summary["profile"], "combinations": data.texts("combinations"),
               "prior_like": data.texts("prior_like")}
    status = {"iterations": lambda: data.integer("iterations", low=0),
              "change": lambda: data.number("change", finite=False),
              "settled": lambda: data.boolean("settled")}
    checked.update({key: status[key]() for key in STATUS_KEYS if key in summary})
    return checked


def _profile_bases(path, machine, profile) -> tuple:
    """The bases of ``profile`` on ``machine``, built again; a profile an identification
    does not take is refused naming ``path``."""
    if not isinstance(profile, str):
        raise SavedResultError(f"{path}: 'profile': expected 'constant' or "
                                     f"'gp:<length mm>'; got {profile!r}")
    try:
        return travel_bases(machine, profile)
    except InputError as exc:
        raise SavedResultError(f"{path}: {exc}") from None


def _read_covariance(path, errors) -> np.ndarray:
    if not path.is_file():
        raise SavedResultError(f"{path}: missing; precrel identify --out writes it")
    try:
        covariance = np.load(path, allow_pickle=False)
    except (ValueError, OSError) as exc:
        raise SavedResultError(f"{path}: not a numpy array file: {exc}") from None
    n = len(errors)
    if covariance.shape != (n, n) or not np.issubdtype(covariance.dtype, np.floating):
        raise SavedResultError(f"{path}: expected a ({n}, {n}) float array, one row and column per "
                               f"error; got {covariance.dtype} {covariance.shape}")
    _check_covariance(path, "the covariance", covariance)
    _check_sd(path, errors, covariance)
    return covariance


def _check_covariance(path, what: str, covariance) -> None:
    """Finite, symmetric and positive semi-definite, or a SavedResultError naming ``what``."""
    if not np.all(np.isfinite(covariance)):
        raise SavedResultError(f"{path}: {what} holds numbers that are not finite")
    scale = np.abs(covariance).max()
    if np.abs(covariance - covariance.T).max() > SYMMETRY_TOLERANCE * scale:
        raise SavedResultError(f"{path}: {what} is not symmetric")
    values = np.linalg.eigvalsh(covariance)
    if values[0] < -PSD_TOLERANCE * max(values[-1], 0.0):
        raise SavedResultError(f"{path}: {what} is not positive semi-definite (eigenvalue "
                               f"{values[0]:.3g})")


def _check_sd(path, errors, covariance) -> None:
    sd = np.sqrt(np.maximum(np.diag(covariance), 0.0))
    written = errors["posterior_sd"].to_numpy()
    off = np.abs(sd - written) > SD_AGREEMENT * np.maximum(np.abs(written), 1e-300)
    if off.any():
        row = int(np.flatnonzero(off)[0])
        raise SavedResultError(f"{path}: the covariance gives error {errors['error'].iloc[row]!r} "
                               f"sd {sd[row]:.6g}, errors.csv says {written[row]:.6g}; the files "
                               f"are not of one identification")


def _read_coefficients(path, machine, bases, errors, covariance) -> dict:
    """The posterior of an identification along travel from ``coefficients.npz``, checked
    against the rebuilt ``bases``, ``errors.csv`` and ``covariance.npy``."""
    arrays = _load_arrays(path)
    prior_sd = _array(path, arrays, "prior_sd", (machine.n_errors,))
    if np.any(prior_sd <= 0):
        raise SavedResultError(f"{path}: 'prior_sd' of error "
                               f"{machine.error_names[int(np.argmax(prior_sd <= 0))]!r}: expected "
                               f"a number > 0")
    saved = tuple(_saved_basis(path, arrays, a, basis) for a, basis in enumerate(bases))
    coefficients = Coefficients(saved, prior_sd)
    theta = _array(path, arrays, "theta", (coefficients.size,))
    theta_covariance = _array(path, arrays, "theta_covariance",
                              (coefficients.size, coefficients.size))
    _check_covariance(path, "'theta_covariance'", theta_covariance)
    rows = coefficients.mean_matrix()
    posterior = {"prior_sd": np.sqrt(np.sum(rows ** 2, axis=1)), "mean": rows @ theta,
                 "covariance": covariance, "coefficients": coefficients, "theta": theta,
                 "theta_covariance": theta_covariance,
                 "positions": tuple(_positions(path, arrays, a, axis)
                                    for a, axis in enumerate(machine.axis_specs))}
    _check_rows(path, errors, posterior)
    given = rows @ theta_covariance @ rows.T
    if np.abs(given - covariance).max() > COVARIANCE_AGREEMENT * np.abs(covariance).max():
        raise SavedResultError(f"{path}: the coefficients' covariance does not give "
                               f"{COVARIANCE_FILE}; the files are not of one identification")
    return posterior


def _load_arrays(path) -> dict:
    if not path.is_file():
        raise SavedResultError(f"{path}: missing; precrel identify --out writes it under a "
                               f"profile along travel")
    try:
        with np.load(path, allow_pickle=False) as loaded:
            return {key: loaded[key] for key in loaded.files}
    except (ValueError, OSError, EOFError, zipfile.BadZipFile, AttributeError) as exc:
        raise SavedResultError(f"{path}: not a numpy archive of arrays: {exc}") from None


def _array(path, arrays, key: str, shape: tuple) -> np.ndarray:
    """``arrays[key]``, a finite float array of ``shape`` (None: any length there)."""
    if key not in arrays:
        raise SavedResultError(f"{path}: missing array {key!r}")
    value = arrays[key]
    fits = value.ndim == len(shape) and all(want is None or want == got
                                            for want, got in zip(shape, value.shape))
    if not fits or not np.issubdtype(value.dtype, np.floating):
        wanted = tuple("any" if want is None else want for want in shape)
        raise SavedResultError(f"{path}: array {key!r}: expected a float array of shape "
                               f"{wanted}; got {value.dtype} {value.shape}")
    if not np.all(np.isfinite(value)):
        raise SavedResultError(f"{path}: array {key!r} holds numbers that are not finite")
    return value


def _saved_basis(path, arrays, a: int, rebuilt):
    """Axis ``a``'s saved basis, checked against the one the profile builds."""
    if not isinstance(rebuilt, GaussianBasis):
        return rebuilt
    name = rebuilt.axis.name
    points = _array(path, arrays, f"points_{a}", rebuilt.points.shape)
    if not np.allclose(points, rebuilt.points, rtol=1e-12, atol=1e-12):
        raise SavedResultError(f"{path}: array 'points_{a}': not the grid profile "
                               f"{rebuilt.model} lays along axis {name!r}")
    loadings = _array(path, arrays, f"loadings_{a}", (len(points), None))
    saved = GaussianBasis(rebuilt.axis, rebuilt.model, points, loadings)
    gap = _grid_correlation_gap(saved, rebuilt)
    if gap > BASIS_AGREEMENT:
        raise SavedResultError(f"{path}: array 'loadings_{a}': not a basis of profile "
                               f"{rebuilt.model} along axis {name!r} (the correlation it gives on "
                               f"the grid differs by {gap:.2g}, at most {BASIS_AGREEMENT:g})")
    return saved


def _grid_correlation_gap(saved, rebuilt) -> float:
    """Largest difference between ``ψ(S) ψ(S)ᵀ`` of two bases on the grid ``S``: the
    correlation each gives, the same whatever the signs or rotations of the eigenvectors."""
    correlation = cross_correlation(rebuilt.model, rebuilt.axis, rebuilt.points,
                                    rebuilt.points)
    psi_saved, psi_rebuilt = correlation @ saved.loadings, correlation @ rebuilt.loadings
    return float(np.abs(psi_saved @ psi_saved.T - psi_rebuilt @ psi_rebuilt.T).max())


def _positions(path, arrays, a: int, axis) -> np.ndarray:
    key = f"positions_{a}"
    positions = _array(path, arrays, key, (None,))
    low, high = axis.stroke
    margin = 1e-9 * max(1.0, abs(low), abs(high))
    if np.any((positions < low - margin) | (positions > high + margin)):
        raise SavedResultError(f"{path}: array {key!r}: positions outside the stroke of axis "
                               f"{axis.name!r}")
    return positions


def _check_rows(path, errors, posterior) -> None:
    """The coefficients' prior σ and mean of each row of ``errors.csv`` against it."""
    for column, key in (("prior_sd", "prior_sd"), ("posterior_mean", "mean")):
        written = errors[column].to_numpy()
        given = posterior[key]
        # a mean within ZERO_RESOLUTION of the prior σ is written as 0 (its rounding)
        floor = ZERO_RESOLUTION * posterior["prior_sd"] if key == "mean" else 0.0
        off = np.abs(given - written) > np.maximum(
            SD_AGREEMENT * np.maximum(np.abs(written), 1e-300), floor)
        if off.any():
            row = int(np.flatnonzero(off)[0])
            raise SavedResultError(f"{path}: the coefficients give error "
                                   f"{errors['error'].iloc[row]!r} {column} {given[row]:.6g}, "
                                   f"errors.csv says {written[row]:.6g}; the files are not of one "
                                   f"identification")
