"""Tolerances for a service life: the per-pose rows of the first passage over ``[0, T]``
under a fixed linear drift, and their certificate over the continuous workspace
(docs/life-allocation.md).

At a pose ``q`` an output read to first order is ``y(t) = J(q)·e(t)`` with
``e(t) = e(0) + r·t`` (:mod:`reliability.model.drift`, ``kind = "linear"``): ``y(0)`` is
normal with mean 0 and variance ``σ0² = Σ_i J_i² σ_i²`` (Eq. 20, the allocated variable)
and the drift ``d = J·r·T`` normal with mean 0 and variance ``s_d² = Σ_i J_i² (ρ_i T)²``
(fixed: ``ρ`` the drift rates, independent errors). The output stays within ``±I`` at every
age of ``[0, T]`` with probability ``G(σ0, s_d)``
(:func:`reliability.life.first_passage.first_passage_within`), and the life target reads

    G(σ0(q), s_d(q)) ≥ R   at every pose q.                                   (L1)

**G is decreasing in σ0 and in s_d.** Given ``d`` with ``|d| < 2I``, ``y(0)`` must lie in an
interval containing 0 (``(max(−I, −I − d), min(I, I − d))``), whose probability decreases
as the spread of a centred normal grows; given ``y(0)`` with ``|y(0)| < I`` the drift must
lie in ``(−I − y(0), I − y(0))``, which contains 0 too. So (L1) is ``σ0² ≤ A(s_d²)`` with
``A(v)`` the largest ``σ0²`` meeting it, one root per (pose, output), decreasing in ``v``;
where the drift alone misses the target (``P(|d| < I) < R``, i.e. ``s_d > I/z`` with
``z = Φ⁻¹((1 + R)/2)``) no tolerance meets it, and this is refused naming the pose. By
scale, ``A(v) = I² X(√v / I)²`` with ``X`` one curve per target (:class:`RootCurve`),
computed once by bisection and interpolated. Dividing each row ``Σ_i J_i² u_i / k²`` by its
own ``A`` keeps the allocation the convex problem of Eq. (34) with a per-row right-hand
side (:meth:`LifeRequirement.allowed_variance`, used by
:meth:`allocation.per_pose.problem.AllocationProblem.row_matrix`).

**The certificate.** Over the continuous workspace (L1) asks a bound of two quadratic forms
in ``J(q)`` at once. First the certificate bounds the drift's σ over the strokes (or the
work zone): ``s_d(q) ≤ D`` (:meth:`LifeRequirement.with_drift_bound`). A line
``σ0² + c·s_d² ≤ I² b`` below the curve ``A`` on ``[0, D²]`` then implies (L1) at every pose
where it holds, and its left side is one quadratic form: ``Σ_i J_i² (σ_i² + c (ρ_i T)²)``,
the σ² of the allocation ``σ_i' = √(σ_i² + c (ρ_i T)²)``, which the certificate of
:func:`reliability.first_order.workspace_search.certified_worst` bounds rigorously. ``A`` is
not convex everywhere (it is concave where ``s_d`` is between about 0.47 and 0.88 of
``I/z``), so the line is the segment of the lower convex hull of ``X²`` over
``w = (s_d/I)²`` in ``[0, (D/I)²]`` at the drift of the output's worst pose of the set
(:meth:`RootCurve.support_line`), lowered by its largest excess over the curve on a
four-times-finer check: where the curve is convex it is the tangent there. A bound within
``(1 + rtol)`` of ``I √b`` says the allocation meets (L1) with the limits ``I (1 + rtol)``
at every pose (``λ² I² X(√w/λ)²`` is the curve of the limit ``λI``, and the line scales
alike), as the certificate of the acceptance allocation does
(docs/continuous-allocation.md). Where an output binds at poses of different drift, or in
the concave part, the line is below ``A`` there and the bound says so as an excess; a pose
the certificate finds with ``σ0² > A`` is a cut. The curve between its nodes and the line
between its checked points are numerical, not interval arithmetic (docs/life-allocation.md).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, replace

import numpy as np
import pandas as pd
from scipy.interpolate import CubicSpline

from reliability.basics.display import pose_text, axis_units
from reliability.basics.errors import InputError
from reliability.basics.ties import worst_rows
from reliability.first_order.fosm import error_sigma, required_index
from reliability.first_order.workspace_search import certified_worst
from reliability.life.first_passage import first_passage_within
from reliability.model.drift import checked_age
from reliability.model.machine import OUTPUTS

#: Nodes of the root curve ``X(ρ)`` over ``ρ = s_d/I`` in ``[0, 1/z]`` (cubic spline; it
#: agrees with roots of an independent quadrature to 1e-8 relative,
#: tests/test_life_allocation.py).
CURVE_NODES = 513
#: Bisection steps of each node's root (the bracket ``[0, 1/z]`` halved to 1e-18 of it).
BISECTIONS = 60
#: Points of ``ρ`` on which the lower convex hull of ``X²`` over ``w = ρ²`` is built; the
#: support line is checked on four times as many and lowered by its largest excess there.
HULL_POINTS = 4097
#: Relative margin by which a support line is lowered beyond its checked excess.
LINE_MARGIN = 1e-9


@dataclass(frozen=True, eq=False)
class RootCurve:
    """The largest ``(σ0/I)²`` meeting ``G ≥ R`` as a function of ``ρ = s_d/I``, for one
    target ``R`` (limit 1 by scale).

    Attributes
    ----------
    target : float
    rho_max : float
        ``1/z``: the drift alone reaches the target at ``ρ ≤ rho_max`` only.
    spline : CubicSpline
        ``X(ρ)²`` on :data:`CURVE_NODES` nodes of ``[0, rho_max]``.
    """

    target: float
    rho_max: float
    spline: CubicSpline

    @classmethod
    def of(cls, target: float) -> "RootCurve":
        """The curve of ``target`` (cached: one bisection per target value)."""
        return _curve(float(target))

    def allowed(self, rho) -> np.ndarray:
        """``X(ρ)²``: the largest ``(σ0/I)²`` meeting the target; 0 beyond ``rho_max``."""
        rho = np.asarray(rho, dtype=float)
        inside = rho <= self.rho_max
        value = self.spline(np.where(inside, rho, self.rho_max))
        return np.where(inside, np.maximum(value, 0.0), 0.0)

    def support_line(self, w: float, rho_high: float) -> tuple[float, float]:
        """``(b, c)`` with ``b − c·w' ≤ X(√w')²`` for every ``w'`` in ``[0, rho_high²]``
        (``rho_high`` at most ``rho_max``): the segment over ``w`` of the lower convex hull
        of ``X²`` on :data:`HULL_POINTS` points of that range, checked on four times as many
        and lowered by the excess found there plus :data:`LINE_MARGIN`."""
        rho_high = min(float(rho_high), self.rho_max)
        dense = np.linspace(0.0, rho_high, HULL_POINTS)
        hull = _lower_hull(np.square(dense), self.allowed(dense))
        hull_w, hull_x2 = np.square(dense[hull]), self.allowed(dense[hull])
        segment = int(np.clip(np.searchsorted(hull_w, w, side="right") - 1, 0,
                              len(hull_w) - 2))
        (w0, w1), (x0, x1) = hull_w[segment:segment + 2], hull_x2[segment:segment + 2]
        c = -(x1 - x0) / (w1 - w0)
        b = x0 + c * w0
        check = np.linspace(0.0, rho_high, 4 * HULL_POINTS)
        excess = float(np.max(b - c * check ** 2 - self.allowed(check)))
        return b - max(excess, 0.0) - LINE_MARGIN * b, c


@functools.lru_cache(maxsize=32)
def _curve(target: float) -> RootCurve:
    """Bisection of ``G(s0, ρ; I = 1) = R`` for ``s0`` in ``(0, 1/z]`` at every node ρ (G is
    decreasing in s0, module docstring), then the spline."""
    z = float(required_index(target, "two_sided"))
    rho = np.linspace(0.0, 1.0 / z, CURVE_NODES)
    low, high = np.zeros_like(rho), np.full_like(rho, 1.0 / z)
    for _ in range(BISECTIONS):
        middle = (low + high) / 2
        meets = first_passage_within(1.0, middle, rho) >= target
        low, high = np.where(meets, middle, low), np.where(meets, high, middle)
    low[-1] = 0.0  # at ρ = 1/z the drift alone is at the target
    return RootCurve(target=target, rho_max=1.0 / z, spline=CubicSpline(rho, np.square(low)))


def _lower_hull(x, y) -> np.ndarray:
    """Indices of the lower convex hull of points with increasing ``x`` (monotone chain)."""
    hull: list[int] = []
    for i in range(len(x)):
        while len(hull) >= 2 and _turn(x, y, hull[-2], hull[-1], i) <= 0:
            hull.pop()
        hull.append(i)
    return np.array(hull)


def _turn(x, y, a, b, c) -> float:
    """Cross product of ``(b − a)`` and ``(c − a)``: > 0 for a left (convex) turn."""
    return (x[b] - x[a]) * (y[c] - y[a]) - (y[b] - y[a]) * (x[c] - x[a])


@dataclass(frozen=True, eq=False)
class LifeRequirement:
    """The life target (L1) of a machine over ``years``: what each row may reach.

    Attributes
    ----------
    years : float
        The service life ``T`` (> 0).
    drift_sd : ndarray (n_errors,)
        Standard deviation of each error's drift over the life, ``rate · T``.
    limits, targets : ndarray (6,)
        ``I`` and ``R`` of every output (the problem's machine's).
    curves : tuple of RootCurve
        One per output.
    drift_bound : ndarray (6,) or None
        A certified upper bound of each output's ``s_d`` over the strokes (or the work
        zone), :meth:`with_drift_bound`; None until then.
    """

    years: float
    drift_sd: np.ndarray
    limits: np.ndarray
    targets: np.ndarray
    curves: tuple
    drift_bound: np.ndarray | None = None

    @classmethod
    def of(cls, machine, years) -> "LifeRequirement":
        """The requirement of ``machine`` (its ``[drift]``, limits and targets).

        Raises
        ------
        InputError
            As :func:`checked_life`.
        """
        years = checked_life(machine, years)
        curves = tuple(RootCurve.of(target) for target in machine.targets)
        return cls(years=years, drift_sd=np.asarray(machine.drift.rate, dtype=float) * years,
                   limits=np.asarray(machine.limits, dtype=float),
                   targets=np.asarray(machine.targets, dtype=float), curves=curves)

    def with_drift_bound(self, machine, rtol: float = 1e-3) -> "LifeRequirement":
        """The requirement with :attr:`drift_bound`: the certificate
        (:func:`reliability.first_order.workspace_search.certified_worst`) of the drift's σ,
        ``s_d`` being the σ of the allocation ``ρ T`` read with ``k = 1``."""
        table = certified_worst(machine, np.maximum(self.drift_sd, 1e-300), rtol=rtol,
                                k=1.0, distribution="normal")
        return replace(self, drift_bound=table["sigma_bound"].to_numpy(dtype=float))

    def drift_variance(self, jacobian) -> np.ndarray:
        """``s_d² = Σ_i J_i² (ρ_i T)²`` of every output, ``(..., 6)``."""
        return np.square(jacobian) @ np.square(self.drift_sd)

    def drift_ratio(self, jacobian) -> np.ndarray:
        """``s_d / (I/z)``, ``(..., 6)``: above 1 no tolerance meets the target."""
        rho = np.sqrt(self.drift_variance(jacobian)) / self.limits
        return rho / np.array([curve.rho_max for curve in self.curves])

    def allowed_variance(self, jacobian) -> np.ndarray:
        """``A = I² X(s_d/I)²``, the largest ``σ0²`` meeting (L1) at each (pose, output),
        ``(..., 6)``; 0 where the drift alone misses the target."""
        rho = np.sqrt(self.drift_variance(jacobian)) / self.limits
        return np.square(self.limits) * np.stack(
            [curve.allowed(rho[..., o]) for o, curve in enumerate(self.curves)], axis=-1)


def checked_life(machine, years) -> float:
    """``years`` as a float > 0 for a life allocation of ``machine``, checked before any work.

    Raises
    ------
    InputError
        ``years`` not a number > 0; the machine without a ``[drift]`` table; a drift of kind
        ``'wear'`` (its mean is not 0 and its path is not linear, so the first passage is
        not the two-ended event this allocation constrains).
    """
    years = checked_age(years)
    if years == 0:
        raise InputError("life: the service life must be > 0 years; got 0 (the "
                         "allocation at acceptance is the plain allocate)")
    drift = getattr(machine, "drift", None)
    if drift is None:
        raise InputError("life: the machine file has no [drift] table; a life "
                         "allocation needs the drift rates (docs/machine-file.md)")
    if drift.kind != "linear":
        raise InputError(f"life: drift kind {drift.kind!r} is refused: wear has a mean "
                         f"and a path that is not linear in the age, so staying within "
                         f"the limit at both ends of the life does not mean staying "
                         f"within it throughout, which the allocation's rows assume; "
                         f"use kind 'linear'")
    return years


def life_problem(problem, years, *, bound_drift: bool = True):
    """``problem`` (two-sided, worst case) with the life target (L1) over ``years`` in
    every row, screened again; with ``bound_drift`` (needed by the certificate over the
    continuous workspace) the drift's σ is bounded over the strokes first
    (:meth:`LifeRequirement.with_drift_bound`).

    Raises
    ------
    InputError
        As :meth:`LifeRequirement.of`; a problem under another reading than the two-sided
        worst case; a pose of the problem where the drift alone misses a target (naming
        the output, the pose and the drift's σ over what the target allows).
    """
    if problem.side != "two_sided" or problem.workspace != "worst":
        raise InputError(f"life: the life target is the two-sided probability of staying "
                         f"within the limit at every pose; got side {problem.side!r}, "
                         f"workspace {problem.workspace!r}")
    life = LifeRequirement.of(problem.machine, years)
    check_reachable(problem.machine, life, problem.poses)
    if bound_drift:
        life = life.with_drift_bound(problem.machine)
    return problem.with_life(life)


def check_reachable(machine, life, poses) -> None:
    """Raise an InputError naming the first (pose, output) where the drift alone misses
    the target: ``s_d > I/z`` (no tolerance then meets (L1))."""
    for start in range(0, len(poses), 4096):
        block = poses[start:start + 4096]
        ratio = life.drift_ratio(machine.jacobian(block))
        pose, output = np.unravel_index(np.argmax(ratio), ratio.shape)
        if ratio[pose, output] > 1.0:
            raise InputError(
                f"life: output {OUTPUTS[output]} at pose "
                f"{pose_text(block[pose], machine.axes, axis_units(machine))}: its drift over "
                f"{life.years:g} years alone has σ {ratio[pose, output]:.4g} × what the "
                f"target {life.targets[output]:g} allows within ±{life.limits[output]:g}; no "
                f"tolerances meet it (lower the drift rates, the life or the target)")


def life_loads(problem, tolerances, poses=None) -> np.ndarray:
    """``σ0² / A`` of every output at ``poses`` (default the problem's), ``(n, 6)``: the
    life target (L1) holds where it is ≤ 1 (``inf`` where the drift alone misses it)."""
    if poses is None:  # the problem's rows, chunk by chunk
        return problem.loads(problem.variable(tolerances))
    jacobian = problem.machine.jacobian(np.atleast_2d(poses))
    sigma2 = np.square(jacobian) @ np.square(error_sigma(tolerances, problem.k,
                                                         problem.distribution))
    allowed = problem.life.allowed_variance(jacobian)
    with np.errstate(divide="ignore"):
        return np.where(allowed > 0, sigma2 / np.where(allowed > 0, allowed, 1.0), np.inf)


def life_certificate_table(problem, tolerances, rtol, max_calls, *, stop_share=None,
                           certificate_share=0.5, deadline=None) -> pd.DataFrame:
    """The certificate of (L1) over the continuous workspace at ``tolerances``, per output.

    For each output, the support line ``(b, c)`` at the drift of its worst pose of the set
    (largest ``σ0²/A``, ties by :func:`reliability.basics.ties.worst_rows`) and the
    certificate of the combined σ ``√(σ0² + c s_d²)`` (module docstring), asked for
    ``certificate_share × rtol``, closing every box whose bound is below
    ``(1 + certificate_share × rtol)`` × ``I √b`` (a feasibility test: such a box cannot miss
    the target), and stopped at the first pose above ``(1 + stop_share × rtol)`` × ``I √b``
    (when that pose misses (L1) itself it is a cut; otherwise the output is certified again
    without stopping).

    Returns
    -------
    DataFrame
        Indexed by output: the pose; ``sigma``, ``sigma_bound`` (the combined σ there and its
        bound over the workspace), ``allowed`` (``I √b``), ``excess`` (bound / allowed −
        1), ``meets`` (``excess ≤ rtol``), ``gap``, ``calls``, ``open``, ``certified`` (the
        certificate's); ``sigma0`` and ``life_allowed`` (σ0 and ``√A`` at the pose, whose
        ratio above 1 makes it a cut), ``slope`` (``c``) and ``intercept`` (``b``).
    """
    machine, life = problem.machine, problem.life
    if life.drift_bound is None:
        raise InputError("life certificate: the problem's drift is not bounded over the "
                         "strokes; build it with life_problem(..., bound_drift=True)")
    variance = np.square(error_sigma(tolerances, problem.k, problem.distribution))
    worst = _worst_poses(problem, tolerances)
    rows = []
    for o in range(len(OUTPUTS)):
        drift = float(life.drift_variance(machine.jacobian(worst[o][None]))[0, o])
        b, c = life.curves[o].support_line(drift / life.limits[o] ** 2,
                                           life.drift_bound[o] / life.limits[o])
        allowed = life.limits[o] * np.sqrt(b)
        combined = np.sqrt(variance + c * np.square(life.drift_sd))
        row = _output_row(problem, combined, o, allowed, rtol, max_calls, stop_share,
                          certificate_share, deadline, tolerances)
        rows.append(dict(row, allowed=allowed, slope=c, intercept=b))
    table = pd.DataFrame(rows, index=pd.Index(OUTPUTS, name="output"))
    table["excess"] = table["sigma_bound"] / table["allowed"] - 1.0
    table["meets"] = table["excess"] <= rtol
    return table


def _output_row(problem, combined, o, allowed, rtol, max_calls, stop_share,
                certificate_share, deadline, tolerances) -> dict:
    """One output's certificate row: stopped at a short pose if asked, and certified again
    in full when that pose meets (L1) itself (the line, not the allocation, is short)."""
    machine = problem.machine
    close = allowed * (1.0 + certificate_share * rtol)  # a box below it cannot fail (L1)
    stop = None if stop_share is None else \
        np.full(len(OUTPUTS), allowed * (1.0 + stop_share * rtol))  # only output o's is read
    for above in ((stop, None) if stop is not None else (None,)):
        table = certified_worst(machine, combined, rtol=certificate_share * rtol, k=1.0,
                                distribution="normal", max_calls=max_calls,
                                memory=problem.memory, stop_above=above, deadline=deadline,
                                outputs=[OUTPUTS[o]], feasibility=True,
                                close_below=np.full(len(OUTPUTS), close))
        row = table.iloc[0].to_dict()
        pose = np.array([row[axis] for axis in machine.axes], dtype=float)
        load = float(life_loads(problem, tolerances, pose)[0, o])
        if np.isfinite(row["sigma_bound"]) or load > 1.0:
            break
    jacobian = machine.jacobian(pose[None])
    row["sigma0"] = float(np.sqrt(np.square(jacobian[0, o])
                                  @ np.square(error_sigma(tolerances, problem.k,
                                                          problem.distribution))))
    row["life_allowed"] = float(np.sqrt(problem.life.allowed_variance(jacobian)[0, o]))
    if row["life_allowed"] == 0.0:
        check_reachable(machine, problem.life, pose[None])
    return row


def _worst_poses(problem, tolerances) -> np.ndarray:
    """Each output's pose of the set with the largest ``σ0²/A`` (ties by the rule of
    :func:`reliability.basics.ties.worst_rows`), ``(6, n_axes)``."""
    loads = problem.loads(problem.variable(tolerances))
    return problem.poses[np.asarray(worst_rows(loads, problem.poses), dtype=int)]
