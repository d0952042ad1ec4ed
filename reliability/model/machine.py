"""A serial machine described as data (docs/machine-file.md), loaded and validated from
TOML.

A machine is an ordered chain of axes from the workpiece to the tool. Each axis is linear
or rotary about/along x, y or z, with a stroke and a size (guide length or rotation
diameter, used by the cost model of Eqs. 25–26). Between consecutive axes sits a joint
carrying six assembly errors (Eq. 14). The description also holds the design limits and
reliability targets of the six comprehensive errors (Table 2), the initial (reference)
tolerance allocation (Table 4 for the paper's machine) and the cost coefficients (Table 5).

The error vector has ``6 * n_axes`` motion errors (axis by axis in chain order) followed by
``6 * (n_axes - 1)`` assembly errors (joint by joint), each in the component order
``dx dy dz ex ey ez``; lengths in mm, angles in rad.
"""

from __future__ import annotations

import math
import tomllib
import unicodedata
from dataclasses import dataclass, field, fields
from importlib import resources
from pathlib import Path
from types import MappingProxyType
from typing import Mapping

import numpy as np
import pandas as pd

from ..basics import checks
from ..basics.display import number_text
from ..basics.errors import InputError, InputTypeError, MachineDescriptionError
from . import kinematics
from .correlation import (check_correlation_matrix, correlation_to_toml, parse_correlation,
                          with_correlation)
from .error_draws import DISTRIBUTIONS
from .iso_names import iso_names
from .profiles import profile_model
from .work_zone import SHAPES, WorkZone

COMPONENTS = ("dx", "dy", "dz", "ex", "ey", "ez")
OUTPUTS = COMPONENTS
AXIS_KINDS = ("linear", "rotary")
DIRECTIONS = ("x", "y", "z")
FULL_TURN = (0.0, 2.0 * math.pi)
#: Optional keys of a linear axis read by ISO 230-2 positioning tests only (mm).
POSITIONING_KEYS = ("repeatability", "reversal")
#: Largest magnitude accepted for a stroke end or an offset (mm: 1 km) and for an axis
#: size (m), and for any other number of a description; larger values overflow the
#: model's squares and the cost model's powers.
LARGEST_LENGTH = 1e6
LARGEST_SIZE = 1e3
LARGEST = 1e12


@dataclass(frozen=True)
class Axis:
    """One axis of the chain.

    Attributes
    ----------
    name : str
        Unique label, e.g. ``"X"``.
    kind : {'linear', 'rotary'}
    direction : {'x', 'y', 'z'}
        Direction of travel (linear) or of the rotation axis (rotary).
    stroke : tuple of float
        ``(min, max)`` in mm (linear) or rad (rotary).
    size : float
        Guide length L (linear) or rotation diameter D (rotary), in m (Table 3).
    full_turn : bool
        A rotary axis that turns a whole revolution; its stroke is ``[0, 2π)`` and grids
        do not repeat 0 = 2π.
    offset : tuple of float
        Fixed translation (mm) from the previous axis' frame to this axis' frame, applied
        before the axis' motion. Zero in the paper, whose frames all share one origin.
    repeatability : float
        σ (mm) of one approach to a position of a linear axis, beyond its geometric errors
        (ISO 230-2 separates it from them); enters positioning tests only
        (:mod:`reliability.acceptance.prediction`). Default 0.
    reversal : float
        Reversal value (mm) of a linear axis, the difference between approaching a position
        from below and from above (ISO 230-2's B); enters positioning tests only. Default 0.
    """

    name: str
    kind: str
    direction: str
    stroke: tuple[float, float]
    size: float
    full_turn: bool = False
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    repeatability: float = 0.0
    reversal: float = 0.0


#: Units a tolerance may be expressed in inside the cost (``[cost] units``): how many of
#: each unit one mm (length) or one rad (angle) is.
COST_LENGTH_UNITS = {"mm": 1.0, "um": 1e3}
COST_ANGLE_UNITS = {"rad": 1.0, "urad": 1e6, "arcsec": 180.0 * 3600.0 / np.pi}
#: Spellings of the cost units read as their ASCII names: the micro sign (U+00B5) and the
#: Greek small letter mu (U+03BC).
COST_UNIT_SPELLINGS = {"µm": "um", "μm": "um", "µrad": "urad", "μrad": "urad"}


@dataclass(frozen=True)
class CostCoefficients:
    """Fuzzy cost coefficients of Eqs. (25)–(27) (Table 5).

    ``a``: linear positioning along the axis; ``b``: other linear-axis items, per m of
    guide; ``c``: rotation about the axis; ``d``: other rotary-axis items, per m of
    diameter; ``assembly``: ``m_ij`` per joint name. ``a`` and ``b`` are None on a machine
    without linear axes, ``c`` and ``d`` on one without rotary axes.

    ``units``: ``(length, angle)``, the units the tolerance t is expressed in inside the
    cost ``w / t²`` (``[cost] units`` in the machine file; :data:`COST_LENGTH_UNITS`,
    :data:`COST_ANGLE_UNITS`). They change the cost only; limits, tolerances and bounds
    stay in mm and rad. None when the file does not say (read as mm and rad).
    """

    a: float | None
    b: float | None
    c: float | None
    d: float | None
    assembly: Mapping[str, float]
    units: tuple[str, str] | None = None

    def __post_init__(self):
        object.__setattr__(self, "assembly", MappingProxyType(dict(self.assembly)))

    def __reduce__(self):
        return (CostCoefficients, (self.a, self.b, self.c, self.d, dict(self.assembly),
                                   self.units))

    @property
    def unit_scales(self) -> tuple[float, float]:
        """How many cost units one mm and one rad are (1, 1 without stated units)."""
        length, angle = self.units or ("mm", "rad")
        return COST_LENGTH_UNITS[length], COST_ANGLE_UNITS[angle]


@dataclass(frozen=True)
class Machine:
    """A serial machine: axes, requirements, initial allocation and cost coefficients.

    Build one with :func:`load_machine`, :func:`machine_from_dict` or
    :func:`hobbing_machine`. The kinematic model is :meth:`comprehensive_error` (exact,
    Eq. 18) and :meth:`jacobian` (analytic first-order sensitivities).
    """

    name: str
    axis_specs: tuple[Axis, ...]
    limits: np.ndarray
    targets: np.ndarray
    initial_allocation: np.ndarray
    cost_coefficients: CostCoefficients
    tool_offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    correlation: np.ndarray | None = field(default=None, repr=False)
    tolerance_bounds: np.ndarray | None = field(default=None, repr=False)
    frame: str = "tool"
    distribution: str = "normal"
    profile: str = "constant"
    work_zone: WorkZone | None = None
    _index: Mapping[str, int] = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        for name in ("limits", "targets", "initial_allocation"):
            value = np.array(getattr(self, name), dtype=float)
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        index = {n: i for i, n in enumerate(self.error_names)}
        index.update({n: i for i, n in enumerate(self.iso_names)})
        object.__setattr__(self, "_index", MappingProxyType(index))
        if self.correlation is not None:
            object.__setattr__(self, "correlation",
                               check_correlation_matrix(self.correlation, self.error_names))
        kinematics.check_frame(self.frame)
        if self.distribution not in DISTRIBUTIONS:
            raise InputError(f"distribution must be 'normal' or 'truncated'; got "
                             f"{self.distribution!r}")
        object.__setattr__(self, "profile", _checked_profile(self.profile))
        if self.tolerance_bounds is not None:
            object.__setattr__(self, "tolerance_bounds",
                               _checked_bounds(self.tolerance_bounds, self.error_names))
        if self.work_zone is not None and not isinstance(self.work_zone, WorkZone):
            raise InputTypeError(f"work_zone must be a WorkZone or None; got "
                                 f"{type(self.work_zone).__name__}")

    def __reduce__(self):
        """Pickle and copy through the constructor (the name index is rebuilt)."""
        state = {f.name: getattr(self, f.name) for f in fields(self) if f.init}
        return (_rebuild, (type(self), state))

    def __eq__(self, other) -> bool:
        """Equal when every described field is equal (arrays element by element)."""
        if type(other) is not type(self):
            return NotImplemented
        return all(_same(getattr(self, f.name), getattr(other, f.name))
                   for f in fields(self) if f.compare)

    def to_toml(self) -> str:
        """The description as machine-file TOML text (the machine file's one writer);
        :func:`machine_from_toml` of it gives an equal machine."""
        import tomli_w

        return tomli_w.dumps(machine_to_dict(self))

    # ----- names -------------------------------------------------------------------
    @property
    def axes(self) -> tuple[str, ...]:
        """Axis names in chain order, workpiece to tool."""
        return tuple(a.name for a in self.axis_specs)

    @property
    def joints(self) -> tuple[str, ...]:
        """Joint names ``"<axis>-<axis>"`` between consecutive axes."""
        return joint_names(self.axes)

    @property
    def outputs(self) -> tuple[str, ...]:
        """The six comprehensive errors, ``dx dy dz ex ey ez``."""
        return OUTPUTS

    @property
    def error_names(self) -> tuple[str, ...]:
        """All error names: motion errors axis by axis, then assembly errors (docs/model.md)."""
        return error_names(self.axes)

    @property
    def iso_names(self) -> tuple[str, ...]:
        """ISO 230-1 symbols aligned with :attr:`error_names`
        (:mod:`reliability.model.iso_names`)."""
        return iso_names(self.error_names)

    @property
    def n_errors(self) -> int:
        """Number of geometric errors, ``12 n_axes − 6`` (66 for six axes)."""
        return 6 * (2 * len(self.axis_specs) - 1)

    def error_index(self, name: str) -> int:
        """Position of an error by paper name or ISO 230-1 symbol; unknown names raise
        KeyError."""
        try:
            return self._index[name]
        except KeyError:
            raise KeyError(unknown_error_text(name, self.axes)) from None

    def error_vector(self, values, default: float | None = 0.0) -> np.ndarray:
        """Build an error (or tolerance) vector from ``{name: value}`` or a pandas Series.

        Parameters
        ----------
        values : Mapping[str, float] or pandas.Series
            Values by error name (paper name or ISO 230-1 symbol); unknown names and one
            error named twice are refused.
        default : float or None
            Value of the errors not named. ``None`` requires every error to be named.

        Returns
        -------
        numpy.ndarray
            ``(n_errors,)`` in the order of :attr:`error_names`.
        """
        if not isinstance(values, (Mapping, pd.Series)):
            raise InputTypeError(f"values must be a mapping or pandas Series by error name; "
                                 f"got a {type(values).__name__} (use the array directly "
                                 f"if it is already in the order of error_names)")
        items = dict(values.items())
        named = {}
        for name in items:
            index = self.error_index(name)
            if index in named:
                raise KeyError(f"{named[index]!r} and {name!r} name the same error")
            named[index] = name
        missing = [n for i, n in enumerate(self.error_names) if i not in named]
        if default is None and missing:
            raise KeyError(f"values missing for {len(missing)} errors, first {missing[0]!r}")
        out = np.full(self.n_errors, np.nan if default is None else float(default))
        for index, name in named.items():
            out[index] = checks.finite_float(items[name], f"values[{name!r}]")
        return out

    def with_correlation(self, pairs) -> "Machine":
        """This machine with correlated errors; see
        :func:`reliability.model.correlation.with_correlation`."""
        return with_correlation(self, pairs)

    # ----- model -------------------------------------------------------------------
    def comprehensive_error(self, q, x, frame: str | None = None) -> np.ndarray:
        """Exact tool–workpiece pose error, Eqs. (16)–(18), in ``frame`` (default
        :attr:`frame`: ``"tool"``, Eq. 18, or ``"workpiece"``); see
        :mod:`reliability.model.kinematics`.

        A low-level evaluation of the chain: ``q`` may lie outside the strokes (the kinematics
        extend smoothly, e.g. X = 10 000 mm on a 0–400 mm stroke), which is what a caller
        extrapolating on purpose needs. The studies (:func:`reliability.first_order.fosm.fosm`, the
        samplers, the allocation) refuse poses outside the strokes unless told
        ``allow_outside_stroke=True``; check a pose with
        :func:`reliability.basics.checks.poses_in_strokes` before calling this directly.
        """
        return kinematics.comprehensive_error(self, q, x, frame or self.frame)

    def jacobian(self, q, frame: str | None = None) -> np.ndarray:
        """First-order sensitivities ``(..., 6, n_errors)`` in ``frame`` (default
        :attr:`frame`); see :mod:`reliability.model.kinematics`."""
        return kinematics.jacobian(self, q, frame or self.frame)

    def check_positions(self, q) -> np.ndarray:
        """Return ``q`` as a float array of shape ``(..., n_axes)`` or raise InputError.

        A DataFrame is aligned to :attr:`axes` by its column names."""
        if isinstance(q, pd.DataFrame):
            q = checks.labelled(q, self.axes, "positions")
        q = _with_last_axis(q, len(self.axis_specs), "positions", f" for axes {self.axes}")
        return checks.finite_values(q, "positions", self.axes)

    def check_errors(self, x) -> np.ndarray:
        """Return ``x`` as a float array of shape ``(..., n_errors)`` or raise InputError.

        A Series or mapping is aligned to :attr:`error_names` by name (every name once)."""
        x = _with_last_axis(checks.labelled(x, self.error_names, "errors"), self.n_errors,
                            "errors")
        return checks.finite_values(x, "errors", self.error_names)

    def check_tolerances(self, tolerances) -> np.ndarray:
        """Return tolerances ``(..., n_errors)``, all finite and > 0, or raise InputError.

        A Series or mapping is aligned to :attr:`error_names` by name (every name once);
        strings and other non-numbers raise :class:`~reliability.basics.errors.InputTypeError`."""
        t = _with_last_axis(checks.labelled(tolerances, self.error_names, "tolerances"),
                            self.n_errors, "tolerances")
        bad = ~(np.isfinite(t) & (t > 0))
        if np.any(bad):
            first = int(np.argwhere(bad)[0][-1])
            raise InputError(f"tolerance of {self.error_names[first]!r} must be finite and "
                             f"> 0; got {number_text(t[np.nonzero(bad)][0])}")
        return t


def _rebuild(cls, state):
    return cls(**state)


def _same(a, b) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return np.shape(a) == np.shape(b) and bool(np.array_equal(a, b))
    return a == b


def _with_last_axis(values, size: int, what: str, detail: str = "") -> np.ndarray:
    """``values`` as floats whose last axis has ``size`` entries, or an InputError."""
    array = checks.numeric_array(values, what)
    if array.ndim < 1 or array.shape[-1] != size:
        raise InputError(f"{what} must have shape (..., {size}){detail}; got {array.shape}")
    return array


def joint_names(axes) -> tuple[str, ...]:
    """Joint names ``"<axis>-<axis>"`` between consecutive axes of a chain."""
    return tuple(f"{a}-{b}" for a, b in zip(axes[:-1], axes[1:]))


def error_names(axes) -> tuple[str, ...]:
    """Error names of a chain with these axis names, in the order of docs/model.md."""
    owners = tuple(axes) + joint_names(axes)
    return tuple(f"{owner}.{comp}" for owner in owners for comp in COMPONENTS)


def unknown_error_text(name, axes, what: str = "error name") -> str:
    """Why ``name`` (an error name, an item, a key: ``what``) is no error of a chain with
    these axis names: the close matches, and how the errors are named instead of all of
    their names."""
    names = error_names(axes)
    return (f"unknown {what} {name!r}"
            f"{checks.close_matches_text(name, names + iso_names(names))}; the "
            f"{len(names)} errors are named <axis>.<{'|'.join(COMPONENTS)}> (e.g. "
            f"{names[0]!r}) for the axes "
            f"{', '.join(axes)} and <joint>.<…> for the joints "
            f"{', '.join(joint_names(axes)) or '(none)'}, or by their ISO 230-1 symbols "
            f"(docs/iso-names.md)")


# ----- loading -----------------------------------------------------------------------
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
                      "tool_offset", "correlation", "bounds", "workzone"}, source)
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


def _checked_profile(value) -> str:
    """The error-profile model's name (:func:`reliability.model.profiles.profile_model`)."""
    if not isinstance(value, str):
        raise InputError(f"profile must be 'independent', 'constant' or 'gp:<length mm>'; "
                         f"got {value!r}")
    return str(profile_model(value))


def _parse_profile(table, source: str) -> str:
    """``[requirements] profile``: how a built machine's errors hang together along travel
    (``"constant"`` by default; ``"independent"`` is the paper's grid experiment)."""
    try:
        return _checked_profile(table.get("profile", "constant"))
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


def _checked_bounds(bounds, names) -> np.ndarray:
    """``(2, n_errors)`` finite positive bounds with lower <= upper, read-only."""
    array = np.array(bounds, dtype=float)
    if array.shape != (2, len(names)) or not np.all(np.isfinite(array) & (array > 0)):
        raise MachineDescriptionError(f"tolerance_bounds must be (2, {len(names)}) positive "
                                      f"finite (lower, upper) tolerances")
    bad = np.flatnonzero(array[0] > array[1])
    if len(bad):
        raise MachineDescriptionError(f"bounds of {names[bad[0]]!r}: lower exceeds upper")
    array.setflags(write=False)
    return array


# ----- writing -----------------------------------------------------------------------
def machine_to_dict(machine: Machine) -> dict:
    """The machine-file layout of ``machine`` (what :func:`machine_from_dict` reads)."""
    table = {
        "name": machine.name,
        "tool_offset": [float(v) for v in machine.tool_offset],
        "axes": [_axis_to_dict(axis) for axis in machine.axis_specs],
        "requirements": {output: {"limit": float(limit), "target": float(target)}
                         for output, limit, target in zip(OUTPUTS, machine.limits,
                                                          machine.targets)},
        "initial_allocation": _initial_to_dict(machine),
        "cost": _cost_to_dict(machine.cost_coefficients),
    }
    if not any(machine.tool_offset):
        del table["tool_offset"]
    if machine.distribution != "normal":
        table["requirements"]["distribution"] = machine.distribution
    if machine.profile != "constant":
        table["requirements"]["profile"] = machine.profile
    if machine.correlation is not None:
        table["correlation"] = correlation_to_toml(machine)
    if machine.tolerance_bounds is not None:
        table["bounds"] = _bounds_to_dict(machine)
    if machine.frame != "tool":
        table["requirements"]["frame"] = machine.frame
    if machine.work_zone is not None:
        table["workzone"] = machine.work_zone.to_dict()
    return table


def _bounds_to_dict(machine: Machine) -> dict:
    """Most common translational and angular pair as defaults, the rest as items."""
    names, (low, high) = machine.error_names, machine.tolerance_bounds
    angular = np.array([n.split(".")[1].startswith("e") for n in names])
    table = {}
    for key, mask in (("translation", ~angular), ("rotation", angular)):
        pairs, counts = np.unique(np.column_stack([low[mask], high[mask]]), axis=0,
                                  return_counts=True)
        table[key] = [float(v) for v in pairs[np.argmax(counts)]]
    default = np.where(angular, np.array(table["rotation"])[:, None],
                       np.array(table["translation"])[:, None])
    differ = np.flatnonzero((low != default[0]) | (high != default[1]))
    if len(differ):
        table["items"] = {names[i]: [float(low[i]), float(high[i])] for i in differ}
    return table


def _axis_to_dict(axis: Axis) -> dict:
    entry = {"name": axis.name, "kind": axis.kind, "direction": axis.direction}
    if axis.full_turn:
        entry["full_turn"] = True
    else:
        entry["stroke"] = [float(v) for v in axis.stroke]
    entry["size"] = float(axis.size)
    if any(axis.offset):
        entry["offset"] = [float(v) for v in axis.offset]
    for key in POSITIONING_KEYS:
        if getattr(axis, key):
            entry[key] = float(getattr(axis, key))
    return entry


def _initial_to_dict(machine: Machine) -> dict:
    """Most common translational and angular value as defaults, the rest as items."""
    names = machine.error_names
    values = machine.initial_allocation
    angular = np.array([n.split(".")[1].startswith("e") for n in names])
    table = {"translation": _most_common(values[~angular]),
             "rotation": _most_common(values[angular])}
    default = np.where(angular, table["rotation"], table["translation"])
    items = {names[i]: float(values[i]) for i in np.flatnonzero(values != default)}
    if items:
        table["items"] = items
    return table


def _most_common(values: np.ndarray) -> float:
    unique, counts = np.unique(values, return_counts=True)
    return float(unique[np.argmax(counts)])


def _cost_to_dict(cost: CostCoefficients) -> dict:
    table = {k: float(getattr(cost, k)) for k in "abcd" if getattr(cost, k) is not None}
    table["assembly"] = {joint: float(m) for joint, m in cost.assembly.items()}
    if cost.units is not None:
        table["units"] = {"length": cost.units[0], "angle": cost.units[1]}
    return table
