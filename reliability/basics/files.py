"""Writing result files safely: never over an existing file unless asked, and atomically.

:func:`check_destination` is the one check of where a file or a report folder may be
written; every save calls it before writing, and the command line calls it before any work
(rewording its refusals in terms of its options). A save writes to a temporary file in the
destination folder and renames it into place, so an interrupted save leaves either the old
file or the new one, never half of one. Files and folders get the permissions the user's umask
gives a new file or folder (0644 and 0755 under umask 022), as ``open`` and ``mkdir`` would.
"""

from __future__ import annotations

import os
import tempfile
import tomllib
from decimal import ROUND_DOWN, ROUND_UP, Decimal
from pathlib import Path

import numpy as np
import pandas as pd

from .errors import InputError, InputTypeError

#: Significant digits of every number the toolkit writes to a CSV, markdown or JSON file.
SIGNIFICANT = 6


def as_written(values, digits: int = SIGNIFICANT) -> np.ndarray:
    """``values`` exactly as they read back from a file written to ``digits`` significant
    digits (``%.{digits}g``): what a later command reading that file computes with."""
    values = np.asarray(values, dtype=float)
    return np.array([float(f"{v:.{digits}g}") for v in values.ravel()]).reshape(values.shape)


def rounded_down(values, digits: int = SIGNIFICANT) -> np.ndarray:
    """Positive ``values`` cut (rounded toward zero) to ``digits`` significant digits, as
    floats that a file written with ``%.{digits}g`` holds exactly and reads back unchanged.

    A value whose nearest ``digits``-digit decimal reads back at or below it is written as
    that decimal (``0.0015`` stays ``0.0015``); any other is cut in exact decimal arithmetic.
    Either way what a file reads back is never above the value: a tolerance written this
    way is never looser than the one computed. :func:`rounded_up` is its mirror.

    Raises
    ------
    InputError
        A value that is not a finite number > 0.
    """
    return _rounded(values, digits, ROUND_DOWN, "down")


def rounded_up(values, digits: int = SIGNIFICANT) -> np.ndarray:
    """Positive ``values`` rounded away from zero to ``digits`` significant digits, as
    floats that ``%.{digits}g`` writes exactly: what is written is never below the value
    (an upper bound stays an upper bound: ``2.04831e-05`` at 5 digits is ``2.0484e-05``).

    Raises
    ------
    InputError
        A value that is not a finite number > 0.
    """
    return _rounded(values, digits, ROUND_UP, "up")


def _rounded(values, digits: int, rounding: str, words: str) -> np.ndarray:
    values = np.asarray(values, dtype=float)
    bad = np.flatnonzero(~(np.isfinite(values) & (values > 0)))
    if len(bad):
        raise InputError(f"values: entry {int(bad[0])} is {float(values.ravel()[bad[0]])!r}; "
                         f"expected a finite number > 0 to round {words}")
    return np.array([_cut(float(v), digits, rounding)
                     for v in values.ravel()]).reshape(values.shape)


def _cut(value: float, digits: int, rounding: str) -> float:
    nearest = float(f"{value:.{digits}g}")
    if nearest == value or (nearest < value) == (rounding == ROUND_DOWN):
        return nearest
    exact = Decimal(value)
    step = Decimal(1).scaleb(exact.adjusted() - digits + 1)
    return float(exact.quantize(step, rounding=rounding))


def probability_text(value: float, digits: int = SIGNIFICANT) -> str:
    """A probability as a file keeps it: both ``value`` and ``1 − value`` to ``digits``
    significant digits (``0.999999999``, never a rounded ``1``); 0 and 1 as ``0`` and ``1``.
    """
    value = float(value)
    if not 0.0 < value < 1.0:
        return f"{value:g}"
    smallest = min(value, 1.0 - value)
    decimals = digits - 1 - int(np.floor(np.log10(smallest)))
    return f"{value:.{decimals}f}".rstrip("0")


#: Permissions asked for a new file and a new folder, before the umask (as ``open``/``mkdir``).
NEW_FILE_MODE, NEW_FOLDER_MODE = 0o666, 0o777


def read_toml(path) -> dict:
    """The TOML file at ``path``, parsed; :class:`InputError` naming the file if it is not
    UTF-8 text or not valid TOML."""
    path = Path(path)
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{path}: not valid TOML: {exc}") from None
    except UnicodeDecodeError:
        raise InputError(f"{path}: not a text file (UTF-8 TOML expected)") from None


def current_umask() -> int:
    """The process's umask: read from ``/proc/self/status`` where the system has it (no
    change of process state), else by setting it and setting it back."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("Umask:"):
                return int(line.split()[1], 8)
    except OSError:
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def make_temporary_folder(beside: Path) -> Path:
    """A new, empty folder next to ``beside`` (same file system, so it can be renamed onto
    it), with the permissions ``mkdir`` would give under the user's umask."""
    folder = Path(tempfile.mkdtemp(dir=beside.parent, prefix=f".{beside.name}.",
                                   suffix=".partial"))
    folder.chmod(NEW_FOLDER_MODE & ~current_umask())
    return folder


def check_path(path) -> Path:
    """``path`` as a Path: refused unless it is a non-empty str or path (to read or write).

    Raises
    ------
    InputTypeError
        ``path`` is not a str or path.
    InputError
        ``path`` is empty.
    """
    if not isinstance(path, (str, os.PathLike)):
        raise InputTypeError(f"path must be a file name (str or Path); got "
                             f"{type(path).__name__}")
    if str(path) == "":
        raise InputError("path must not be empty")
    return Path(path)


def check_destination(path, overwrite: bool = False, *, folder: bool = False,
                      markers=()) -> Path:
    """Where a result may be written: refused before any work, or returned as a Path.

    Parameters
    ----------
    path : str or os.PathLike
        A file to write, or with ``folder=True`` a folder to write into (it may not exist
        yet; its parent must).
    overwrite : bool
        Whether an existing file (or, for a folder, an earlier result in it) may be replaced.
    folder : bool
        ``path`` names a folder rather than a file.
    markers : iterable of str
        With ``folder=True``: file names whose presence in the folder marks an earlier result
        (e.g. ``report.md``); the folder is refused when one exists and not ``overwrite``.

    Raises
    ------
    InputTypeError
        ``path`` is not a str or path, or ``overwrite`` is not a bool.
    InputError
        ``path`` is empty.
    IsADirectoryError, NotADirectoryError
        A file is asked for where a folder is, or a folder where a file is.
    FileExistsError
        The file (or a marker file of the folder) exists and ``overwrite`` is false.
    FileNotFoundError
        The folder that should hold ``path`` does not exist.
    """
    path = check_path(path)
    if not isinstance(overwrite, bool):
        raise InputTypeError(f"overwrite must be True or False; got {overwrite!r}")
    if folder and path.exists() and not path.is_dir():
        raise NotADirectoryError(f"{path} is a file; expected a folder")
    if not folder and path.is_dir():
        raise IsADirectoryError(f"{path} is a folder; give a file name")
    existing = [path / name for name in markers if (path / name).exists()] if folder else \
        [path] if path.exists() else []
    if existing and not overwrite:
        raise FileExistsError(f"{existing[0]} exists; pass overwrite=True to replace it")
    if not path.parent.is_dir():
        raise FileNotFoundError(f"folder {path.parent} does not exist")
    return path


def atomic_write_bytes(path, data: bytes, overwrite: bool = False) -> Path:
    """Write ``data`` to ``path`` atomically.

    Parameters
    ----------
    path : str or Path
    data : bytes
    overwrite : bool
        Replace an existing file; otherwise an existing file raises FileExistsError.
    """
    path = check_destination(path, overwrite)
    handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.",
                                         suffix=".tmp")
    try:
        os.chmod(handle, NEW_FILE_MODE & ~current_umask())
        with os.fdopen(handle, "wb") as stream:
            stream.write(data)
            stream.flush()
            os.fsync(stream.fileno())
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
    return path


def atomic_write_text(path, text: str, overwrite: bool = False) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically; see :func:`atomic_write_bytes`."""
    return atomic_write_bytes(path, text.encode("utf-8"), overwrite)


def write_csv(frame: pd.DataFrame, path, overwrite: bool = False, **kwargs) -> Path:
    """Write a table as CSV atomically, refusing to replace a file unless ``overwrite``."""
    return atomic_write_text(path, frame.to_csv(**kwargs), overwrite)
