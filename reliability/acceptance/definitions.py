"""Acceptance-test files: the ``[[tests]]`` TOML layout (docs/acceptance.md), read, checked and
written (:func:`table_of_test`).

One ``[[tests]]`` table per test, each with ``name``, ``kind`` and ``limit``::

    [[tests]]
    name = "circle_xy_r100"
    kind = "circular"                            # circular | positioning | rotary
    plane = "xy"
    centre = { X = 0.0, Y = 250.0, Z = -100.0 }  # every axis (mm, rad)
    radius = 100.0                               # mm
    limit = 0.0008                               # mm, on G

Every refusal (unknown kind, axis, plane or key; a missing key; a radius or target that
leaves the strokes; a limit <= 0) is an :class:`~reliability.basics.errors.InputError` that names
the file, the test and the key, raised before any computation: the tests' paths are built
and checked against the machine while reading. A limit over 1 mm is accepted but looks
written in µm: :func:`unit_warnings` lists such limits.
"""

from __future__ import annotations

import math
from typing import Mapping

from ..basics.errors import InputError
from ..basics.files import read_toml
from ..model.machine_checks import implausible_values
from .iso_tests import KINDS, CircularTest, PositioningTest, RotaryTest, build_path

COMMON_KEYS = ("name", "kind", "limit")
#: Keys of each kind: required, then optional.
KEYS = {
    "circular": (("plane", "centre", "radius"), ()),
    "positioning": (("axis", "line"), ("targets", "runs")),
    "rotary": (("axis", "centre"), ("sweep",)),
}


def read_tests(path, machine) -> tuple:
    """Read and check a test file against ``machine``.

    Parameters
    ----------
    path : str or Path
    machine : Machine

    Returns
    -------
    tuple of CircularTest, PositioningTest, RotaryTest
    """
    data = read_toml(path)
    return parse_tests(data, machine, source=str(path))


def unit_warnings(tests, source: str = "tests") -> list[str]:
    """Limits that look written in µm (over 1 mm;
    :func:`reliability.model.machine_checks.implausible_values`), one sentence each.

    Parameters
    ----------
    tests : tuple of CircularTest, PositioningTest, RotaryTest
        As :func:`read_tests` returns them.
    source : str
        The test file, named in each sentence.

    Returns
    -------
    list of str
    """
    return implausible_values((f"{source}: test {test.name!r}: the limit on {quantity}",
                               value, "mm")
                              for test in tests for quantity, value in test.limits.items())


def parse_tests(data: Mapping, machine, source: str = "tests") -> tuple:
    """Check a parsed test file (the TOML layout) and build its tests."""
    if set(data) != {"tests"}:
        extra = sorted(set(data) - {"tests"})
        raise InputError(f"{source}: unknown top-level key {extra[0]!r}; a test file holds "
                         f"[[tests]] tables only" if extra else
                         f"{source}: no [[tests]] table")
    entries = data["tests"]
    if not isinstance(entries, list) or not entries or \
            not all(isinstance(e, Mapping) for e in entries):
        raise InputError(f"{source}: 'tests' must be one or more [[tests]] tables")
    tests, names = [], set()
    for position, entry in enumerate(entries):
        test = parse_test(entry, source, position)
        if test.name in names:
            raise InputError(f"{source}: test name {test.name!r} is used twice")
        names.add(test.name)
        try:
            build_path(machine, test)
        except InputError as exc:
            raise InputError(f"{source}: {exc}") from None
        tests.append(test)
    return tuple(tests)


def parse_test(entry: Mapping, source: str = "tests", position: int = 0):
    """One ``[[tests]]`` table checked and built into its test (not yet against a machine:
    :func:`~reliability.acceptance.iso_tests.build_path` does that); errors name ``source``
    and the test, or its ``position`` when it has no name."""
    name = entry.get("name")
    if not isinstance(name, str) or not name.strip():
        raise InputError(f"{source}: tests[{position}], key 'name': expected a non-empty "
                         f"string; got {name!r}")
    where = f"{source}: test {name!r}"
    kind = entry.get("kind")
    if kind not in KINDS:
        raise InputError(f"{where}, key 'kind': unknown kind {kind!r}; use one of "
                         f"{tuple(KINDS)}")
    required, optional = KEYS[kind]
    allowed = set(COMMON_KEYS) | set(required) | set(optional)
    unknown = sorted(set(entry) - allowed)
    if unknown:
        raise InputError(f"{where}: unknown key {unknown[0]!r} for a {kind} test; allowed: "
                         f"{', '.join(sorted(allowed))}")
    for key in ("limit", *required):
        if key not in entry:
            raise InputError(f"{where}: missing key {key!r}")
    return {"circular": _circular, "positioning": _positioning, "rotary": _rotary}[kind](
        entry, where)


def _circular(entry, where) -> CircularTest:
    plane = entry["plane"]
    if not isinstance(plane, str):
        raise InputError(f"{where}, key 'plane': expected 'xy', 'yz' or 'zx'; got {plane!r}")
    return CircularTest(name=entry["name"], plane=plane,
                        centre=_positions(entry["centre"], where, "centre"),
                        radius=_positive(entry["radius"], where, "radius"),
                        limit=_positive(entry["limit"], where, "limit"))


def _positioning(entry, where) -> PositioningTest:
    targets = entry.get("targets")
    if targets is not None:
        if not isinstance(targets, list):
            raise InputError(f"{where}, key 'targets': expected a list of positions (mm)")
        targets = tuple(_number(v, where, "targets") for v in targets)
    runs = entry.get("runs", PositioningTest.runs)
    if isinstance(runs, bool) or not isinstance(runs, int) or runs < 2:
        raise InputError(f"{where}, key 'runs': expected an integer >= 2 (ISO 230-2: 5); "
                         f"got {runs!r}")
    return PositioningTest(name=entry["name"], axis=_axis(entry, where),
                           line=_positions(entry["line"], where, "line"),
                           limits=_limits(entry["limit"], PositioningTest.quantities, where),
                           targets=targets, runs=runs)


def _rotary(entry, where) -> RotaryTest:
    sweep = entry.get("sweep")
    if sweep is not None:
        if not isinstance(sweep, list) or len(sweep) != 2:
            raise InputError(f"{where}, key 'sweep': expected [start, end] (rad)")
        sweep = tuple(_number(v, where, "sweep") for v in sweep)
    return RotaryTest(name=entry["name"], axis=_axis(entry, where),
                      centre=_positions(entry["centre"], where, "centre"),
                      limits=_limits(entry["limit"], RotaryTest.quantities, where),
                      sweep=sweep)


def _axis(entry, where) -> str:
    axis = entry["axis"]
    if not isinstance(axis, str):
        raise InputError(f"{where}, key 'axis': expected an axis name; got {axis!r}")
    return axis


def _positions(table, where, key) -> dict[str, float]:
    if not isinstance(table, Mapping):
        raise InputError(f"{where}, key {key!r}: expected a table of axis positions, e.g. "
                         f"{{ X = 0.0, Y = 250.0 }}")
    return {str(axis): _number(value, where, f"{key}.{axis}") for axis, value in table.items()}


def _limits(table, quantities, where) -> dict[str, float]:
    if not isinstance(table, Mapping) or not table:
        raise InputError(f"{where}, key 'limit': expected a table of limits on any of "
                         f"{', '.join(quantities)} (mm), e.g. {{ {quantities[0]} = 0.005 }}")
    unknown = [q for q in table if q not in quantities]
    if unknown:
        raise InputError(f"{where}, key 'limit': unknown quantity {unknown[0]!r}; use any of "
                         f"{', '.join(quantities)}")
    return {q: _positive(v, where, f"limit.{q}") for q, v in table.items()}


def _number(value, where, key) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or \
            not math.isfinite(float(value)):
        raise InputError(f"{where}, key {key!r}: expected a finite number; got {value!r}")
    return float(value)


def _positive(value, where, key) -> float:
    value = _number(value, where, key)
    if value <= 0:
        raise InputError(f"{where}, key {key!r}: must be > 0 mm; got {value!r}")
    return value


def table_of_test(test) -> dict:
    """The ``[[tests]]`` table of ``test``: what :func:`parse_test` reads back into an equal
    test."""
    table = {"name": test.name, "kind": test.kind}
    if isinstance(test, CircularTest):
        return {**table, "plane": test.plane, "centre": dict(test.centre),
                "radius": test.radius, "limit": test.limit}
    if isinstance(test, PositioningTest):
        table.update(axis=test.axis, line=dict(test.line), limit=dict(test.limits),
                     runs=test.runs)
        if test.targets is not None:
            table["targets"] = list(test.targets)
        return table
    table.update(axis=test.axis, centre=dict(test.centre), limit=dict(test.limits))
    if test.sweep is not None:
        table["sweep"] = list(test.sweep)
    return table
