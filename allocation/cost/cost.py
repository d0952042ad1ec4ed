"""Power-exponent precision-cost model of a serial machine (Sec. 4.2, Eqs. 25-28).

Every geometric error ``i`` with tolerance ``t_i`` costs ``w_i / t_i**2``; the weight
``w_i`` depends on what the error is:

* linear axis moving along ``D`` with guide length ``L`` (m): its positioning error
  ``"d<D>"`` costs ``a / t**2``, its other five errors ``b L / t**2`` (Eq. 25);
* rotary axis turning about ``D`` with rotation diameter ``D_r`` (m): its angular
  positioning error ``"e<D>"`` costs ``c / t**2``, its other five errors
  ``d D_r / t**2`` (Eq. 26);
* assembly error of joint ``j``: ``m_j / t**2`` for each of its six components (Eq. 27).

The machine cost is ``F = k1 sum F_linear + k2 sum F_rotary + k3 sum F_assembly``
(Eq. 28), so ``F = sum_i w_i / t_i**2`` with the group factor folded into ``w_i``.

**Units.** ``t`` in ``w / t**2`` is expressed in the machine file's cost units
(``[cost] units = { length = "mm" | "um", angle = "rad" | "urad" | "arcsec" }``; mm and rad
when not stated), so the weight of an item is ``w / s**2`` per mm or rad, with ``s`` the
number of cost units in one mm or rad. The units decide how translational and angular items
weigh against each other: in mm and rad an angular item at 1.45e-5 rad weighs about 4e4
times a translational one at 0.003 mm, and the optimiser leaves the translational items to
their bounds (see docs/cost-units.md).

The paper does not publish ``k1``, ``k2``, ``k3``; they default to 1 here. For that reason
the absolute costs of Table 7 (1.0065e10 initial, 9.0886e9 optimised) cannot be
recomputed: with ``k = (1, 1, 1)`` the initial allocation of Table 4 costs 4.277e11
(linear 2.354e11, rotary 9.94e10, assembly 9.29e10). Ratios between allocations under
one set of ``k`` are what this model gives.

The machine is read through a small contract, so any serial machine works:
``machine.axis_specs`` (axes with ``name``, ``kind`` 'linear'/'rotary', ``direction``
'x'/'y'/'z', ``size`` in m), ``machine.joints`` (joint names), ``machine.error_names``
(``"<axis>.<comp>"`` then ``"<joint>.<comp>"``, comp in ``dx dy dz ex ey ez``) and
``machine.cost_coefficients`` (``a``, ``b``, ``c``, ``d`` and a mapping ``assembly``
joint -> ``m_j``).
"""

from dataclasses import dataclass
from math import isfinite

import numpy as np
import pandas as pd

from reliability.basics import checks
from reliability.basics.errors import InputError, MachineDescriptionError

__all__ = ["COMPONENTS", "GROUPS", "CostModel", "cost_weights"]

#: Error components of every axis and joint, in the order of the error names.
COMPONENTS = ("dx", "dy", "dz", "ex", "ey", "ez")
#: The three cost groups of Eq. 28, in the order of ``k1``, ``k2``, ``k3``.
GROUPS = ("linear", "rotary", "assembly")


@dataclass(frozen=True, eq=False)
class CostModel:
    """The cost ``F(t) = sum_i w_i / t_i**2`` of a machine's tolerance allocation.

    Build it with :meth:`from_machine`.

    Attributes
    ----------
    names : tuple of str
        Error names, in the machine's order.
    weights : numpy.ndarray, shape (n_errors,)
        ``w_i`` including the group factor ``k1``, ``k2`` or ``k3`` (Eq. 28).
    groups : tuple of str
        ``'linear'``, ``'rotary'`` or ``'assembly'`` for each error.
    owners : tuple of str
        The axis or joint each error belongs to.
    k : tuple of float
        The group factors ``(k1, k2, k3)``.
    units : tuple of str or None
        ``(length, angle)`` units of t inside the cost; None: not stated (mm, rad).
    """

    names: tuple
    weights: np.ndarray
    groups: tuple
    owners: tuple
    k: tuple
    units: tuple | None = None

    @classmethod
    def from_machine(cls, machine, k1=1.0, k2=1.0, k3=1.0):
        """Build the cost model of ``machine`` (Eqs. 25-28).

        Parameters
        ----------
        machine : object
            A machine exposing ``axis_specs``, ``joints``, ``error_names`` and
            ``cost_coefficients`` (see the module docstring).
        k1, k2, k3 : float, optional
            Weights of the linear-axis, rotary-axis and assembly costs (Eq. 28); finite
            and non-negative. The paper does not publish them; default 1.

        Returns
        -------
        CostModel

        Raises
        ------
        MachineDescriptionError
            If the machine description is inconsistent (the message names the axis,
            joint, coefficient or error name at fault).
        InputError
            If a group factor is negative or not finite.
        """
        k = _check_group_factors((k1, k2, k3))
        items = _cost_items(machine)
        names = tuple(machine.error_names)
        _check_names_match(names, items)
        groups = tuple(items[name][0] for name in names)
        owners = tuple(items[name][1] for name in names)
        factor = dict(zip(GROUPS, k))
        coefficients = machine.cost_coefficients
        length, angle = getattr(coefficients, "unit_scales", (1.0, 1.0))
        scale = np.array([angle if name.split(".")[-1].startswith("e") else length
                          for name in names])
        weights = np.array(
            [factor[items[name][0]] * items[name][2] for name in names]  # Eq. (28)
        ) / np.square(scale)
        weights.setflags(write=False)
        return cls(names=names, weights=weights, groups=groups, owners=owners, k=k,
                   units=getattr(coefficients, "units", None))

    def shares(self, t) -> pd.DataFrame:
        """Each group's share of the cost at ``t``, split into translational and angular
        items: rows ``linear``, ``rotary``, ``assembly``, columns ``translational`` and
        ``angular`` (fractions summing to 1)."""
        costs = np.asarray(self.item_costs(t), dtype=float)
        angular = np.array([name.split(".")[-1].startswith("e") for name in self.names])
        frame = pd.DataFrame(0.0, index=pd.Index(GROUPS, name="group"),
                             columns=["translational", "angular"])
        for group, is_angular, cost in zip(self.groups, angular, costs):
            frame.loc[group, "angular" if is_angular else "translational"] += cost
        return frame / costs.sum()

    @property
    def n_errors(self):
        """Number of errors (length of a tolerance vector)."""
        return len(self.names)

    def item_costs(self, t):
        """Cost of every error, ``w_i / t_i**2``.

        Parameters
        ----------
        t : array_like, shape (..., n_errors)
            Tolerances (mm or rad), finite and > 0.

        Returns
        -------
        numpy.ndarray, shape (..., n_errors)
        """
        t = self._check_tolerances(t)
        return self.weights / t**2  # Eqs. (25)-(27), k folded into the weights

    def total(self, t):
        """Total cost ``F`` of one or many allocations (Eq. 28).

        Parameters
        ----------
        t : array_like, shape (..., n_errors)
            Tolerances (mm or rad), finite and > 0.

        Returns
        -------
        float or numpy.ndarray, shape (...)
            A float for a single allocation.
        """
        total = self.item_costs(t).sum(axis=-1)  # Eq. (28)
        return float(total) if total.ndim == 0 else total

    def breakdown(self, t):
        """Tabulate the cost of one allocation item by item.

        Parameters
        ----------
        t : array_like, shape (n_errors,)
            Tolerances (mm or rad), finite and > 0.

        Returns
        -------
        pandas.DataFrame
            Index: error names. Columns ``group``, ``owner``, ``weight``,
            ``tolerance``, ``cost`` and ``share`` (of the total cost).
        """
        t = self._check_single(t)
        cost = self.item_costs(t)
        return self.to_frame().assign(tolerance=t, cost=cost, share=cost / cost.sum())

    def to_frame(self):
        """The weights item by item.

        Returns
        -------
        pandas.DataFrame
            Index: error names. Columns ``group``, ``owner`` and ``weight``.
        """
        return pd.DataFrame(
            {"group": self.groups, "owner": self.owners, "weight": self.weights},
            index=pd.Index(self.names, name="error"),
        )

    def by_group(self, t):
        """Cost of one allocation per group of Eq. 28, and the total.

        Parameters
        ----------
        t : array_like, shape (n_errors,)
            Tolerances (mm or rad), finite and > 0.

        Returns
        -------
        pandas.Series
            Index ``linear``, ``rotary``, ``assembly``, ``total``; the group sums
            already include ``k1``, ``k2``, ``k3``.
        """
        cost = self.breakdown(t)["cost"]
        sums = cost.groupby(np.asarray(self.groups)).sum().reindex(GROUPS, fill_value=0.0)
        sums["total"] = cost.sum()  # Eq. (28)
        sums.name = "cost"
        return sums

    def _check_single(self, t):
        t = checks.labelled(t, self.names, "tolerances")
        if t.shape != (self.n_errors,):
            raise InputError(
                f"expected one allocation of shape ({self.n_errors},), got shape {t.shape}"
            )
        return t

    def _check_tolerances(self, t):
        t = checks.labelled(t, self.names, "tolerances")
        if t.ndim == 0 or t.shape[-1] != self.n_errors:
            raise InputError(
                f"expected tolerances of shape (..., {self.n_errors}), got shape {t.shape}"
            )
        bad = np.argwhere(~(np.isfinite(t) & (t > 0)))
        if bad.size:
            where = tuple(int(i) for i in bad[0])
            batch = f" at batch index {where[:-1]}" if t.ndim > 1 else ""
            raise InputError(
                f"tolerance of {self.names[where[-1]]!r}{batch} is {t[where]}; "
                "tolerances must be finite and > 0"
            )
        return t


def cost_weights(machine, k=(1.0, 1.0, 1.0)):
    """Weights ``w_i`` such that the machine cost is ``F = sum_i w_i / t_i**2``.

    Parameters
    ----------
    machine : object
        A machine exposing ``axis_specs``, ``joints``, ``error_names`` and
        ``cost_coefficients`` (see the module docstring).
    k : sequence of 3 floats, optional
        ``(k1, k2, k3)`` of Eq. 28, default ``(1, 1, 1)``.

    Returns
    -------
    numpy.ndarray, shape (n_errors,)
        In the order of ``machine.error_names``.

    Notes
    -----
    For the paper's machine (Tables 3, 5) ``X.dx`` has weight ``a = 1.98``, ``X.dy``
    has ``b L_x = 1.5 * 4``, ``C.ez`` has ``c = 1.83`` and ``C.dx`` has ``d D_C = 1.4 * 3``.
    """
    if len(k) != 3:
        raise InputError(f"k must hold (k1, k2, k3), got {len(k)} values")
    return CostModel.from_machine(machine, *k).weights


def _cost_items(machine):
    """Map every error name the machine's axes and joints define to (group, owner, w)."""
    coefficients = _check_coefficients(machine.cost_coefficients, machine.joints)
    items = {}
    for axis in machine.axis_specs:
        _check_axis(axis)
        group, main, other = _axis_coefficients(axis, coefficients)
        for comp in COMPONENTS:
            is_main = comp == ("d" if axis.kind == "linear" else "e") + axis.direction
            weight = main if is_main else other  # Eq. (25): a, b L; Eq. (26): c, d D
            items[f"{axis.name}.{comp}"] = (group, axis.name, weight)
    for joint in machine.joints:
        m_joint = coefficients["assembly"][joint]
        for comp in COMPONENTS:
            items[f"{joint}.{comp}"] = ("assembly", joint, m_joint)  # Eq. (27)
    return items


def _axis_coefficients(axis, coefficients):
    main, other = ("a", "b") if axis.kind == "linear" else ("c", "d")
    for field in (main, other):
        if coefficients[field] is None:
            raise MachineDescriptionError(f"{axis.kind} axis {axis.name!r} needs cost "
                                          f"coefficient {field}")
    return axis.kind, coefficients[main], coefficients[other] * axis.size


def _check_axis(axis):
    if axis.kind not in ("linear", "rotary"):
        raise MachineDescriptionError(
            f"axis {axis.name!r} has kind {axis.kind!r}; expected 'linear' or 'rotary'"
        )
    if axis.direction not in ("x", "y", "z"):
        raise MachineDescriptionError(
            f"axis {axis.name!r} has direction {axis.direction!r}; expected 'x', 'y' or 'z'"
        )
    if not (isfinite(axis.size) and axis.size > 0):
        raise MachineDescriptionError(
            f"axis {axis.name!r} has size {axis.size!r}; the guide length or rotation "
            "diameter must be finite and > 0"
        )


def _check_coefficients(cost_coefficients, joints):
    coefficients = {}
    for field in ("a", "b", "c", "d"):
        value = getattr(cost_coefficients, field)
        coefficients[field] = None if value is None else _nonnegative(
            value, f"cost coefficient {field}", MachineDescriptionError
        )
    assembly = dict(cost_coefficients.assembly)
    missing = [joint for joint in joints if joint not in assembly]
    if missing:
        raise MachineDescriptionError(f"no assembly cost coefficient for joint(s) {missing}")
    unknown = [joint for joint in assembly if joint not in joints]
    if unknown:
        raise MachineDescriptionError(
            f"assembly cost coefficient(s) given for unknown joint(s) {unknown}; "
            f"the machine's joints are {list(joints)}"
        )
    coefficients["assembly"] = {
        joint: _nonnegative(value, f"assembly cost coefficient of joint {joint!r}",
                            MachineDescriptionError)
        for joint, value in assembly.items()
    }
    return coefficients


def _check_group_factors(k):
    return tuple(_nonnegative(value, f"k{i}") for i, value in enumerate(k, start=1))


def _nonnegative(value, what, error=InputError):
    """``value`` as a float, finite and >= 0, or ``error`` naming ``what``."""
    value = float(checks.numeric_array(value, what, ndim=0))
    if not (isfinite(value) and value >= 0):
        raise error(f"{what} is {value!r}; it must be finite and >= 0")
    return value


def _check_names_match(names, items):
    unknown = [name for name in names if name not in items]
    if unknown:
        raise MachineDescriptionError(
            f"error name {unknown[0]!r} is not a component of any axis in "
            "machine.axis_specs or joint in machine.joints"
        )
    if len(set(names)) != len(names):
        duplicate = next(name for name in names if names.count(name) > 1)
        raise MachineDescriptionError(f"error name {duplicate!r} appears more than once")
    missing = [name for name in items if name not in set(names)]
    if missing:
        raise MachineDescriptionError(
            f"machine.error_names lacks {missing[0]!r} (and {len(missing) - 1} more) "
            "that the axes and joints define"
        )
