"""The machine file's reader (docs/machine-file.md): TOML text or its parsed tables,
validated and built into a :class:`~reliability.model.machine.Machine`.

Every malformed description is refused with a
:class:`~reliability.basics.errors.MachineDescriptionError` naming the source, the table, the
axis and the key. The writer is :meth:`~reliability.model.machine.Machine.to_toml`; reading
what it writes gives an equal machine.
"""

from __future__ import annotations

import math
import tomllib
import unicodedata
from importlib import resources
from pathlib import Path
from types import MappingProxyType
from typing import Mapping

import numpy as np

from ..basics import checks
from ..basics.errors import InputError, MachineDescriptionError
from . import kinematics
from .correlation import parse_correlation
from .drift import KINDS as DRIFT_KINDS, Drift
from .error_draws import DISTRIBUTIONS
from .iso_names import iso_names
from .machine import (COST_ANGLE_UNITS, COST_LENGTH_UNITS, OUTPUTS, POSITIONING_KEYS, Axis,
                      CostCoefficients, Machine, checked_profile, error_names, joint_names,
                      unknown_error_text)
from .work_zone import SHAPES, WorkZone

AXIS_KINDS = ("linear", "rotary")
DIRECTIONS = ("x", "y", "z")
FULL_TURN = (0.0, 2.0 * math.pi)
#: Largest magnitude accepted for a stroke end or an offset (mm: 1 km) and for an axis
#: size (m), and for any other number of a description; larger values overflow the
#: model's squares and the cost model's powers.
LARGEST_LENGTH = 1e6
LARGEST_SIZE = 1e3
LARGEST = 1e12
#: Spellings of the cost units read as their ASCII names: the micro sign (U+00B5) and the
#: Greek small letter mu (U+03BC).
COST_UNIT_SPELLINGS = {"µm": "um", "μm": "um", "µrad": "urad", "μrad": "urad"}


def hobbing_machine() -> Machine:
    """The paper's large CNC gear hobbing machine (CNC-LGHM), Tables 2–5.

    The δz limit is 0.02 mm as in Eq. (35) and Table 8, not the 0.05 mm printed in
    Table 2 (an erratum, docs/model.md).
    """
    text = resources.files("reliability").joinpath("machines/hobbing.toml").read_text()
    return machine_from_toml(text, source="hobbing.toml")


def load_machine(path) -> Machine:
    """Load and validate a machine description from a TOML file (the machine file's one
    reader; :meth:`Machine.to_toml` gives the text to write one).

    Raises
    ------
    MachineDescriptionError
        Naming the file and the offending key, axis or value.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise MachineDescriptionError(f"{path}: not a text file (UTF-8 TOML expected): byte "
                                      f"{exc.start} is {exc.object[exc.start:exc.start + 1]!r}"
                                      ) from None
    return machine_from_toml(text, source=str(path))


def machine_from_toml(text: str, source: str = "machine") -> Machine:
    """Validate machine-file TOML text (what :meth:`Machine.to_toml` returns) and build a
    :class:`Machine`; errors name ``source``."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise MachineDescriptionError(f"{source}: not valid TOML: {exc}") from None
    return machine_from_dict(data, source=source)


def machine_from_dict(data: Mapping, source: str = "machine") -> Machine:
    """Validate a parsed description (the TOML layout) and build a :class:`Machine`."""
    _only_keys(data, {"name", "axes", "requirements", "initial_allocation", "cost",
                      "tool_offset", "correlation", "bounds", "workzone", "drift"}, source)
    axes = _parse_axes(_require(data, "axes", source), source)
    names = tuple(a.name for a in axes)
    requirements = _require(data, "requirements", source)
    limits, targets = _parse_requirements(requirements, source)
    machine = Machine(
        name=str(data.get("name", source)),
        axis_specs=tuple(axes),
        limits=limits,
        targets=targets,
        initial_allocation=_parse_initial(_require(data, "initial_allocation", source),
                                          names, source),
        cost_coefficients=_parse_cost(_require(data, "cost", source), joint_names(names),
                                      {a.kind for a in axes}, source),
        tool_offset=_vector3(data.get("tool_offset", (0, 0, 0)), f"{source}: tool_offset"),
        tolerance_bounds=None if "bounds" not in data else
        _parse_bounds(data["bounds"], names, source),
        frame=_parse_frame(requirements.get("frame", "tool"), f"{source}: requirements.frame"),
        distribution=_parse_distribution(requirements, source),
        profile=_parse_profile(requirements, source),
        work_zone=None if "workzone" not in data else
        _parse_work_zone(data["workzone"], f"{source}: workzone"),
        drift=None if "drift" not in data else _parse_drift(data["drift"], names, source),
    )
    if "correlation" in data:
        machine = parse_correlation(machine, data["correlation"], source)
    return machine


def _require(table: Mapping, key: str, where: str):
    if key not in table:
        raise MachineDescriptionError(f"{where}: missing key {key!r}")
    return table[key]


def _only_keys(table: Mapping, allowed: set[str], where: str, axes=None) -> None:
    """Refuse keys outside ``allowed``; keys that name errors (``axes`` given) are
    refused with the close matches and how errors are named, not with every name."""
    if not isinstance(table, Mapping):
        raise MachineDescriptionError(f"{where}: expected a table, got {type(table).__name__}")
    unknown = sorted(set(table) - allowed)
    if unknown and axes is not None:
        raise MachineDescriptionError(f"{where}: "
                                      f"{unknown_error_text(unknown[0], axes, 'key')}")
    if unknown:
        raise MachineDescriptionError(f"{where}: unknown key {unknown[0]!r}"
                                      f"{checks.close_matches_text(unknown[0], allowed)}; "
                                      f"allowed: {', '.join(sorted(allowed))}")


def _number(value, where: str, positive: bool = False, largest: float = LARGEST) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise MachineDescriptionError(f"{where}: expected a number, got {value!r}")
    if isinstance(value, int) and abs(value) > largest:
        raise MachineDescriptionError(f"{where}: magnitude must be at most {largest:g}, got an "
                                      f"integer of {len(str(abs(value)))} digits")
    value = float(value)
    if not math.isfinite(value):
        raise MachineDescriptionError(f"{where}: must be finite, got {value!r}")
    if abs(value) > largest:
        raise MachineDescriptionError(f"{where}: magnitude must be at most {largest:g}, "
                                      f"got {value!r}")
    if positive and value <= 0:
        raise MachineDescriptionError(f"{where}: must be > 0, got {value!r}")
    return value


def _vector3(value, where: str) -> tuple[float, float, float]:
    if not isinstance(value, (list, tuple)) or len(value) != 3:
        raise MachineDescriptionError(f"{where}: expected three numbers [x, y, z]")
    return tuple(_number(v, where, largest=LARGEST_LENGTH) for v in value)


def _parse_axes(entries, source: str) -> list[Axis]:
    if not isinstance(entries, list) or len(entries) < 1:
        raise MachineDescriptionError(f"{source}: 'axes' must be a non-empty array of tables")
    axes, seen = [], set()
    for position, entry in enumerate(entries):
        axis = _parse_axis(entry, f"{source}: axes[{position}]")
        if axis.name in seen:
            raise MachineDescriptionError(f"{source}: duplicate axis {axis.name!r}")
        seen.add(axis.name)
        axes.append(axis)
    return axes


def _parse_axis(entry, where: str) -> Axis:
    _only_keys(entry, {"name", "kind", "direction", "stroke", "size", "full_turn", "offset",
                       *POSITIONING_KEYS}, where)
    name = _require(entry, "name", where)
    if not isinstance(name, str) or not name or any(c in name for c in ".-") or any(
            c.isspace() or unicodedata.category(c).startswith("C") for c in name):
        raise MachineDescriptionError(f"{where}: axis name must be a non-empty string "
                                      f"without '.', '-', whitespace or control characters, "
                                      f"got {name!r}")
    where = f"{where} (axis {name!r})"
    kind = _require(entry, "kind", where)
    if kind not in AXIS_KINDS:
        raise MachineDescriptionError(f"{where}: unknown kind {kind!r}; use 'linear' or 'rotary'")
    direction = _require(entry, "direction", where)
    if direction not in DIRECTIONS:
        raise MachineDescriptionError(f"{where}: unknown direction {direction!r}; "
                                      f"use 'x', 'y' or 'z'")
    full_turn = entry.get("full_turn", False)
    if not isinstance(full_turn, bool):
        raise MachineDescriptionError(f"{where}: full_turn must be true or false")
    if full_turn and kind != "rotary":
        raise MachineDescriptionError(f"{where}: full_turn applies to rotary axes only")
    stroke = _parse_stroke(entry, full_turn, where, kind)
    try:
        size = _number(_require(entry, "size", where), f"{where}: size", positive=True,
                       largest=LARGEST_SIZE)
    except MachineDescriptionError as error:
        raise MachineDescriptionError(f"{error}; size is the guide length (linear axis) or "
                                      f"rotation diameter (rotary axis) in metres (m), e.g. "
                                      f"2.8 for a 2800 mm guide") from None
    offset = _vector3(entry.get("offset", (0, 0, 0)), f"{where}: offset")
    return Axis(name, kind, direction, stroke, size, full_turn, offset,
                **_positioning_values(entry, kind, where))


def _positioning_values(entry, kind: str, where: str) -> dict[str, float]:
    """``repeatability`` and ``reversal`` (mm, >= 0, linear axes only; default 0)."""
    values = {}
    for key in POSITIONING_KEYS:
        if key not in entry:
            continue
        if kind != "linear":
            raise MachineDescriptionError(f"{where}: {key} applies to linear axes only (it "
                                          f"enters ISO 230-2 positioning tests)")
        value = _number(entry[key], f"{where}: {key}", largest=LARGEST_LENGTH)
        if value < 0:
            raise MachineDescriptionError(f"{where}: {key} must be >= 0 mm, got {value!r}")
        values[key] = value
    return values


def _parse_stroke(entry, full_turn: bool, where: str, kind: str) -> tuple[float, float]:
    if full_turn:
        if "stroke" in entry:
            raise MachineDescriptionError(f"{where}: give either full_turn or a stroke, not both")
        return FULL_TURN
    stroke = _require(entry, "stroke", where)
    if not isinstance(stroke, list) or len(stroke) != 2:
        raise MachineDescriptionError(f"{where}: stroke must be [min, max]")
    low, high = (_number(v, f"{where}: stroke", largest=LARGEST_LENGTH) for v in stroke)
    if low >= high:
        raise MachineDescriptionError(f"{where}: stroke min {low} must be < max {high}")
    if kind == "rotary" and high - low > FULL_TURN[1] * (1 + 1e-12):
        raise MachineDescriptionError(
            f"{where}: a limited rotary stroke spans at most one turn (2π rad); "
            f"[{low}, {high}] spans {(high - low) / FULL_TURN[1]:.3g} turns. Strokes are in "
            f"radians (degrees given?); use full_turn = true for a whole revolution")
    return (low, high)


def _parse_requirements(table, source: str) -> tuple[np.ndarray, np.ndarray]:
    where = f"{source}: requirements"
    _only_keys(table, set(OUTPUTS) | {"frame", "distribution", "profile"}, where)
    limits, targets = [], []
    for output in OUTPUTS:
        entry = _require(table, output, where)
        at = f"{where}.{output}"
        _only_keys(entry, {"limit", "target"}, at)
        limits.append(_number(_require(entry, "limit", at), f"{at}.limit", positive=True))
        target = _number(_require(entry, "target", at), f"{at}.target")
        if not 0.0 < target < 1.0:
            raise MachineDescriptionError(f"{at}.target: must lie in (0, 1), got {target}")
        targets.append(target)
    return np.array(limits), np.array(targets)


def _parse_frame(value, where: str) -> str:
    """``[requirements] frame = "tool" | "workpiece"``: where the outputs are read."""
    if value not in kinematics.FRAMES:
        raise MachineDescriptionError(f"{where}: expected \"tool\" (Eq. 18, turns with the "
                                      f"rotary axes) or \"workpiece\"; got {value!r}")
    return value


def _parse_distribution(table, source: str) -> str:
    """``[requirements] distribution``: how every computation of the study reads a
    tolerance (``"normal"`` by default)."""
    value = table.get("distribution", "normal")
    if value not in DISTRIBUTIONS:
        raise MachineDescriptionError(f"{source}: requirements.distribution: expected "
                                      f"'normal' or 'truncated'; got {value!r}")
    return value



def _parse_profile(table, source: str) -> str:
    """``[requirements] profile``: how a built machine's errors hang together along travel
    (``"constant"`` by default; ``"independent"`` is the paper's grid experiment)."""
    try:
        return checked_profile(table.get("profile", "constant"))
    except InputError as error:
        raise MachineDescriptionError(f"{source}: requirements.profile: {error}") from None


COST_KEYS = {"linear": "ab", "rotary": "cd"}  # coefficients each kind of axis needs


def _parse_cost(table, joints: tuple[str, ...], kinds: set[str],
                source: str) -> CostCoefficients:
    """Cost coefficients; those of a kind of axis the machine lacks may be omitted."""
    where = f"{source}: cost"
    _only_keys(table, {"a", "b", "c", "d", "assembly", "units"}, where)
    needed = "".join(COST_KEYS[kind] for kind in sorted(kinds))
    coefficients = {k: _number(_require(table, k, where), f"{where}.{k}", positive=True)
                    if k in needed or k in table else None for k in "abcd"}
    assembly = _require(table, "assembly", where) if joints else table.get("assembly", {})
    _only_keys(assembly, set(joints), f"{where}.assembly")
    m = {j: _number(_require(assembly, j, f"{where}.assembly"), f"{where}.assembly.{j}",
                    positive=True) for j in joints}
    return CostCoefficients(**coefficients, assembly=MappingProxyType(m),
                            units=_parse_cost_units(table.get("units"), f"{where}.units"))


def _parse_cost_units(table, where: str) -> tuple[str, str] | None:
    """``units = { length = "mm" | "um", angle = "rad" | "urad" | "arcsec" }``; "µm" and
    "µrad" (micro sign or Greek mu) are read as "um" and "urad"."""
    if table is None:
        return None
    if not isinstance(table, Mapping):
        raise MachineDescriptionError(f"{where}: expected a table like "
                                      f'{{ length = "mm", angle = "rad" }}; got {table!r}')
    _only_keys(table, {"length", "angle"}, where)
    length, angle = (_require(table, key, where) for key in ("length", "angle"))
    length, angle = (COST_UNIT_SPELLINGS.get(value, value) if isinstance(value, str) else
                     value for value in (length, angle))
    for key, value, allowed in (("length", length, COST_LENGTH_UNITS),
                                ("angle", angle, COST_ANGLE_UNITS)):
        if value not in allowed:
            raise MachineDescriptionError(f"{where}.{key}: {value!r} is not one of "
                                          f"{', '.join(map(repr, allowed))}")
    return length, angle


def _parse_initial(table, axes: tuple[str, ...], source: str) -> np.ndarray:
    """``[initial_allocation]``: one tolerance per error, ``(n_errors,)``."""
    def tolerance(value, where):
        return _number(value, where, positive=True)

    return _per_error(table, axes, f"{source}: initial_allocation", tolerance)


def _parse_bounds(table, axes: tuple[str, ...], source: str) -> np.ndarray:
    """``[bounds]``: ``translation = [lo, hi]`` (mm), ``rotation = [lo, hi]`` (rad) and
    ``items = { "X.dx" = [lo, hi] }``, the achievable tolerances; ``(2, n_errors)``."""
    return _per_error(table, axes, f"{source}: bounds", _pair).T


def _parse_drift(table, axes: tuple[str, ...], source: str) -> Drift:
    """``[drift]``: ``kind`` (``"linear"``, the default, or ``"wear"``) and per-error values
    like ``[initial_allocation]``'s, in mm or rad per year: the standard deviation of the
    rate (linear) or the pair ``[mean, sd]`` of one year's wear (:mod:`.drift`)."""
    where = f"{source}: drift"
    _only_keys(table, {"kind", "translation", "rotation", "items"}, where)
    kind = table.get("kind", "linear")
    if kind not in DRIFT_KINDS:
        raise MachineDescriptionError(f"{where}.kind: expected one of "
                                      f"{', '.join(map(repr, DRIFT_KINDS))}; got {kind!r}")
    values = {key: value for key, value in table.items() if key != "kind"}
    if kind == "linear":
        return Drift(kind, _per_error(values, axes, where, _drift_rate))
    pairs = _per_error(values, axes, where, _wear_pair)
    return Drift(kind, pairs[:, 0], pairs[:, 1])


def _drift_rate(value, where: str) -> float:
    """A standard deviation of a drift rate ≥ 0 (mm or rad per year)."""
    rate = _number(value, where)
    if rate < 0:
        raise MachineDescriptionError(f"{where}: a drift rate's standard deviation must be "
                                      f"≥ 0 (mm or rad per year); got {value!r}")
    return rate


def _wear_pair(value, where: str) -> tuple[float, float]:
    """``[mean, sd]`` of one year's wear, both ≥ 0 (mm or rad per year)."""
    if isinstance(value, (str, bytes)) or not hasattr(value, "__len__") or len(value) != 2:
        raise MachineDescriptionError(f"{where}: expected [mean, sd] of one year's wear (mm "
                                      f"or rad per year, kind \"wear\"); got {value!r}")
    return tuple(_drift_rate(v, where) for v in value)


def _per_error(table, axes: tuple[str, ...], where: str, read) -> np.ndarray:
    """A table of ``translation`` and ``rotation`` defaults and per-error ``items``
    (by paper name or ISO symbol), each value read by ``read(value, where)``; one row per
    error."""
    _only_keys(table, {"translation", "rotation", "items"}, where)
    translation = read(_require(table, "translation", where), f"{where}.translation")
    rotation = read(_require(table, "rotation", where), f"{where}.rotation")
    names = error_names(axes)
    angular = [n.split(".")[1].startswith("e") for n in names]
    values = np.array([rotation if a else translation for a in angular], dtype=float)
    items = table.get("items", {})
    index = {n: i for i, n in enumerate(names)}
    index.update({n: i for i, n in enumerate(iso_names(names))})
    _only_keys(items, set(index), f"{where}.items", axes)
    given = {}
    for name, value in items.items():
        if index[name] in given:
            raise MachineDescriptionError(f"{where}.items: {given[index[name]]!r} and "
                                          f"{name!r} name the same error")
        given[index[name]] = name
        values[index[name]] = read(value, f"{where}.items.{name}")
    return values


ZONE_KEYS = {"box": {"shape", "min", "max", "tilt"},
             "cylinder": {"shape", "centre", "radius", "z", "tilt"}}


def _parse_work_zone(table, where: str) -> WorkZone:
    """``[workzone]``: ``shape = "box"`` with ``min``, ``max`` (mm), or ``shape =
    "cylinder"`` with ``centre``, ``radius``, ``z`` (mm); optional ``tilt = [lo, hi]``
    (degrees)."""
    _only_keys(table, set().union(*ZONE_KEYS.values()), where)
    shape = _require(table, "shape", where)
    if shape not in SHAPES:
        raise MachineDescriptionError(f"{where}.shape: expected \"box\" or \"cylinder\"; "
                                      f"got {shape!r}")
    _only_keys(table, ZONE_KEYS[shape], f"{where} (shape {shape!r})")
    if shape == "box":
        values = {"low": _vector3(_require(table, "min", where), f"{where}.min"),
                  "high": _vector3(_require(table, "max", where), f"{where}.max")}
    else:
        values = {"centre": _lengths(_require(table, "centre", where), 2, f"{where}.centre"),
                  "radius": _number(_require(table, "radius", where), f"{where}.radius",
                                    positive=True, largest=LARGEST_LENGTH),
                  "z": _lengths(_require(table, "z", where), 2, f"{where}.z")}
    if "tilt" in table:
        values["tilt"] = _lengths(table["tilt"], 2, f"{where}.tilt")
    try:
        return WorkZone(shape, **values)
    except InputError as error:
        raise MachineDescriptionError(f"{where}: {error}") from None


def _lengths(value, count: int, where: str) -> tuple[float, ...]:
    """``count`` finite numbers, or a MachineDescriptionError naming ``where``."""
    if not isinstance(value, (list, tuple)) or len(value) != count:
        raise MachineDescriptionError(f"{where}: expected {count} numbers; got {value!r}")
    return tuple(_number(v, where, largest=LARGEST_LENGTH) for v in value)


def _pair(value, where: str) -> tuple[float, float]:
    """``[lo, hi]`` with 0 < lo <= hi, or a MachineDescriptionError naming ``where``."""
    if isinstance(value, (str, bytes)) or not hasattr(value, "__len__") or len(value) != 2:
        raise MachineDescriptionError(f"{where}: expected [lo, hi] (two tolerances, mm or "
                                      f"rad); got {value!r}")
    low, high = (_number(v, where, positive=True) for v in value)
    if low > high:
        raise MachineDescriptionError(f"{where}: lo = {low:g} exceeds hi = {high:g}")
    return low, high
