"""A machine description read back to its author: a summary, and the likely mistakes.

A machine file can be valid and still not mean what its author meant: degrees written
where radians belong, millimetres where the cost model wants metres, an offset that has
no effect. :func:`likely_mistakes` lists such findings as warnings (the machine still
loads); :func:`unit_mistakes` the part of them about units, which every command repeats;
:func:`implausible_values` is the one check of a tolerance or limit that looks written in
µm or arc seconds, shared by the machine, tolerance, acceptance-test and catalogue files;
:func:`describe` prints the description with its units.

Units of a machine file: strokes and offsets in mm (linear) or rad (rotary); sizes (guide
length L, rotation diameter D; Eqs. 25–26) in m; limits in mm (dx dy dz) and rad
(ex ey ez); tolerances likewise.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from ..basics.display import OUTPUT_UNITS, output_limits_text
from ..basics.errors import InputTypeError
from .machine import OUTPUTS, Machine
from .poses import full_grid
from .work_zone import inside_zone, zone_text

LARGEST_SIZE_M = 20.0  # a guide length or rotation diameter beyond this is taken for mm
SMALLEST_LINEAR_STROKE_MM = 1.0  # a linear stroke shorter than this is taken for metres
LARGEST_LINEAR_LIMIT_MM = 1.0  # a tolerance or limit beyond this suggests µm written as mm
LARGEST_ANGULAR_LIMIT_RAD = 0.01  # 0.57°, 2063″: beyond this suggests arcsec, µrad or degrees
ARCSEC_RAD = math.pi / 648000.0
TURN = 2.0 * math.pi
TURN_TOLERANCE = 1e-6  # a stroke this close to 2π covers a full turn


def likely_mistakes(machine) -> list[str]:
    """Warnings about a description that is valid but probably not what was meant.

    Parameters
    ----------
    machine : Machine

    Returns
    -------
    list of str
        One sentence per finding, naming the axis or output and the value; empty when
        nothing looks wrong.
    """
    _check_machine(machine)
    warnings = []
    for check in (_first_offset, *UNIT_CHECKS[:3], _parallel_linear_axes, *UNIT_CHECKS[3:],
                  _cost_units, _empty_zone):
        warnings.extend(check(machine))
    return warnings


def unit_mistakes(machine) -> list[str]:
    """The warnings of :func:`likely_mistakes` about units (strokes, sizes, limits,
    tolerances and bounds that look written in the wrong unit), which every command that
    loads the machine repeats.

    Parameters
    ----------
    machine : Machine

    Returns
    -------
    list of str
    """
    _check_machine(machine)
    return [text for check in UNIT_CHECKS for text in check(machine)]


def implausible_values(entries) -> list[str]:
    """Tolerances or limits that look written in µm or angles in arc seconds, µrad or
    degrees: above 1 mm (translational) or 0.01 rad = 2063 arcsec (angular).

    Parameters
    ----------
    entries : iterable of (str, float, str)
        What each value is (``"the limit of dx"``), the value, and the unit it was read in
        (``"mm"`` or ``"rad"``).

    Returns
    -------
    list of str
        One sentence per implausible value, naming it, its value and unit and the likely
        mistake.
    """
    warnings = []
    for what, value, unit in entries:
        value = float(value)
        if unit == "mm" and value > LARGEST_LINEAR_LIMIT_MM:
            warnings.append(f"{what} is {value:g} mm, over {LARGEST_LINEAR_LIMIT_MM:g} mm: "
                            f"almost surely µm written as mm (did you mean "
                            f"{value / 1000.0:g} mm?)")
        if unit == "rad" and value > LARGEST_ANGULAR_LIMIT_RAD:
            warnings.append(f"{what} is {value:g} rad ({math.degrees(value):.3g} degrees), "
                            f"over {LARGEST_ANGULAR_LIMIT_RAD:g} rad: almost surely arc "
                            f"seconds, µrad or degrees written as rad ({value:g} arcsec "
                            f"would be {value * ARCSEC_RAD:.3g} rad)")
    return warnings


def tolerance_warnings(machine, tolerances, source: str = "tolerances") -> list[str]:
    """Tolerances of an allocation (one per error, mm and rad) that look written in µm or
    arc seconds (:func:`implausible_values`).

    Parameters
    ----------
    machine : Machine
    tolerances : array_like (n_errors,)
    source : str
        Where the tolerances were read, named in each sentence.

    Returns
    -------
    list of str
    """
    _check_machine(machine)
    values = machine.check_tolerances(tolerances)
    return implausible_values(
        (f"{source}: the tolerance of {name}", value,
         "rad" if name.split(".")[1].startswith("e") else "mm")
        for name, value in zip(machine.error_names, values))


def _first_offset(machine) -> list[str]:
    """The first axis' offset is a fixed shift of the workpiece frame: it cancels."""
    first = machine.axis_specs[0]
    if not any(first.offset):
        return []
    return [f"axis {first.name!r} is first in the chain; its offset {list(first.offset)} mm "
            f"has no effect (a fixed shift of the workpiece frame cancels in Eq. 18). "
            f"Did you mean it for the next axis or for tool_offset?"]


def _rotary_strokes(machine) -> list[str]:
    warnings = []
    for axis in machine.axis_specs:
        if axis.kind != "rotary" or axis.full_turn:
            continue
        width = axis.stroke[1] - axis.stroke[0]
        if width > TURN + TURN_TOLERANCE:
            warnings.append(
                f"rotary axis {axis.name!r} has a stroke of {width:.4g} rad "
                f"({width / TURN:.3g} turns): degrees given for radians? Strokes of "
                f"rotary axes are in rad; use full_turn = true for a whole revolution")
        elif abs(width - TURN) <= TURN_TOLERANCE:
            warnings.append(
                f"rotary axis {axis.name!r} has a stroke of one full turn; set "
                f"full_turn = true so that grids do not count 0 and 2π as two poses")
    return warnings


def _sizes(machine) -> list[str]:
    warnings = []
    for axis in machine.axis_specs:
        what = "guide length" if axis.kind == "linear" else "rotation diameter"
        if axis.size > LARGEST_SIZE_M:
            warnings.append(
                f"axis {axis.name!r} has a {what} (size) of {axis.size:g} m: millimetres "
                f"given for metres? The cost model (Eqs. 25–26) takes sizes in m")
        elif axis.kind == "linear" and axis.size * 1000.0 < _width(axis):
            warnings.append(
                f"linear axis {axis.name!r} has a guide length of {axis.size:g} m, shorter "
                f"than its stroke of {_width(axis):g} mm: is the size or the stroke in the "
                f"wrong unit?")
    return warnings


def _cost_units(machine) -> list[str]:
    """A cost without stated units is read in mm and rad, which makes translational items
    nearly free beside angular ones."""
    if machine.cost_coefficients.units is not None:
        return []
    return ["the [cost] table states no 'units': the cost w/t² reads t in mm and rad, where "
            "an angular item at 1e-5 rad weighs about 1e5 times a translational one at 0.003 mm, so "
            "translational tolerances end up decided by the bounds; say which units you mean "
            "with [cost] units = { length = \"um\", angle = \"arcsec\" } (or \"mm\", "
            "\"rad\" to keep these), see docs/cost-units.md"]


def _empty_zone(machine) -> list[str]:
    """A work zone that holds no pose of the 5-point grid leaves the grid's studies
    nothing to judge."""
    if machine.work_zone is None or inside_zone(machine, full_grid(machine)).any():
        return []
    return [f"no pose of the 5-point grid lies in the {zone_text(machine)}: the grid's "
            f"studies (predict, allocate, report) will refuse it; check the zone against "
            f"the strokes and tool_offset (mm, workpiece frame), or use more points per axis"]


def _linear_strokes(machine) -> list[str]:
    return [f"linear axis {axis.name!r} has a stroke of only {_width(axis):g} mm: metres "
            f"given for millimetres? Strokes of linear axes are in mm"
            for axis in machine.axis_specs
            if axis.kind == "linear" and _width(axis) < SMALLEST_LINEAR_STROKE_MM]


def _parallel_linear_axes(machine) -> list[str]:
    seen, warnings = {}, []
    for axis in machine.axis_specs:
        if axis.kind != "linear":
            continue
        if axis.direction in seen:
            warnings.append(f"linear axes {seen[axis.direction]!r} and {axis.name!r} both "
                            f"move along {axis.direction}: is one direction wrong?")
        seen.setdefault(axis.direction, axis.name)
    return warnings


def _limits(machine) -> list[str]:
    return implausible_values((f"the requirement's limit of {output}", limit, unit)
                              for output, limit, unit in zip(OUTPUTS, machine.limits,
                                                             OUTPUT_UNITS))


def _tolerances(machine) -> list[str]:
    """Initial tolerances and bounds that look written in µm or arc seconds."""
    units = ["rad" if name.split(".")[1].startswith("e") else "mm"
             for name in machine.error_names]
    tables = [("initial_allocation: the tolerance", machine.initial_allocation)]
    if machine.tolerance_bounds is not None:
        tables.append(("bounds: the upper bound", machine.tolerance_bounds[1]))
    return [text for table, values in tables for text in implausible_values(
        (f"{table} of {name}", value, unit)
        for name, value, unit in zip(machine.error_names, values, units))]


def _initial_allocation(machine) -> list[str]:
    """A single error's tolerance at or above an output's limit cannot be met."""
    angular = np.array([name.split(".")[1].startswith("e") for name in machine.error_names])
    warnings = []
    for is_angular, outputs in ((False, slice(0, 3)), (True, slice(3, 6))):
        values = machine.initial_allocation[angular == is_angular]
        names = np.array(machine.error_names)[angular == is_angular]
        smallest = machine.limits[outputs].min()
        worst = int(np.argmax(values))
        if values[worst] >= smallest:
            unit = "rad" if is_angular else "mm"
            warnings.append(f"the initial tolerance of {names[worst]} ({values[worst]:g} "
                            f"{unit}) is not smaller than the tightest limit "
                            f"({smallest:g} {unit}); check the units of initial_allocation")
    return warnings


UNIT_CHECKS = (_rotary_strokes, _sizes, _linear_strokes, _limits, _tolerances,
               _initial_allocation)


def _check_machine(machine) -> None:
    if not isinstance(machine, Machine):
        raise InputTypeError(f"machine must be a Machine (see reliability.load_machine); "
                             f"got {type(machine).__name__}")


def _width(axis) -> float:
    return axis.stroke[1] - axis.stroke[0]


# ----- description -------------------------------------------------------------------
def describe(machine) -> str:
    """The machine as text: chain, axes with strokes and units, errors, requirements.

    Parameters
    ----------
    machine : Machine

    Returns
    -------
    str
    """
    _check_machine(machine)
    n_axes = len(machine.axis_specs)
    lines = [f"Machine: {machine.name}",
             f"Chain, workpiece to tool: {' '.join(machine.axes)} ({n_axes} axes); "
             f"{machine.n_errors} geometric errors ({6 * n_axes} motion, "
             f"{6 * (n_axes - 1)} assembly)", "",
             _axis_table(machine).to_string(index=False),
             f"Tool offset: {_vector(machine.tool_offset)} mm",
             f"Workspace: {_workspace_line(machine)}", "",
             "Requirements (|error| < limit with probability ≥ target)",
             _requirement_table(machine).to_string(), _distribution_line(machine), _profile_line(machine), "",
             _initial_line(machine), _cost_line(machine)]
    return "\n".join(lines)


def _workspace_line(machine) -> str:
    """The work zone and how many poses of the 5-point grid it holds."""
    if machine.work_zone is None:
        return zone_text(machine)
    grid = full_grid(machine)
    return f"{zone_text(machine)}; {int(inside_zone(machine, grid).sum())} of the " \
           f"{len(grid)} poses of the 5-point grid inside"


def _distribution_line(machine) -> str:
    """How a tolerance t is read in every computation of the study."""
    if machine.distribution == "truncated":
        return ("Tolerances read as normal with σ = t/3 truncated at ±t (distribution = "
                "'truncated')")
    return "Tolerances read as normal with σ = t/3 (distribution = 'normal')"


def _profile_line(machine) -> str:
    """How a built machine's errors hang together along travel, for the machine yield."""
    words = {"constant": "one value per built machine along each travel",
             "independent": "a fresh value at every grid point (the paper's Sec. 5.3)"}
    meaning = words.get(machine.profile, "a Gaussian process along travel with correlation "
                                         f"length {machine.profile[3:]} mm")
    return f"Machine yield: errors {meaning} (profile = '{machine.profile}')"


def _axis_table(machine) -> pd.DataFrame:
    rows = []
    for axis in machine.axis_specs:
        unit = "mm" if axis.kind == "linear" else "rad"
        stroke = "full turn [0, 2π)" if axis.full_turn else \
            f"{axis.stroke[0]:g} … {axis.stroke[1]:g} {unit}"
        if axis.kind == "rotary" and not axis.full_turn:
            low, high = (math.degrees(v) for v in axis.stroke)
            stroke += f" ({low:.4g}° … {high:.4g}°)"
        what = "L" if axis.kind == "linear" else "D"
        rows.append({"axis": axis.name, "kind": axis.kind, "direction": axis.direction,
                     "stroke": stroke, "size [m]": f"{what} = {axis.size:g}",
                     "offset [mm]": _vector(axis.offset)})
        if any(a.repeatability or a.reversal for a in machine.axis_specs):
            rows[-1]["repeatability σ [mm]"] = f"{axis.repeatability:g}"
            rows[-1]["reversal [mm]"] = f"{axis.reversal:g}"
    return pd.DataFrame(rows)


def _requirement_table(machine) -> pd.DataFrame:
    return pd.DataFrame({"limit": output_limits_text(machine.limits),
                         "target": machine.targets},
                        index=pd.Index(OUTPUTS, name="output"))


def _initial_line(machine) -> str:
    angular = np.array([name.split(".")[1].startswith("e") for name in machine.error_names])
    values = machine.initial_allocation
    parts = []
    for mask, label, unit in ((~angular, "translational", "mm"), (angular, "angular", "rad")):
        unique = np.unique(values[mask])
        text = f"{unique[0]:g}" if len(unique) == 1 else \
            f"{unique.min():g} … {unique.max():g}"
        parts.append(f"{label} {text} {unit}")
    return "Initial allocation: " + ", ".join(parts)


def _cost_line(machine) -> str:
    cost = machine.cost_coefficients
    given = [f"{k} = {getattr(cost, k):g}" for k in "abcd" if getattr(cost, k) is not None]
    assembly = ", ".join(f"{j} {m:g}" for j, m in cost.assembly.items())
    return "Cost coefficients: " + ", ".join(given) + \
        (f"; assembly {assembly}" if assembly else "")


def _vector(values) -> str:
    return "[" + ", ".join(f"{v:g}" for v in values) + "]"
