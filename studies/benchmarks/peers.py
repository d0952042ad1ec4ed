"""Three of our computations against well-known peer libraries, in one run, in one table.

Run as ``python -m studies.benchmarks.peers`` (``--quick`` for a smoke run with fewer GWO
iterations and fewer repeats, ``--seed`` to change the seed). The peers are optional
(``pip install 'precision-reliability[bench]'``); a missing one is reported and its rows
are skipped.

What is measured, on the paper's hobbing machine:

1. **Grey Wolf Optimiser** on the paper's allocation problem (one-sided reading, worst
   case over the 5^6 grid, 100 wolves, 500 iterations). Ours: ``problem.solve_gwo``,
   vectorised over the pack, with Deb's feasibility rules. Simple reference (a floor, not
   a peer): :func:`allocation.grey_wolf_reference`, the same algorithm as a loop over
   wolves, with the same seed. Peer: mealpy's ``OriginalGWO``. mealpy takes one scalar
   fitness, evaluated one wolf at a time, so it gets a scalar that orders allocations
   exactly as Deb's rules do (the cost where feasible, ``F_max (1 + violation)``
   otherwise, ``F_max`` the cost at the lower bounds, the largest in the box); our GWO run
   on that very scalar is shown to follow the same trajectory as with Deb's rules. All
   search the same normalised box ``[0, 1]^d`` (``t = lower + z (upper - lower)``) and
   make the same number of objective evaluations (mealpy has no batch evaluation: its
   'swarm' mode still calls the objective once per wolf, and its thread/process modes
   are not used, everything runs on one core). Reported: wall time and the final cost
   above the certified optimum (``problem.solve_exact()``).
2. **Certified allocation**: ``problem.solve_exact()`` against cvxpy with the Clarabel
   interior-point solver on the same convex problem (minimise ``sum w_i / u_i``, ``u =
   t^2``, subject to the same screened rows ``G u <= 1`` and the same bounds), for the
   two-sided and the one-sided reading. Clarabel is given the problem with ``u`` divided
   by its upper bound and the cost by its value there (a diagonal change of variable:
   the same problem, O(1) numbers); the problem in raw units is tried too. Reported: time
   (best of 3), the relative cost difference and the largest constraint violation of the
   peer's answer over all (pose, output) rows of the grid and over the bounds.
3. **Rare event at 1e-6 on the exact model**: the δx output at its worst grid pose, the
   Table 4 tolerances scaled so that the linear (FOSM) two-sided failure probability is exactly
   1e-6. The errors are independent normals with σ = t/3 (untruncated); the model is the exact
   chain product ``machine.comprehensive_error``. Ours: importance sampling
   (:func:`reliability.sampling.rare_events.failure_probability`) to CoV 0.1. Peer: OpenTURNS on
   the same exact model as a vectorised ``ot.PythonFunction`` of the standard-normal error vector.
   The failure ``|y| >= I`` has two disjoint tails, each with its own design point, so the peer
   runs FORM and post-analytical importance sampling on each smooth one-sided limit state ``1 -+
   y/I`` and adds the two probabilities (exact, since the tails are disjoint), each tail to CoV
   0.1·√2 so that the sum reaches 0.1; FORM with OpenTURNS' default finite-difference gradient, and
   with the analytic linear gradient (the information ours uses). A second pair compares subset
   simulation, ours against ``ot.SubsetSampling`` on the two-sided limit state ``1 - |y|/I`` (no
   design point needed). Exact-model evaluations are counted inside the wrapped function (FORM's
   included). Reported: mean calls over independent runs, the mean estimate over the exact linear
   value 1e-6 (the exact model is near-linear there). Both importance samplers draw blocks of
   ``--batch`` samples (default 100) and test the CoV after each.

Times are wall times with BLAS limited to one thread; nothing is asserted.
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from dataclasses import dataclass
from importlib import import_module, metadata

import numpy as np
from scipy.stats import norm

import allocation
import reliability
from reliability.sampling.rare_events import failure_probability, worst_grid_pose
from studies.workflows.timing import best_time, one_blas_thread

INSTALL_HINT = "pip install 'precision-reliability[bench]'"
PEER_PACKAGES = ("mealpy", "cvxpy", "clarabel", "openturns")
RARE_LEVEL = 1e-6  # linear two-sided failure probability of the rare-event rows
RARE_OUTPUT = "dx"
TARGET_COV = 0.1
K = 3.0  # tolerances are ±3σ


@dataclass(frozen=True)
class Settings:
    """What one run of the benchmark does.

    Attributes
    ----------
    seed : int
        Root seed of every random stream.
    n_wolves, n_iterations : int
        GWO pack size and iterations (paper: 100, 500).
    rare_repeats : int
        Independent importance-sampling runs per method.
    subset_repeats : int
        Independent subset-simulation runs per method.
    batch : int
        Samples per block of both importance samplers (ours and the peer's).
    subset_level : int
        Samples per level of OpenTURNS' subset simulation.
    subset_budget : int
        Evaluation budget of our subset simulation (it sizes its levels for CoV 0.1).
    """

    seed: int
    n_wolves: int
    n_iterations: int
    rare_repeats: int
    subset_repeats: int
    batch: int
    subset_level: int
    subset_budget: int


@dataclass(frozen=True)
class Row:
    """One line of the table (already formatted cells)."""

    measured: str
    ours: str
    peer: str
    ratio: str
    agreement: str


# ----- shared helpers ------------------------------------------------------------------
def load_peer(name: str):
    """Import a peer library, or print why it is unavailable and return None.

    Parameters
    ----------
    name : str
        Module name (``'mealpy'``, ``'cvxpy'``, ``'openturns'``).

    Returns
    -------
    module or None
    """
    try:
        return import_module(name)
    except ImportError:
        print(f"{name} not installed: {INSTALL_HINT}")
    except Exception as exc:  # noqa: BLE001 - a broken install must not stop the others
        print(f"{name} could not be imported ({type(exc).__name__}: {exc}); its rows are "
              f"skipped")
    return None


def single_thread():
    """A context pinning every BLAS/OpenMP pool loaded so far to one thread.

    Entered again after a peer is imported, so that the libraries it loads are pinned too.
    """
    from threadpoolctl import threadpool_limits

    return threadpool_limits(limits=1)


def versions() -> str:
    """Installed versions of numpy, scipy and the peer packages, as one line."""
    parts = []
    for name in ("numpy", "scipy") + PEER_PACKAGES:
        try:
            parts.append(f"{name} {metadata.version(name)}")
        except metadata.PackageNotFoundError:
            parts.append(f"{name} (not installed)")
    return ", ".join(parts)


def seconds(value: float) -> str:
    """A duration for the table: ms below one second, else s."""
    return f"{1e3 * value:.1f} ms" if value < 1.0 else f"{value:.2f} s"


def markdown_table(rows) -> str:
    """The rows as a markdown table with padded columns."""
    header = Row("Measured", "Ours", "Peer (or reference)", "Peer / ours", "Agreement")
    cells = [[row.measured, row.ours, row.peer, row.ratio, row.agreement]
             for row in (header, *rows)]
    widths = [max(len(line[i]) for line in cells) for i in range(5)]
    lines = ["| " + " | ".join(text.ljust(w) for text, w in zip(line, widths, strict=True)) + " |"
             for line in cells]
    lines.insert(1, "|" + "|".join("-" * (w + 2) for w in widths) + "|")
    return "\n".join(lines)


# ----- 1. Grey Wolf Optimiser ------------------------------------------------------------
def free_to_full(problem):
    """The map from the free items' tolerances ``x (..., d)`` to all tolerances
    ``t (..., n_errors)``, locked items held at their value (as ``solve_gwo`` does)."""
    free = ~problem.locked

    def full(x):
        x = np.asarray(x, dtype=float)
        t = np.broadcast_to(problem.lower, x.shape[:-1] + problem.lower.shape).copy()
        t[..., free] = x
        return t

    return full


def search_space(problem):
    """The free items' box and the map from the normalised box ``[0, 1]^d`` to tolerances.

    Parameters
    ----------
    problem : allocation.AllocationProblem

    Returns
    -------
    lower, upper : ndarray (d,)
        Bounds of the free items.
    to_tolerances : callable
        ``z (..., d) -> t (..., n_errors)``, ``x = lower (1 - z) + upper z`` on the free
        items (the map our GWO uses internally).
    """
    free = ~problem.locked
    lower, upper = problem.lower[free], problem.upper[free]
    full = free_to_full(problem)
    return lower, upper, lambda z: full(lower * (1.0 - np.asarray(z)) + upper * np.asarray(z))


def deb_functions(problem):
    """Cost and total violation over the free items' tolerances, as ``solve_gwo`` uses.

    Returns
    -------
    objective, violation : callable
        ``x (m, d) -> (m,)``, vectorised.
    """
    full = free_to_full(problem)
    return (lambda x: problem.cost.total(full(x)),
            lambda x: problem.violation(full(x)))


def deb_scalar(problem):
    """One number per allocation that orders allocations as Deb's rules do.

    Feasible: the cost. Infeasible: ``F_max (1 + violation)``, ``F_max`` being the cost
    at the lower bounds, which no allocation of the box exceeds (the cost decreases in
    every tolerance); so every feasible point beats every infeasible one, and infeasible
    points rank by violation.

    Returns
    -------
    callable
        ``t (m, n_errors) -> (m,)``, vectorised.
    """
    worst = float(problem.cost.total(problem.lower))

    def scalar(t):
        violation = problem.violation(t)
        return np.where(violation > 0.0, worst * (1.0 + violation), problem.cost.total(t))

    return scalar


def time_ours_gwo(problem, settings):
    """Wall time and result of ``problem.solve_gwo`` (one run)."""
    return best_time(lambda: problem.solve_gwo(n_wolves=settings.n_wolves,
                                               n_iterations=settings.n_iterations,
                                               rng=settings.seed), 1)


def time_reference_gwo(problem, settings):
    """Wall time and result of the loop-over-wolves GWO on the same functions and seed."""
    objective, violation = deb_functions(problem)
    free = ~problem.locked
    return best_time(lambda: allocation.grey_wolf_reference(
        objective, problem.lower[free], problem.upper[free], violation=violation,
        n_wolves=settings.n_wolves, n_iterations=settings.n_iterations,
        rng=settings.seed), 1)


def time_ours_on_scalar(problem, settings):
    """Our vectorised GWO on mealpy's scalar (no separate violation): time and result."""
    free = ~problem.locked
    scalar, full = deb_scalar(problem), free_to_full(problem)
    return best_time(lambda: allocation.grey_wolf(
        lambda x: scalar(full(x)), problem.lower[free], problem.upper[free],
        n_wolves=settings.n_wolves, n_iterations=settings.n_iterations, rng=settings.seed), 1)


def time_mealpy_gwo(problem, settings):
    """mealpy's OriginalGWO on the scalar of :func:`deb_scalar`, in the normalised box.

    Returns
    -------
    dict or None
        ``seconds``, ``tolerances`` (best found), ``calls`` (objective evaluations) and
        ``in_objective`` (seconds spent inside the objective); None without mealpy.
    """
    if load_peer("mealpy") is None:
        return None
    from mealpy import FloatVar
    from mealpy.swarm_based.GWO import OriginalGWO

    lower, _, to_tolerances = search_space(problem)
    scalar = deb_scalar(problem)
    tally = {"calls": 0, "seconds": 0.0}

    def fitness(z):  # mealpy hands over one wolf at a time
        start = time.perf_counter()
        value = float(scalar(to_tolerances(z[None, :]))[0])
        tally["calls"] += 1
        tally["seconds"] += time.perf_counter() - start
        return value

    spec = {"obj_func": fitness, "minmax": "min", "log_to": None,
            "bounds": FloatVar(lb=np.zeros(lower.size), ub=np.ones(lower.size))}
    with single_thread():
        optimiser = OriginalGWO(epoch=settings.n_iterations, pop_size=settings.n_wolves)
        elapsed, best = best_time(lambda: optimiser.solve(spec, seed=settings.seed), 1)
    return {"seconds": elapsed, "tolerances": to_tolerances(best.solution),
            "calls": tally["calls"], "in_objective": tally["seconds"]}


def above_exact(problem, tolerances, exact_cost) -> str:
    """Cost above the certified optimum in %, with the feasibility verdict."""
    cost = float(problem.cost.total(tolerances))
    verdict = "feasible" if problem.meets_targets(tolerances) else "INFEASIBLE"
    return f"{100.0 * (cost / exact_cost - 1.0):+.2f} % ({verdict})"


def gwo_rows(machine, settings):
    """Table rows of the GWO comparison (one-sided reading, as the paper)."""
    problem = allocation.AllocationProblem.build(machine, side="one_sided")
    exact_cost = problem.solve_exact().cost
    evaluations = settings.n_wolves * (settings.n_iterations + 1)
    size = f"{settings.n_wolves}x{settings.n_iterations}"
    t_ours, ours = time_ours_gwo(problem, settings)
    t_reference, reference = time_reference_gwo(problem, settings)
    _, on_scalar = time_ours_on_scalar(problem, settings)
    free = ~problem.locked
    same_reference = np.array_equal(reference.x, ours.tolerances[free])
    same_scalar = np.array_equal(on_scalar.x, ours.tolerances[free])
    ours_text = above_exact(problem, ours.tolerances, exact_cost)
    rows = [
        Row(f"GWO {size}, one-sided, vs loop over wolves (floor)",
            f"{seconds(t_ours)}, {evaluations} evals", f"{seconds(t_reference)}, "
            f"{reference.n_evaluations} evals", f"{t_reference / t_ours:.1f} x",
            f"above exact: ours {ours_text}; same trajectory: "
            f"{'yes' if same_reference else 'NO'}"),
        Row("GWO, ours on mealpy's scalar objective (fairness check)",
            f"{evaluations} evals", "-", "-",
            f"same trajectory as with Deb's rules: {'yes' if same_scalar else 'NO'}"),
    ]
    peer = time_mealpy_gwo(problem, settings)
    if peer is not None:
        rows.append(Row(
            f"GWO {size}, one-sided, vs mealpy OriginalGWO",
            f"{seconds(t_ours)}, {evaluations} evals (pack at once)",
            f"{seconds(peer['seconds'])}, {peer['calls']} evals one by one "
            f"({seconds(peer['in_objective'])} in the objective)",
            f"{peer['seconds'] / t_ours:.1f} x",
            f"above exact: ours {ours_text}, mealpy "
            f"{above_exact(problem, peer['tolerances'], exact_cost)}"))
    return rows


# ----- 2. certified allocation -----------------------------------------------------------
def clarabel_solve(problem, scaled: bool):
    """The allocation's convex core through cvxpy and Clarabel.

    Parameters
    ----------
    problem : allocation.AllocationProblem
        Worst-case reading (rows in ``u = t^2``).
    scaled : bool
        Solve in ``v = u / u_upper`` with the cost divided by its value at ``u_upper``
        (O(1) numbers), else in raw units.

    Returns
    -------
    dict
        ``seconds`` (wall, from building the cvxpy problem to the answer), ``compile``
        and ``solve`` (cvxpy's and Clarabel's own times, NaN on failure), ``status`` and
        ``u`` (None when the solver fails).
    """
    import cvxpy as cp

    w, G = problem.cost.weights, problem.rows.matrix
    low, high = problem.variable(problem.lower), problem.variable(problem.upper)
    scale_u = high if scaled else np.ones_like(high)
    scale_f = float(np.sum(w / high)) if scaled else 1.0
    start = time.perf_counter()
    v = cp.Variable(w.size)
    cost = cp.sum(cp.multiply(w / scale_u / scale_f, cp.inv_pos(v)))
    model = cp.Problem(cp.Minimize(cost), [(G * scale_u) @ v <= 1.0,
                                           v >= low / scale_u, v <= high / scale_u])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # an inaccurate solve is reported, not warned
        try:
            model.solve(solver=cp.CLARABEL)
        except cp.error.SolverError:
            return {"seconds": time.perf_counter() - start, "compile": np.nan,
                    "solve": np.nan, "status": "solver error", "u": None}
    elapsed = time.perf_counter() - start
    u = None if v.value is None else np.asarray(v.value) * scale_u
    return {"seconds": elapsed, "compile": model.compilation_time,
            "solve": model.solver_stats.solve_time, "status": model.status, "u": u}


def worst_violation(problem, u) -> tuple[float, float]:
    """Largest row violation over every (pose, output) of the grid, ``max(load) - 1``
    (negative: slack), and largest relative bound violation (0 when inside)."""
    load = float(problem.loads(u).max()) - 1.0
    low, high = problem.variable(problem.lower), problem.variable(problem.upper)
    bounds = max(0.0, float(np.max((low - u) / low)), float(np.max((u - high) / high)))
    return load, bounds


def convex_rows(machine, settings):
    """Table rows of the certified solve against cvxpy + Clarabel, both readings."""
    if load_peer("cvxpy") is None:
        return []
    import cvxpy as cp

    if cp.CLARABEL not in cp.installed_solvers():
        print(f"clarabel not installed: {INSTALL_HINT}")
        return []
    rows = []
    with single_thread():
        for side in ("two_sided", "one_sided"):
            problem = allocation.AllocationProblem.build(machine, side=side)
            t_ours, exact = best_time(problem.solve_exact, 3)
            attempts = [clarabel_solve(problem, scaled=True) for _ in range(3)]
            peer = min(attempts, key=lambda attempt: attempt["seconds"])
            rows.append(convex_row(problem, side, t_ours, exact, peer))
            raw = clarabel_solve(problem, scaled=False)
            rows.append(raw_clarabel_row(problem, side, exact, raw))
    return rows


def convex_row(problem, side, t_ours, exact, peer) -> Row:
    """The row of one reading: times, cost difference and the peer's violations."""
    n_rows = len(problem.rows.matrix)
    measured = (f"exact allocation, {side.replace('_', '-')} ({n_rows} screened rows), best "
                "of 3, vs cvxpy + Clarabel")
    ours = f"{seconds(t_ours)} (gap {exact.certificate['relative_gap']:.0e})"
    if peer["u"] is None:
        return Row(measured, ours, f"cvxpy+Clarabel: {peer['status']}", "-", "-")
    cost = float(np.sum(problem.cost.weights / peer["u"]))
    load, bounds = worst_violation(problem, peer["u"])
    own_load, _ = worst_violation(problem, problem.variable(exact.tolerances))
    return Row(measured, ours,
               f"{seconds(peer['seconds'])} (cvxpy {seconds(peer['compile'])} + Clarabel "
               f"{seconds(peer['solve'])}, {peer['status']})",
               f"{peer['seconds'] / t_ours:.1f} x",
               f"cost peer/ours - 1 = {cost / exact.cost - 1.0:+.1e}; max load - 1 over "
               f"{len(problem.poses) * len(reliability.OUTPUTS)} rows: peer {load:+.1e}, ours "
               f"{own_load:+.1e}; bounds {bounds:.0e}")


def raw_clarabel_row(problem, side, exact, raw) -> Row:
    """The row of Clarabel on the problem in raw units (u ~ 1e-11..1e-5, cost ~ 1e11)."""
    measured = f"  same, {side.replace('_', '-')}, Clarabel given raw units"
    if raw["u"] is None:
        return Row(measured, "-", f"{seconds(raw['seconds'])}, {raw['status']}", "-",
                   "no answer")
    cost = float(np.sum(problem.cost.weights / raw["u"]))
    load, bounds = worst_violation(problem, raw["u"])
    return Row(measured, "-", f"{seconds(raw['seconds'])}, status {raw['status']}", "-",
               f"unusable: max load - 1 {load:+.1e}, bounds off by {bounds:.0e} "
               f"(cost peer/ours - 1 = {cost / exact.cost - 1.0:+.1e})")


# ----- 3. rare event on the exact model ----------------------------------------------------
@dataclass(frozen=True)
class RareSetup:
    """The rare-event problem shared by ours and the peer.

    Attributes
    ----------
    machine : Machine
    pose : ndarray (n_axes,)
        Worst grid pose of the output under the Table 4 allocation.
    tolerances : ndarray (n_errors,)
        Table 4 scaled so that the linear two-sided failure probability is the level.
    output : int
        Index of the output (δx).
    beta : float
        Linear reliability index of each tail, ``2 Φ(-β)`` = the level.
    exact : float
        ``2 Φ(-β)``, the linear model's closed form.
    """

    machine: object
    pose: np.ndarray
    tolerances: np.ndarray
    output: int
    beta: float
    exact: float

    @property
    def sigma(self) -> np.ndarray:
        """Standard deviations of the errors, ``t / 3``."""
        return self.tolerances / K

    @property
    def limit(self) -> float:
        """Limit ``I`` of the output."""
        return float(self.machine.limits[self.output])

    def response(self, u) -> np.ndarray:
        """The output ``y`` of the exact model at standard-normal errors ``u (m, n)``."""
        x = np.asarray(u, dtype=float) * self.sigma
        return self.machine.comprehensive_error(self.pose, x)[:, self.output]

    @property
    def slope(self) -> np.ndarray:
        """Linear sensitivities ``dy/du`` at ``u = 0`` (analytic Jacobian times σ)."""
        return self.machine.jacobian(self.pose)[self.output] * self.sigma


def rare_setup(machine, level: float = RARE_LEVEL, output: str = RARE_OUTPUT) -> RareSetup:
    """Scale the Table 4 allocation so that ``output`` fails with ``level`` (linear,
    two-sided) at its worst grid pose.

    The linear output is normal with σ_y = |J ⊙ t/3|; multiplying every tolerance by
    ``I / (β σ_y)`` with ``β = Φ⁻¹(1 - level/2)`` puts each tail at ``Φ(-β)``.
    """
    index = reliability.OUTPUTS.index(output)
    reference = machine.initial_allocation
    pose = worst_grid_pose(machine, reference, output)
    spread = float(np.linalg.norm(machine.jacobian(pose)[index] * reference / K))
    beta = float(norm.isf(level / 2.0))
    tolerances = reference * machine.limits[index] / (beta * spread)
    return RareSetup(machine=machine, pose=pose, tolerances=tolerances, output=index,
                     beta=beta, exact=float(2.0 * norm.sf(beta)))


def child_seeds(seed: int, n: int, stream: int) -> list:
    """``n`` independent seed sequences of sub-stream ``stream`` of the root seed."""
    return np.random.SeedSequence(seed).spawn(stream + 1)[stream].spawn(n)


def ours_rare(setup, settings, method: str, seeds):
    """Our estimator, one run per seed.

    Returns
    -------
    dict
        Per-run arrays ``calls``, ``estimate``, ``cov`` and the mean wall time ``seconds``.
    """
    budget = settings.subset_budget if method == "subset" else 20_000
    results, start = [], time.perf_counter()
    for seed in seeds:
        results.append(failure_probability(
            setup.machine, setup.tolerances, setup.pose, event=RARE_OUTPUT, method=method,
            target_cov=TARGET_COV, max_evaluations=budget, batch=settings.batch, k=K,
            rng=seed))
    return {"calls": np.array([r.n_evaluations for r in results]),
            "estimate": np.array([r.probability for r in results]),
            "cov": np.array([r.cov for r in results]),
            "seconds": (time.perf_counter() - start) / len(results)}


class CountingModel:
    """Exact-model evaluations (rows) made through the OpenTURNS wrappers."""

    def __init__(self):
        self.count = 0

    def limit_state(self, ot, setup, kind: str, analytic_gradient: bool = False):
        """An ``ot.PythonFunction`` of the standard-normal error vector.

        Parameters
        ----------
        ot : module
            openturns.
        setup : RareSetup
        kind : {'upper', 'lower', 'both'}
            ``1 - y/I`` (upper tail), ``1 + y/I`` (lower tail) or ``1 - |y|/I``; failure
            is a value ``<= 0``.
        analytic_gradient : bool
            Give the linear sensitivities as the gradient (no model call), instead of
            OpenTURNS' finite differences.
        """
        sign = {"upper": 1.0, "lower": -1.0, "both": 0.0}[kind]
        limit = setup.limit

        def values(u):
            u = np.asarray(u, dtype=float)
            self.count += len(u)
            y = setup.response(u)
            g = 1.0 - (np.abs(y) if kind == "both" else sign * y) / limit
            return g[:, None]

        if not analytic_gradient:
            return ot.PythonFunction(setup.tolerances.size, 1, func_sample=values)
        gradient = (-sign * setup.slope / limit)[:, None]
        return ot.PythonFunction(setup.tolerances.size, 1, func_sample=values,
                                 gradient=lambda u: gradient)


def openturns_tail(ot, setup, counter, kind, analytic_gradient, settings):
    """FORM then post-analytical importance sampling on one tail.

    Returns
    -------
    (float, float)
        The tail's probability estimate and its variance.
    """
    inputs = ot.RandomVector(ot.Normal(setup.tolerances.size))
    function = counter.limit_state(ot, setup, kind, analytic_gradient)
    event = ot.ThresholdEvent(ot.CompositeRandomVector(function, inputs), ot.LessOrEqual(),
                              0.0)
    solver = ot.AbdoRackwitz()
    solver.setStartingPoint(ot.Point(setup.tolerances.size))
    form = ot.FORM(solver, event)
    form.run()
    sampler = ot.PostAnalyticalImportanceSampling(form.getResult())
    sampler.setBlockSize(settings.batch)
    sampler.setMaximumOuterSampling(10 ** 7)
    sampler.setMaximumCoefficientOfVariation(TARGET_COV * np.sqrt(2.0))
    sampler.run()
    result = sampler.getResult()
    return result.getProbabilityEstimate(), result.getVarianceEstimate()


def openturns_importance(ot, setup, settings, seeds, analytic_gradient: bool):
    """The peer's two-tail FORM + importance sampling, one run per seed.

    Returns
    -------
    dict
        As :func:`ours_rare`.
    """
    calls, estimates, covs, start = [], [], [], time.perf_counter()
    for seed in seeds:
        ot.RandomGenerator.SetSeed(int(seed.generate_state(1)[0]))
        counter = CountingModel()
        tails = [openturns_tail(ot, setup, counter, kind, analytic_gradient, settings)
                 for kind in ("upper", "lower")]
        probability = sum(p for p, _ in tails)
        calls.append(counter.count)
        estimates.append(probability)
        covs.append(np.sqrt(sum(v for _, v in tails)) / probability)
    return {"calls": np.array(calls), "estimate": np.array(estimates),
            "cov": np.array(covs), "seconds": (time.perf_counter() - start) / len(seeds)}


def openturns_subset(ot, setup, settings, seeds):
    """``ot.SubsetSampling`` on ``1 - |y|/I``, one run per seed; as :func:`ours_rare`."""
    inputs = ot.RandomVector(ot.Normal(setup.tolerances.size))
    block = min(1000, settings.subset_level)
    calls, estimates, covs, start = [], [], [], time.perf_counter()
    for seed in seeds:
        ot.RandomGenerator.SetSeed(int(seed.generate_state(1)[0]))
        counter = CountingModel()
        function = counter.limit_state(ot, setup, "both")
        event = ot.ThresholdEvent(ot.CompositeRandomVector(function, inputs),
                                  ot.LessOrEqual(), 0.0)
        sampler = ot.SubsetSampling(event)
        sampler.setBlockSize(block)
        sampler.setMaximumOuterSampling(max(1, settings.subset_level // block))
        sampler.run()
        result = sampler.getResult()
        calls.append(counter.count)
        estimates.append(result.getProbabilityEstimate())
        covs.append(result.getCoefficientOfVariation())
    return {"calls": np.array(calls), "estimate": np.array(estimates),
            "cov": np.array(covs), "seconds": (time.perf_counter() - start) / len(seeds)}


def normalised_calls(run) -> float:
    """Mean calls scaled to CoV 0.1, ``calls (CoV / 0.1)^2`` (CoV² ∝ 1/calls)."""
    return float(np.mean(run["calls"] * np.square(run["cov"] / TARGET_COV)))


def estimate_text(run, exact) -> str:
    """Mean estimate over the exact value, ± its standard error over the runs."""
    ratio = run["estimate"] / exact
    error = ratio.std(ddof=1) / np.sqrt(ratio.size) if ratio.size > 1 else np.nan
    spread = f" ± {error:.2f}" if np.isfinite(error) else ""
    return f"{ratio.mean():.2f}{spread}"


def runs(n: int) -> str:
    """``'1 run'`` or ``'n runs'``."""
    return f"{n} run" if n == 1 else f"{n} runs"


def calls_text(run, normalised: bool = False) -> str:
    """Mean calls (or calls normalised to CoV 0.1), mean CoV and mean wall time per run."""
    calls = normalised_calls(run) if normalised else float(np.mean(run["calls"]))
    raw = f" of {np.mean(run['calls']):,.0f}" if normalised else ""
    return (f"{calls:,.0f} calls{raw} (CoV {np.mean(run['cov']):.3f}, "
            f"{seconds(run['seconds'])}/run)")


def rare_rows(machine, settings):
    """Table rows of the rare-event comparison."""
    setup = rare_setup(machine)
    ours = ours_rare(setup, settings, "importance",
                     child_seeds(settings.seed, settings.rare_repeats, 0))
    ot = load_peer("openturns")
    if ot is None:
        return [], setup
    rows = []
    with single_thread():
        ot.TBB.SetThreadsNumber(1)
        for stream, analytic in ((1, False), (2, True)):
            peer = openturns_importance(ot, setup, settings,
                                        child_seeds(settings.seed, settings.rare_repeats,
                                                    stream), analytic)
            gradient = "analytic linear gradient" if analytic else "finite-diff. gradient"
            rows.append(Row(
                f"P_f = 1e-6, IS to CoV 0.1 ({runs(settings.rare_repeats)}), vs OT FORM "
                f"({gradient}) + PAIS per tail",
                calls_text(ours), calls_text(peer),
                f"{np.mean(peer['calls']) / np.mean(ours['calls']):.1f} x",
                f"mean estimate / exact: ours {estimate_text(ours, setup.exact)}, OT "
                f"{estimate_text(peer, setup.exact)}"))
        subset_ours = ours_rare(setup, settings, "subset",
                                child_seeds(settings.seed, settings.subset_repeats, 3))
        subset_peer = openturns_subset(ot, setup, settings,
                                       child_seeds(settings.seed, settings.subset_repeats, 4))
        rows.append(Row(
            f"P_f = 1e-6, subset simulation ({runs(settings.subset_repeats)}), vs OT "
            f"SubsetSampling on 1 - abs(y)/I; calls scaled to CoV 0.1",
            calls_text(subset_ours, True), calls_text(subset_peer, True),
            f"{normalised_calls(subset_peer) / normalised_calls(subset_ours):.1f} x",
            f"mean estimate / exact: ours {estimate_text(subset_ours, setup.exact)}, OT "
            f"{estimate_text(subset_peer, setup.exact)}"))
    return rows, setup


# ----- driver ----------------------------------------------------------------------------
def settings_from(args) -> Settings:
    """Full (paper) or quick settings from the parsed arguments."""
    if args.quick:
        return Settings(seed=args.seed, n_wolves=100, n_iterations=20, rare_repeats=3,
                        subset_repeats=1, batch=args.batch, subset_level=4_000,
                        subset_budget=40_000)
    return Settings(seed=args.seed, n_wolves=100, n_iterations=500, rare_repeats=20,
                    subset_repeats=5, batch=args.batch, subset_level=14_000,
                    subset_budget=200_000)


def print_header(machine, settings, setup) -> None:
    """What was run, with seeds and versions."""
    print(f"Peer benchmarks: {machine.name}; seed {settings.seed}")
    print(f"  versions: {versions()}")
    print(f"  GWO: {settings.n_wolves} wolves x {settings.n_iterations} iterations, "
          f"rng={settings.seed} for ours and the loop reference, seed={settings.seed} for "
          f"mealpy; box [0.5, 1.5] x Table 4, normalised to [0, 1]^d for every GWO")
    if setup is not None:
        pose = ", ".join(f"{axis}={value:.4g}" for axis, value in
                         zip(machine.axes, setup.pose, strict=True))
        print(f"  rare event: {RARE_OUTPUT} at its worst grid pose ({pose}); Table 4 x "
              f"{setup.tolerances[0] / machine.initial_allocation[0]:.4f}; exact (linear "
              f"closed form 2Φ(-β), β = {setup.beta:.4f}) = {setup.exact:.3e}; normal "
              f"errors σ = t/3, untruncated")
        print(f"  rare-event seeds: numpy.random.SeedSequence({settings.seed}).spawn(5)"
              f"[stream].spawn(runs); streams 0 ours IS, 1-2 OT IS, 3 ours subset, "
              f"4 OT subset (OT seeded by the first word of each child's state); "
              f"{settings.batch} samples per IS block (ours and OT); OT subset "
              f"{settings.subset_level} samples per level, ours sized by its budget "
              f"{settings.subset_budget}")


def print_notes() -> None:
    """Reading aids printed under the table."""
    print("\nPeer / ours: the peer's time (or calls) over ours; above 1, ours is faster. "
          "'Above exact': final cost over the certified optimum of the same problem.")
    print("mealpy evaluates one wolf per objective call (the objective is our numpy "
          "code on a single row); ours evaluates the whole pack per call. mealpy's "
          "OriginalGWO also keeps each wolf's better of old and new position.")
    print("IS = importance sampling; PAIS = OpenTURNS' post-analytical importance "
          "sampling at the FORM design point. OT's calls include FORM's (both tails); "
          "ours include the design-point refinement. Subset: OT runs a fixed number of "
          "samples per level, so calls are compared after scaling each run to CoV 0.1.")


def parse_arguments(argv):
    """The command-line options."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=2023, help="root seed (default 2023)")
    parser.add_argument("--quick", action="store_true",
                        help="smoke run: 20 GWO iterations, fewer rare-event runs")
    parser.add_argument("--batch", type=int, default=100,
                        help="samples per importance-sampling block, ours and OT's")
    return parser.parse_args(argv)


@one_blas_thread
def main(argv=None) -> int:
    """Run every comparison and print the table; returns the exit status."""
    args = parse_arguments(argv)
    settings = settings_from(args)
    wall = time.perf_counter()
    machine = reliability.hobbing_machine()
    rows = gwo_rows(machine, settings)
    rows += convex_rows(machine, settings)
    rare, setup = rare_rows(machine, settings)
    rows += rare
    print()
    print_header(machine, settings, setup)
    print()
    print(markdown_table(rows))
    print_notes()
    print(f"\nTotal wall time {time.perf_counter() - wall:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
