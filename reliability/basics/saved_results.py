"""Saving results as JSON with their metadata, and reloading them with every field verified.

A saved result is one JSON object::

    {"format": "<kind>", "format_version": 1, "toolkit_version": "0.2.0", "payload": {...}}

``format`` says what the file holds (e.g. ``"precrel.fosm_result"``), ``format_version`` the
layout of the payload, ``toolkit_version`` which release wrote it (for the record only).
The payload is written by the result's own module; on reload it is read through a
:class:`PayloadReader`, whose every accessor checks type, shape and range and raises
:class:`~reliability.basics.errors.SavedResultError` naming the file and the field at fault.
Files are written atomically and never over an existing file unless ``overwrite=True``.
Floats are written with all their digits, so a reloaded result is bit-for-bit the saved one.
"""

from __future__ import annotations

import json
import math
from importlib import metadata
from pathlib import Path
from typing import Protocol, runtime_checkable

import numpy as np
import pandas as pd

from .errors import InputError, InputTypeError, SavedResultError
from .files import atomic_write_text, check_destination, check_path

FORMAT_VERSION = 1
DISTRIBUTION = "precision-reliability"


@runtime_checkable
class SavedResult(Protocol):
    """What every result a user can get offers: ``summary()`` (readable text),
    ``to_frame()`` (a DataFrame), ``save(path, overwrite=False)`` and the classmethod
    ``load(path)``, which checks the file and keeps the result's verdicts."""

    def summary(self) -> str: ...

    def to_frame(self) -> pd.DataFrame: ...

    def save(self, path, overwrite: bool = False) -> Path: ...

    @classmethod
    def load(cls, path): ...


def toolkit_version() -> str:
    """Version of the installed toolkit, or ``"unknown"`` when it is not installed."""
    try:
        return metadata.version(DISTRIBUTION)
    except metadata.PackageNotFoundError:
        return "unknown"


def save_payload(path, kind: str, payload: dict, overwrite: bool = False) -> Path:
    """Write ``payload`` (JSON-ready) under the format tag ``kind`` to ``path``.

    Parameters
    ----------
    path : str or Path
    kind : str
        Format tag, checked on reload.
    payload : dict
        Built from plain numbers, strings, lists and the encoders of this module.
    overwrite : bool
        Replace an existing file; otherwise an existing file raises FileExistsError.
    """
    check_destination(path, overwrite)
    document = {"format": kind, "format_version": FORMAT_VERSION,
                "toolkit_version": toolkit_version(), "payload": payload}
    text = json.dumps(document, indent=1, default=plain_json)
    return atomic_write_text(path, text + "\n", overwrite)


def load_payload(path, kind: str) -> "PayloadReader":
    """Read a file written by :func:`save_payload` with tag ``kind``.

    Raises
    ------
    SavedResultError
        The file is missing, not JSON, of another format or version; names the file.
    """
    path = check_path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise SavedResultError(f"{path}: no such file") from None
    except (UnicodeDecodeError, IsADirectoryError) as exc:
        raise SavedResultError(f"{path}: not a saved result ({exc})") from None
    try:
        document = json.loads(text)
    except json.JSONDecodeError as exc:
        raise SavedResultError(f"{path}: not valid JSON: {exc}") from None
    top = PayloadReader(path, document, "")
    found = top.text("format")
    if found != kind:
        raise SavedResultError(f"{path}: field 'format': holds {found!r}, expected {kind!r}")
    version = top.integer("format_version")
    if version != FORMAT_VERSION:
        raise SavedResultError(f"{path}: field 'format_version': {version} is not readable "
                               f"by this toolkit (reads {FORMAT_VERSION})")
    top.text("toolkit_version")
    return top.table("payload")


def check_count(value, name: str) -> int:
    """A whole number >= 1 (e.g. how many rows a summary lists)."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise InputTypeError(f"{name} must be a whole number; got {value!r}")
    if value < 1:
        raise InputError(f"{name} must be >= 1; got {value}")
    return int(value)


# ----- encoding ----------------------------------------------------------------------
def encode_frame(frame: pd.DataFrame | None) -> dict | None:
    """A table as ``{"index_name", "index", "columns": {name: values}}``."""
    if frame is None:
        return None
    return {"index_name": frame.index.name, "index": frame.index.tolist(),
            "columns": {str(c): frame[c].tolist() for c in frame.columns}}


def plain_json(value):
    """JSON form of numpy scalars and arrays: the ``default`` of :func:`json.dumps` for every
    JSON file of results (saved results here, the result store's records).

    Raises
    ------
    InputTypeError
        For any other type (a ``TypeError``).
    """
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, tuple):
        return list(value)
    raise InputTypeError(f"cannot save a {type(value).__name__} in a result file")


# ----- verified reading --------------------------------------------------------------
class PayloadReader:
    """Typed, checked access to one JSON object of a saved result.

    Every accessor takes the field name and raises :class:`SavedResultError` with the
    file and the dotted field path when the field is absent or not as expected.
    """

    def __init__(self, path: Path, data, where: str):
        self.path, self.where = path, where
        if not isinstance(data, dict):
            raise self.error(None, f"expected an object, got {type(data).__name__}")
        self.data = data

    def error(self, key, problem: str) -> SavedResultError:
        """The exception for a problem with field ``key`` (None: this object itself)."""
        field = ".".join(p for p in (self.where, key) if p) or "(top level)"
        return SavedResultError(f"{self.path}: field {field!r}: {problem}")

    def raw(self, key: str):
        if key not in self.data:
            raise self.error(key, "missing")
        return self.data[key]

    def table(self, key: str) -> "PayloadReader":
        """A nested object."""
        return PayloadReader(self.path, self.raw(key), ".".join(p for p in (self.where, key)
                                                                  if p))

    def text(self, key: str, choices=None) -> str:
        value = self.raw(key)
        if not isinstance(value, str):
            raise self.error(key, f"expected text, got {value!r}")
        if choices is not None and value not in choices:
            raise self.error(key, f"expected one of {tuple(choices)}, got {value!r}")
        return value

    def texts(self, key: str, size: int | None = None, unique: bool = False
              ) -> tuple[str, ...]:
        value = self.raw(key)
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            raise self.error(key, "expected a list of texts")
        if size is not None and len(value) != size:
            raise self.error(key, f"expected {size} entries, got {len(value)}")
        if unique and len(set(value)) != len(value):
            duplicate = next(v for v in value if value.count(v) > 1)
            raise self.error(key, f"{duplicate!r} appears more than once")
        return tuple(value)

    def boolean(self, key: str) -> bool:
        value = self.raw(key)
        if not isinstance(value, bool):
            raise self.error(key, f"expected true or false, got {value!r}")
        return value

    def integer(self, key: str, low: int | None = None) -> int:
        value = self.raw(key)
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.error(key, f"expected a whole number, got {value!r}")
        if low is not None and value < low:
            raise self.error(key, f"expected a whole number >= {low}, got {value}")
        return value

    def number(self, key: str, positive: bool = False, finite: bool = True) -> float:
        value = self.raw(key)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.error(key, f"expected a number, got {value!r}")
        value = float(value)
        if finite and not math.isfinite(value):
            raise self.error(key, f"expected a finite number, got {value!r}")
        if positive and not value > 0:
            raise self.error(key, f"expected a number > 0, got {value!r}")
        return value

    def array(self, key: str, shape: tuple, *, dtype=float, low=None, high=None,
              positive: bool = False, nan: bool = False) -> np.ndarray:
        """A numeric array of exactly ``shape`` (None entries match any length), finite
        (or NaN, a value not computed, when ``nan``), optionally ``> 0`` or within
        ``[low, high]``."""
        value = self.raw(key)
        try:
            array = np.array(value, dtype=float)
        except (TypeError, ValueError):
            raise self.error(key, "expected a numeric array") from None
        expected = tuple(array.shape[i] if n is None and i < array.ndim else n
                         for i, n in enumerate(shape))
        if array.shape != expected:
            raise self.error(key, f"expected shape {_shape_text(shape)}, got {array.shape}")
        self._check_values(key, array, low, high, positive, dtype, nan)
        return array.astype(dtype)

    def _check_values(self, key, array, low, high, positive, dtype, nan=False):
        bad = np.isinf(array) if nan else ~np.isfinite(array)
        what = ["finite or NaN" if nan else "finite"]
        if dtype is not float:
            bad |= array != np.round(array)
            what.append("whole numbers")
        if positive:
            bad |= ~(array > 0) & ~np.isnan(array)
            what.append("> 0")
        if low is not None or high is not None:
            bad |= (array < (-np.inf if low is None else low)) | \
                (array > (np.inf if high is None else high))
            what.append(f"in [{'-inf' if low is None else low}, "
                        f"{'inf' if high is None else high}]")
        if bad.any():
            first = tuple(int(i) for i in np.argwhere(bad)[0])
            raise self.error(key, f"entries must be {', '.join(what)}; entry {list(first)} "
                                  f"is {float(array[first])!r}")

    def frame(self, key: str, columns=None, index=None) -> pd.DataFrame | None:
        """A table saved by :func:`encode_frame` (None when saved as null), with at least
        ``columns`` and, when given, exactly ``index``."""
        if self.data.get(key, ...) is None:
            return None
        part = self.table(key)
        labels = part.raw("index")
        body = part.table("columns")
        if not isinstance(labels, list):
            raise part.error("index", "expected a list")
        for name, values in body.data.items():
            if not isinstance(values, list) or len(values) != len(labels):
                raise body.error(name, f"expected {len(labels)} values, one per row")
        missing = [c for c in columns or () if c not in body.data]
        if missing:
            raise part.error("columns", f"lacks column {missing[0]!r}")
        if index is not None and tuple(labels) != tuple(index):
            raise part.error("index", f"expected rows {tuple(index)}, got {tuple(labels)}")
        name = part.data.get("index_name")
        return pd.DataFrame(body.data, index=pd.Index(labels, name=name))


def _shape_text(shape) -> str:
    return "(" + ", ".join("n" if n is None else str(n) for n in shape) + \
        ("," if len(shape) == 1 else "") + ")"
