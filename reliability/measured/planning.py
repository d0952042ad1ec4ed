"""Planning the measurements: the candidate runs that best pin down what decides the
machine's limits, within a budget (docs/measurements.md).

The posterior covariance of a linear-Gaussian identification depends only on where the runs
read and how well, not on what they read. With the errors scaled by their prior σ
(``S = diag σ``, σ = t/3 of the allocation in force), a run ``r`` adds the information
``G_r = S F_r S`` (``F_r`` its information about the errors once its own set-up is
estimated; set-ups are per run, so the information of a plan is the sum of its runs'), and
the scaled posterior covariance of a plan ``P`` is ``(I + Σ_{r∈P} G_r)⁻¹``. ``F_r`` is
:func:`~reliability.measured.identification.plan_information` of the run alone.

What decides the limits is each output's σ at its worst pose: the grid pose where the
prior σ of the output (machine frame) is largest. The plan minimises

    V(P) = Σ_o (σ_o,post(P) / I_o)²,  σ_o,post² = g_oᵀ (I + Σ G_r)⁻¹ g_o,

``g_o`` the output's row of the Jacobian at its worst pose times ``S``: the six posterior
variances in units of their limits. ``V`` is not submodular in general, so the choice is
made twice: greedily by gain per cost with lazy evaluation (a run's last gain bounds its
next one when the gains shrink as the plan grows, and it is re-evaluated whenever it comes
first), kept against the best single affordable run, then improved by exchanging one run for
another (or adding one) while that lowers ``V`` within the budget; and, when there are at most
:data:`EXHAUSTIVE_CANDIDATES` candidates, over every affordable subset. The better is
chosen, and the output says which.
"""

from __future__ import annotations

import heapq
import itertools
import math
from dataclasses import dataclass
from typing import Mapping

import numpy as np
import pandas as pd

from ..basics.errors import InputError, SavedResultError
from ..basics.files import read_toml
from ..basics.saved_fields import Array, Frame, Number, Text, read_fields, write_fields
from ..basics.saved_fields import Mapping as SavedMapping
from ..basics.saved_results import load_payload, save_payload
from ..model.kinematics import output_variance
from ..model.machine import OUTPUTS
from ..model.poses import workspace_grid
from .identification import plan_information
from .plans import parse_plan

#: Every affordable subset is searched when there are at most this many candidates.
EXHAUSTIVE_CANDIDATES = 12
#: Cost of a run whose entry gives none.
DEFAULT_COST = 1.0


@dataclass(frozen=True, eq=False)
class Candidate:
    """A candidate run: the run, its plan-file entry (written back when chosen), its cost."""

    run: object
    entry: dict
    cost: float


@dataclass(frozen=True, eq=False)
class MeasurementPlan:
    """The chosen runs and what they buy.

    Attributes
    ----------
    machine : Machine
    candidates : tuple of Candidate
    budget : float
    chosen : tuple of int
        Indices of the chosen candidates, in the order each adds the most per cost.
    added : ndarray
        ``V`` removed by each chosen run, in that order.
    method : str
        How the choice was made, in words.
    objective : dict
        ``V`` of no run, of the chosen runs, of every candidate, and of the greedy choice.
    outputs : DataFrame
        Per output: ``limit``, ``worst_pose`` (positions), and its σ there with no run
        (``prior_sd``), with the chosen runs and with every candidate.
    alone : ndarray
        ``V`` removed by each candidate alone.
    """

    machine: object
    candidates: tuple
    budget: float
    chosen: tuple
    added: np.ndarray
    method: str
    objective: dict
    outputs: pd.DataFrame
    alone: np.ndarray

    @property
    def cost(self) -> float:
        """Total cost of the chosen runs."""
        return float(sum(self.candidates[i].cost for i in self.chosen))

    def candidate_table(self) -> pd.DataFrame:
        """Every candidate: ``run, cost, readings, alone`` (share of ``V`` it removes
        alone), ``chosen``."""
        prior = self.objective["none"]
        return pd.DataFrame({
            "run": [c.run.name for c in self.candidates],
            "cost": [c.cost for c in self.candidates],
            "readings": [len(c.run.poses) * len(c.run.quantities) for c in self.candidates],
            "alone": self.alone / prior,
            "chosen": [i in self.chosen for i in range(len(self.candidates))]})

    def summary(self) -> str:
        """The choice, what each chosen run adds, and each output's σ at its worst pose."""
        v = self.objective
        lines = [f"{len(self.chosen)} of {len(self.candidates)} candidate runs chosen, cost "
                 f"{self.cost:g} of the budget {self.budget:g} (all candidates cost "
                 f"{sum(c.cost for c in self.candidates):g}); {self.method}",
                 f"V = sum over outputs of (posterior sd / limit)^2 at each output's worst "
                 f"pose: no run {v['none']:.4g}, chosen {v['chosen']:.4g}, every candidate "
                 f"{v['all']:.4g} (the chosen runs remove "
                 f"{_share(v['none'] - v['chosen'], v['none'] - v['all'])} of what every "
                 f"candidate removes)", "", "what each chosen run adds, in order:"]
        lines += [f"  {self.candidates[i].run.name} (cost {self.candidates[i].cost:g}): "
                  f"V -{added:.4g} ({100 * added / v['none']:.1f} % of V with no run)"
                  for i, added in zip(self.chosen, self.added)]
        return "\n".join(lines)

    def to_frame(self) -> pd.DataFrame:
        """Every candidate and whether it was chosen: :meth:`candidate_table`."""
        return self.candidate_table()

    def save(self, path, overwrite: bool = False):
        """Save as JSON (:data:`SAVED_FIELDS` and every candidate's plan-file entry, tag
        :data:`SAVED_FORMAT`); the machine is not saved. An existing file is kept unless
        ``overwrite``. Returns the path."""
        payload = write_fields(self, SAVED_FIELDS)
        payload["candidates"] = [candidate.entry for candidate in self.candidates]
        return save_payload(path, SAVED_FORMAT, payload, overwrite)

    @classmethod
    def load(cls, path, machine) -> "MeasurementPlan":
        """Reload a plan written by :meth:`save` for ``machine`` (the one it was planned
        for): the candidates are parsed again from their saved entries against it and
        every field is checked (the chosen runs within the budget), so the choice and its
        cost are the saved ones. A damaged field raises
        :class:`~reliability.basics.errors.SavedResultError` naming the file and field."""
        data = load_payload(path, SAVED_FORMAT)
        entries = data.raw("candidates")
        try:
            candidates = parse_candidates({"tests": entries}, machine,
                                          source=f"{path}: field 'candidates'")
        except InputError as exc:
            raise SavedResultError(str(exc)) from None
        values = read_fields(data, SAVED_FIELDS)
        chosen = values["chosen"]
        if np.any(chosen >= len(candidates)) or len(set(chosen)) != len(chosen):
            raise data.error("chosen", "expected distinct candidate numbers")
        if len(values["added"]) != len(chosen) or len(values["alone"]) != len(candidates):
            raise data.error("added", "expected one entry per chosen run ('alone': one per "
                                      "candidate)")
        values["chosen"] = tuple(int(i) for i in chosen)
        plan = cls(machine=machine, candidates=candidates, **values)
        if plan.cost > plan.budget * (1 + 1e-12):
            raise data.error("chosen", "the chosen runs cost more than the budget")
        return plan

    def to_toml(self, source: str = "") -> str:
        """The chosen runs as a plan file, in the candidates' order."""
        import tomli_w
        entries = [self.candidates[i].entry for i in sorted(self.chosen)]
        head = (f"# Measurement plan chosen from {source or 'the candidates'} for "
                f"{self.machine.name!r}: {len(entries)} runs, cost {self.cost:g} of the "
                f"budget {self.budget:g} (docs/measurements.md).\n\n")
        return head + tomli_w.dumps({"tests": entries})


SAVED_FORMAT = "precrel.measurement_plan"
SAVED_FIELDS = (Number("budget", positive=True), Array("chosen", (None,), dtype=int, low=0),
                Array("added", (None,)), Text("method"), SavedMapping("objective"),
                Frame("outputs", ("limit", "prior_sd")), Array("alone", (None,)))


def read_candidates(path, machine) -> tuple[Candidate, ...]:
    """Read a plan file whose tests may carry ``cost`` (default 1) as candidate runs."""
    data = read_toml(path)
    return parse_candidates(data, machine, source=str(path))


def parse_candidates(data: Mapping, machine, source: str = "candidates"
                     ) -> tuple[Candidate, ...]:
    """Check a parsed candidate plan: the plan itself (:func:`parse_plan`) and each cost."""
    entries = data.get("tests") if isinstance(data, Mapping) else None
    if not isinstance(entries, list) or not all(isinstance(e, Mapping) for e in entries):
        raise InputError(f"{source}: expected one or more [[tests]] tables")
    costs = [_cost(entry, f"{source}: test {entry.get('name')!r}") for entry in entries]
    runs = parse_plan(data, machine, source)
    return tuple(Candidate(run, dict(entry), cost)
                 for run, entry, cost in zip(runs, entries, costs))


def _cost(entry, where) -> float:
    value = entry.get("cost", DEFAULT_COST)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or \
            not math.isfinite(value) or value <= 0:
        raise InputError(f"{where}, key 'cost': expected a number > 0; got {value!r}")
    return float(value)


def plan_measurements(machine, candidates, budget: float, *, tolerances=None,
                      points: int = 5) -> MeasurementPlan:
    """Choose the candidate runs that best pin down each output's σ at its worst pose.

    Parameters
    ----------
    machine : Machine
    candidates : sequence of Candidate
        From :func:`read_candidates`.
    budget : float
        Total cost the chosen runs may take.
    tolerances : array_like, optional
        Allocation in force (prior σ = t/3); the initial allocation by default.
    points : int
        Grid points per axis among which each output's worst pose is sought.

    Returns
    -------
    MeasurementPlan
    """
    candidates = tuple(candidates)
    if not candidates:
        raise InputError("candidates: give at least one run")
    if isinstance(budget, bool) or not isinstance(budget, (int, float)) or \
            not math.isfinite(budget) or budget <= 0:
        raise InputError(f"budget: expected a number > 0; got {budget!r}")
    t = machine.initial_allocation if tolerances is None else machine.check_tolerances(tolerances)
    prior_sd = np.asarray(t, dtype=float) / 3.0
    information = [run_information(machine, c.run, prior_sd) for c in candidates]
    rows, worst = worst_rows(machine, prior_sd, points)
    score = _Objective(rows, information, machine.limits)
    costs = np.array([c.cost for c in candidates])
    greedy = _improve_by_swaps(score, costs, budget, _lazy_greedy(score, costs, budget))
    chosen, method = greedy, "greedy by gain per cost with lazy evaluation, then swaps"
    if len(candidates) <= EXHAUSTIVE_CANDIDATES:
        best = _exhaustive(score, costs, budget)
        chosen = best if score(best) < score(greedy) - 1e-12 * score(()) else greedy
        method += (f"; every affordable subset searched ({len(candidates)} candidates): "
                   + ("the greedy choice is the best" if chosen == greedy else
                      f"a better one than the greedy choice (V {score(greedy):.4g}) "
                      f"chosen"))
    order, added = _greedy_order(score, chosen)
    everything = tuple(range(len(candidates)))
    return MeasurementPlan(
        machine=machine, candidates=candidates, budget=float(budget), chosen=order,
        added=added, method=method,
        objective={"none": score(()), "chosen": score(order), "all": score(everything),
                   "greedy": score(greedy)},
        outputs=pd.DataFrame({"limit": machine.limits, "worst_pose": list(worst),
                              "prior_sd": score.sd(()), "chosen_sd": score.sd(order),
                              "all_sd": score.sd(everything)},
                             index=pd.Index(OUTPUTS, name="output")),
        alone=np.array([score(()) - score((i,)) for i in everything]))


def run_information(machine, run, prior_sd) -> np.ndarray:
    """``G_r = S F_r S``: the prior-scaled information one run gives about the errors."""
    return plan_information(machine, (run,)) * np.outer(prior_sd, prior_sd)


def worst_rows(machine, prior_sd, points) -> tuple[np.ndarray, np.ndarray]:
    """``(6, n_errors)`` rows ``g_o / I_o`` (Jacobian row at the output's worst grid pose,
    machine frame, times the prior σ) and the ``(6, n_axes)`` worst poses."""
    grid = workspace_grid(machine, points)
    variance = output_variance(machine, grid, prior_sd ** 2, frame=machine.frame)
    worst = grid[np.argmax(variance, axis=0)]
    jacobian = machine.jacobian(worst)
    rows = jacobian[np.arange(6), np.arange(6), :] * prior_sd / machine.limits[:, None]
    return rows, worst


class _Objective:
    """``V`` of a set of candidates, and each output's posterior σ at its worst pose."""

    def __init__(self, rows, information, limits):
        self.rows = rows
        self.information = information
        self.limits = limits

    def _scaled_variances(self, chosen) -> np.ndarray:
        precision = np.eye(self.rows.shape[1]) + sum(
            (self.information[i] for i in chosen), np.zeros_like(self.information[0]))
        solved = np.linalg.solve(precision, self.rows.T)
        return np.einsum("oi,io->o", self.rows, solved)

    def __call__(self, chosen) -> float:
        return float(self._scaled_variances(chosen).sum())

    def sd(self, chosen) -> np.ndarray:
        """Each output's σ (mm, rad) at its worst pose, limits put back."""
        return np.sqrt(np.maximum(self._scaled_variances(chosen), 0.0)) * self.limits


def _lazy_greedy(score, costs, budget) -> tuple:
    """Greedy by gain per cost with lazy re-evaluation, against the best single run."""
    chosen, spent, current = [], 0.0, score(())
    queue = [(-(current - score((i,))) / costs[i], i) for i in range(len(costs))]
    heapq.heapify(queue)
    while queue:
        _, i = heapq.heappop(queue)
        if spent + costs[i] > budget:
            continue
        fresh = (current - score((*chosen, i))) / costs[i]
        if queue and fresh < -queue[0][0]:
            heapq.heappush(queue, (-fresh, i))
            continue
        if fresh <= 0:
            break
        chosen.append(i)
        spent += costs[i]
        current = score(chosen)
    affordable = [i for i in range(len(costs)) if costs[i] <= budget]
    single = min(affordable, key=lambda i: score((i,)), default=None)
    if single is not None and score((single,)) < score(chosen):
        return (single,)
    return tuple(sorted(chosen))


def _improve_by_swaps(score, costs, budget, chosen) -> tuple:
    """``chosen`` with one run exchanged for another, or one added, while the best such
    change that fits the budget lowers ``V``."""
    chosen = tuple(chosen)
    while True:
        others = [j for j in range(len(costs)) if j not in chosen]
        changes = [tuple(sorted((*chosen, j))) for j in others] + \
            [tuple(sorted((*(k for k in chosen if k != i), j)))
             for i in chosen for j in others]
        changes = [c for c in changes if costs[list(c)].sum() <= budget]
        best = min(changes, key=score, default=None)
        if best is None or score(best) >= score(chosen):
            return chosen
        chosen = best


def _exhaustive(score, costs, budget) -> tuple:
    """The affordable subset of least ``V`` (the first found on ties)."""
    best, best_value = (), score(())
    for size in range(1, len(costs) + 1):
        for subset in itertools.combinations(range(len(costs)), size):
            if costs[list(subset)].sum() <= budget:
                value = score(subset)
                if value < best_value:
                    best, best_value = subset, value
    return best


def _greedy_order(score, chosen) -> tuple[tuple, np.ndarray]:
    """``chosen`` ordered by what each adds to those before it, and what it adds."""
    order, added, left = [], [], list(chosen)
    while left:
        gains = [score(order) - score((*order, i)) for i in left]
        k = int(np.argmax(gains))
        order.append(left.pop(k))
        added.append(gains[k])
    return tuple(order), np.array(added)


def _share(part: float, whole: float) -> str:
    return "all" if whole <= 0 else f"{100 * part / whole:.1f} %"
