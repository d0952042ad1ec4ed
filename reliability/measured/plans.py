"""Measurement plans: a test file (docs/acceptance.md) whose tests carry ``u`` (mm) and
``u_angle`` (rad), plus ``kind = "line"`` runs; each test is one run (docs/measurements.md).

A circular test reads ``radial`` about its centre, a positioning test the quantity along
its axis, a rotary test ``dx dy dz``; a line run reads its ``quantities`` at its ``targets``
(ISO 230-2 spacing by default) along ``axis`` with the other axes at ``line``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from ..acceptance.definitions import parse_tests
from ..acceptance.iso_tests import PositioningTest, build_path, tool_point
from ..basics.errors import InputError
from ..basics.files import read_toml
from .measurement_files import Measurements

#: Quantities read in mm (``u``) and in rad (``u_angle``).
TRANSLATIONS = ("dx", "dy", "dz")
ANGLES = ("ex", "ey", "ez")
#: Keys a plan adds to every test, and the keys of a line run.
UNCERTAINTY_KEYS = ("u", "u_angle")
#: What a run costs, read by the planning of measurements (reliability.measured.planning).
PLAN_KEYS = (*UNCERTAINTY_KEYS, "cost")
LINE_KEYS = ("name", "kind", "axis", "line", "targets", "quantities", *PLAN_KEYS)


@dataclass(frozen=True, eq=False)
class PlannedRun:
    """One run of a plan: where it reads, what, and how well.

    Attributes
    ----------
    name : str
    poses : ndarray (P, n_axes)
    quantities : tuple of str
        Read at every pose.
    u : ndarray (len(quantities),)
        Standard uncertainty of each quantity (mm or rad).
    centre : ndarray (3,) or None
        The ballbar's centre (mm, workpiece frame) of a ``radial`` run.
    """

    name: str
    poses: np.ndarray
    quantities: tuple[str, ...]
    u: np.ndarray
    centre: np.ndarray | None = None


def read_plan(path, machine) -> tuple[PlannedRun, ...]:
    """Read and check a plan file against ``machine``."""
    data = read_toml(path)
    return parse_plan(data, machine, source=str(path))


def parse_plan(data: Mapping, machine, source: str = "plan") -> tuple[PlannedRun, ...]:
    """Check a parsed plan and build its runs, in file order."""
    entries = data.get("tests") if isinstance(data, Mapping) else None
    if not isinstance(entries, list) or not entries or \
            not all(isinstance(e, Mapping) for e in entries):
        raise InputError(f"{source}: expected one or more [[tests]] tables")
    tests = [{k: v for k, v in e.items() if k not in PLAN_KEYS} for e in entries
             if e.get("kind") != "line"]
    built = iter(parse_tests({"tests": tests}, machine, source) if tests else ())
    runs = []
    for entry in entries:
        where = f"{source}: test {entry.get('name')!r}"
        run = _line_run(entry, machine, where) if entry.get("kind") == "line" else \
            _test_run(next(built), entry, machine, where)
        runs.append(run)
    names = [run.name for run in runs]
    twice = [name for name in names if names.count(name) > 1]
    if twice:
        raise InputError(f"{source}: run name {twice[0]!r} is used twice")
    return tuple(runs)


def _test_run(test, entry, machine, where) -> PlannedRun:
    path = build_path(machine, test)
    if test.kind == "circular":
        return PlannedRun(test.name, path.poses, ("radial",),
                          np.array([_uncertainty(entry, "u", where)]),
                          tool_point(machine, path.poses).mean(axis=0))
    if test.kind == "positioning":
        along = int(np.argmax(np.abs(path.directions[0])))
        return PlannedRun(test.name, path.poses, (TRANSLATIONS[along],),
                          np.array([_uncertainty(entry, "u", where)]))
    return PlannedRun(test.name, path.poses, TRANSLATIONS,
                      np.full(3, _uncertainty(entry, "u", where)))


def _line_run(entry, machine, where) -> PlannedRun:
    unknown = sorted(set(entry) - set(LINE_KEYS))
    if unknown:
        raise InputError(f"{where}: unknown key {unknown[0]!r} for a line run; allowed: "
                         f"{', '.join(LINE_KEYS)}")
    for key in ("axis", "line", "quantities"):
        if key not in entry:
            raise InputError(f"{where}: missing key {key!r}")
    quantities = entry["quantities"]
    if not isinstance(quantities, list) or not quantities or \
            any(q not in TRANSLATIONS + ANGLES for q in quantities) or \
            len(set(quantities)) != len(quantities):
        raise InputError(f"{where}, key 'quantities': expected distinct names among "
                         f"{', '.join(TRANSLATIONS + ANGLES)}; got {quantities!r}")
    targets = entry.get("targets")
    along = PositioningTest(name=entry["name"], axis=entry["axis"], line=entry["line"],
                            limits={"E": 1.0},
                            targets=None if targets is None else tuple(targets))
    try:
        path = build_path(machine, along)
    except InputError as exc:
        raise InputError(f"{where}: {str(exc).split(': ', 1)[-1]}") from None
    u = np.array([_uncertainty(entry, "u_angle" if q in ANGLES else "u", where)
                  for q in quantities])
    return PlannedRun(entry["name"], path.poses, tuple(quantities), u)


def _uncertainty(entry, key, where) -> float:
    value = entry.get(key)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or \
            not math.isfinite(value) or value <= 0:
        unit = "rad" if key == "u_angle" else "mm"
        raise InputError(f"{where}, key {key!r}: expected the standard uncertainty of a "
                         f"reading, a number > 0 {unit}; got {value!r}")
    return float(value)


def planned_readings(plan) -> Measurements:
    """Every reading of the plan's runs, value 0: its run, pose, quantity, nominal ballbar
    centre (NaN off ``radial`` readings) and ``u``; where, what and how well each is read."""
    parts = {"run": [], "poses": [], "quantity": [], "centre": [], "u": []}
    for run in plan:
        count = len(run.poses) * len(run.quantities)
        parts["run"].append(np.full(count, run.name, dtype=object))
        parts["poses"].append(np.repeat(run.poses, len(run.quantities), axis=0))
        parts["quantity"].append(np.tile(np.array(run.quantities, dtype=object),
                                         len(run.poses)))
        centre = np.full(3, np.nan) if run.centre is None else run.centre
        parts["centre"].append(np.repeat(centre[None, :], count, axis=0))
        parts["u"].append(np.tile(run.u, len(run.poses)))
    joined = {key: np.concatenate(values) for key, values in parts.items()}
    return Measurements(value=np.zeros(len(joined["u"])), **joined)
