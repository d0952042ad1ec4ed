"""The cheapest choice of one class per catalogue component, certified by a MILP solver.

With the FOSM readings the variance of output ``o`` at a pose is linear in the items'
variances (Eq. 20, σ_i = t_i/k), so every constraint row of the worst-case allocation
problem (:class:`~allocation.per_pose.problem.AllocationProblem`, ``row @ u ≤ 1`` with ``u = t²``;
``u = t`` for the worst-case stack) is linear in the class indicators ``x_cj`` (1 when
component ``c`` takes class ``j``)::

    minimise    Σ_cj price_cj x_cj
    subject to  Σ_j x_cj = 1                                     for every component c
                Σ_cj (row_r[items c] @ u(T_cj)) x_cj ≤ 1 − row_r[rest] @ u(t_start)
                                                                  for every row r
                x_cj ∈ {0, 1}

Items in no component keep the problem's reference tolerances (the study's starting
allocation); catalogue classes are used as given, so the problem's search box does not
apply to them. The rows are the problem's poses screened afresh for the box the catalogue
spans (each catalogue item up to its loosest class, every other item at its start): the
box step then removes only rows no choice can load above 1, and duplicates and dominance
are exact for any tolerances, so the screened rows are exactly the problem's constraints.
More poses (e.g. worst poses of a continuous-workspace certificate) are added with
:meth:`AllocationProblem.with_poses` and become rows the same way.

The integer program is solved by HiGHS through :func:`scipy.optimize.milp` with a relative
gap of :data:`MIP_REL_GAP` (not HiGHS's default 1e-4), by row generation: HiGHS first sees
no row, then after each answer the rows that answer violates (the most loaded of each
output) are added and the program solved again, until an answer violates no row. Each
program has a subset of the rows, so its dual bound is a lower bound on the full optimum,
and its answer, feasible for every row, is the full optimum with the same gap. On the
paper's machine about a hundred of its ~3000 screened rows suffice, several times faster
than giving HiGHS every row (``python -m studies.benchmarks.catalogue``).

The answer is then re-checked on every row of every pose of the problem. HiGHS accepts
rows within its feasibility tolerance, so an answer that exceeds a row it already has by
more than :data:`LOAD_TOLERANCE` is cut off (a no-good cut on that one choice) and the
program solved again: every choice cut off is infeasible, so the certificate still holds.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy.optimize import Bounds, LinearConstraint, milp

from reliability.basics.display import (axis_units, lower_bound_text, pose_text,
                                        upper_bound_text)
from reliability.basics.errors import InputError, InputTypeError
from reliability.basics.files import write_csv
from reliability.basics.errors import SavedResultError
from reliability.basics.saved_fields import (Array, Flag, Frame, Mapping, Number, load_fields,
                                            save_fields)
from reliability.basics.saved_results import check_count
from reliability.model.machine import OUTPUTS

from ..per_pose.problem import AllocationProblem
from ..solvers.convex import InfeasibleAllocationError
from .catalogue import Catalogue

#: Relative gap between the price found and HiGHS's dual bound at which the search stops.
MIP_REL_GAP = 1e-9
#: A row's load (σ² over the allowed σ², or stack over limit) may exceed 1 by this much.
LOAD_TOLERANCE = 1e-9
#: No-good cuts allowed for choices HiGHS accepts within its feasibility tolerance.
MAX_CUTS = 50
#: Violated rows of each output added per round of row generation.
ROWS_PER_ROUND = 16
CHOICE_COLUMNS = ("component", "class", "price")


class CatalogueInfeasibleError(InfeasibleAllocationError):
    """No choice of classes meets every requirement.

    Attributes
    ----------
    blocking : DataFrame
        Rows (output, pose) that exceed their limit even with every component at its
        tightest class, worst first, with the pose's axis positions (mm, rad) and the load
        (1 = what the requirement allows); empty when every row alone can be met but no
        single choice meets them all.
    """

    def __init__(self, message: str, blocking: pd.DataFrame):
        ValueError.__init__(self, message)
        self.blocking = blocking
        self.rows = ()
        self.loads = np.asarray(blocking.get("load", ()), dtype=float)


@dataclass(frozen=True, eq=False)
class CatalogueResult:
    """The certified cheapest choice of classes (:func:`solve_catalogue`).

    Attributes
    ----------
    problem : AllocationProblem
    catalogue : Catalogue
    choice : dict
        Component name -> chosen class name, in the catalogue's order.
    price : float
        Total price of the choice.
    gap : float
        Relative gap ``(price − dual bound) / price`` proved by HiGHS (≤ 1e-9 when
        ``certified``).
    dual_bound : float
        No choice meeting the requirements costs less.
    tolerances : ndarray (n_errors,)
        The tolerances that follow: each component's items at its chosen class, every
        other item at the problem's reference.
    feasible : bool
        The re-check on every row of every pose passed (largest load ≤ 1 + 1e-9).
    certified : bool
        HiGHS proved optimality to the gap and the re-check passed.
    worst : DataFrame
        Per output: the largest load at the choice, σ (or the stack) over what the target
        allows, the pose where it occurs and its axis positions.
    neighbours : DataFrame
        Per component, the class one step tighter and one looser (see
        :meth:`Component.loosest_first`) with the other components held: the price change,
        the total price and whether it still meets every requirement, else the output and
        pose it breaks (its index ``pose`` among the problem's poses, -1 when it meets
        every requirement, and its axis positions, NaN then).
    details : dict
        ``rows`` (screened rows, per step), ``variables``, ``nodes`` (of the last HiGHS
        run), ``rounds`` and ``active_rows`` of the row generation, ``cuts``,
        ``max_load``, ``poses``.
    """

    problem: object = field(repr=False)
    catalogue: Catalogue = field(repr=False)
    choice: dict
    price: float
    gap: float
    dual_bound: float
    tolerances: np.ndarray
    feasible: bool
    certified: bool
    worst: pd.DataFrame
    neighbours: pd.DataFrame
    details: dict

    def to_frame(self) -> pd.DataFrame:
        """The choice: columns ``component, class, price``, one row per component."""
        prices = [next(k.price for k in c.classes if k.name == self.choice[c.name])
                  for c in self.catalogue.components]
        return pd.DataFrame({"component": list(self.choice),
                             "class": list(self.choice.values()), "price": prices},
                            columns=list(CHOICE_COLUMNS))

    def binding(self) -> pd.DataFrame:
        """What binds: each output that forbids a one-class loosening of some component,
        with those components, and the output's largest load at the choice and its pose
        (axis positions)."""
        broken = self.neighbours[(self.neighbours["direction"] == "looser")
                                 & ~self.neighbours["meets"].astype(bool)]
        rows = []
        for output in OUTPUTS:
            blocked = broken[broken["breaks"] == output]
            if len(blocked):
                rows.append({"output": output,
                             "blocks_loosening_of": ", ".join(blocked["component"]),
                             "worst_load": float(self.worst.loc[output, "load"]),
                             "worst_pose": _pose_text(self.problem,
                                                      int(self.worst.loc[output, "pose"]))})
        return pd.DataFrame(rows, columns=["output", "blocks_loosening_of", "worst_load",
                                           "worst_pose"])

    def summary(self) -> str:
        """The choice, its price and certificate, what binds and the neighbours' prices."""
        currency = f" {self.catalogue.currency}" if self.catalogue.currency else ""
        problem = self.problem
        lines = [] if self.feasible else ["NOT FEASIBLE: the re-check found a row above "
                                          "its limit; do not use this choice"]
        lines += [f"Component choice from {len(self.catalogue.components)} components "
                  f"({self.catalogue.n_choices:,} possible choices) for "
                  f"{problem.machine.name}: every target at every one of "
                  f"{len(problem.poses)} poses, {_reading(problem)}; classes as given (no "
                  f"search box), items in no component at the starting tolerances",
                  f"total price {self.price:.6g}{currency}",
                  f"relative gap {upper_bound_text(self.gap, 2)} "
                  f"({'certified optimum' if self.certified else 'NOT certified'}; "
                  f"dual bound {lower_bound_text(self.dual_bound)}, "
                  f"{self.details['nodes']} nodes)",
                  "", self.to_frame().to_string(index=False), ""]
        binding = self.binding()
        if len(binding):
            lines += ["What binds (requirements that forbid loosening a component by one "
                      "class):", binding.to_string(index=False)]
        else:
            lines.append("What binds: no requirement forbids loosening any component by "
                         "one class (every component is at its loosest class or a looser "
                         "one costs more)")
        lines += ["", "Moving one component by one class, the others held:",
                  neighbour_table(self).to_string(index=False)]
        return "\n".join(lines)

    def __repr__(self) -> str:
        return self.summary()

    def to_csv(self, path, overwrite: bool = False, *, significant: int | None = None):
        """Write :meth:`to_frame` (columns ``component, class, price``, no total row);
        returns the path."""
        float_format = None if significant is None else \
            f"%.{check_count(significant, 'significant')}g"
        return write_csv(self.to_frame(), path, overwrite, index=False,
                         float_format=float_format)

    def save(self, path, overwrite: bool = False):
        """Save as JSON (:data:`SAVED_FIELDS`, tag :data:`SAVED_FORMAT`); the problem and
        the catalogue are not saved. An existing file is kept unless ``overwrite``.
        Returns the path."""
        return save_fields(self, path, SAVED_FORMAT, SAVED_FIELDS, overwrite)

    @classmethod
    def load(cls, path, problem, catalogue) -> "CatalogueResult":
        """Reload a choice written by :meth:`save` for ``problem`` and ``catalogue`` (the
        ones it was solved for), every field checked: each component's class is one of
        the catalogue's, the price is the sum of the chosen classes' prices and the
        tolerances are one per error of the problem, so the choice, its price and its
        certificate are the saved ones. A damaged field raises
        :class:`~reliability.basics.errors.SavedResultError` naming the file and field."""
        data, values = load_fields(path, SAVED_FORMAT, SAVED_FIELDS)
        classes = {c.name: {k.name: k.price for k in c.classes}
                   for c in catalogue.components}
        choice = values["choice"]
        if list(choice) != list(classes) or any(choice[c] not in classes[c] for c in choice):
            raise data.error("choice", "expected one of its classes for every component of "
                                       "the catalogue, in its order")
        price = sum(classes[c][choice[c]] for c in choice)
        if not np.isclose(values["price"], price, rtol=1e-12):
            raise data.error("price", f"is not the price of the chosen classes ({price!r})")
        if len(values["tolerances"]) != len(problem.names):
            raise SavedResultError(f"{path}: field 'tolerances': expected one per error of "
                                   f"the problem ({len(problem.names)})")
        return cls(problem=problem, catalogue=catalogue, **values)


SAVED_FORMAT = "precrel.catalogue_result"
SAVED_FIELDS = (Mapping("choice"), Number("price", low=0.0), Number("gap"),
                Number("dual_bound"), Array("tolerances", (None,), positive=True),
                Flag("feasible"), Flag("certified"), Frame("worst", ("load", "pose")),
                Frame("neighbours", ("component", "direction", "meets", "breaks")),
                Mapping("details"))


def neighbour_table(result: CatalogueResult) -> pd.DataFrame:
    """One line per component: chosen class, and the price change one class tighter and one
    looser (or what breaks and at which axis positions, or that there is no such class)."""
    rows = []
    for name, chosen in result.choice.items():
        row = {"component": name, "class": chosen}
        moves = result.neighbours[result.neighbours["component"] == name]
        for direction in ("tighter", "looser"):
            move = moves[moves["direction"] == direction]
            if not len(move):
                row[direction] = "none"
                continue
            move = move.iloc[0]
            row[direction] = (f"{move['class']}: {move['price_change']:+.6g}"
                              if move["meets"] else
                              f"{move['class']}: breaks {move['breaks']} at "
                              f"{_pose_text(result.problem, int(move['pose']))}")
        rows.append(row)
    return pd.DataFrame(rows, columns=["component", "class", "tighter", "looser"])


def solve_catalogue(problem, catalogue) -> CatalogueResult:
    """The cheapest choice of one class per component that meets every requirement.

    Parameters
    ----------
    problem : AllocationProblem
        Worst-case reading (``workspace='worst'``), any side. Items in no component keep
        ``problem.reference``; the problem's bounds do not apply to catalogue classes.
    catalogue : Catalogue
        Its items are checked against the problem's machine first.

    Returns
    -------
    CatalogueResult

    Raises
    ------
    InputError, InputTypeError
        A problem of the workspace-mean reading, or a catalogue naming items the machine
        does not have.
    CatalogueInfeasibleError
        No choice meets every requirement; names the output and pose that block.
    """
    if not isinstance(problem, AllocationProblem):
        raise InputTypeError(f"problem must be an AllocationProblem; got "
                             f"{type(problem).__name__}")
    if not isinstance(catalogue, Catalogue):
        raise InputTypeError(f"catalogue must be a Catalogue (allocation.load_catalogue); "
                             f"got {type(catalogue).__name__}")
    if problem.workspace != "worst":
        raise InputError("solve_catalogue: the workspace-mean reading is not linear in the "
                         "classes; build the problem with workspace='worst'")
    catalogue = catalogue.for_machine(problem.machine)
    model = _Model(problem, catalogue)
    model.check_reachable()
    x, solution, rounds = model.solve()
    chosen = np.flatnonzero(x)
    t = model.tolerances(chosen)
    loads = problem.loads(problem.variable(t))  # every row of every pose: the re-check
    max_load = float(loads.max())
    feasible = max_load <= 1.0 + LOAD_TOLERANCE
    price = float(model.prices[chosen].sum())
    bound = float(solution.mip_dual_bound)
    gap = max(0.0, (price - bound) / price)
    choice = {c.name: c.classes[j - start].name
              for c, start, j in zip(catalogue.components, model.starts, chosen)}
    return CatalogueResult(
        problem=problem, catalogue=catalogue, choice=choice, price=price, gap=gap,
        dual_bound=bound, tolerances=t, feasible=feasible,
        certified=bool(feasible and gap <= MIP_REL_GAP), worst=_worst(problem, loads),
        neighbours=model.neighbours(chosen),
        details={"rows": model.rows.counts, "variables": len(model.prices),
                 "nodes": int(solution.mip_node_count), **rounds,
                 "max_load": max_load, "poses": len(problem.poses)})


class _Model:
    """The integer program of one problem and catalogue (module docstring)."""

    def __init__(self, problem, catalogue):
        self.problem, self.catalogue = problem, catalogue
        index = {name: i for i, name in enumerate(problem.names)}
        self.items = [np.array([index[i] for i in c.items]) for c in catalogue.components]
        self.classes = [c.tolerance_matrix() for c in catalogue.components]
        self.prices = np.concatenate([c.prices() for c in catalogue.components])
        sizes = [len(c.classes) for c in catalogue.components]
        self.starts = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(int)
        self.owner = np.repeat(np.arange(len(sizes)), sizes)  # component of each variable
        upper = problem.reference.copy()
        for items, tolerances in zip(self.items, self.classes):
            upper[items] = tolerances.max(axis=0)
        self.rows = problem.rows_up_to(upper)
        matrix = self.rows.matrix
        rest = np.ones(len(upper), dtype=bool)
        for items in self.items:
            rest[items] = False
        self.base = matrix[:, rest] @ problem.variable(problem.reference[rest])
        self.coefficients = np.hstack([matrix[:, items] @ problem.variable(tolerances).T
                                       for items, tolerances in zip(self.items,
                                                                    self.classes)])

    def tolerances(self, chosen) -> np.ndarray:
        t = self.problem.reference.copy()
        for items, tolerances, start, j in zip(self.items, self.classes, self.starts, chosen):
            t[items] = tolerances[j - start]
        return t

    def check_reachable(self) -> None:
        """Refuse when some row exceeds 1 even with every component at its tightest class
        (for that row); names the worst such row."""
        least = self.base + sum(self.coefficients[:, self.owner == c].min(axis=1)
                                for c in range(len(self.items)))
        blocked = np.flatnonzero(least > 1.0 + LOAD_TOLERANCE)
        if not len(blocked):
            return
        blocked = blocked[np.argsort(-least[blocked], kind="stable")]
        frame = pd.DataFrame({"output": np.array(OUTPUTS)[self.rows.output[blocked]],
                              "pose": self.rows.pose[blocked]})
        for i, axis in enumerate(self.problem.machine.axes):
            frame[axis] = self.problem.poses[frame["pose"].to_numpy(), i]
        frame["load"] = least[blocked]
        first = frame.iloc[0]
        raise CatalogueInfeasibleError(
            f"no choice of classes meets {first['output']} at "
            f"{_pose_text(self.problem, int(first['pose']))}: even the tightest classes "
            f"leave its load at {first['load']:.4g} (1 = what the requirement allows); "
            f"{len(frame)} (output, pose) row(s) blocked in all", frame)

    def solve(self):
        """``(x, milp result, details)`` by row generation (module docstring): solve with
        the rows found violated so far, add the rows the answer violates, repeat; the
        answer that violates none is re-checked on all poses."""
        n = len(self.prices)
        one_each = np.zeros((len(self.items), n))
        one_each[self.owner, np.arange(n)] = 1.0
        active, cuts, rounds = np.zeros(0, dtype=int), [], 0
        while True:
            rounds += 1
            solution = self._milp(one_each, active, cuts)
            x = np.round(solution.x).astype(bool)
            load = self.base + self.coefficients[:, x].sum(axis=1)
            added = self._most_violated(load, active)
            if len(added):
                active = np.union1d(active, added)
                continue
            t = self.tolerances(np.flatnonzero(x))
            if load.max(initial=0.0) <= 1.0 + LOAD_TOLERANCE and \
                    self.problem.loads(self.problem.variable(t)).max() <= 1.0 + LOAD_TOLERANCE:
                return x, solution, {"cuts": len(cuts), "rounds": rounds,
                                     "active_rows": len(active)}
            if len(cuts) == MAX_CUTS:
                raise RuntimeError(f"HiGHS kept returning choices above a limit after "
                                   f"{MAX_CUTS} cuts")
            cuts.append(LinearConstraint(x.astype(float)[None, :], -np.inf,
                                         len(self.items) - 1.0))

    def _milp(self, one_each, active, cuts):
        """HiGHS on the rows ``active`` and the no-good ``cuts``, to the certified gap."""
        constraints = [LinearConstraint(one_each, 1.0, 1.0), *cuts]
        if len(active):
            constraints.append(LinearConstraint(self.coefficients[active], -np.inf,
                                                1.0 - self.base[active]))
        solution = milp(self.prices, integrality=np.ones(len(self.prices)),
                        bounds=Bounds(0.0, 1.0), constraints=constraints,
                        options={"mip_rel_gap": MIP_REL_GAP})
        if solution.status == 2:  # a subset of the rows already admits no choice
            raise CatalogueInfeasibleError(
                "no choice of classes meets every requirement at every pose, although each "
                "(output, pose) alone can be met by the tightest classes; tighter classes "
                "or looser limits are needed", pd.DataFrame())
        if solution.status != 0:
            raise RuntimeError(f"HiGHS did not finish: {solution.message}")
        return solution

    def _most_violated(self, load, active) -> np.ndarray:
        """Rows above their limit and not yet active: the :data:`ROWS_PER_ROUND` most
        loaded of each output."""
        violated = np.flatnonzero(load > 1.0 + LOAD_TOLERANCE)
        violated = violated[~np.isin(violated, active)]
        picked = []
        for output in np.unique(self.rows.output[violated]):
            rows = violated[self.rows.output[violated] == output]
            picked.append(rows[np.argsort(-load[rows], kind="stable")[:ROWS_PER_ROUND]])
        return np.concatenate(picked) if picked else np.zeros(0, dtype=int)

    def neighbours(self, chosen) -> pd.DataFrame:
        """Each component moved one class tighter and one looser, the others held."""
        load = self.base + self.coefficients[:, chosen].sum(axis=1)
        records = []
        for c, component in enumerate(self.catalogue.components):
            order = component.loosest_first()
            here = int(np.flatnonzero(order == chosen[c] - self.starts[c])[0])
            for direction, step in (("looser", -1), ("tighter", 1)):
                if not 0 <= here + step < len(order):
                    continue
                new = self.starts[c] + order[here + step]
                moved = load - self.coefficients[:, chosen[c]] + self.coefficients[:, new]
                worst = int(np.argmax(moved)) if len(moved) else -1
                meets = worst < 0 or moved[worst] <= 1.0 + LOAD_TOLERANCE
                change = float(self.prices[new] - self.prices[chosen[c]])
                records.append({
                    "component": component.name, "direction": direction,
                    "class": component.classes[order[here + step]].name,
                    "price_change": change,
                    "price": float(self.prices[chosen].sum()) + change, "meets": meets,
                    "breaks": "" if meets else OUTPUTS[self.rows.output[worst]],
                    "pose": -1 if meets else int(self.rows.pose[worst]),
                    "load": float(moved[worst]) if worst >= 0 else 0.0})
        frame = pd.DataFrame(records, columns=["component", "direction", "class",
                                               "price_change", "price", "meets", "breaks",
                                               "pose", "load"])
        broken = frame["pose"].to_numpy() >= 0
        positions = pose_frame(self.problem, np.where(broken, frame["pose"], 0))
        return pd.concat([frame, positions.where(pd.Series(broken), axis=0)], axis=1)


def _worst(problem, loads) -> pd.DataFrame:
    """Per output: largest load over the poses, its σ ratio and the pose."""
    pose = np.argmax(loads, axis=0)
    load = loads[pose, np.arange(len(OUTPUTS))]
    ratio = load if problem.side == "stack" else np.sqrt(load)
    frame = pd.DataFrame({"load": load, "ratio": ratio, "pose": pose},
                         index=pd.Index(OUTPUTS, name="output"))
    return pd.concat([frame, pose_frame(problem, pose).set_index(frame.index)], axis=1)


def pose_frame(problem, pose) -> pd.DataFrame:
    """Axis positions of the given poses: ``<axis>_mm`` or ``<axis>_deg`` columns."""
    positions = problem.poses[np.asarray(pose, dtype=int)]
    columns = {}
    for i, spec in enumerate(problem.machine.axis_specs):
        linear = spec.kind == "linear"
        columns[f"{spec.name}_{'mm' if linear else 'deg'}"] = \
            positions[:, i] if linear else np.degrees(positions[:, i])
    return pd.DataFrame(columns)


def _pose_text(problem, pose) -> str:
    """One of the problem's poses by its axis positions, ``"C=144 deg, Y=-300 mm, …"``."""
    machine = problem.machine
    return pose_text(problem.poses[pose], machine.axes, axis_units(machine), digits=6)


def _reading(problem) -> str:
    if problem.side == "stack":
        return "worst-case stack Σ|J| t ≤ I"
    return (f"{problem.side.replace('_', '-')} probability, tolerances ±{problem.k:g}σ "
            f"(FOSM, Eqs. 19–23)")
