"""A result's saved payload described field by field, written and read back checked.

A result module lists the fields it saves, each with its kind::

    FIELDS = (Array("poses", ("n", None)), Array("probability", ("n",), low=0, high=1),
              Integer("n_points", low=1), Text("distribution", ("normal", "truncated")))

:func:`write_fields` turns a result into the JSON-ready payload of
:func:`~reliability.basics.saved_results.save_payload`; :func:`read_fields` reads a payload
(a :class:`~reliability.basics.saved_results.PayloadReader`) back into the keyword arguments
of the result's constructor, every field checked by its kind. A shape entry that is a text
(``"n"``) is a length shared by the fields that name it: the first field read fixes it and
every later one must agree. A field declared ``optional`` may be saved as ``null`` (None).
A damaged field raises :class:`~reliability.basics.errors.SavedResultError` naming the file
and the field.
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np

from .saved_results import PayloadReader, encode_frame, load_payload, save_payload

PLAIN = (str, int, float, bool, type(None))


class Field(ABC):
    """One saved field: its name, whether it may be None, how it is written and read (each
    kind of field says how it reads)."""

    def __init__(self, name: str, optional: bool = False):
        self.name, self.optional = name, optional

    def write(self, value):
        """The JSON-ready form of ``value`` (numpy values are converted on writing)."""
        return value

    @abstractmethod
    def read(self, data, dims: dict):
        """The field's value from ``data``, checked; ``dims`` holds the shared lengths."""


class Number(Field):
    """A float, finite unless ``finite=False``, optionally ``> 0`` or within
    ``[low, high]``."""

    def __init__(self, name, optional=False, *, positive=False, finite=True, low=None,
                 high=None):
        super().__init__(name, optional)
        self.positive, self.finite, self.low, self.high = positive, finite, low, high

    def read(self, data, dims):
        value = data.number(self.name, positive=self.positive, finite=self.finite)
        if (self.low is not None and value < self.low) or \
                (self.high is not None and value > self.high):
            raise data.error(self.name, f"expected a number in [{self.low}, {self.high}], "
                                        f"got {value!r}")
        return value


class Integer(Field):
    """A whole number, optionally ``>= low``."""

    def __init__(self, name, optional=False, *, low=None):
        super().__init__(name, optional)
        self.low = low

    def read(self, data, dims):
        return data.integer(self.name, low=self.low)


class Flag(Field):
    """``true`` or ``false``."""

    def read(self, data, dims):
        return data.boolean(self.name)


class Text(Field):
    """A text, optionally one of ``choices``."""

    def __init__(self, name, choices=None, optional=False):
        super().__init__(name, optional)
        self.choices = choices

    def read(self, data, dims):
        return data.text(self.name, self.choices)


class Texts(Field):
    """A tuple of texts; ``size`` an int or a shared length's name."""

    def __init__(self, name, size=None, optional=False, *, unique=False):
        super().__init__(name, optional)
        self.size, self.unique = size, unique

    def read(self, data, dims):
        size = dims.get(self.size, self.size) if isinstance(self.size, str) else self.size
        value = data.texts(self.name, size=size if isinstance(size, int) else None,
                           unique=self.unique)
        if isinstance(self.size, str):
            dims[self.size] = len(value)
        return value


class TextLists(Field):
    """A tuple of tuples of texts; ``size`` (of the outer tuple) an int or a shared
    length's name."""

    def __init__(self, name, size=None, optional=False):
        super().__init__(name, optional)
        self.size = size

    def read(self, data, dims):
        rows = data.raw(self.name)
        if not isinstance(rows, list) or not all(
                isinstance(row, list) and all(isinstance(v, str) for v in row) for row in rows):
            raise data.error(self.name, "expected a list of lists of texts")
        size = dims.get(self.size, self.size) if isinstance(self.size, str) else self.size
        if isinstance(size, int) and len(rows) != size:
            raise data.error(self.name, f"expected {size} entries, got {len(rows)}")
        if isinstance(self.size, str):
            dims[self.size] = len(rows)
        return tuple(tuple(row) for row in rows)


class Array(Field):
    """A numeric array of ``shape`` (ints, None for any length, or shared lengths' names),
    of ``dtype`` (``float``, ``int`` or ``bool``), finite (or NaN where ``nan``),
    optionally ``> 0`` or within ``[low, high]``."""

    def __init__(self, name, shape, optional=False, *, dtype=float, low=None, high=None,
                 positive=False, nan=False):
        super().__init__(name, optional)
        self.shape, self.dtype, self.positive, self.nan = tuple(shape), dtype, positive, nan
        self.low, self.high = (0, 1) if dtype is bool else (low, high)

    def read(self, data, dims):
        wanted = tuple(dims.get(n) if isinstance(n, str) else n for n in self.shape)
        array = data.array(self.name, wanted, dtype=np.int64 if self.dtype is int else float,
                           low=self.low, high=self.high, positive=self.positive,
                           nan=self.nan)
        for n, length in zip(self.shape, array.shape):
            if isinstance(n, str):
                dims[n] = length
        return array.astype(bool) if self.dtype is bool else array


class Frame(Field):
    """A table (:func:`~reliability.basics.saved_results.encode_frame`) with at least
    ``columns``; its index is named as saved."""

    def __init__(self, name, columns=(), optional=False):
        super().__init__(name, optional)
        self.columns = tuple(columns)

    def write(self, value):
        return encode_frame(value)

    def read(self, data, dims):
        return data.frame(self.name, columns=self.columns)


class Mapping(Field):
    """A dict of names to plain values: numbers, texts, flags, None, and lists and dicts of
    them."""

    def write(self, value):
        return {str(key): item for key, item in value.items()}

    def read(self, data, dims):
        part = data.table(self.name)
        for key, item in part.data.items():
            if not _plain(item):
                raise part.error(key, f"expected a plain value, got {item!r}")
        return dict(part.data)


def _plain(value) -> bool:
    """Whether ``value`` is built from plain JSON values only."""
    if isinstance(value, list):
        return all(_plain(v) for v in value)
    if isinstance(value, dict):
        return all(isinstance(k, str) and _plain(v) for k, v in value.items())
    return isinstance(value, PLAIN)


class Nested(Field):
    """Another result saved inside this one, through ``kind.payload(value)`` and
    ``kind.from_payload(data)`` (``kind`` the result's class, or a class that saves a
    result of another)."""

    def __init__(self, name, kind: type, optional=False):
        super().__init__(name, optional)
        self.kind = kind

    def write(self, value):
        return self.kind.payload(value)

    def read(self, data, dims):
        return self.kind.from_payload(data.table(self.name))


class Record(Field):
    """One object (e.g. a bound or a solver's residuals) saved as its ``fields`` and rebuilt
    by ``build(**values)``."""

    def __init__(self, name, fields, build, optional=False):
        super().__init__(name, optional)
        self.fields, self.build = tuple(fields), build

    def write(self, value):
        return write_fields(value, self.fields)

    def read(self, data, dims):
        return self.build(**read_fields(data.table(self.name), self.fields))


class Records(Field):
    """A tuple of objects (e.g. a machine's axes), each saved as its ``fields`` and rebuilt
    by ``build(**values)``."""

    def __init__(self, name, fields, build, optional=False):
        super().__init__(name, optional)
        self.fields, self.build = tuple(fields), build

    def write(self, value):
        return [write_fields(item, self.fields) for item in value]

    def read(self, data, dims):
        items = data.raw(self.name)
        if not isinstance(items, list):
            raise data.error(self.name, "expected a list")
        return tuple(self.build(**read_fields(PayloadReader(data.path, item, f"{data.where}."
                                                            f"{self.name}[{i}]".lstrip(".")),
                                              self.fields))
                     for i, item in enumerate(items))


def write_fields(result, fields) -> dict:
    """The payload of ``result``: each field's value (an attribute of the same name)."""
    payload = {}
    for field in fields:
        value = getattr(result, field.name)
        payload[field.name] = None if value is None else field.write(value)
    return payload


def read_fields(data, fields) -> dict:
    """The checked value of each field in ``data``, by name.

    Raises
    ------
    SavedResultError
        A field is missing, None without being optional, or not of its kind.
    """
    dims, values = {}, {}
    for field in fields:
        if data.raw(field.name) is None:
            if not field.optional:
                raise data.error(field.name, "expected a value, got null")
            values[field.name] = None
        else:
            values[field.name] = field.read(data, dims)
    return values


def save_fields(result, path, kind: str, fields, overwrite: bool = False):
    """Save ``result``'s ``fields`` under the format tag ``kind``; returns the path."""
    return save_payload(path, kind, write_fields(result, fields), overwrite)


def load_fields(path, kind: str, fields) -> tuple:
    """The payload reader of a file of ``kind`` and its fields' checked values."""
    data = load_payload(path, kind)
    return data, read_fields(data, fields)
