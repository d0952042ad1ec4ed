"""The worst pose over the continuous workspace, with a certificate (docs/certified-workspace.md).

Eq. (35) asks the targets over the whole stroke of every axis. For each output o,
:func:`certified_worst` finds a pose q* and a rigorous upper bound ``U`` of the output's
spread over the stroke box, with ``(U − value(q*))/value(q*) ≤ rtol``, by branch and bound
over pose boxes. Two readings of the spread:

* ``'sigma'``: ``σ_o(q) = (Σ_i J_oi(q)² σ_i²)^½`` (Eq. 20). σ² is an exact per-axis
  expansion (:func:`reliability.first_order.pose_expansion.variance_expansion`); on a box of centre
  c and half-widths h, Taylor's theorem with the Lagrange remainder gives

      σ²(c + d) ≤ σ²(c) + Σ_a h_a |g_a(c)| + ½ Σ_a h_a² max(H_aa, 0) + Σ_{a<b} h_a h_b |H_ab|

  with the gradient g exact at the centre and the Hessian H enclosed over the box from
  the expansion's coefficients (each basis function's range on an interval is exact);
* ``'stack'``: the first-order worst-case stack ``s_o(q) = Σ_i |J_oi(q)| t_i`` (the
  classical reading of :mod:`allocation.per_pose.problem`'s ``side='stack'``). Each weighted entry
  ``w_i = J_oi t_i`` is an exact per-axis expansion
  (:func:`reliability.first_order.pose_expansion.jacobian_expansion`); on a box
  ``w_i(c + d) = w_i(c) + ∇w_i(c)·d + r_i`` with ``|r_i| ≤ ½ Σ_ab h_a h_b K_i,ab`` and
  ``K_i,ab`` a bound of ``|∂_ab w_i|`` over the strokes (:func:`curvature_bound`), so
  ``s(c + d) ≤ max over the box's vertices of Σ_i |w_i(c) + ∇w_i(c)·d| + Σ_i max|r_i|``
  (a sum of absolute values of affine functions is convex, so its maximum over a box is
  at a vertex).

**Branch and bound.** Every step evaluates all open boxes at once (in chunks): the bound,
and two candidates, the centre and the vertex that maximises the box's linear model (so
that a maximum on the stroke's boundary is approached to second order). Boxes whose bound
is at most ``(1 + rtol)`` times the best candidate (on σ, so ``(1 + rtol)²`` on σ²) are
closed; the others are halved along the axis contributing most to their bound. An axis the
spread does not depend on contributes exactly nothing and is never split. The first
candidate is the best point of a coarse grid, improved for σ by a bounded local search on
the expansion (L-BFGS-B), which also polishes the final candidate
(:mod:`reliability.first_order.box_models` holds both readings' bounds and starts). For the
allocation loop the search can stop early: at the first candidate above a value
(``stop_above``, a cut), at a deadline, and it can close boxes below a value whatever the
best candidate (``close_below``, a feasibility test).

**A work zone.** On a machine with a work zone (:mod:`reliability.model.work_zone`) the
workspace is the zone's poses. Each open box is classified by the enclosure of its tool
point and tilt (:class:`reliability.first_order.zone_enclosure.ZoneEnclosure`): a box proved
outside the zone is dropped, a box proved inside is searched as above, and a box across the
boundary is kept whole, never replaced by a face (the face may lie outside the zone), and
bounded by the lower of its whole-box bound and the bound of the Lagrangian ``σ² − λ·g``
(or stack ``− λ·g``) of the zone's constraints ``g ≤ 0``
(:mod:`reliability.first_order.zone_bound`), with λ the multipliers at the best candidates
or fitted to the box: any ``λ ≥ 0`` bounds the spread over the box's poses in the zone, and the
multipliers of the worst pose make the bound close to second order there. It is halved by
its shares of the bound and of the stroke and by its part of the enclosures that reach
across the zone's limits. Only candidates inside the zone count, the local searches are
constrained to it (SLSQP), and every axis keeps the position its candidate was found at.
"""

from __future__ import annotations

import time

import numpy as np
import pandas as pd

from ..basics import checks
from ..basics.chunks import chunks
from ..basics.errors import InputError
from ..basics.files import rounded_up
from ..basics.ties import SEARCH_RTOL, TIE_RTOL, worst_rows
from ..model.error_draws import DISTRIBUTIONS
from ..model.kinematics import jacobian, output_variance
from ..model.machine import OUTPUTS
from .box_models import BOX_MEMORY, SigmaModel, StackModel, rising_step
from .canonical_maxima import NearCandidates, representatives, snap_positions
from .fosm import error_sigma
from .pose_expansion import jacobian_expansion, point_tree, variance_expansion
from .zone_bound import ZoneConstraints
from .zone_enclosure import ZoneEnclosure

#: The spreads the certificate can bound: σ (Eq. 20) or the first-order worst-case stack.
READINGS = ("sigma", "stack")
#: The pose sets a study can ask for: the continuous strokes (certified) or the grid.
WORKSPACES = ("continuous", "grid")
#: Relative tolerance in σ (or the stack) of the certificate when a study does not say.
DEFAULT_RTOL = 1e-3
#: Box evaluations one output may spend before the search stops uncertified.
MAX_BOX_CALLS = 2_000_000
#: Relative margin below ``1 + rtol`` at which a box is closed, so that the value at the
#: reported pose recomputed from the chain (equal to the expansion's to about 1e-15) still
#: meets ``rtol``.
CLOSING_MARGIN = 1e-9
#: Significant digits of a reported gap (rounded up: it bounds the relative distance of
#: the reported value from the largest).
GAP_DIGITS = 2
#: Fraction of a stroke's span within which a reported position is put on the stroke's end.
END_SNAP = 1e-12
#: Best candidates (work zone) from which the search on the boundary starts and at which
#: the constraints' multipliers are taken.
MULTIPLIER_POINTS = 4
#: Sets of multipliers (work zone) from the best candidates, the latest first, whose
#: Lagrangians bound the boxes across the boundary, beside one fitted to each box.
MULTIPLIER_SETS = 4
#: Sweeps of coordinate descent that fit a box's own multipliers.
FIT_SWEEPS = 3
#: Box evaluations every output's search makes before it stops at a deadline already
#: passed, so that an output reached late still has a useful bound (about a second).
DEADLINE_CALLS = 2000


def certified_worst(machine, tolerances, *, rtol: float = DEFAULT_RTOL, k: float = 3.0,
                    distribution: str | None = None, reading: str = "sigma",
                    max_calls: int = MAX_BOX_CALLS, memory: int | None = None,
                    stop_above=None, close_below=None,
                    deadline: float | None = None, outputs=None,
                    feasibility: bool = False) -> pd.DataFrame:
    """Largest σ (or worst-case stack) of each output over the continuous stroke box, with
    a rigorous bound.

    Parameters
    ----------
    machine : Machine
        With independent errors (``machine.correlation`` None); the outputs are read in
        ``machine.frame`` (tool, Eq. 18, or workpiece).
    tolerances : array_like
        ``(n_errors,)`` allocation, read as ±kσ.
    rtol : float
        Relative gap ``bound/value − 1`` at which the search stops, in (0, 1).
    k : float
        Coverage factor (σ reading).
    distribution : {'normal', 'truncated'}, optional
        Reading of a tolerance for σ (:func:`reliability.first_order.fosm.error_sigma`);
        ``machine.distribution`` by default. The stack uses the tolerances themselves.
    reading : {'sigma', 'stack'}
        The certified spread: σ (Eq. 20) or the worst-case stack ``Σ_i |J_oi| t_i``.
    max_calls : int
        Box evaluations per output before the search stops with ``certified`` False.
    memory : int, optional
        Bytes of temporary arrays per chunk of boxes (:data:`BOX_MEMORY` by default).
    stop_above : array_like, optional
        ``(6,)`` values (σ or the stack, per output): an output's search stops as soon as
        it meets a pose where the value exceeds its entry, and reports that pose with
        the bound ``+inf`` (nothing bounded, ``certified`` False). A search that never
        meets one runs as without ``stop_above`` and gives the same row. The cutting-plane
        loop (:func:`allocation.per_pose.continuous.solve_continuous`) passes what the
        targets allow, so that a certificate at an allocation that is short somewhere
        returns its cuts without proving the rest.
    close_below : array_like, optional
        ``(6,)`` values (σ or the stack, per output), used once an output (in the order
        of :data:`OUTPUTS`) has stopped at a pose above ``stop_above``, i.e. when the
        table is a search for cuts rather than a certificate: in the outputs after it, a
        box whose bound is at most the entry is closed whatever the best candidate (the
        feasibility test "is the spread anywhere above this?"), so their bound stays at
        most ``max(close_below, (1 + rtol) × value)`` and ``gap`` may exceed ``rtol``.
    deadline : float, optional
        A :func:`time.perf_counter` time after which every output's search stops as at
        ``max_calls`` once it has evaluated :data:`DEADLINE_CALLS` boxes: the boxes still
        open count in the bound (rigorous, with a wider gap), ``certified`` False unless the
        gap is met.
    outputs : sequence of str, optional
        Certify only these outputs (names of :data:`OUTPUTS`, in that order in the table);
        default all six. The life allocation certifies each output under its own
        allocation (:mod:`allocation.per_pose.life`).
    feasibility : bool
        Apply ``close_below`` from the first output on, not only after an output has
        stopped: every output's table then answers "is the spread anywhere above
        ``close_below``?" (its bound at most ``max(close_below, (1 + rtol) × value)``), which
        is what the life allocation's certificate asks.

    Returns
    -------
    pandas.DataFrame
        Indexed by output: the pose (one column per axis, mm or rad); ``sigma`` there and
        ``sigma_bound`` (an upper bound of σ over every pose of the strokes, or of the
        machine's work zone when it has one), or ``stack``
        and ``stack_bound`` under ``reading='stack'``; ``gap`` (``bound/value − 1``,
        rounded up to :data:`GAP_DIGITS` digits and at least :data:`CLOSING_MARGIN`),
        ``certified`` (gap ≤ rtol), ``calls`` (boxes evaluated), ``open`` (boxes still
        open when the search stopped: 0 unless stopped by ``max_calls``, ``deadline`` or
        ``stop_above``), ``seconds`` (the search
        and a sixth of the expansion's time, so the column sums to the total). The value
        at the pose is computed from the chain itself; the local maxima of every region of
        near-best candidates are polished and rounded to the pose resolution
        (:mod:`reliability.first_order.canonical_maxima`), and among those within
        :data:`reliability.basics.ties.SEARCH_RTOL` of the largest the first in
        lexicographic order is reported (:func:`reliability.basics.ties.worst_rows`), so
        that symmetric twins give the same pose on every computer. ``attrs`` holds ``rtol``,
        ``distribution`` and ``reading``.

    Raises
    ------
    InputError
        For a bad ``rtol``, ``k``, ``distribution``, ``reading``, ``max_calls``,
        ``stop_above``, ``deadline`` or allocation, correlated errors, or a machine whose
        chain fails the expansion check (:mod:`reliability.first_order.pose_expansion`).
    """
    rtol = checks.finite_float(rtol, "rtol", 0.0, 1.0, low_open=True, high_open=True)
    reading = checks.choice(reading, "reading", READINGS)
    max_calls = checks.positive_int(max_calls, "max_calls")
    if machine.correlation is not None:
        raise InputError("machine: certified_worst bounds σ² = Σ J² σ² of independent "
                         "errors; this machine's errors are correlated")
    t = machine.check_tolerances(tolerances)
    if t.ndim != 1:
        raise InputError(f"tolerances must be one allocation of shape ({machine.n_errors},)")
    distribution = machine.distribution if distribution is None else distribution
    checks.choice(distribution, "distribution", DISTRIBUTIONS)
    k = checks.finite_float(k, "k", 0.0, low_open=True)
    above = _output_values(stop_above, "stop_above", np.inf)
    below = _output_values(close_below, "close_below", 0.0)
    if deadline is not None:
        deadline = checks.finite_float(deadline, "deadline")
    chosen = _chosen_outputs(outputs)
    started = time.perf_counter()
    if reading == "sigma":
        variance = np.square(error_sigma(t, k, distribution))
        expansion = variance_expansion(machine, variance, machine.frame)
        models = [SigmaModel(expansion.restricted(o)) for o in range(len(OUTPUTS))]

        def direct(q, o):
            return np.sqrt(output_variance(machine, q, variance, machine.frame)[:, o])
    else:
        expansion = jacobian_expansion(machine, t, machine.frame)
        models = [StackModel(expansion.restricted(o)) for o in range(len(OUTPUTS))]

        def direct(q, o):
            return np.abs(jacobian(machine, q, machine.frame)[:, o, :]) @ t
    zone = None if machine.work_zone is None else ZoneEnclosure(machine)
    shared = (time.perf_counter() - started) / len(chosen)  # the expansion, per output
    rows = []
    for o in chosen:
        stopped = feasibility or any(np.isinf(row[f"{reading}_bound"]) for row in rows)
        rows.append(_certify(machine, models[o], lambda q, o=o: direct(q, o), rtol, max_calls,
                             memory, reading, shared, zone,
                             (above[o], below[o] if stopped else 0.0, deadline)))
    frame = pd.DataFrame(rows, index=pd.Index([OUTPUTS[o] for o in chosen], name="output"))
    frame.attrs.update(rtol=rtol, distribution=distribution, reading=reading)
    return frame


def _chosen_outputs(outputs) -> list[int]:
    """Indices of ``outputs`` (names of :data:`OUTPUTS`) in the order of :data:`OUTPUTS`;
    all six when None."""
    if outputs is None:
        return list(range(len(OUTPUTS)))
    names = [outputs] if isinstance(outputs, str) else list(outputs)
    unknown = [name for name in names if name not in OUTPUTS]
    if unknown or not names:
        raise InputError(f"outputs must name one or more of {OUTPUTS}; got {outputs!r}")
    return sorted({OUTPUTS.index(name) for name in names})


def _output_values(values, name, default) -> np.ndarray:
    """``values`` checked: ``(6,)`` positive values, or ``default`` for each output
    without them."""
    if values is None:
        return np.full(len(OUTPUTS), default)
    array = checks.numeric_array(values, name, 1)
    if array.shape != (len(OUTPUTS),) or not np.all(array > 0):
        raise InputError(f"{name} must hold one positive value per output "
                         f"({len(OUTPUTS)}); got {array.tolist()}")
    return array


def _certify(machine, model, direct, rtol, max_calls, memory, reading, shared,
             zone=None, ends=(np.inf, 0.0, None)) -> dict:
    """One output's row: branch and bound on the model (in the work zone ``zone``, if
    any; ``ends`` = (stop above, close below, deadline) as in :func:`certified_worst`),
    the value at the reported pose from the chain itself; ``shared`` seconds (its share of
    the expansion) added to its time."""
    above, below, deadline = ends
    started = time.perf_counter() - shared
    low, high = model.local_strokes(machine)
    tied, bound, calls, still_open = branch_and_bound(
        model, low, high, rtol, max_calls, memory, zone,
        above=model.function_of(above), below=model.function_of(below), deadline=deadline)
    if zone is None:
        tied[:, model.fixed] = low[model.fixed]  # axes the spread does not depend on
    poses = _snapped_poses(machine, model, _onto_ends(tied, low, high), zone)
    values = direct(poses)
    choice = worst_rows(values, poses, rtol=SEARCH_RTOL)
    value = float(values[choice])
    bound = max(model.spread(bound), value)
    row = dict(zip(machine.axes, poses[choice]))
    row.update({reading: value, f"{reading}_bound": bound, "gap": _gap(bound, value),
                "certified": bool(bound <= value * (1 + rtol)), "calls": int(calls),
                "open": int(still_open), "seconds": time.perf_counter() - started})
    return row


def _gap(bound, value) -> float:
    """``bound/value − 1`` as the upper bound it is: at least :data:`CLOSING_MARGIN` (below
    it the gap is the rounding of the bound's terms, which differs between computers) and
    rounded up to :data:`GAP_DIGITS` significant digits; infinite when the search stopped
    without a bound (``stop_above``) or the value is 0 and the bound is not."""
    gap = bound / value - 1.0 if value > 0 else (0.0 if bound <= 0 else np.inf)
    return float(rounded_up(max(gap, CLOSING_MARGIN), GAP_DIGITS)) if np.isfinite(gap) \
        else float(gap)


def _snapped_poses(machine, model, points, zone):
    """The poses of local ``points``, each rounded to the resolution of the strokes
    (:func:`reliability.first_order.canonical_maxima.snap_positions`) where the rounded pose
    stays in the work zone, so that the same maximum reads the same on every computer."""
    poses = model.expansion.pose(np.unique(points, axis=0))
    low = np.array([axis.stroke[0] for axis in machine.axis_specs], dtype=float)
    high = np.array([axis.stroke[1] for axis in machine.axis_specs], dtype=float)
    snapped = snap_positions(poses, low, high)
    if zone is not None:
        snapped = np.where(zone.contains(snapped)[:, None], snapped, poses)
    return np.unique(snapped, axis=0)


def _onto_ends(points, low, high):
    """Points within :data:`END_SNAP` of the span from a stroke's end put on the end, so
    that a worst pose at the end of a stroke reads as that end rather than as a rounding
    residue of a local search."""
    near = END_SNAP * (high - low)
    points = np.where(points - low <= near, low, points)
    return np.where(high - points <= near, high, points)


def branch_and_bound(model, low, high, rtol, max_calls, memory=None, zone=None, *,
                     above=np.inf, below=0.0, deadline=None):
    """Branch and bound of one model over the box ``[low, high]`` of local coordinates, or
    over its poses in a work zone.

    Parameters
    ----------
    model : SigmaModel or StackModel
        Its ``boxes(low, high)`` gives, per box, a rigorous upper bound of the model's
        function, each axis' contribution to it and the box's best candidate point.
    low, high : ndarray (n_axes,)
    rtol : float
        Relative tolerance on the spread (``model.spread`` of the function).
    max_calls : int
    memory : int, optional
    zone : ZoneEnclosure, optional
        The machine's work zone (module docstring); None for the whole box.
    above : float
        Stop as soon as a candidate's function value exceeds it; the bound is then
        ``+inf``.
    below : float
        Close a box whose bound is at most this function value, whatever the best
        candidate.
    deadline : float, optional
        :func:`time.perf_counter` time after which the search stops as at ``max_calls``,
        once it has evaluated :data:`DEADLINE_CALLS` boxes.

    Returns
    -------
    tied : ndarray (n_tied, n_axes)
        The local maxima polished from every region of near-best candidates
        (:mod:`reliability.first_order.canonical_maxima`) within
        :data:`reliability.basics.ties.SEARCH_RTOL` (in the spread) of the best, so that
        symmetric twins are all there whatever order the boxes were visited in.
    bound : float
        Upper bound of the function over the whole box (over its poses in the zone).
    calls : int
        Boxes evaluated.
    still_open : int
        Boxes open when the search stopped (0 when it closed them all).
    """
    inside = _zone_test(model, zone)
    boundary = _ZoneBoundary.for_model(model, zone, low, high, inside)
    tied, best = model.start(low, high, inside, boundary.search)
    tied, best = boundary.update(tied, best)
    near = NearCandidates(2 * (model.closing_factor(rtol) - 1), len(low))
    near.add(tied, model.values(tied), best)
    limit = model.closing_factor(rtol) * (1 - CLOSING_MARGIN)
    box_low, box_high = low[None, :], high[None, :]
    closed_bound = -np.inf
    calls = 0
    while (len(box_low) and calls < max_calls and best <= above
           and not (calls >= DEADLINE_CALLS and _late(deadline))):
        across = _across_zone(model, zone, box_low, box_high, memory)
        box_low, box_high, across = box_low[~across[0]], box_high[~across[0]], across[1]
        if not len(box_low):
            break
        evaluated = _evaluate(model, box_low, box_high, memory, parts=zone is not None)
        bound, contribution, points, values, slope = evaluated[:5]
        calls += len(box_low)
        values = np.where(inside(points), values, -np.inf)
        top = values.max()
        if top > best * (1 + TIE_RTOL):
            tied = tied[:0]
        best = max(best, top)
        tied = np.unique(np.vstack([tied[model.values(tied) >= best * (1 - TIE_RTOL)],
                                    points[values >= best * (1 - TIE_RTOL)]]), axis=0)
        tied, best = boundary.update(tied, best)
        near.add(points[np.isfinite(values)], values[np.isfinite(values)], best)
        closing = max(best * limit, below * (1 - CLOSING_MARGIN))
        # only boxes the whole-box bound leaves open need the Lagrangian's
        bound, contribution = boundary.tighten(bound, contribution, box_low, box_high,
                                               across & (bound > closing), memory,
                                               evaluated[5:])
        done = bound <= closing
        if done.any():
            closed_bound = max(closed_bound, bound[done].max())
        keep = ~done
        slope = np.where(across[:, None], 0.0, slope)  # a face may leave the zone
        split = across & keep
        if split.any():
            contribution[split] = _across_split(model, zone, contribution[split],
                                                box_low[split], box_high[split], high - low)
        box_low, box_high = _narrow(box_low[keep], box_high[keep], contribution[keep],
                                    slope[keep])
    still_open = len(box_low)
    if best > above:
        closed_bound = np.inf
    elif len(box_low):  # stopped by max_calls or the deadline: the open boxes still count
        across = _across_zone(model, zone, box_low, box_high, memory)
        box_low, box_high, across = box_low[~across[0]], box_high[~across[0]], across[1]
        if len(box_low):
            bound, contribution = _evaluate(model, box_low, box_high, memory)[:2]
            bound = boundary.tighten(bound, contribution, box_low, box_high, across,
                                     memory)[0]
            closed_bound = max(closed_bound, bound.max())
            calls += len(box_low)
    tied, best = _polished_maxima(model, boundary, inside, tied, near, high - low)
    return tied, max(closed_bound, best), calls, still_open


def _late(deadline) -> bool:
    """Whether the :func:`time.perf_counter` time ``deadline`` (None: never) has passed."""
    return deadline is not None and time.perf_counter() > deadline


def _polished_maxima(model, boundary, inside, tied, near, span):
    """The local maxima polished from one near-best candidate of each region
    (:func:`reliability.first_order.canonical_maxima.representatives`), beside the tied
    candidates: those within :data:`reliability.basics.ties.SEARCH_RTOL` (in the spread) of
    the best, and the best value."""
    regions = representatives(near.points, near.values, span)
    polished = boundary.search(np.vstack([tied[:1], regions]))
    candidates = np.vstack([tied, regions, polished[inside(polished)]])
    values = model.values(candidates)
    best = float(values.max())
    return candidates[values >= best / model.closing_factor(SEARCH_RTOL)], best


class _ZoneBoundary:
    """What the work zone's constraints add to the search
    (:mod:`reliability.first_order.zone_bound`): the local search kept to the zone, and
    Lagrangian bounds of the boxes across its boundary, with the multipliers at the best
    candidates found so far and one fitted to each box. Without a zone the search is the
    model's own and the bounds are left as they are."""

    def __init__(self, model, constraints, low, high, inside):
        self.model, self.constraints = model, constraints
        self.low, self.high, self.inside = low, high, inside
        self.multipliers = np.zeros((0, 0 if constraints is None else constraints.count))
        self.searched = -np.inf

    @classmethod
    def for_model(cls, model, zone, low, high, inside):
        constraints = None if zone is None else ZoneConstraints(zone)
        return cls(model, constraints, low, high, inside)

    def search(self, starts):
        """Local maxima from ``starts``: in the zone when it has constraints."""
        if self.constraints is None:
            return self.model.polish(starts, self.low, self.high)
        return self.constraints.search(lambda x: _point_slope(self.model, x), starts,
                                       self.low, self.high)

    def update(self, tied, best):
        """After a better candidate: the search on the zone's boundary from it, and the
        multipliers at the best candidates; ``(tied, best)`` with what the search found."""
        if self.constraints is None or best <= self.searched * (1 + TIE_RTOL):
            return tied, best
        found = self.search(tied[:MULTIPLIER_POINTS])
        found = found[self.inside(found)]
        values = self.model.values(found)
        if len(found) and values.max() > best * (1 + TIE_RTOL):
            tied, best = found[values >= values.max() * (1 - TIE_RTOL)], float(values.max())
        self.searched = best
        found = np.array([self.constraints.multipliers(_point_slope(self.model, point)[1],
                                                       point, self.low, self.high)
                          for point in tied[:MULTIPLIER_POINTS]])
        kept = []
        for multipliers in np.vstack([found, self.multipliers]):
            if multipliers.any() and not any(np.array_equal(multipliers, k) for k in kept):
                kept.append(multipliers)
        self.multipliers = np.array(kept[:MULTIPLIER_SETS]).reshape(-1, found.shape[1])
        return tied, best

    def tighten(self, bound, contribution, low, high, across, memory, parts=()):
        """The bounds (and contributions) of the boxes across the boundary replaced by
        their Lagrangian bound (:meth:`_lagrangian_bounds`) where it is lower; ``parts``,
        the model's own parts of every box when it gave them (``model.boxes``)."""
        rows = np.flatnonzero(across)
        if self.constraints is None or not len(rows):
            return bound, contribution
        per_box = self.model.bytes_per_box + self.constraints.bytes_per_box
        for part in chunks(len(rows), per_box, BOX_MEMORY if memory is None else memory):
            chosen = rows[part]
            other = self._lagrangian_bounds(low[chosen], high[chosen],
                                            [part[chosen] for part in parts])
            other, share = other if self.model.reading == "sigma" else \
                (other, contribution[chosen])
            lower = other < bound[chosen]
            bound[chosen[lower]] = other[lower]
            contribution[chosen[lower]] = share[lower]
        return bound, contribution

    def _lagrangian_bounds(self, low, high, parts=()):
        """The σ reading's Lagrangian bounds (:meth:`_sigma_bounds`) and shares, or the
        stack's bounds (:meth:`_stack_bounds`)."""
        if self.model.reading == "sigma":
            return self._sigma_bounds(low, high, parts)
        return self._stack_bounds(low, high)

    def _weights(self, gradient, g, g_gradient, g_mid, g_rad, half):
        """The multipliers kept and the one fitted to each box, ``(b, k, n_constraints)``."""
        kept = np.broadcast_to(self.multipliers[None], (len(half),) + self.multipliers.shape)
        fitted = _fitted_multipliers(gradient, g, g_gradient, g_mid, g_rad, half)
        return np.concatenate([kept, fitted[:, None]], axis=1)

    def _stack_bounds(self, low, high):
        """Per box, the least over the multipliers of the bound of the stack minus
        ``λ·g``: ``g`` below its linear model by at most its second-order remainder, the
        stack's linear model minus λ times ``g``'s is convex in the step, so largest at a
        vertex (along the axes the stack does not depend on, at the end where ``−λ·∇g``
        rises), plus both remainders and the margins; ``(b,)``."""
        model, e = self.model, self.model.expansion
        centre, half = (low + high) / 2, (high - low) / 2
        point = point_tree(e, centre, 1)
        value = point[()]
        gradient = np.stack([point[(a,)] for a in range(e.n_axes)], axis=1)
        g, g_gradient, g_mid, g_rad = self.constraints.parts(low, high)
        slope = np.einsum("bai,bi->ba", gradient, np.sign(value))
        weights = self._weights(slope, g, g_gradient, g_mid, g_rad, half)
        steps = half[:, None, :] * model.vertices[None]
        totals = np.abs(value[:, None, :] + np.matmul(steps, gradient)).sum(axis=-1)
        pull = np.einsum("bkj,bja->bka", weights, g_gradient)  # λ·∇g
        rise = (totals[:, None, :] - np.einsum("bka,bva->bkv", pull, steps)).max(axis=2)
        fixed_rise = (np.abs(pull) * (half * model.fixed)[:, None, :]).sum(axis=2)
        g_remainder = 0.5 * np.einsum("bjac,ba,bc->bj", np.abs(g_mid) + g_rad, half, half)
        total = (rise + fixed_rise - np.einsum("bkj,bj->bk", weights, g)
                 + np.einsum("bkj,bj->bk", weights, g_remainder)
                 + (0.5 * half * (half @ model.curvature)).sum(axis=1)[:, None]
                 + e.margin.sum() + weights @ self.constraints.margins)
        return total.min(axis=1)

    def _sigma_bounds(self, low, high, parts=()):
        """Per box, the least over the multipliers kept and one fitted to the box of the
        second-order Taylor bound of ``L = f − λ·g`` over the box (its Hessian enclosed by
        ``f``'s minus λ times the constraints'), plus the margins: an upper bound of ``f``
        over the box's poses in the zone. Returns the bounds ``(b,)`` and each axis' share
        ``(b, n_axes)``. ``parts``: σ², its gradient and Hessian enclosure of the boxes
        as the model computed them (:meth:`SigmaModel.boxes`), computed here if empty."""
        e = self.model.expansion
        half = (high - low) / 2
        f_value, gradient, f_mid, f_rad = parts or self.model.boxes(low, high, parts=True)[5:]
        g, g_gradient, g_mid, g_rad = self.constraints.parts(low, high)
        weights = self._weights(gradient, g, g_gradient, g_mid, g_rad, half)
        value = f_value[:, None] - np.einsum("bkj,bj->bk", weights, g)
        slope = gradient[:, None] - np.einsum("bkj,bja->bka", weights, g_gradient)
        mid = f_mid[:, None] - np.einsum("bkj,bjac->bkac", weights, g_mid)
        rad = f_rad[:, None] + np.einsum("bkj,bjac->bkac", weights, g_rad)
        diagonal = np.arange(e.n_axes)
        curvature = (mid + rad)[..., diagonal, diagonal]
        cross = np.abs(mid) + rad
        cross[..., diagonal, diagonal] = 0.0
        step = rising_step(np.abs(slope), curvature, np.broadcast_to(half[:, None], slope.shape))
        rise = (np.abs(slope) * step + 0.5 * curvature * step ** 2
                + 0.5 * half[:, None] * np.einsum("bkac,bc->bka", cross, half))
        total = value + rise.sum(axis=2) + e.margin + weights @ self.constraints.margins
        least = np.argmin(total, axis=1)
        rows = np.arange(len(low))
        return total[rows, least], rise[rows, least]


def _point_slope(model, point):
    """The model's function and its gradient at a local point, ``(value, (n_axes,))``:
    σ², or the stack ``Σ_i |w_i|`` with ``Σ_i sign(w_i) ∇w_i`` (one of its
    subgradients)."""
    tree = point_tree(model.expansion, np.asarray(point, dtype=float)[None, :], 1)
    gradient = np.stack([tree[(a,)][0] for a in range(model.expansion.n_axes)])
    if model.reading == "sigma":
        return float(tree[()][0]), gradient
    return float(np.abs(tree[()][0]).sum()), gradient @ np.sign(tree[()][0])


def _fitted_multipliers(gradient, g, g_gradient, g_mid, g_rad, half):
    """Per box, multipliers ``λ ≥ 0`` of the constraints the box may pass (``g``'s Taylor
    bound over it above 0) that make ``f − λ·g`` level at its centre, scaled by the box:
    non-negative least squares of ``h ⊙ ∇f`` on the ``h ⊙ ∇g_j`` by
    :data:`FIT_SWEEPS` sweeps of projected coordinate descent; ``(b, n_constraints)``."""
    passed = (g + np.einsum("bja,ba->bj", np.abs(g_gradient), half)
              + 0.5 * np.einsum("bjac,ba,bc->bj", np.abs(g_mid) + g_rad, half, half)) > 0
    columns = g_gradient * half[:, None, :]
    target = gradient * half
    norms = np.square(columns).sum(axis=2)
    multipliers = np.zeros(g.shape)
    for _ in range(FIT_SWEEPS):
        for j in range(g.shape[1]):
            residual = target - np.einsum("bj,bja->ba", multipliers, columns)
            step = np.divide((residual * columns[:, j]).sum(axis=1), norms[:, j],
                             out=np.zeros(len(g)), where=norms[:, j] > 0)
            multipliers[:, j] = np.where(passed[:, j],
                                         np.maximum(multipliers[:, j] + step, 0.0), 0.0)
    return multipliers


def _zone_test(model, zone):
    """Which points of local coordinates ``(b, n_axes)`` are in the work zone (all
    without one)."""
    if zone is None:
        return lambda points: np.ones(len(points), dtype=bool)
    return lambda points: zone.contains(model.expansion.pose(points))


def _across_zone(model, zone, low, high, memory=None):
    """Boxes proved outside the work zone, and boxes across its boundary (proved neither
    outside nor inside); none of either without a zone."""
    if zone is None:
        return np.zeros((2, len(low)), dtype=bool)
    outside, inside = zone.classify(model.expansion.pose(low), model.expansion.pose(high),
                                    BOX_MEMORY if memory is None else memory)
    return outside, ~outside[~outside] & ~inside[~outside]


def _across_split(model, zone, contribution, low, high, span):
    """What boxes across the zone's boundary are halved by: each axis' share of the bound,
    of the stroke and its part of the tool point's enclosure where it reaches across the
    zone's limits (:meth:`ZoneEnclosure.split_shares`), so that the boundary is resolved
    along the axes it depends on while it is wide against the zone."""
    total = contribution.sum(axis=1, keepdims=True)
    share = np.divide(contribution, total, out=np.zeros_like(contribution), where=total > 0)
    return (share + zone.split_shares(model.expansion.pose(low), model.expansion.pose(high))
            + (high - low) / span)


def _evaluate(model, low, high, memory, parts=False):
    """``model.boxes`` (with ``parts``) over all boxes in chunks within the memory
    budget."""
    memory = BOX_MEMORY if memory is None else memory
    parts = [model.boxes(low[part], high[part], parts)
             for part in chunks(len(low), model.bytes_per_box, memory)]
    return tuple(np.concatenate(items) for items in zip(*parts))


def _narrow(low, high, contribution, slope):
    """Each box monotone along some axes replaced by its face where the function is
    largest (the maximum over the box is on it); the others halved (:func:`_halve`)."""
    monotone = (slope != 0).any(axis=1)
    face_low = np.where(slope > 0, high, low)[monotone]
    face_high = np.where(slope < 0, low, high)[monotone]
    halved_low, halved_high = _halve(low[~monotone], high[~monotone],
                                     contribution[~monotone])
    return np.vstack([face_low, halved_low]), np.vstack([face_high, halved_high])


def _halve(low, high, contribution):
    """Each box split in two along the axis of its largest contribution to the bound."""
    axis = np.argmax(contribution, axis=1)
    rows = np.arange(len(low))
    middle = (low[rows, axis] + high[rows, axis]) / 2
    left_high, right_low = high.copy(), low.copy()
    left_high[rows, axis] = middle
    right_low[rows, axis] = middle
    return np.vstack([low, right_low]), np.vstack([left_high, high])
