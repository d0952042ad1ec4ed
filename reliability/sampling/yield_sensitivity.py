"""What each tolerance buys: the derivative of the machine yield with respect to ``ln t_i``.

The machine yield ``Y(t) = P(a built machine passes)`` (:mod:`reliability.sampling.machine_yield`)
falls as a tolerance is loosened; ``∂Y/∂ln t_i`` is the change of the yield (a fraction) per
unit of ``ln t_i``, so loosening item ``i`` by 1 % changes the yield by about
``0.01 ∂Y/∂ln t_i`` and tightening it by 10 % by ``ln(0.9) ∂Y/∂ln t_i``. A group of items that
cannot be told apart (:func:`reliability.model.identifiability.indistinguishable_groups`) is
scaled together; its derivative is the sum of its members'.

Score function (likelihood ratio)
---------------------------------
Under the normal reading a built machine's errors are ``x = D(t) z`` with ``z = M u``: ``u`` the
yield's standard normal draws (:meth:`YieldModel.draws`), ``M`` the profile's factor along travel
times the item correlation's factor, ``D(t)`` the scale ``t/k`` of each item. Scaling ``t_i``
by ``1 + ε`` is the same as drawing ``u`` from ``N(0, Σ_ε)`` with ``Σ_ε = A Aᵀ``,
``A = I + ε M⁺ E_i M`` (``E_i`` selects item ``i``'s entries), so

    ∂Y/∂ln t_i = E[pass(u) s_i(u)],    s_i(u) = uᵀ M⁺ E_i M u − tr(M⁺ E_i M),

the score of the Gaussian family at ``ε = 0``. Per axis ``M = L_P ⊗ L_R`` (travel and item
factors) and the score reduces to ``s_i = Σ_pq a_pi Π_pq z_qi − r`` with ``Π = L_P⁺ L_P`` the
projector on the travel factor's rows, ``r`` its rank (1 under the constant profile, ``P``
otherwise), ``a = U L_R⁻¹`` and ``z = U L_Rᵀ`` (``U`` the axis' draws ``(P, 6)``); for an
assembly item ``s_i = a_i z_i − 1``. ``E[s_i] = 0``, so the estimate is the
sample covariance of the pass indicator and the score, which has a far smaller variance near a
yield of 1 than the plain mean; its standard error is the standard deviation of the centred
products over ``√N``. One evaluation of the chain per machine, the same as the yield itself,
gives every item's derivative.

Under the truncated reading the support ``±t_i`` moves with ``t_i`` and the score misses the
mass that crosses it, so that reading uses the check below instead.

Central differences with common random numbers
----------------------------------------------
``(Y(t e^{h e_i}) − Y(t e^{−h e_i})) / 2h`` with every machine drawn once (``u`` fixed): the two
yields differ only through the machines that flip, so the difference has a small variance. Its
standard error is that of the per-machine differences. It costs two evaluations of every
machine per item and carries a bias of order ``h²``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..basics import checks
from ..basics.errors import InputError
from ..basics.saved_fields import (Array, Integer, Number, Text, TextLists, Texts,
                                   load_fields, save_fields)
from ..model.error_draws import grid_factors
from ..model.identifiability import indistinguishable_groups
from ..model.profiles import travel_factors
from .machine_yield import DEFAULT_MACHINES

METHODS = ("auto", "score", "difference")
#: Half step ``h`` in ``ln t`` of the central differences.
DEFAULT_STEP = 0.1
#: Columns of :meth:`YieldSensitivity.to_frame` (and of ``yield_sensitivity.csv``).
SENSITIVITY_COLUMNS = ("error", "dyield_dlnt", "se")
#: Singular values of a travel factor below this share of its largest span no direction.
RANK_RTOL = 1e-10


@dataclass(frozen=True, eq=False)
class YieldSensitivity:
    """``∂ yield / ∂ ln t`` of every item and group of indistinguishable items.

    Attributes
    ----------
    errors : tuple of str
        Item names, then each group as its members joined by ``+``.
    members : tuple of tuple of str
        The items scaled together in each row.
    dyield_dlnt, se : ndarray
        The derivative (a fraction per unit of ``ln t``) and its standard error.
    yield_estimate : float
        The crude yield of the same machines.
    machines : int
    method : str
        ``'score'`` or ``'difference'``.
    step : float or None
        ``h`` of the central differences.
    """

    errors: tuple[str, ...]
    members: tuple[tuple[str, ...], ...]
    dyield_dlnt: np.ndarray
    se: np.ndarray
    yield_estimate: float
    machines: int
    method: str
    step: float | None = None

    def to_frame(self) -> pd.DataFrame:
        """``error, dyield_dlnt, se``, in the machine's order, groups last."""
        return pd.DataFrame({"error": list(self.errors), "dyield_dlnt": self.dyield_dlnt,
                             "se": self.se}, columns=list(SENSITIVITY_COLUMNS))

    def ranked(self) -> pd.DataFrame:
        """:meth:`to_frame` by decreasing ``|dyield_dlnt|``."""
        frame = self.to_frame()
        order = np.argsort(-np.abs(frame["dyield_dlnt"].to_numpy()), kind="stable")
        return frame.iloc[order].reset_index(drop=True)

    def summary(self, top: int = 10) -> str:
        """The ``top`` items and groups by ``|∂Y/∂ln t|``."""
        how = ("score function on the yield's own draws" if self.method == "score" else
               f"central differences (h = {self.step:g} in ln t, common random numbers)")
        lines = [f"d yield / d ln t of {len(self.errors)} items and groups, {how}; "
                 f"{self.machines} machines, yield {self.yield_estimate:.4f}"]
        for row in self.ranked().head(top).itertuples(index=False):
            lines.append(f"  {row.error:<24} {row.dyield_dlnt:+.5f} ± {row.se:.5f}")
        return "\n".join(lines)

    def save(self, path, overwrite: bool = False):
        """Save as JSON (:data:`SAVED_FIELDS`, tag :data:`SAVED_FORMAT`); an existing file
        is kept unless ``overwrite``. Returns the path."""
        return save_fields(self, path, SAVED_FORMAT, SAVED_FIELDS, overwrite)

    @classmethod
    def load(cls, path) -> "YieldSensitivity":
        """Reload derivatives written by :meth:`save`, every field checked (each row's name
        is its members joined by ``+``). A damaged field raises
        :class:`~reliability.basics.errors.SavedResultError` naming the file and field."""
        data, values = load_fields(path, SAVED_FORMAT, SAVED_FIELDS)
        joined = tuple("+".join(row) for row in values["members"])
        if joined != values["errors"]:
            raise data.error("members", "each row's members must join with '+' into its "
                                        "name in 'errors'")
        return cls(**values)


SAVED_FORMAT = "precrel.yield_sensitivity"
SAVED_FIELDS = (Texts("errors", "rows", unique=True), TextLists("members", "rows"),
                Array("dyield_dlnt", ("rows",)),
                Array("se", ("rows",), low=0.0), Number("yield_estimate", low=0.0, high=1.0),
                Integer("machines", low=1), Text("method", ("score", "difference")),
                Number("step", optional=True, positive=True))


def yield_sensitivity(model, tolerances, *, draws=None, machines: int = DEFAULT_MACHINES,
                      rng=None, method: str = "auto", step: float = DEFAULT_STEP,
                      errors=None, groups=None) -> YieldSensitivity:
    """``∂ yield / ∂ ln t_i`` of each item (and group) at an allocation, with standard errors.

    Parameters
    ----------
    model : YieldModel
        The machine, its profile, reading and grid (:class:`~reliability.sampling.machine_yield.YieldModel`).
    tolerances : array_like
        ``(n_errors,)`` allocation.
    draws : ndarray (machines, model.dimension), optional
        The standard normal draws of the built machines (:meth:`YieldModel.draws`); drawn
        from ``rng`` when not given.
    machines : int
        Built machines drawn when ``draws`` is not given.
    rng : None, int or numpy.random.Generator
    method : {'auto', 'score', 'difference'}
        ``'score'`` (normal reading only), ``'difference'`` (any reading); ``'auto'`` takes
        the score function under the normal reading.
    step : float
        ``h`` of the central differences, in ``ln t``.
    errors : sequence of str, optional
        The items to report (all by default).
    groups : sequence of sequence of str, optional
        Items scaled together, each group reported as one more row; the indistinguishable
        groups over the model's grid by default (only with ``errors`` not given).

    Returns
    -------
    YieldSensitivity
    """
    machine = model.machine
    t = checks.one_allocation(machine, tolerances)
    checks.choice(method, "method", METHODS)
    step = checks.finite_float(step, "step", 0.0, low_open=True)
    u = model.draws(machines, rng) if draws is None else _checked_draws(model, draws)
    if method == "auto":
        method = "score" if model.distribution == "normal" else "difference"
    if method == "score" and model.distribution != "normal":
        raise InputError(f"method 'score' needs the normal reading: under "
                         f"{model.distribution!r} the support ±t moves with t; use method "
                         f"'difference'")
    members = _rows(machine, model, errors, groups)
    passed = model.output_ratios(u, t).max(axis=1) < 1.0
    if method == "score":
        value, se = _score_estimates(model, u, passed, members)
    else:
        value, se = _difference_estimates(model, u, t, passed, members, step)
    return YieldSensitivity(errors=tuple("+".join(m) for m in members), members=members,
                            dyield_dlnt=value, se=se, yield_estimate=float(passed.mean()),
                            machines=len(u), method=method,
                            step=step if method == "difference" else None)


def item_scores(model, u) -> np.ndarray:
    """``(R, n_errors)``: the score ``s_i(u)`` of every item for draws ``u (R, dimension)``
    (the module's docstring); each has mean 0 under ``u ~ N(0, I)``."""
    machine = model.machine
    n, points = len(machine.axis_specs), model.experiment.points
    travel = travel_factors(machine, model.profiles, model.experiment.axis_points)
    if machine.correlation is None:
        item_factors = np.broadcast_to(np.eye(6), (n, 6, 6))
        assembly_factor = np.eye(6 * (n - 1))
    else:
        item_factors, assembly_factor = grid_factors(machine)
    projectors, ranks = zip(*(_row_projector(factor) for factor in travel))
    motion = u[:, :n * points * 6].reshape(len(u), n, points, 6)
    inverse = np.stack([_inverse(f, machine, a) for a, f in enumerate(item_factors)])
    a = np.einsum("Rapj,aji->Rapi", motion, inverse, optimize=True)
    z = np.einsum("Raqj,aij->Raqi", motion, item_factors, optimize=True)
    motion_score = np.einsum("Rapi,apq,Raqi->Rai", a, np.stack(projectors), z, optimize=True)
    motion_score -= np.asarray(ranks, dtype=float)[:, None]
    assembly = u[:, n * points * 6:]
    assembly_score = (assembly @ _inverse(assembly_factor, machine, None)) \
        * (assembly @ assembly_factor.T) - 1.0
    return np.concatenate([motion_score.reshape(len(u), -1), assembly_score], axis=1)


def _score_estimates(model, u, passed, members):
    scores = item_scores(model, u)
    index = [[model.machine.error_index(name) for name in row] for row in members]
    summed = np.stack([scores[:, row].sum(axis=1) for row in index], axis=1)
    products = (passed - passed.mean())[:, None] * (summed - summed.mean(axis=0))
    value, se = _mean_and_error(products)
    return value * len(u) / (len(u) - 1), se


def _difference_estimates(model, u, t, passed, members, step):
    terms = np.empty((len(u), len(members)))
    for column, row in enumerate(members):
        index = [model.machine.error_index(name) for name in row]
        looser, tighter = t.copy(), t.copy()
        looser[index] *= np.exp(step)
        tighter[index] *= np.exp(-step)
        up = model.output_ratios(u, looser).max(axis=1) < 1.0
        down = model.output_ratios(u, tighter).max(axis=1) < 1.0
        terms[:, column] = (up.astype(float) - down) / (2.0 * step)
    return _mean_and_error(terms)


def _mean_and_error(terms):
    return terms.mean(axis=0), terms.std(axis=0, ddof=1) / np.sqrt(len(terms))


def _rows(machine, model, errors, groups) -> tuple[tuple[str, ...], ...]:
    if errors is None:
        items = machine.error_names
        if groups is None:
            groups = indistinguishable_groups(machine, model.experiment.poses)
    else:
        items = tuple(machine.error_names[machine.error_index(name)] for name in errors)
    rows = [(name,) for name in items]
    for group in groups or ():
        rows.append(tuple(machine.error_names[machine.error_index(name)] for name in group))
    return tuple(rows)


def _checked_draws(model, draws) -> np.ndarray:
    u = np.asarray(draws, dtype=float)
    if u.ndim != 2 or u.shape[1] != model.dimension or len(u) < 2:
        raise InputError(f"draws: expected (machines >= 2, {model.dimension}) standard normal "
                         f"draws of the yield model; got shape {u.shape}")
    return u


def _row_projector(factor) -> tuple[np.ndarray, int]:
    """``L⁺ L``, the projector on the row space of a travel factor, and its rank."""
    _, values, rows = np.linalg.svd(factor)
    rank = int(np.sum(values > RANK_RTOL * values[0]))
    return rows[:rank].T @ rows[:rank], rank


def _inverse(factor, machine, axis) -> np.ndarray:
    """``L⁻¹`` of an item-correlation factor; a singular one (a pair at ρ = ±1) is refused:
    scaling one item of such a pair leaves the distribution's support."""
    if np.linalg.cond(factor) > 1e12:
        where = "assembly errors" if axis is None else f"axis {machine.axes[axis]}'s errors"
        raise InputError(f"machine {machine.name!r}: the correlation of the {where} is "
                         f"singular (a pair at ±1); the score function needs it invertible, "
                         f"use method 'difference'")
    return np.linalg.inv(factor)
