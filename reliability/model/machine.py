"""A serial machine described as data (docs/machine-file.md): its axes, requirements,
tolerances and costs, and the machine file's writer (:meth:`Machine.to_toml`). The file's
reader, which validates a description and builds a :class:`Machine`, is
:mod:`reliability.model.machine_file`.

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

from dataclasses import dataclass, field, fields
from types import MappingProxyType
from typing import Mapping

import numpy as np
import pandas as pd

from ..basics import checks
from ..basics.display import number_text
from ..basics.errors import InputError, InputTypeError, MachineDescriptionError
from . import kinematics
from .drift import Drift
from .correlation import check_correlation_matrix, correlation_to_toml, with_correlation
from .error_draws import DISTRIBUTIONS
from .iso_names import iso_names
from .profiles import profile_model
from .work_zone import WorkZone

COMPONENTS = ("dx", "dy", "dz", "ex", "ey", "ez")
OUTPUTS = COMPONENTS
#: Optional keys of a linear axis read by ISO 230-2 positioning tests only (mm).
POSITIONING_KEYS = ("repeatability", "reversal")


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

    Build one with :func:`~reliability.model.machine_file.load_machine`,
    :func:`~reliability.model.machine_file.machine_from_dict` or
    :func:`~reliability.model.machine_file.hobbing_machine`. The kinematic model is
    :meth:`comprehensive_error` (exact, Eq. 18) and :meth:`jacobian` (analytic first-order
    sensitivities).
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
    drift: Drift | None = field(default=None, repr=False)
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
        object.__setattr__(self, "profile", checked_profile(self.profile))
        if self.tolerance_bounds is not None:
            object.__setattr__(self, "tolerance_bounds",
                               _checked_bounds(self.tolerance_bounds, self.error_names))
        if self.work_zone is not None and not isinstance(self.work_zone, WorkZone):
            raise InputTypeError(f"work_zone must be a WorkZone or None; got "
                                 f"{type(self.work_zone).__name__}")
        if self.drift is not None:
            _check_drift(self.drift, self.n_errors)

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
        :func:`~reliability.model.machine_file.machine_from_toml` of it gives an equal
        machine."""
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


def checked_profile(value) -> str:
    """The error-profile model's name (:func:`reliability.model.profiles.profile_model`)."""
    if not isinstance(value, str):
        raise InputError(f"profile must be 'independent', 'constant' or 'gp:<length mm>'; "
                         f"got {value!r}")
    return str(profile_model(value))


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
    """The machine-file layout of ``machine`` (what
    :func:`~reliability.model.machine_file.machine_from_dict` reads)."""
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
    if machine.drift is not None:
        table["drift"] = machine.drift.to_dict(machine.error_names)
    return table


def _check_drift(drift, n_errors: int) -> None:
    """A :class:`~reliability.model.drift.Drift` with one value per error, or raise."""
    if not isinstance(drift, Drift):
        raise InputTypeError(f"drift must be a Drift or None; got {type(drift).__name__}")
    if drift.rate.shape != (n_errors,):
        raise InputError(f"drift must give one rate per error ({n_errors}); got "
                         f"{drift.rate.shape[0]}")


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
