"""Allocations whose targets hold between grid points: one cutting-plane loop on poses,
certified over the continuous workspace or searched only (docs/continuous-allocation.md).

Eq. (35) asks the targets over the whole stroke of every axis; the grid problem
(:class:`~allocation.per_pose.problem.AllocationProblem`) holds them at the poses of a grid only. A
finite pose set is a relaxation of the continuous problem, so its optimum costs at most the
continuous optimum. :func:`solve_continuous` closes the gap by an exchange (cutting-plane)
method:

1. solve the problem on the current pose set (certified convex optimum,
   :mod:`allocation.solvers.convex`);
2. find the worst pose of each output at that optimum: first by the local search from the
   worst poses of the set (:func:`reliability.first_order.workspace_search.searched_worst`,
   cheap, for the σ readings), and, when the search finds no output short by more than a
   quarter of ``rtol``, by the certificate
   (:func:`reliability.first_order.workspace_search.certified_worst`), a rigorous upper bound of
   the output's σ (or worst-case stack) over the whole stroke box, asked to stop an output at
   its first pose short by more than a quarter of ``rtol`` (a cut; the outputs after it then
   only look for cuts);
3. add the poses of every output short of its requirement (all at once) and solve again;
4. stop when the certified bound of every output is within ``rtol`` of what its target allows:
   σ ≤ ``I/z`` (two- or one-sided reading; under ``distribution="truncated"`` σ is the
   truncated one) or the stack ≤ ``I`` (stack reading).

At the stop the allocation ``t`` meets every target over the continuous workspace with the
allowed σ (or limit) widened by the factor ``1 + rtol``, and it is the optimum of a
relaxation of the continuous problem, so

    F*(limits × (1 + rtol)) ≤ F(t) ≤ F*(limits)

where ``F*(·)`` is the continuous optimum: the cost is the continuous optimum to ``rtol``
in σ. The certificate is asked for half of ``rtol`` so that the loop can close the other
half with finitely many cuts; a certificate that stops no output early is the full one, and
its bounds are within ``(1 + ¼ rtol)(1 + ½ rtol) < 1 + rtol`` of what the targets allow.
When the certificate does not reach its gap within its box evaluations, the loop reaches
its cap on solves, its ``time_limit`` or a Ctrl-C, the result says so and is not certified;
stopped by the time or Ctrl-C, it offers the allocation scaled into certified feasibility
(:attr:`ContinuousAllocation.scaled`).

With ``certify=False`` the same loop cuts the poses the local search finds short by more
than ``rtol`` and stops when it finds none: no certificate is asked for, and the result says
"not certified: searched only". :func:`solve_over_workspace` is that mode under its older
name and signature.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from reliability.basics import checks
from reliability.basics.display import (OUTPUT_UNITS, axis_units, pose_frame, pose_text,
                                        upper_bound_text)
from reliability.basics.errors import InputError
from reliability.basics.saved_fields import (Array, Flag, Frame, Integer, Number, Text,
                                            read_fields, write_fields)
from reliability.basics.saved_results import load_payload, save_payload
from reliability.first_order.certificate import DEFAULT_RTOL, MAX_BOX_CALLS, WORKSPACES
from reliability.first_order.workspace_search import certified_worst, searched_worst

from .life import life_certificate_table
from .result_files import gap_text
from .solve import AllocationResult

#: The pose sets an allocation can be certified over: the continuous strokes or the grid.
WORKSPACE_CHOICES = WORKSPACES
#: Solves of the convex problem (the grid's included) before the loop stops uncertified.
MAX_SOLVES = 30
#: Share of ``rtol`` the certificate's own gap may take; the loop's cuts close the rest.
CERTIFICATE_SHARE = 0.5
#: Share of ``rtol`` by which an output found short by the local search is cut at once,
#: without a certificate (``SEARCH_SHARE + CERTIFICATE_SHARE < 1`` leaves room to stop);
#: searched only (``certify=False``), the search cuts by the whole ``rtol``.
SEARCH_SHARE = 0.25
#: Share of ``rtol`` above what its target allows below which the loop's certificate,
#: once it has stopped an output at a short pose (it then only looks for cuts), closes a
#: box of the outputs after it whatever their best candidate.
CLOSE_SHARE = 1.0
#: Local searches per output, from the poses of the set where it is largest.
SEARCH_STARTS = 3
#: Relative margin by which :attr:`ContinuousAllocation.scaled` is scaled beyond the
#: largest excess, so that the rounding of the scaled bounds stays below what is allowed.
SCALE_MARGIN = 1e-9


@dataclass(frozen=True, eq=False)
class ContinuousAllocation:
    """An allocation whose targets are certified over the continuous workspace (or not, or
    searched only).

    Attributes
    ----------
    result : AllocationResult
        The certified convex optimum on the grid plus the added poses (its ``problem``
        holds them all); the allocation itself.
    grid : AllocationResult
        The optimum on the grid alone (the first solve), for comparison.
    certified : bool
        Every output's certified bound is within ``rtol`` of what its target allows at
        ``result.tolerances``. Never true when ``searched_only``.
    rtol : float
        Relative tolerance in σ (stack reading: in the stack); searched only, how far above
        what its target allows an output found by the search may be.
    certificate : DataFrame or None
        The last certificate (:func:`reliability.first_order.workspace_search.certified_worst`)
        with, per output, ``allowed`` (σ the target allows, or the limit for the stack), ``excess``
        (bound / allowed − 1) and ``meets`` (excess ≤ rtol); None when no certificate was computed
        (the loop stopped before, or searched only). ``attrs['current']`` says whether it was
        computed at ``result.tolerances``.
    added : DataFrame
        The poses added, in order: ``solve`` (the solve they follow), ``source``
        (``'search'`` or ``'certificate'``), ``output``, the pose (``<axis>_mm`` /
        ``<axis>_deg``) and ``ratio`` (σ or stack there over what the target allows).
    solves, certificate_calls, searches : int
        Convex solves (1: the grid optimum already holds), certificate calls and local
        searches.
    seconds : float
    reason : str
        Why the result is not certified ('' when certified; ``'searched only'`` when the
        search-only loop ran to its end).
    searched_only : bool
        The loop ran without the certificate (``certify=False``): it stopped when the local
        search found no output short by more than ``rtol``, which proves nothing between
        the poses it did not reach.
    capped : bool
        The loop stopped at ``max_solves`` with outputs still short.
    workspace : str
        ``'continuous'``.
    scaled : ndarray or None
        When not certified but the last certificate is of this allocation and bounds every
        output: the allocation divided by ``1 + e`` (e its largest excess, and a margin of
        :data:`SCALE_MARGIN`). σ and the stack are linear in a common factor on the
        tolerances, so every output's certified bound then meets what its target allows:
        the scaled allocation is certified feasible over the continuous workspace (it may
        leave the box of bounds and moves locked items too; :meth:`summary` says). None
        otherwise.
    """

    result: object = field(repr=False)
    grid: object = field(repr=False)
    certified: bool
    rtol: float
    certificate: pd.DataFrame | None
    added: pd.DataFrame
    solves: int
    certificate_calls: int
    searches: int
    seconds: float
    reason: str = ""
    searched_only: bool = False
    capped: bool = False
    workspace: str = "continuous"
    scaled: np.ndarray | None = field(default=None, repr=False)

    @property
    def tolerances(self) -> np.ndarray:
        return self.result.tolerances

    @property
    def cost(self) -> float:
        return self.result.cost

    @property
    def cost_ratio(self) -> float:
        """Cost of this allocation over the grid optimum's (≥ 1 up to the solver's gap)."""
        return self.result.cost / self.grid.cost

    @property
    def quantity(self) -> str:
        """What the tolerance is relative to: ``'σ'`` or ``'the worst-case stack'``."""
        return "the worst-case stack" if self.result.problem.side == "stack" else "σ"

    @property
    def statement(self) -> str:
        """One line naming the workspace and whether it is certified."""
        if self.certified:
            return (f"certified over the continuous workspace to {self.rtol:g} in "
                    f"{self.quantity}")
        if self.searched_only and not self.capped:
            return (f"not certified: searched only — a local search from the "
                    f"{len(self.result.problem.poses)} grid and added poses finds no output "
                    f"short by more than {self.rtol:g} in {self.quantity}; the targets hold at "
                    f"those poses, and between them only as far as the search sees")
        return (f"NOT certified over the continuous workspace ({self.reason}); the targets "
                f"hold at the {len(self.result.problem.poses)} grid and added poses only")

    def summary(self) -> str:
        """The statement, the work done, the cost against the grid optimum, and the
        certificate per output."""
        lines = [f"workspace: continuous — {self.statement}",
                 f"{self.solves} convex solve(s), {len(self.added)} pose(s) added, "
                 f"{self.searches} local search(es), {self.certificate_calls} certificate "
                 f"call(s), {self.seconds:.1f} s; cost {self.cost_ratio:.6f} × the "
                 f"{len(self.grid.problem.poses)}-pose grid optimum's"]
        if self.scaled is not None:
            lines.append(self._scaled_text())
        if self.certificate is not None:
            lines += ["", "certified worst pose of each output"
                      + ("" if self.certificate.attrs.get("current", True) else
                         " (at an earlier solve)") + ":",
                      certificate_text(self.result.problem, self.certificate)]
        return "\n".join(lines)

    def _scaled_text(self) -> str:
        """What :attr:`scaled` is and costs."""
        problem = self.result.problem
        factor = float(self.scaled[0] / self.tolerances[0])
        cost = float(problem.cost.total(self.scaled))
        below = int(np.sum(self.scaled < problem.lower))
        locked = int(np.sum(problem.locked))
        return (f"certified feasible instead: this allocation × {factor:.6f} (every item "
                f"scaled by 1/(1 + the largest certified excess)), at {cost / self.cost:.6f} "
                f"× its cost ({cost / self.grid.cost:.6f} × the grid optimum's)"
                + (f"; {below} item(s) below the box's lower bound" if below else "")
                + (f"; {locked} locked item(s) scaled too" if locked else ""))

    def __repr__(self) -> str:
        return self.summary()

    def to_frame(self) -> pd.DataFrame:
        """The allocation (:meth:`AllocationResult.to_frame` of :attr:`result`) with the
        workspace's verdict in every row: ``certified`` and ``searched_only``."""
        frame = self.result.to_frame()
        frame["certified"] = self.certified
        frame["searched_only"] = self.searched_only
        return frame

    def save(self, path, overwrite: bool = False):
        """Save as JSON (tag :data:`SAVED_FORMAT`): :data:`SAVED_FIELDS`, both allocations
        (``result`` and ``grid``, as :meth:`AllocationResult.save` writes them) and whether
        the certificate is current. An existing file is kept unless ``overwrite``. Returns
        the path."""
        payload = write_fields(self, SAVED_FIELDS)
        payload.update(result=self.result.payload(), grid=self.grid.payload(),
                       certificate_current=self.certificate is None
                       or bool(self.certificate.attrs.get("current", True)))
        return save_payload(path, SAVED_FORMAT, payload, overwrite)

    @classmethod
    def load(cls, path, problem, grid_problem) -> "ContinuousAllocation":
        """Reload an allocation written by :meth:`save`, every field checked; ``problem``
        (the grid plus the added poses, ``result.problem``) and ``grid_problem`` (the grid
        alone) are checked to be the saved allocations' problems and attached. The
        verdict (certified, searched only, capped) and the certificate are the saved
        ones. A damaged field raises
        :class:`~reliability.basics.errors.SavedResultError` naming the file and field."""
        data = load_payload(path, SAVED_FORMAT)
        values = read_fields(data, SAVED_FIELDS)
        values["result"] = AllocationResult.from_payload(data.table("result"), problem)
        values["grid"] = AllocationResult.from_payload(data.table("grid"), grid_problem)
        if values["certified"] and values["searched_only"]:
            raise data.error("certified", "cannot be true for a search-only result")
        if values["certificate"] is not None:
            values["certificate"].attrs["current"] = data.boolean("certificate_current")
        return cls(**values)


SAVED_FORMAT = "precrel.continuous_allocation"
SAVED_FIELDS = (Flag("certified"), Number("rtol", positive=True),
                Frame("certificate", ("allowed", "excess", "meets"), optional=True),
                Frame("added", ("solve", "source", "output", "ratio")),
                Integer("solves", low=0), Integer("certificate_calls", low=0),
                Integer("searches", low=0), Number("seconds", low=0.0), Text("reason"),
                Flag("searched_only"), Flag("capped"), Text("workspace", WORKSPACES),
                Array("scaled", (None,), optional=True, positive=True))


def continuous_unavailable(machine) -> str | None:
    """Why the continuous certificate cannot cover a study of ``machine`` (its frame and error
    model), in words; None when it can."""
    if getattr(machine, "correlation", None) is not None:
        return "the certificate bounds σ of independent errors and this machine's are correlated"
    return None


def check_continuous(machine, side: str = "two_sided") -> None:
    """Refuse, before any work, a study the continuous certificate cannot cover.

    Parameters
    ----------
    machine : Machine
        In the frame and with the error model of the study.
    side : {'two_sided', 'one_sided', 'stack'}

    Raises
    ------
    InputError
        Naming the workspace, why (:func:`continuous_unavailable`) and suggesting the grid.
    """
    why = continuous_unavailable(machine)
    if why is not None:
        raise InputError(f"workspace 'continuous' is not available: {why}; use workspace "
                         f"'grid' (--workspace grid) for the allocation on the grid poses")


def solve_continuous(problem, *, rtol: float = DEFAULT_RTOL, max_solves: int = MAX_SOLVES,
                     max_calls: int = MAX_BOX_CALLS, search: bool = True,
                     certify: bool = True, progress=None,
                     time_limit: float | None = None) -> ContinuousAllocation:
    """The cheapest allocation meeting the targets over the continuous workspace, to ``rtol``.

    Parameters
    ----------
    problem : AllocationProblem
        A worst-case problem on a grid (or any pose set); its reading (two-sided,
        one-sided or stack), distribution, bounds and costs are kept.
    rtol : float
        Relative tolerance in σ (or the stack) of the certificate, in (0, 1). Searched only,
        any ``rtol ≥ 0``: an output is short when the search finds σ above ``1 + rtol``
        times what its target allows.
    max_solves : int
        Convex solves at most (the grid's included).
    max_calls : int
        Box evaluations per output and certificate call
        (:func:`reliability.first_order.workspace_search.certified_worst`).
    search : bool
        Cut the poses the local search
        (:func:`reliability.first_order.workspace_search.searched_worst`) finds short before
        asking the certificate (σ readings only; fewer certificate calls).
    certify : bool
        Stop on the certificate (default). False: the search alone finds the cuts and the
        loop stops when it finds no output short; the result is not certified ("searched
        only"). Needs ``search`` and a σ reading (the search reads σ, not the stack).
    progress : callable, optional
        ``progress(text)`` after each step: the solve, the largest excess, the outputs
        short, the boxes left open and the seconds since the start.
    time_limit : float, optional
        Seconds after which the loop stops (a certificate under way stops at its deadline
        with the boxes still open counted in its bound) with the allocation of the last
        solve, ``certified`` False and the reason "not certified to rtol: stopped by the
        time limit after S s". Ctrl-C (KeyboardInterrupt) during the loop stops it alike
        ("… interrupted after S s"). Either way, when the last certificate is of that
        allocation and bounds every output, :attr:`ContinuousAllocation.scaled` is the
        allocation scaled into certified feasibility.

    Returns
    -------
    ContinuousAllocation
    """
    certify, search = bool(certify), bool(search)
    rtol = (checks.finite_float(rtol, "rtol", 0.0, 1.0, low_open=True, high_open=True)
            if certify else checks.finite_float(rtol, "rtol", 0.0))
    max_solves = checks.positive_int(max_solves, "max_solves")
    max_calls = checks.positive_int(max_calls, "max_calls")
    if time_limit is not None:
        time_limit = checks.finite_float(time_limit, "time_limit", 0.0, low_open=True)
    progress = progress or (lambda text: None)
    checks.callback(progress, "progress")
    _check_loop(problem, certify, search)
    loop = _Loop(problem, rtol, max_calls,
                 search and problem.side != "stack" and problem.life is None, certify,
                 progress, time_limit)
    try:
        loop.run(max_solves)
    except KeyboardInterrupt:
        loop.reason = f"not certified to rtol: interrupted after {loop.elapsed():.1f} s"
    return loop.answer()


def _check_loop(problem, certify, search) -> None:
    """Refuse, before any work, a problem or mode the loop cannot run."""
    if problem.workspace != "worst":
        raise InputError("workspace 'continuous' needs the worst-case reading (the "
                         "workspace-mean reading averages over the grid poses); use the "
                         "grid")
    if certify:
        check_continuous(problem.machine, problem.side)
    elif problem.life is not None:
        raise InputError("certify=False: a life problem is found short by its certificate "
                         "only (the local search reads σ against one allowed σ per output)")
    elif problem.side == "stack":
        raise InputError("certify=False needs a σ reading: the local search reads σ, and "
                         "under the stack reading only the certificate finds poses")
    elif not search:
        raise InputError("certify=False needs search=True: without the certificate the "
                         "local search is what finds the poses")


class _Loop:
    """The state of the cutting-plane loop of :func:`solve_continuous`: the pose set, its
    optimum, the last certificate, the poses added and the counts."""

    def __init__(self, problem, rtol, max_calls, search, certify, progress, time_limit):
        self.started = time.perf_counter()
        self.problem, self.rtol, self.max_calls = problem, rtol, max_calls
        self.search, self.certify, self.progress = search, certify, progress
        self.deadline = None if time_limit is None else self.started + time_limit
        self.current, self.result = problem, problem.solve_exact()
        self.grid, self.solves, self.calls, self.searches = self.result, 1, 0, 0
        self.added, self.table, self.table_solve = [], None, 0
        self.reason, self.capped = "", False

    def elapsed(self) -> float:
        return time.perf_counter() - self.started

    def late(self) -> bool:
        return self.deadline is not None and time.perf_counter() > self.deadline

    def run(self, max_solves) -> None:
        """Solve, cut, solve again until nothing is cut, the cap or the time limit."""
        while True:
            if self.late():
                self.reason = self._late_reason()
                return
            cut = self._cuts()
            if not len(cut):
                if self.certify and self.late() and not self.table["meets"].all():
                    self.reason = self._late_reason()  # cut short of its gap by the deadline
                return
            if self.late():
                self.reason = self._late_reason()
                return
            if self.solves >= max_solves:
                self.reason = (f"stopped after {max_solves} solves with output(s) "
                               f"{', '.join(cut['output'])} still short")
                self.capped = True
                return
            current = self.current.with_poses(
                cut[list(self.problem.machine.axes)].to_numpy(dtype=float))
            self.result, self.current = current.solve_exact(), current
            self.added.append(cut.assign(solve=self.solves))
            self.solves += 1

    def _late_reason(self) -> str:
        return (f"not certified to rtol: stopped by the time limit after "
                f"{self.elapsed():.1f} s")

    def _cuts(self) -> pd.DataFrame:
        """The poses to cut at the current optimum: the local search's, or when it finds
        none (and certifying) the certificate's, asked to stop at the first pose short by
        more than :data:`SEARCH_SHARE` × rtol."""
        cut = None
        threshold = SEARCH_SHARE * self.rtol if self.certify else self.rtol
        if self.search:
            self.searches += 1
            cut, largest = _searched_cuts(self.current, self.result.tolerances, threshold)
            self.progress(f"solve {self.solves}: cost {self.result.cost:.6g}; local search: "
                          f"largest σ {largest - 1:+.3g} over what the targets allow; "
                          f"{len(cut)} output(s) short by more than {threshold:g}; "
                          f"{self.elapsed():.1f} s")
        if self.certify and (cut is None or not len(cut)):
            self.calls += 1
            self.table = certificate_table(self.current, self.result.tolerances, self.rtol,
                                           self.max_calls, stop_share=SEARCH_SHARE,
                                           close_share=CLOSE_SHARE, deadline=self.deadline)
            self.table_solve = self.solves
            cut = _certified_cuts(self.current, self.table, self.rtol)
            self.progress(_certificate_line(self.solves, self.result.cost, self.table,
                                            len(cut), self.elapsed()))
        return cut

    def answer(self) -> ContinuousAllocation:
        table, reason = self.table, self.reason
        current = table is not None and self.table_solve == self.solves
        if table is not None:
            table.attrs["current"] = current
        is_certified = (self.certify and not reason and current
                        and bool(table["meets"].all()))
        if self.certify and not is_certified and not reason:
            reason = _uncertified_reason(table, self.rtol)
        if not self.certify and not reason:
            reason = "searched only"
        scaled = (_scaled(self.result, table) if current and not is_certified
                  and self.problem.life is None else None)  # the drift does not scale
        return ContinuousAllocation(
            result=self.result, grid=self.grid, certified=is_certified, rtol=self.rtol,
            certificate=table, added=_added_frame(self.problem.machine, self.added),
            solves=self.solves, certificate_calls=self.calls, searches=self.searches,
            seconds=self.elapsed(), reason=reason, searched_only=not self.certify,
            capped=self.capped, scaled=scaled)


def _certificate_line(solve, cost, table, short, seconds) -> str:
    """The progress line of one certificate: the largest excess of the outputs it bounds,
    the outputs it found short, the boxes left open, the time."""
    bounded = table["excess"][np.isfinite(table["excess"])]
    largest = f"{bounded.max():+.3g}" if len(bounded) else "none bounded"
    return (f"solve {solve}: cost {cost:.6g}; certificate: largest excess {largest} over "
            f"what the targets allow; {short} output(s) to cut; "
            f"{int(table['open'].sum())} box(es) open; {seconds:.1f} s")


def _scaled(result, table) -> np.ndarray | None:
    """The allocation divided by ``(1 + e)(1 + SCALE_MARGIN)``, e the largest excess of
    its certificate, when e is finite and positive: σ (Eq. 20, any distribution) and the
    stack are linear in a common factor on the tolerances, and so is the certificate's
    bound, so every output's bound then falls to what its target allows; None
    otherwise."""
    excess = float(table["excess"].max())
    if not np.isfinite(excess) or excess <= 0:
        return None
    return result.tolerances / ((1.0 + excess) * (1.0 + SCALE_MARGIN))


def solve_over_workspace(problem, *, max_rounds: int = 20, tolerance: float = 1e-6,
                         log=lambda message: None):
    """Exact optimum of a worst-case problem, refined until the local search finds no pose
    between grid points where it falls short: :func:`solve_continuous` searched only.

    The loop of :func:`solve_continuous` with ``certify=False``: solve, search from the
    worst poses of the set
    (:func:`reliability.first_order.workspace_search.searched_worst`), add every pose where
    an output's β is below ``(1 − tolerance)`` times the required index (σ above
    ``1/(1 − tolerance)`` times what its target allows), solve again. Nothing is certified
    between the poses; :func:`solve_continuous` with the certificate is the certified
    answer.

    Parameters
    ----------
    problem : AllocationProblem
        A worst-case problem (``workspace='worst'``) under a σ reading.
    max_rounds : int
        Solves at most; an error is raised if the search still finds a pose short of its
        target after the last one.
    tolerance : float
        Relative shortfall of β below the required index that counts as short, in [0, 1).
    log : callable
        Called with a line per round.

    Returns
    -------
    result : AllocationResult
        Exact optimum on the grid plus the added poses.
    added : ndarray (n_added, n_axes)
        The poses added to the grid, in the order they were added.

    Raises
    ------
    RuntimeError
        The search still finds a pose short of its target after ``max_rounds`` solves.
    """
    max_rounds = checks.positive_int(max_rounds, "max_rounds")
    tolerance = checks.finite_float(tolerance, "tolerance", 0.0, 1.0, high_open=True)
    checks.callback(log, "log")
    # β < R (1 − τ)  ⟺  σ / (I/R) > 1 / (1 − τ) = 1 + τ / (1 − τ)
    loop = solve_continuous(problem, rtol=tolerance / (1.0 - tolerance),
                            max_solves=max_rounds, certify=False, progress=log)
    if loop.capped:
        raise RuntimeError(f"continuous search still finds poses short of the target after "
                           f"{max_rounds} rounds")
    return loop.result, loop.result.problem.poses[len(problem.poses):]


def certificate_table(problem, tolerances, rtol: float = DEFAULT_RTOL,
                      max_calls: int = MAX_BOX_CALLS, *, stop_share: float | None = None,
                      close_share: float | None = None,
                      deadline: float | None = None) -> pd.DataFrame:
    """The certificate of ``tolerances`` under the problem's reading, asked for
    ``CERTIFICATE_SHARE × rtol``, with what each output's target allows (``allowed``: σ
    ``I/z``, or the limit ``I`` for the stack), ``excess`` = bound / allowed − 1 and
    ``meets`` (``excess ≤ rtol``). With ``stop_share``, an output's search stops at the
    first pose above ``(1 + stop_share × rtol)`` × allowed (its bound is then ``+inf``);
    ``deadline`` as in :func:`~reliability.first_order.workspace_search.certified_worst`.
    A life problem's certificate is :func:`allocation.per_pose.life.life_certificate_table`."""
    if problem.life is not None:
        return life_certificate_table(problem, tolerances, rtol, max_calls,
                                      stop_share=stop_share,
                                      certificate_share=CERTIFICATE_SHARE, deadline=deadline)
    machine = problem.machine
    if problem.side == "stack":
        allowed = machine.limits
        options = dict(reading="stack")
    else:
        allowed = problem.allowed_sigma
        options = dict(distribution=problem.distribution)
    above = None if stop_share is None else np.asarray(allowed) * (1.0 + stop_share * rtol)
    below = None if close_share is None else np.asarray(allowed) * (1.0 + close_share * rtol)
    table = certified_worst(machine, tolerances, rtol=CERTIFICATE_SHARE * rtol,
                            k=problem.k, max_calls=max_calls, memory=problem.memory,
                            stop_above=above, close_below=below, deadline=deadline,
                            **options)
    bound = _columns(problem)[1]
    table = table.copy()
    table["allowed"] = allowed
    table["excess"] = table[bound] / allowed - 1.0
    table["meets"] = table["excess"] <= rtol
    return table


def certificate_text(problem, table) -> str:
    """The certificate as a table for people: worst pose (mm, deg), value, bound, allowed,
    excess, per output."""
    machine = problem.machine
    value, bound = _columns(problem)
    name = "stack" if problem.side == "stack" else "sigma"
    shown = pd.DataFrame({
        "certified worst pose": [pose_text(row, machine.axes, axis_units(machine), digits=6)
                                 for row in table[list(machine.axes)].to_numpy(dtype=float)],
        "unit": list(OUTPUT_UNITS),
        name: [f"{v:.6g}" for v in table[value]],
        f"{name} bound": [upper_bound_text(v, 6) for v in table[bound]],
        "allowed": [f"{v:.6g}" for v in table["allowed"]],
        "bound/allowed - 1": [upper_bound_text(v, 3) for v in table["excess"]],
        "certificate gap": [gap_text(v) for v in table["gap"]],
    }, index=table.index)
    return shown.to_string()


def _columns(problem) -> tuple[str, str]:
    """The certificate's value and bound columns under the problem's reading."""
    return ("stack", "stack_bound") if problem.side == "stack" else ("sigma", "sigma_bound")


def _certified_cuts(problem, table, rtol) -> pd.DataFrame:
    """Outputs whose bound exceeds what the target allows by more than ``rtol`` and whose
    certified worst pose is itself short (so its row cuts off the current optimum)."""
    value, _ = _columns(problem)
    ratio = (table[value].to_numpy() / table["allowed"].to_numpy() if problem.life is None
             else table["sigma0"].to_numpy() / table["life_allowed"].to_numpy())
    short = (table["excess"].to_numpy() > rtol) & (ratio > 1.0)
    frame = table.loc[short, list(problem.machine.axes)].reset_index()
    frame["ratio"] = ratio[short]
    frame["source"] = "certificate"
    return frame


def _searched_cuts(problem, tolerances, threshold) -> tuple[pd.DataFrame, float]:
    """Outputs that the local search finds short by more than ``threshold`` (σ over the
    allowed σ minus 1), with the poses found, and the largest σ / allowed σ it found.

    The search (:func:`reliability.first_order.workspace_search.searched_worst`) starts from
    the poses of the set where each output is largest, reads σ under the problem's ``k`` and
    distribution, and maximises σ over the σ its target allows, so that outputs in mm and in
    rad are searched alike; its poses are rounded to a resolution and its ties broken by one
    rule, so the poses it adds are the same on every computer."""
    allowed = problem.allowed_sigma
    found = searched_worst(problem.machine, tolerances, problem.poses, k=problem.k,
                           distribution=problem.distribution, scale=allowed,
                           starts=SEARCH_STARTS, grid_sigma=problem.sigma(tolerances),
                           memory=problem.memory)
    ratio = found["sigma"].to_numpy() / allowed
    short = ratio > 1.0 + threshold
    frame = found.loc[short, list(problem.machine.axes)].reset_index()
    frame["ratio"] = ratio[short]
    frame["source"] = "search"
    return frame, float(ratio.max())


def _uncertified_reason(table, rtol) -> str:
    """Why a certificate with no pose to cut does not certify: an output's bound is above
    what the target allows while its certificate's gap is too wide to find a short pose."""
    worst = table["excess"].idxmax()
    row = table.loc[worst]
    if "slope" in table:  # a life certificate (allocation.per_pose.life)
        return (f"the bound on {worst} exceeds what its line allows by {row['excess']:.3g} "
                f"> {rtol:g} while its worst pose meets the life target: the line "
                f"σ0² + c·s_d² below the life curve is not tight where {worst} binds "
                f"(docs/life-allocation.md)")
    return (f"the bound on {worst} exceeds what its target allows by {row['excess']:.3g} "
            f"> {rtol:g} and its certificate stopped at gap {row['gap']:.3g} after "
            f"{int(row['calls'])} box evaluations")


def _added_frame(machine, parts) -> pd.DataFrame:
    """The added poses for people: solve, source, output, pose in mm / deg, ratio."""
    columns = ["solve", "source", "output"]
    if not parts:
        empty = pose_frame(np.zeros((0, len(machine.axes))), machine.axes,
                           axis_units(machine), style="csv")
        return pd.concat([pd.DataFrame(columns=columns), empty, pd.DataFrame(columns=["ratio"])],
                         axis=1)
    joined = pd.concat(parts, ignore_index=True)
    poses = pose_frame(joined[list(machine.axes)].to_numpy(dtype=float), machine.axes,
                       axis_units(machine), style="csv")
    return pd.concat([joined[columns], poses, joined[["ratio"]]], axis=1)


