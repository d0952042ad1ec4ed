"""Measurement plans: a test file (docs/acceptance.md) whose tests carry ``u`` (mm) and
``u_angle`` (rad), plus ``kind = "line"`` runs; each test is one run (docs/measurements.md).

A circular test reads ``radial`` about its centre (once, unlabelled, or in each direction of
travel its ``directions`` key lists, ``["+", "-"]``), a positioning test the quantity along
its axis at every target in each of its ``runs`` cycles (ISO 230-2's 5 by default) in both
directions of approach, a rotary test ``dx dy dz``; a line run reads its ``quantities`` at
its ``targets`` (ISO 230-2 spacing by default) along ``axis`` with the other axes at
``line``. Readings of positioning runs and of circles with ``directions`` carry their cycle
and direction (the acceptance runs of ``precrel evaluate``).
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
PLAN_KEYS = (*UNCERTAINTY_KEYS, "cost", "directions")
#: Directions of approach (positioning) or travel (circular): ``+`` along the axis, ``-``.
DIRECTIONS = ("+", "-")
LINE_KEYS = ("name", "kind", "axis", "line", "targets", "quantities", *UNCERTAINTY_KEYS,
             "cost")


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
    cycles : int
        Cycles of an acceptance run (a positioning test's ``runs``, 1 for a circle read in
        labelled directions); 0: a run read once, without cycle and direction.
    directions : tuple of str
        Of an acceptance run: ``+`` and/or ``-`` (:data:`DIRECTIONS`), read in each cycle.
    approach : tuple of float or None
        Of a positioning run: its axis' ``(repeatability σ, reversal B)`` (mm) and the sign
        of its travel along the quantity read, drawn into each approach by
        :func:`reliability.measured.simulated_measurements.simulate_measurements`.
    """

    name: str
    poses: np.ndarray
    quantities: tuple[str, ...]
    u: np.ndarray
    centre: np.ndarray | None = None
    cycles: int = 0
    directions: tuple[str, ...] = ()
    approach: tuple[float, float, float] | None = None


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
    if "directions" in entry and test.kind != "circular":
        raise InputError(f"{where}: key 'directions' belongs to circular tests (a "
                         f"positioning test reads both directions in each of its runs)")
    if test.kind == "circular":
        directions = _directions(entry, where)
        return PlannedRun(test.name, path.poses, ("radial",),
                          np.array([_uncertainty(entry, "u", where)]),
                          tool_point(machine, path.poses).mean(axis=0),
                          cycles=1 if directions else 0, directions=directions)
    if test.kind == "positioning":
        along = int(np.argmax(np.abs(path.directions[0])))
        axis = machine.axis_specs[machine.axes.index(test.axis)]
        return PlannedRun(test.name, path.poses, (TRANSLATIONS[along],),
                          np.array([_uncertainty(entry, "u", where)]), cycles=test.runs,
                          directions=DIRECTIONS,
                          approach=(axis.repeatability, axis.reversal,
                                    float(np.sign(path.directions[0][along]))))
    return PlannedRun(test.name, path.poses, TRANSLATIONS,
                      np.full(3, _uncertainty(entry, "u", where)))


def _directions(entry, where) -> tuple[str, ...]:
    """A circle's ``directions``: distinct ``+``/``-``, or none (one unlabelled turn)."""
    value = entry.get("directions", [])
    if not isinstance(value, list) or any(d not in DIRECTIONS for d in value) or \
            len(set(value)) != len(value):
        raise InputError(f"{where}, key 'directions': expected a list of distinct "
                         f"directions of travel among {DIRECTIONS}; got {value!r}")
    return tuple(value)


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
    centre (NaN off ``radial`` readings) and ``u``; where, what and how well each is read.

    An acceptance run is read in every cycle and direction, cycle by cycle, each direction
    in its order of travel (``-`` from the last pose back); then the readings carry their
    ``cycle`` and ``direction`` (0 and blank on other runs)."""
    parts = {"run": [], "poses": [], "quantity": [], "centre": [], "u": [], "cycle": [],
             "direction": []}
    for run in plan:
        poses, cycle, direction = _order_of_reading(run)
        count = len(poses) * len(run.quantities)
        parts["run"].append(np.full(count, run.name, dtype=object))
        parts["poses"].append(np.repeat(poses, len(run.quantities), axis=0))
        parts["quantity"].append(np.tile(np.array(run.quantities, dtype=object), len(poses)))
        centre = np.full(3, np.nan) if run.centre is None else run.centre
        parts["centre"].append(np.repeat(centre[None, :], count, axis=0))
        parts["u"].append(np.tile(run.u, len(poses)))
        parts["cycle"].append(np.repeat(cycle, len(run.quantities)))
        parts["direction"].append(np.repeat(direction, len(run.quantities)))
    joined = {key: np.concatenate(values) for key, values in parts.items()}
    if not any(run.directions for run in plan):
        joined["cycle"] = joined["direction"] = None
    return Measurements(value=np.zeros(len(joined["u"])), **joined)


def _order_of_reading(run):
    """The run's poses in the order read, with each one's cycle and direction."""
    if not run.directions:
        return run.poses, np.zeros(len(run.poses), dtype=int), \
            np.full(len(run.poses), "", dtype=object)
    sweeps = [run.poses if d == "+" else run.poses[::-1] for d in run.directions]
    one_cycle = np.concatenate(sweeps)
    count = len(one_cycle)
    direction = np.concatenate([np.full(len(run.poses), d, dtype=object)
                                for d in run.directions])
    return np.tile(one_cycle, (run.cycles, 1)), np.repeat(np.arange(1, run.cycles + 1), count), \
        np.tile(direction, run.cycles)
