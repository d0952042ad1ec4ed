"""An allocation result printed for reading, saved as JSON or CSV and reloaded verified.

The allocation CSV (columns ``error, reference, allocated``, one row per error) has one
writer, :func:`allocation_to_csv` (its table: :func:`allocation_frame`), and one reader,
:func:`read_allocation_csv`, used by the library and the command line alike. Written to
a number of significant digits, the allocated tolerances are rounded down
(:func:`written_tolerances`), so the file meets every target the result meets.

The drawing file ``drawing_tolerances.csv`` (columns ``error, iso, name, tolerance,
unit``) gives the tolerances to write on drawings: each in µm or arcsec with its ISO 230-1
symbol and plain name, rounded down to a resolution (0.1 µm and 0.1 arcsec by default,
:func:`drawing_tolerances`). Its writer is :func:`drawing_to_csv`; :func:`read_allocation_csv`
reads it as it reads an allocation CSV.

The JSON file holds the allocation, its cost, feasibility, certificate, binding
constraints, GWO history and per-requirement elasticities, and what is needed to read them
without the machine: the error names, the reference allocation and the bounds, the cost
weights (so the cost is re-checked on reload), the reading (side, workspace, k) and the
machine's name, axes and units. A reloaded result carries a :class:`SavedProblem` in
place of the :class:`~allocation.per_pose.problem.AllocationProblem` unless the problem is given.
"""

from __future__ import annotations

from dataclasses import dataclass
from decimal import Decimal

import numpy as np
import pandas as pd

from reliability.basics.display import (UNIT_SCALES, axis_units, error_units, number_text,
                                        percent_number, percentage_text, pose_columns,
                                        tolerance_numbers, unit_symbol)
from reliability.basics.errors import InputError, InputTypeError
from reliability.basics.files import SIGNIFICANT, as_written, rounded_down, write_csv
from reliability.basics.saved_results import check_count, encode_frame, load_payload, save_payload
from reliability.model.iso_names import plain_names
from reliability.model.machine import OUTPUTS

from ..cost.cost import GROUPS, CostModel
from .elasticity import limit_texts

KIND = "precrel.allocation_result"
METHODS = ("exact", "gwo", "compensated")
COST_RTOL = 1e-9  # the saved cost must be Σ w/t² of the saved tolerances
CSV_COLUMNS = ("error", "reference", "allocated")
READINGS = {"worst": "every target at every pose", "mean": "targets on the workspace mean"}
#: Share of the cost below which an item at a bound counts as nearly free.
NEARLY_FREE_SHARE = 1e-3
#: Relative distance within which a solver's tolerance is taken to be on its bound.
AT_BOUND_RTOL = 1e-12
#: Significant digits a Lagrange multiplier (and an elasticity made from it) is written to:
#: the dual solver fixes their sums per output only to about 1e-5 relative.
MULTIPLIER_DIGITS = 3
#: A relative duality gap below this is shown as "< GAP_SHOWN": its value is solver noise
#: that differs between computers, while the bound is what the certificate guarantees.
GAP_SHOWN = 1e-8
#: The drawing file: its name, its columns, its units (lengths, angles) and the default
#: resolution a tolerance is rounded down to, in those units.
DRAWING_FILE = "drawing_tolerances.csv"
DRAWING_COLUMNS = ("error", "iso", "name", "tolerance", "unit")
DRAWING_UNITS = ("um", "arcsec")
DRAWING_RESOLUTION = (0.1, 0.1)
#: Units a tolerance file may give each kind of item in, and other spellings read as them.
LENGTH_UNITS, ANGLE_UNITS = ("mm", "um"), ("rad", "urad", "arcsec")
UNIT_SPELLINGS = {"µm": "um", "μm": "um", "µrad": "urad", "μrad": "urad"}


def cost_units_text(cost) -> str:
    """The units t is read in inside the cost, and whether the machine file states them."""
    length, angle = cost.units or ("mm", "rad")
    stated = "" if cost.units else " (not stated in the machine file: read as mm and rad)"
    return f"cost w/t² with t in {length} and {angle}{stated}"


def cost_shares_text(cost, t) -> str:
    """Each cost group's share at ``t``, translational and angular items apart, e.g.
    ``linear: translational < 0.01 %, angular 55.02 %; …``
    (:func:`~reliability.basics.display.percentage_text`)."""
    shares = cost.shares(t)
    return "; ".join(f"{group}: translational {percentage_text(row.translational)}, "
                     f"angular {percentage_text(row.angular)}"
                     for group, row in shares.iterrows())


def nearly_free_text(result) -> str:
    """The items at a bound carrying under 0.1 % of the cost, or an empty string."""
    names = result.nearly_free()
    if not names:
        return ""
    shown = ", ".join(names[:12]) + (f" and {len(names) - 12} more" if len(names) > 12 else "")
    return (f"{len(names)} items nearly free (at a bound, each under "
            f"{100 * NEARLY_FREE_SHARE:g} % of the cost: their tolerance is decided by the "
            f"bound, not by cost): {shown}")


def gap_bound(gap: float) -> float:
    """The relative duality gap as the toolkit writes it: :data:`GAP_SHOWN` when smaller,
    otherwise rounded up to two significant digits (NaN stays NaN)."""
    gap = float(gap)
    if not np.isfinite(gap) or gap < GAP_SHOWN:
        return gap if not np.isfinite(gap) else GAP_SHOWN
    scale = 10.0 ** (np.floor(np.log10(gap)) - 1)
    return float(np.ceil(gap / scale) * scale)


def gap_text(gap: float) -> str:
    """``"< 1e-08"`` for a gap below :data:`GAP_SHOWN`, else ``"≤ 2.3e-05"`` (rounded up)."""
    gap = float(gap)
    if not np.isfinite(gap):
        return "unknown"
    return f"< {GAP_SHOWN:.0e}" if gap < GAP_SHOWN else f"≤ {gap_bound(gap):.2g}"


@dataclass(frozen=True, eq=False)
class SavedProblem:
    """What a reloaded :class:`AllocationResult` knows of its problem.

    Attributes
    ----------
    machine_name : str
    axes, units : tuple of str
        Axis names and units (``'mm'``/``'rad'``) of the poses in ``result.active``.
    names : tuple of str
        Error names.
    reference, lower, upper : ndarray (n_errors,)
        Reference allocation and tolerance bounds.
    side, workspace : str
        The reliability reading of the problem.
    k : float
        Tolerances are ±kσ.
    n_poses : int
        Poses the constraints were held at.
    cost : CostModel
        The cost weights, so :meth:`AllocationResult.breakdown` still works.
    distribution : str
        How tolerances were read (``'normal'`` or ``'truncated'``); files written before
        the field existed were all ``'normal'``.
    """

    machine_name: str
    axes: tuple
    units: tuple
    names: tuple
    reference: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    side: str
    workspace: str
    k: float
    n_poses: int
    cost: CostModel
    distribution: str = "normal"

    @property
    def locked(self) -> np.ndarray:
        """Boolean mask of items held fixed (lower == upper)."""
        return self.lower == self.upper


def _context(problem) -> SavedProblem | object:
    """The problem's description in the form of :class:`SavedProblem`."""
    if isinstance(problem, SavedProblem):
        return problem
    machine = problem.machine
    return SavedProblem(machine_name=machine.name, axes=machine.axes,
                        units=axis_units(machine), names=tuple(problem.names),
                        reference=problem.reference, lower=problem.lower,
                        upper=problem.upper, side=problem.side, workspace=problem.workspace,
                        k=problem.k, n_poses=len(problem.poses), cost=problem.cost,
                        distribution=problem.distribution)


# ----- printing ------------------------------------------------------------------------
def allocation_summary(result, top: int = 5) -> str:
    """Feasibility (loudly when missing), cost relative to the reference, what binds and
    the largest changes from the reference."""
    top = check_count(top, "top")
    context = _context(result.problem)
    reference_cost = context.cost.total(context.reference)
    lines = [] if result.feasible else [_not_feasible_line(result)]
    lines += [f"Allocation by {_method_text(result)} for {context.machine_name}: "
              f"{READINGS[context.workspace]} over {context.n_poses} poses, "
              f"{context.side.replace('_', '-')} probability, tolerances ±{context.k:g}σ "
              f"({context.distribution})",
              f"Cost {result.cost / reference_cost:.4f} × the reference allocation "
              f"(F = {result.cost:.4g} against {reference_cost:.4g})",
              _status_line(result), ""]
    lines += _binding_lines(result, context)
    lines += ["", "Largest changes from the reference (tolerance in mm or rad)",
              _changes(result, top).to_string()]
    return "\n".join(lines)


def _not_feasible_line(result) -> str:
    violation = result.certificate.get("violation")
    amount = "" if violation is None else f" (total violation {violation:.3g})"
    return (f"NOT FEASIBLE: this {result.method} allocation misses at least one "
            f"reliability target{amount}; do not use it")


def _method_text(result) -> str:
    if result.method == "gwo":
        return "the Grey Wolf Optimiser (no optimality certificate)"
    certified = result.certificate.get("certified", False)
    gap = result.certificate.get("relative_gap")
    shown = "" if gap is None else f", relative gap {gap_text(gap)}"
    return f"the exact solver ({'certified' if certified else 'NOT certified'}{shown})"


def _status_line(result) -> str:
    status = result.to_frame()["status"].value_counts()
    parts = [f"{int(status.get(s, 0))} {label}" for s, label in
             (("lower", "at the lower bound"), ("upper", "at the upper bound"),
              ("free", "inside the bounds"), ("locked", "locked"))]
    return "Items: " + ", ".join(parts)


def _binding_lines(result, context) -> list[str]:
    if result.requirements is not None:
        binding = result.requirements[result.requirements["binding_rows"] > 0]
        table = pd.DataFrame({"binding_rows": binding["binding_rows"],
                              "dlncost/dln_limit": limit_texts(binding)})
        if "bound_with" in binding:
            table["bound_with"] = binding["bound_with"]
        head = ["What binds: requirements with binding rows (dlncost/dln_limit: relaxing a "
                "limit by 1 % changes the cost by about this many %; negative, a saving; "
                "two values where outputs bind together and only their joint change is "
                "determined, docs/non-unique.md)",
                table.to_string()]
    else:
        outputs = sorted(set(result.active["output"])) if len(result.active) else []
        head = [f"What binds: {', '.join(outputs) if outputs else 'no reliability target'}"]
    if len(result.active) and "pose" in result.active:
        rows = result.active.head(6)
        poses = pose_columns(rows[list(context.axes)].to_numpy(), context.axes,
                             context.units)
        poses.insert(0, "pose #", rows["pose"].to_numpy())
        poses.insert(0, "output", rows["output"].to_numpy())
        more = len(result.active) - len(rows)
        head += ["", "Binding constraints (output at pose, axis positions)"
                 + (f"; first {len(rows)} of {len(result.active)}" if more else ""),
                 poses.to_string(index=False)]
    return head


def _changes(result, top: int) -> pd.DataFrame:
    """The ``top`` largest changes, tolerances in mm or rad cut to 0.001 µm or arcsec and
    the change to 0.01 %."""
    frame = result.to_frame()
    units = error_units(frame.index, None)
    order = frame["rate"].abs().sort_values(ascending=False, kind="stable").index
    shown = frame.assign(reference=tolerance_numbers(frame["reference"], units),
                         allocated=tolerance_numbers(frame["allocated"], units))
    shown["change [%]"] = [percent_number(v) for v in shown.pop("rate")]
    return shown.loc[order[:top]]


# ----- files ---------------------------------------------------------------------------
def allocation_frame(result, significant: int | None = None) -> pd.DataFrame:
    """The allocation CSV's table: columns ``error, reference, allocated``, one row per
    error in the machine's order; with ``significant``, the allocation as a file written to
    that many digits holds it (:func:`written_tolerances`)."""
    context = _context(result.problem)
    allocated = result.tolerances if significant is None else \
        written_tolerances(result, significant)
    return pd.DataFrame({"error": context.names, "reference": context.reference,
                         "allocated": allocated}, columns=list(CSV_COLUMNS))


def written_tolerances(result, significant: int = SIGNIFICANT) -> np.ndarray:
    """The result's tolerances rounded down (tighter) to ``significant`` significant
    digits: what an allocation CSV written to those digits holds and every reader computes
    with.

    With independent errors each output's σ at each pose, the worst-case stack sum and
    the probability that all outputs are inside at once are monotone in each tolerance, so
    a tighter allocation meets every target the computed one meets. A tolerance the solver
    put on a bound (within :data:`AT_BOUND_RTOL`, the last few bits of its arithmetic) is
    the bound: it is written as the bound when the file holds that bound exactly, so
    ``0.0015`` is not written ``0.00149999``, below its lower bound.
    """
    significant = check_count(significant, "significant")
    context = _context(result.problem)
    written = rounded_down(result.tolerances, significant)
    for bound in (context.lower, context.upper):
        exact = as_written(bound, significant) == bound
        on_bound = np.abs(result.tolerances - bound) <= AT_BOUND_RTOL * bound
        written = np.where(exact & on_bound, bound, written)
    return written


def written_cost_text(result, significant: int = SIGNIFICANT) -> str:
    """The rounding of the written allocation and its cost beside the computed one."""
    context = _context(result.problem)
    written = context.cost.total(written_tolerances(result, significant))
    return (f"written rounded down to {significant} significant digits (items on a bound "
            f"as the bound); cost of the written allocation {written:.6g} "
            f"({written / result.cost - 1:+.2g} relative to {result.cost:.6g})")


def allocation_to_csv(result, path, overwrite: bool = False, *,
                      significant: int | None = None, not_certified: str | None = None):
    """Write :func:`allocation_frame` to ``path``.

    Parameters
    ----------
    result : AllocationResult
    path : str or Path
    overwrite : bool
        Replace an existing file; otherwise an existing file raises FileExistsError.
    significant : int, optional
        Significant digits of the numbers; all digits (an exact round trip) by default.
        The allocated tolerances are rounded down (:func:`written_tolerances`), so the file
        meets every target the result meets; the reference column to the nearest.
    not_certified : str, optional
        Why the allocation is not certified over the continuous workspace: the file then
        has two more columns, ``certified`` (false) and ``reason``, which readers of
        allocation files ignore.
    """
    float_format = None if significant is None else \
        f"%.{check_count(significant, 'significant')}g"
    frame = allocation_frame(result, significant)
    if not_certified is not None:
        frame = frame.assign(certified=False, reason=not_certified)
    return write_csv(frame, path, overwrite, index=False, float_format=float_format)


def drawing_tolerances(names, tolerances, resolution=DRAWING_RESOLUTION
                       ) -> tuple[list[str], np.ndarray]:
    """Tolerances as written on drawings: each rounded down to a multiple of the
    resolution in µm (lengths) or arcsec (angles).

    Parameters
    ----------
    names : sequence of str
        Error names (``"<owner>.d*"`` lengths, ``"<owner>.e*"`` angles).
    tolerances : array_like
        Tolerances in mm and rad, aligned with ``names``.
    resolution : (float, float)
        Resolution of lengths in µm and of angles in arcsec.

    Returns
    -------
    texts : list of str
        Each tolerance as its drawing gives it, in µm or arcsec (``"3.4"``).
    values : ndarray
        The same in mm and rad, as :func:`read_allocation_csv` reads them back: never above
        the given tolerance, so the drawing meets every target the allocation meets.

    Raises
    ------
    InputError
        A resolution that is not a finite number > 0, or a tolerance below its resolution.
    """
    steps = [_resolution_step(value, kind) for value, kind in
             zip(resolution, ("length", "angle"))]
    units = error_units(names, DRAWING_UNITS)
    texts, values = [], []
    for name, tolerance, unit in zip(names, np.asarray(tolerances, dtype=float), units):
        step = steps[DRAWING_UNITS.index(unit)]
        text = _drawn(float(tolerance), UNIT_SCALES[unit], step)
        if text is None:
            raise InputError(f"tolerance of {name!r} is {number_text(float(tolerance))} in "
                             f"mm or rad, below the drawing resolution {step} "
                             f"{unit_symbol(unit)}; give a finer resolution")
        texts.append(text)
        values.append(float(text) / UNIT_SCALES[unit])
    return texts, np.array(values)


def _resolution_step(value, kind: str) -> Decimal:
    """A resolution as the exact decimal it is written as."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.number)) \
            or not (np.isfinite(value) and value > 0):
        raise InputError(f"resolution of {kind}s is {number_text(value)}; expected a number "
                         f"> 0 (µm for lengths, arcsec for angles)")
    return Decimal(repr(float(value)))


def _drawn(tolerance: float, scale: float, step: Decimal) -> str | None:
    """The largest multiple of ``step`` whose value read back (``float(text) / scale``) is
    at most ``tolerance``, as text; None when there is none above 0."""
    count = int(Decimal(tolerance * scale) / step) + 1
    while count > 0 and float(str(count * step)) / scale > tolerance:
        count -= 1
    return str(count * step) if count > 0 else None


def drawing_frame(machine, tolerances, resolution=DRAWING_RESOLUTION) -> pd.DataFrame:
    """The drawing file's table (:data:`DRAWING_COLUMNS`), one row per error of
    ``machine``: paper name, ISO 230-1 symbol, plain name, the tolerance rounded down
    (:func:`drawing_tolerances`, text) and its unit (``um`` or ``arcsec``)."""
    texts, _ = drawing_tolerances(machine.error_names, tolerances, resolution)
    return pd.DataFrame({"error": machine.error_names, "iso": machine.iso_names,
                         "name": plain_names(machine), "tolerance": texts,
                         "unit": error_units(machine.error_names, DRAWING_UNITS)},
                        columns=list(DRAWING_COLUMNS))


def drawing_to_csv(machine, tolerances, path, overwrite: bool = False, *,
                   resolution=DRAWING_RESOLUTION):
    """Write :func:`drawing_frame` to ``path`` (refusing to replace a file unless
    ``overwrite``)."""
    return write_csv(drawing_frame(machine, tolerances, resolution), path, overwrite,
                     index=False)


def drawing_check_text(result, resolution=DRAWING_RESOLUTION, *, targets: bool = True) -> str:
    """How the drawing tolerances were rounded, with ``targets`` whether they meet the
    result's per-pose targets on its poses, and their cost beside the result's."""
    problem = result.problem
    _, drawn = drawing_tolerances(problem.names, result.tolerances, resolution)
    cost = problem.cost.total(drawn)
    check = (f"meets the targets at the {len(problem.poses)} poses of the problem: "
             f"{'yes' if problem.meets_targets(drawn) else 'NO'}; " if targets else "")
    return (f"rounded down to {float(resolution[0]):g} µm and "
            f"{float(resolution[1]):g} arcsec, so every item is at most the "
            f"allocation's; {check}cost {cost:.6g} ({cost / result.cost - 1:+.2g} relative "
            f"to the allocation's {result.cost:.6g})")


def read_allocation_csv(path, machine) -> np.ndarray:
    """Tolerances in mm and rad from an allocation CSV (columns ``error`` and
    ``allocated``; what :func:`allocation_to_csv` and ``precrel allocate`` write) or a
    drawing file (columns ``error``, ``tolerance`` and ``unit``; what :func:`drawing_to_csv`
    writes), aligned to the machine's error names. Rows may come in any order and errors
    may be named by their ISO 230-1 symbols; other columns are ignored.

    Raises
    ------
    InputError
        An unreadable table, a missing column, a name the machine does not have, a name
        given twice, a missing name, a value that is not a finite positive number or a unit
        that does not fit its item; the message names the file and the row's error.
    """
    try:
        frame = pd.read_csv(path)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: not a readable CSV table "
                         f"({' '.join(str(exc).split())})") from None
    column = _value_column(frame, path)
    given = frame["error"].astype(str).str.strip()
    unknown = [n for n in given if not _known(machine, n)]
    if unknown:
        raise InputError(f"{path}: unknown error name(s) {unknown[:5]}; "
                         f"the machine's errors are named like {machine.error_names[0]!r} "
                         f"(or by their ISO 230-1 symbols, like {machine.iso_names[0]!r})")
    names = pd.Series([machine.error_names[machine.error_index(n)] for n in given])
    repeated = sorted(set(names[names.duplicated()]))
    if repeated:
        raise InputError(f"{path}: error(s) given twice: {repeated[:5]}")
    absent = [n for n in machine.error_names if n not in set(names)]
    if absent:
        raise InputError(f"{path}: {len(absent)} error(s) missing, e.g. "
                         f"{absent[:5]}; expected one row per error of the machine")
    values = pd.to_numeric(frame[column], errors="coerce").to_numpy(dtype=float)
    bad = np.flatnonzero(~(np.isfinite(values) & (values > 0)))
    if len(bad):
        raise InputError(f"{path}: {column} value of {given[bad[0]]!r} is "
                         f"{number_text(frame[column][bad[0]])}; expected a number > 0")
    if column == "tolerance":
        values = values / _row_scales(frame["unit"], names, given, path)
    return pd.Series(values, index=names).reindex(list(machine.error_names)).to_numpy()


def _value_column(frame: pd.DataFrame, path) -> str:
    """``'allocated'`` (an allocation CSV) or ``'tolerance'`` (a drawing file)."""
    for needed in (("error", "allocated"), ("error", "tolerance", "unit")):
        if all(c in frame.columns for c in needed):
            return needed[1]
    missing_columns = [c for c in ("error", "allocated") if c not in frame.columns]
    raise InputError(f"{path}: missing column(s) {missing_columns}; expected columns "
                     f"'error' and 'allocated' (an allocation file) or 'error', "
                     f"'tolerance' and 'unit' (a drawing file)")


def _row_scales(units: pd.Series, names: pd.Series, given: pd.Series, path) -> np.ndarray:
    """How many of its row's unit one mm or rad is, each unit checked against its item."""
    scales = []
    for row, (unit, name) in enumerate(zip(units.astype(str).str.strip(), names)):
        unit = UNIT_SPELLINGS.get(unit, unit)
        allowed = LENGTH_UNITS if name.rpartition(".")[2].startswith("d") else ANGLE_UNITS
        if unit not in allowed:
            raise InputError(f"{path}: unit of {given[row]!r} is {unit!r}; expected one of "
                             f"{allowed} for a {'length' if allowed is LENGTH_UNITS else 'angle'}")
        scales.append(UNIT_SCALES[unit])
    return np.array(scales)


def _known(machine, name: str) -> bool:
    """Whether ``name`` is one of the machine's error names or ISO 230-1 symbols."""
    try:
        machine.error_index(name)
    except KeyError:
        return False
    return True


def save_allocation(result, path, overwrite: bool = False):
    """Write ``result`` as JSON (see :mod:`reliability.basics.saved_results`)."""
    return save_payload(path, KIND, allocation_payload(result), overwrite)


def allocation_payload(result) -> dict:
    """The JSON-ready fields :func:`save_allocation` writes (also inside other results)."""
    context = _context(result.problem)
    return {
        "machine": context.machine_name, "axes": context.axes, "units": context.units,
        "names": context.names, "reference": context.reference, "lower": context.lower,
        "upper": context.upper, "side": context.side, "workspace": context.workspace,
        "k": context.k, "n_poses": context.n_poses, "distribution": context.distribution,
        "cost_weights": context.cost.weights, "cost_groups": context.cost.groups,
        "cost_owners": context.cost.owners, "cost_k": context.cost.k,
        "method": result.method, "tolerances": result.tolerances, "cost": result.cost,
        "feasible": result.feasible, "certificate": result.certificate,
        "active": encode_frame(result.active), "history": encode_frame(result.history),
        "requirements": encode_frame(result.requirements)}


def load_allocation(cls, path, problem=None):
    """Reload a file written by :func:`save_allocation` as ``cls``, verifying every
    field; with ``problem``, check that it is the saved one and attach it."""
    if problem is not None and not all(hasattr(problem, a) for a in
                                       ("names", "reference", "lower", "upper", "side")):
        raise InputTypeError(f"problem must be an AllocationProblem; got "
                             f"{type(problem).__name__}")
    return allocation_from_payload(cls, load_payload(path, KIND), problem)


def allocation_from_payload(cls, data, problem=None):
    """The ``cls`` :func:`allocation_payload` wrote, read through ``data`` (a
    :class:`~reliability.basics.saved_results.PayloadReader`) and checked as
    :func:`load_allocation` says."""
    saved = _saved_problem(data)
    tolerances = data.array("tolerances", (len(saved.names),), positive=True)
    cost = data.number("cost", positive=True)
    if not np.isclose(cost, saved.cost.total(tolerances), rtol=COST_RTOL, atol=0):
        raise data.error("cost", f"{cost!r} is not the cost of the saved tolerances "
                                 f"({saved.cost.total(tolerances)!r})")
    outside = np.flatnonzero((tolerances < saved.lower * (1 - 1e-12))
                             | (tolerances > saved.upper * (1 + 1e-12)))
    if len(outside):
        raise data.error("tolerances", f"{saved.names[outside[0]]!r} lies outside its "
                                       f"bounds")
    certificate = data.table("certificate").data
    method = data.text("method", METHODS)
    _check_certificate(data, certificate, method)
    if problem is not None:
        _check_same_problem(data, saved, problem)
    return cls(problem=saved if problem is None else problem, method=method,
               tolerances=tolerances, cost=cost, feasible=data.boolean("feasible"),
               certificate=certificate, active=_active(data, saved),
               history=data.frame("history", columns=("cost",)),
               requirements=data.frame("requirements",
                                       columns=("binding_rows", "multiplier", "elasticity"),
                                       index=OUTPUTS))


def _saved_problem(data) -> SavedProblem:
    axes = data.texts("axes", unique=True)
    names = data.texts("names", unique=True)
    n = len(names)
    if n == 0:
        raise data.error("names", "expected at least one error name")
    lower = data.array("lower", (n,), positive=True)
    upper = data.array("upper", (n,), positive=True)
    bad = np.flatnonzero(lower > upper)
    if len(bad):
        raise data.error("lower", f"exceeds 'upper' for {names[bad[0]]!r}")
    groups = data.texts("cost_groups", size=n)
    if any(g not in GROUPS for g in groups):
        raise data.error("cost_groups", f"entries must be one of {GROUPS}")
    cost = CostModel(names=names, weights=data.array("cost_weights", (n,), low=0.0),
                     groups=groups, owners=data.texts("cost_owners", size=n),
                     k=tuple(data.array("cost_k", (3,), low=0.0)))
    return SavedProblem(
        machine_name=data.text("machine"), axes=axes,
        units=data.texts("units", size=len(axes)), names=names,
        reference=data.array("reference", (n,), positive=True), lower=lower, upper=upper,
        side=data.text("side", ("one_sided", "two_sided")),
        workspace=data.text("workspace", ("worst", "mean")),
        k=data.number("k", positive=True), n_poses=data.integer("n_poses", low=1), cost=cost,
        distribution=data.text("distribution", ("normal", "truncated"))
        if "distribution" in data.data else "normal")


def _check_certificate(data, certificate: dict, method: str) -> None:
    needed = {"exact": ("certified", "relative_gap"), "gwo": ("violation",),
              "compensated": ()}[method]
    part = data.table("certificate")
    for key in needed:
        if key == "certified":
            part.boolean(key)
        else:
            part.number(key)


def _active(data, saved: SavedProblem) -> pd.DataFrame:
    frame = data.frame("active")
    if len(frame.columns) == 0:
        return pd.DataFrame()
    frame = frame.reset_index(drop=True)  # the rows of 'active' are only numbered
    if len(frame) == 0:
        return frame
    if "output" not in frame or not frame["output"].isin(OUTPUTS).all():
        raise data.error("active", f"column 'output' must hold output names {OUTPUTS}")
    if "pose" in frame:
        pose = frame["pose"].to_numpy()
        if not (np.issubdtype(pose.dtype, np.integer) and ((pose >= 0)
                                                          & (pose < saved.n_poses)).all()):
            raise data.error("active", f"column 'pose' must hold pose numbers in "
                                       f"[0, {saved.n_poses})")
        missing = [a for a in saved.axes if a not in frame]
        if missing:
            raise data.error("active", f"lacks the position column of axis {missing[0]!r}")
    return frame


def _check_same_problem(data, saved: SavedProblem, problem) -> None:
    given = _context(problem)
    if tuple(given.names) != saved.names:
        raise data.error("names", "the given problem has other error names")
    for key in ("reference", "lower", "upper"):
        if not np.array_equal(getattr(given, key), getattr(saved, key)):
            raise data.error(key, f"differs from the given problem's {key}")
    for key in ("side", "workspace"):
        if getattr(given, key) != getattr(saved, key):
            raise data.error(key, f"{getattr(saved, key)!r} differs from the given "
                                  f"problem's {getattr(given, key)!r}")
