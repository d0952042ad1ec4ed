"""Compensation plans: a measurement plan (docs/measurements.md) plus a ``[compensation]``
table, ``spacing_mm``, ``spacing_deg``, optional ``items`` (default: every item the plan
informs), ``max_correction_mm`` and ``max_correction_rad`` (docs/compensation.md).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np

from ..basics.errors import InputError
from ..basics.files import read_toml
from ..measured.identification import plan_information
from ..measured.plans import parse_plan
from .residual import output_sigma, positioning_variance, residual_covariance, two_sided
from .tables import (DEFAULT_SPACING_DEG, DEFAULT_SPACING_MM, compensation_tables,
                     correction_limits, tabled_mask)

#: Keys of the ``[compensation]`` table.
PLAN_KEYS = ("spacing_mm", "spacing_deg", "items", "max_correction_mm", "max_correction_rad")
#: An item whose prior-scaled information is below this fraction of the largest is not
#: informed by the plan.
UNSEEN = 1e-12
#: The identification reads a tolerance t as σ = t / K.
K = 3.0


@dataclass(frozen=True, eq=False)
class CompensationPlan:
    """How machines will be measured and compensated.

    Attributes
    ----------
    machine : Machine
    runs : tuple of PlannedRun
    information : ndarray (n_errors, n_errors)
        The plan's information about the errors, set-ups eliminated.
    tabled : ndarray of bool (n_errors,)
        Items the table corrects.
    spacing_mm, spacing_deg : float
    max_correction_mm, max_correction_rad : float or None
        The table's range (None: none).
    """

    machine: object
    runs: tuple
    information: np.ndarray
    tabled: np.ndarray
    spacing_mm: float
    spacing_deg: float
    max_correction_mm: float | None = None
    max_correction_rad: float | None = None

    @property
    def max_correction(self) -> np.ndarray:
        """``(n_errors,)``: the table's range per item (mm, rad; inf: none)."""
        return correction_limits(self.machine, self.max_correction_mm,
                                 self.max_correction_rad)

    def tables(self, identification):
        """The compensation tables this plan writes from an identification."""
        return compensation_tables(
            identification, spacing_mm=self.spacing_mm, spacing_deg=self.spacing_deg,
            items=tuple(np.array(self.machine.error_names)[self.tabled]),
            max_correction_mm=self.max_correction_mm,
            max_correction_rad=self.max_correction_rad)

    @property
    def seen(self) -> np.ndarray:
        """Items the plan informs at all (a non-zero row of its information)."""
        scale = self.machine.initial_allocation / K
        scaled = np.abs(self.information) * np.outer(scale, scale)
        return scaled.max(axis=1) > UNSEEN * max(scaled.max(), 1e-300)

    def residual_covariance(self, tolerances) -> np.ndarray:
        """Covariance of the compensated machines' residual errors (mm, rad) for machines
        built to ``tolerances``."""
        t = self.machine.check_tolerances(tolerances)
        return residual_covariance(t / K, self.information, self.tabled)

    def sigma(self, tolerances, poses) -> np.ndarray:
        """``(n_poses, 6)``: σ of the six outputs after compensation, repeatability and
        reversal included (the machine's frame)."""
        return output_sigma(self.machine, poses, self.residual_covariance(tolerances),
                            positioning_variance(self.machine))

    def probability(self, tolerances, poses) -> np.ndarray:
        """``(n_poses, 6)``: FOSM two-sided probability of each output after compensation."""
        return two_sided(self.machine.limits, self.sigma(tolerances, poses))


def read_compensation_plan(path, machine) -> CompensationPlan:
    """Read a plan file with its ``[compensation]`` table."""
    data = read_toml(path)
    return parse_compensation_plan(data, machine, source=str(path))


def parse_compensation_plan(data: Mapping, machine, source: str = "plan") -> CompensationPlan:
    """Check a parsed plan and its ``[compensation]`` table; the plan's information is
    formed here."""
    table = data.get("compensation") if isinstance(data, Mapping) else None
    if not isinstance(table, Mapping):
        raise InputError(f"{source}: expected a [compensation] table with "
                         f"{', '.join(PLAN_KEYS)}")
    unknown = sorted(set(table) - set(PLAN_KEYS))
    if unknown:
        raise InputError(f"{source}, [compensation]: unknown key {unknown[0]!r}; allowed: "
                         f"{', '.join(PLAN_KEYS)}")
    runs = parse_plan(data, machine, source)
    information = plan_information(machine, runs)
    where = f"{source}, [compensation]"
    try:
        ranges = {key: table.get(key) for key in ("max_correction_mm", "max_correction_rad")}
        correction_limits(machine, *ranges.values())
        spacing = {key: _spacing(table, key) for key in ("spacing_mm", "spacing_deg")}
        plan = CompensationPlan(machine, runs, information,
                                np.ones(machine.n_errors, dtype=bool), **spacing, **ranges)
        tabled = plan.seen if table.get("items") is None else \
            tabled_mask(machine, _items(table["items"], where))
    except InputError as exc:
        raise InputError(f"{where}: {exc}") from None
    return CompensationPlan(machine, runs, information, tabled, **spacing, **ranges)


def _spacing(table, key) -> float:
    default = DEFAULT_SPACING_MM if key == "spacing_mm" else DEFAULT_SPACING_DEG
    value = table.get(key, default)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0:
        raise InputError(f"key {key!r}: expected a number > 0; got {value!r}")
    return float(value)


def _items(value, where):
    if not isinstance(value, list) or not value or not all(isinstance(v, str) for v in value):
        raise InputError(f"key 'items': expected a list of error names or ISO symbols; got "
                         f"{value!r}")
    return value
