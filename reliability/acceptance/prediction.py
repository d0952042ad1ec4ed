"""Acceptance tests at design time: ISO 230 test results of machines built to an allocation.

A machine is accepted against standard tests rather than against a reliability at every
pose. :func:`acceptance` predicts, for an allocation of the geometric errors, the
distribution of each test's result over the machines built to it and the probability that a
built machine passes. The tests and the poses they visit are
:mod:`reliability.acceptance.iso_tests`, the ISO statistics of a path
:mod:`reliability.acceptance.iso_statistics`, and the result, its table and its file
:mod:`reliability.acceptance.acceptance_result`. A test value ``v`` passes its limit when
``v < limit`` (:func:`reliability.basics.pass_rule.passes`): a value exactly on its limit
fails, as everywhere in the toolkit.

**What is modelled.** Geometric errors only (the machine file's motion and assembly
errors, Eqs. 2 and 14), plus, for positioning tests only, each linear axis' ``repeatability``
and ``reversal`` from the machine file: no servo, dynamic, thermal or load effects. On a
circle both directions of travel pass through the same poses with the same geometric
errors, so the two directions give the same path and it is evaluated once; ISO 230-4's
``G(a)``, ``G(b)`` and the bidirectional ``G`` coincide. The tool point's deviation in the
workpiece frame is taken to first order
(:func:`reliability.acceptance.iso_tests.deviation_weights`).

**Built machines.** Each machine draws every motion error as a function of its axis'
position (an error profile along travel, :mod:`reliability.model.profiles`: ``gp:<length>`` or
``constant``; the ``independent`` profile has no continuous path and is refused), every assembly
error once, and the repeatability of every approach of every positioning run. A tolerance ``t`` is
read as ``σ = t/k`` (``k = 3``), normal by default (``distribution``). Measured profiles
(:class:`reliability.model.measured_profiles.SystematicErrors`) add their means along the path. All
tests of a file are evaluated on the same built machines, so the probability of passing them all is
estimated as well.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..basics.chunks import chunks
from ..basics.errors import InputError, InputTypeError
from ..basics.streams import generator
from ..model.error_draws import normal_to_marginal
from ..model.measured_profiles import SystematicErrors
from ..model.profiles import ConstantProfile, GaussianProfile, profile_model
from .acceptance_result import DISTRIBUTIONS, AcceptanceResult, result_columns
from .iso_statistics import positioning_statistics
from .iso_tests import (TEST_TYPES, CircularTest, PositioningTest, build_path,
                        deviation_weights, finite_number)

#: Profile used when none is given: a Gaussian process with a 300 mm correlation length.
DEFAULT_PROFILE = "gp:300"
#: Eigenvalues of an along-travel correlation below this share of the largest are dropped.
RANK_TOLERANCE = 1e-10
#: Machines on which each error item's share of a result is estimated (drivers).
DRIVER_MACHINES = 200
#: A result below this (mm) is rounding, not an effect (drivers).
NEGLIGIBLE = 1e-9


@dataclass(frozen=True, eq=False)
class _Plan:
    """Everything about the tests that does not depend on a built machine."""

    paths: tuple
    offsets: tuple          # start of each path's poses in the stacked poses
    weights: np.ndarray     # (P, 3, n_errors): workpiece-frame tool-point deviation per error
    index: tuple            # per axis: (P,) index of each pose's position among the axis'
    factors: tuple          # per axis: (U_a, r_a) along-travel factor at its positions
    mean_deviation: np.ndarray  # (P, 3) from measured means
    item_means: np.ndarray  # (P, n_errors) measured means at the poses
    sigma: np.ndarray       # (n_errors,) t/k
    positioning: dict       # positioning test name: (repeatability σ, reversal) of its axis


def acceptance(machine, tests, tolerances=None, *, machines: int = 2000,
               profile=DEFAULT_PROFILE, distribution: str = "normal", k: float = 3.0,
               systematic=None, confidence: float = 0.95,
               driver_machines: int = DRIVER_MACHINES, memory: int | None = None,
               rng=None) -> AcceptanceResult:
    """Predicted ISO 230 acceptance-test results of machines built to an allocation.

    Parameters
    ----------
    machine : Machine
    tests : sequence of CircularTest, PositioningTest, RotaryTest
        Evaluated on the same built machines (names unique).
    tolerances : array_like, optional
        ``(n_errors,)`` allocation (mm, rad); the machine's initial allocation by default.
    machines : int
        Built machines drawn.
    profile : str or profile model
        Error profile along travel of every axis' motion errors: ``gp:<length mm>``
        (default :data:`DEFAULT_PROFILE`) or ``constant``. Under ``constant`` an axis'
        own positioning error is one offset along its whole travel, so positioning tests
        show only reversal and repeatability, and a circle is an exact ellipse with ``G``
        proportional to its radius. ``independent`` is refused: a fresh value at every
        point does not describe a continuous path.
    distribution : {'normal', 'truncated'}
        Reading of a tolerance: ``σ = t/k``, normal or truncated at ``±t``.
    k : float
    systematic : SystematicErrors, optional
        Measured profiles whose means are added along the paths.
    confidence : float
        Level of the Wilson intervals on the pass probabilities.
    driver_machines : int
        Machines (the first ones drawn) on which each item's share is estimated.
    memory : int, optional
        Bytes of temporary arrays per chunk of machines (:mod:`reliability.basics.chunks`).
    rng : seed or Generator

    Returns
    -------
    AcceptanceResult
    """
    tests = _check_tests(tests)
    model = path_profile(profile, tests)
    _check_options(distribution, k, confidence, machines, driver_machines)
    if machine.correlation is not None:
        raise InputError("acceptance tests do not take the machine's [[correlation]] "
                         "between error items into account yet; remove it to predict them")
    t = machine.initial_allocation if tolerances is None else \
        machine.check_tolerances(tolerances)
    if t.shape != (machine.n_errors,):
        raise InputError(f"tolerances must have shape ({machine.n_errors},); got {t.shape}")
    plan = _plan(machine, tests, model, t / k, systematic)
    draws = _draw(machine, plan, machines, rng)
    latent_map = _latent_map(plan, len(machine.axes)) if distribution == "normal" else None
    values = np.concatenate([_quantities(plan, _slice(draws, part), machine, k, distribution,
                                         latent_map)
                             for part in chunks(machines, _bytes_per_machine(plan), memory)])
    columns = result_columns(tests)
    first = _slice(draws, slice(0, min(driver_machines, machines)))
    drivers = _drivers(plan, first, machine, k, distribution)
    return AcceptanceResult(tests=tests, values=pd.DataFrame(values, columns=columns),
                            drivers=drivers, profile=str(model), distribution=distribution,
                            k=float(k), confidence=float(confidence))


def results_of_deviations(machine, tests, deviations, rng=None) -> pd.DataFrame:
    """Each test's results on given machines, columns ``(test, quantity)`` as
    :attr:`AcceptanceResult.values`.

    ``deviations`` ``(m, P, 3)`` is each machine's tool-point deviation in the workpiece
    frame at the poses of the tests' paths (:func:`build_path`), stacked in test order; the
    repeatability and reversal of positioning runs are drawn from ``rng`` as in
    :func:`acceptance`.
    """
    tests = _check_tests(tests)
    plan = _plan(machine, tests, ConstantProfile(), np.zeros(machine.n_errors), None)
    deviations = np.asarray(deviations, dtype=float)
    if deviations.ndim != 3 or deviations.shape[1:] != (len(plan.weights), 3):
        raise InputError(f"deviations must have shape (machines, {len(plan.weights)}, 3); "
                         f"got {deviations.shape}")
    rng = generator(rng)
    repeat = [rng.standard_normal((len(deviations), p.test.runs, 2, len(p.poses)))
              for p in plan.paths if isinstance(p.test, PositioningTest)]
    return pd.DataFrame(_results(plan, deviations, repeat, scale=(1.0, 1.0)),
                        columns=result_columns(tests))


def _check_options(distribution, k, confidence, machines, driver_machines) -> None:
    if distribution not in DISTRIBUTIONS:
        raise InputError(f"distribution must be one of {DISTRIBUTIONS}; got {distribution!r}")
    if not finite_number(k) or k <= 0:
        raise InputError(f"k must be a finite number > 0; got {k!r}")
    if not finite_number(confidence) or not 0 < confidence < 1:
        raise InputError(f"confidence must be a number in (0, 1); got {confidence!r}")
    for name, value in (("machines", machines), ("driver_machines", driver_machines)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
            raise InputError(f"{name} must be an integer >= 1; got {value!r}")


def _check_tests(tests) -> tuple:
    tests = tuple(tests)
    if not tests:
        raise InputError("tests: give at least one test")
    names = set()
    for test in tests:
        if not isinstance(test, TEST_TYPES):
            raise InputTypeError(f"tests must be CircularTest, PositioningTest or RotaryTest; "
                                 f"got {type(test).__name__}")
        if test.name in names:
            raise InputError(f"test name {test.name!r} is used twice")
        names.add(test.name)
    return tests


def path_profile(profile, tests):
    """The profile model for ``tests``, or a refusal of ``independent`` naming the first test."""
    model = profile_model(profile)
    if not isinstance(model, (GaussianProfile, ConstantProfile)):
        raise InputError(f"profile {str(model)!r} draws a fresh error at every point and does "
                         f"not describe a continuous path; test {tests[0].name!r} "
                         f"({tests[0].kind}) needs 'gp:<length mm>' or 'constant'")
    return model


def _plan(machine, tests, model, sigma, systematic) -> _Plan:
    paths = tuple(build_path(machine, test) for test in tests)
    poses = np.concatenate([p.poses for p in paths])
    offsets = tuple(np.cumsum([0] + [len(p.poses) for p in paths])[:-1])
    weights = deviation_weights(machine, poses)
    index, factors = [], []
    for a, axis in enumerate(machine.axis_specs):
        where = np.mod(poses[:, a], 2.0 * np.pi) if axis.full_turn else poses[:, a]
        # positions equal to 1e-9 (mm, rad) are one position of the profile
        unique, inverse = np.unique(np.round(where, 9), return_inverse=True)
        index.append(inverse.reshape(-1))
        factors.append(travel_factor(model, axis, unique))
    if systematic is None:
        item_means = np.zeros((len(poses), machine.n_errors))
    elif not isinstance(systematic, SystematicErrors):
        raise InputTypeError(f"systematic must be a SystematicErrors; got {systematic!r}")
    else:
        item_means = systematic.means(poses)
    specs = {a.name: a for a in machine.axis_specs}
    positioning = {p.test.name: (specs[p.test.axis].repeatability, specs[p.test.axis].reversal)
                   for p in paths if isinstance(p.test, PositioningTest)}
    return _Plan(paths=paths, offsets=offsets, weights=weights, index=tuple(index),
                 factors=tuple(factors),
                 mean_deviation=np.einsum("poi,pi->po", weights, item_means),
                 item_means=item_means, sigma=np.asarray(sigma, dtype=float),
                 positioning=positioning)


def travel_factor(model, axis, positions) -> np.ndarray:
    """``(U, r)`` factor ``F`` with ``F Fᵀ`` the profile's correlation at ``positions``.

    The eigenvectors of the correlation whose eigenvalues exceed :data:`RANK_TOLERANCE`
    times the largest, scaled by their roots, and each row renormalised to unit length so
    that every position keeps its marginal exactly. A smooth profile at many close positions
    has a low numerical rank ``r``, so a built machine's profile is ``F z`` with only ``r``
    standard normals per error (rank one for ``constant``).
    """
    correlation = model.correlation(axis, positions)
    values, vectors = np.linalg.eigh(correlation)
    keep = values > RANK_TOLERANCE * values[-1]
    factor = vectors[:, keep] * np.sqrt(values[keep])
    return factor / np.linalg.norm(factor, axis=1, keepdims=True)


def _draw(machine, plan, n, rng) -> dict:
    """Every random number of ``n`` built machines, drawn once in a fixed order (so the
    numbers do not depend on the memory budget's chunks)."""
    rng = generator(rng)
    n_axes = len(machine.axes)
    draws = {"motion": [rng.standard_normal((n, f.shape[1], 6)) for f in plan.factors],
             "assembly": rng.standard_normal((n, 6 * (n_axes - 1)))}
    draws["repeat"] = [rng.standard_normal((n, p.test.runs, 2, len(p.poses)))
                       for p in plan.paths if isinstance(p.test, PositioningTest)]
    return draws


def _slice(draws, part) -> dict:
    return {"motion": [z[part] for z in draws["motion"]], "assembly": draws["assembly"][part],
            "repeat": [z[part] for z in draws["repeat"]]}


def _bytes_per_machine(plan) -> int:
    return 8 * len(plan.weights) * (3 + 2 * 6) * 2


def _item_values(plan, draws, machine, k, distribution):
    """Per axis ``(m, U_a, 6)`` motion errors at its positions, and ``(m, n_joint_errors)``
    assembly errors, each ``σ × marginal(z)`` (means are added along the paths)."""
    n_axes = len(machine.axes)
    motion = [normal_to_marginal(np.matmul(f, z), k, distribution)
              * plan.sigma[6 * a:6 * a + 6]
              for a, (f, z) in enumerate(zip(plan.factors, draws["motion"]))]
    assembly = normal_to_marginal(draws["assembly"], k, distribution) * plan.sigma[6 * n_axes:]
    return motion, assembly


def _deviations(plan, motion, assembly, n_axes) -> np.ndarray:
    """``(m, P, 3)`` tool-point deviation in the workpiece frame at every pose, from the
    errors' values (any marginal distribution)."""
    w = plan.weights
    out = assembly @ w[:, :, 6 * n_axes:].reshape(-1, assembly.shape[-1]).T
    out = out.reshape(len(assembly), len(w), 3) + plan.mean_deviation
    for a, values in enumerate(motion):
        at_poses = values[:, plan.index[a], :]                 # (m, P, 6)
        for c in range(6):
            out += at_poses[:, :, c, None] * w[:, :, 6 * a + c]
    return out


def _latent_map(plan, n_axes) -> np.ndarray:
    """``(L, P·3)``: the deviations as a linear map of every standard normal of a machine
    (normal errors only): ``F_a`` along travel, ``σ`` and the weights folded together."""
    blocks = []
    for a, factor in enumerate(plan.factors):
        w = plan.weights[:, :, 6 * a:6 * a + 6] * plan.sigma[6 * a:6 * a + 6]
        blocks.append(np.einsum("pr,poc->rcpo", factor[plan.index[a]], w)
                      .reshape(-1, 3 * len(w)))
    w = plan.weights[:, :, 6 * n_axes:] * plan.sigma[6 * n_axes:]
    blocks.append(np.moveaxis(w, 2, 0).reshape(-1, 3 * len(w)))
    return np.concatenate(blocks)


def _latent(draws) -> np.ndarray:
    """``(m, L)`` a machine's standard normals in the order of :func:`_latent_map`."""
    motion = [z.reshape(len(z), -1) for z in draws["motion"]]
    return np.concatenate(motion + [draws["assembly"]], axis=1)


def _quantities(plan, draws, machine, k, distribution, latent_map=None) -> np.ndarray:
    """``(m, quantities)``: the results of a chunk of machines."""
    if latent_map is not None:   # normal errors: one matrix product
        deviations = (_latent(draws) @ latent_map).reshape(-1, len(plan.weights), 3) \
            + plan.mean_deviation
    else:
        motion, assembly = _item_values(plan, draws, machine, k, distribution)
        deviations = _deviations(plan, motion, assembly, len(machine.axes))
    return _results(plan, deviations, draws["repeat"], scale=(1.0, 1.0))


def _results(plan, deviations, repeat, scale) -> np.ndarray:
    """``(m, quantities)`` every test's results from the deviations along the paths.

    ``scale`` multiplies the repeatability and the reversal of positioning tests (0 to leave
    them out when one geometric item is drawn alone)."""
    noise = iter(repeat)
    columns = []
    for path, start in zip(plan.paths, plan.offsets):
        part = deviations[:, start:start + len(path.poses), :]
        columns.append(_path_results(plan, path, part, next(noise) if isinstance(
            path.test, PositioningTest) else None, scale))
    return np.concatenate(columns, axis=1)


def _path_results(plan, path, deviations, noise, scale) -> np.ndarray:
    """``(m, quantities of the test)`` from the deviations ``(m, P_test, 3)`` of one path."""
    along = deviations @ path.directions.T
    if isinstance(path.test, CircularTest):
        return _circle_g(path, along)[:, None]
    if isinstance(path.test, PositioningTest):
        sigma, reversal = plan.positioning[path.test.name]
        return _positioning_results(along[..., 0], sigma * scale[0], reversal * scale[1],
                                    noise)
    return along.max(axis=1) - along.min(axis=1)


def _circle_g(path, along, iterations: int = 2) -> np.ndarray:
    """``(m,)`` G of circles traced with deviations ``along`` ``(m, P, 2)`` from the nominal.

    The least-squares centre by linear least squares of the radial deviations on
    ``1, cos θ_j, sin θ_j`` at the nominal angles, repeated about the new centre (each pass
    leaves a centre error smaller by about |Δ|/r, and an error e of the centre changes G by
    up to 2e), then the radial range about that centre, exactly. Agrees with
    :func:`circular_deviation` (whose normal equations use the actual directions) to
    10⁻⁷ mm on paths within 30 µm of the circle (tests)."""
    x = path.nominal[:, 0] + along[..., 0]
    y = path.nominal[:, 1] + along[..., 1]
    radius = np.hypot(path.nominal[0, 0], path.nominal[0, 1])
    angles = np.arctan2(path.nominal[:, 1], path.nominal[:, 0])
    basis = np.stack([np.ones_like(angles), np.cos(angles), np.sin(angles)], axis=-1)
    fit = np.linalg.pinv(basis).T                                 # (P, 3): ρ − r, Δcx, Δcy
    cx = cy = np.zeros((len(x), 1))
    for _ in range(iterations):
        step = (np.hypot(x - cx, y - cy) - radius) @ fit
        cx, cy = cx + step[:, 1:2], cy + step[:, 2:3]
    radial = np.hypot(x - cx, y - cy)
    return radial.max(axis=1) - radial.min(axis=1)


def _positioning_results(systematic, sigma, reversal, noise) -> np.ndarray:
    """``(m, 4)`` E, A, R, B of runs whose deviations are the geometric ``systematic``
    ``(m, T)``, ``±reversal/2`` for approaches from below/above and ``σ`` noise."""
    sign = np.array([0.5, -0.5])[:, None]
    deviations = systematic[:, None, None, :] + reversal * sign + sigma * noise
    stats = positioning_statistics(deviations)
    return np.stack([stats[q] for q in PositioningTest.quantities], axis=-1)


def _drivers(plan, draws, machine, k, distribution) -> pd.DataFrame:
    """Each error item's share of each result's mean square, the item drawn alone.

    Items: the machine's errors, and the repeatability and reversal of the axis of each
    positioning test. Mean squares below ``NEGLIGIBLE²`` (rounding) count as zero."""
    n_axes = len(machine.axes)
    motion, assembly = _item_values(plan, draws, machine, k, distribution)
    noise = dict(zip([p.test.name for p in plan.paths if isinstance(p.test, PositioningTest)],
                     draws["repeat"]))
    rows = []
    for path, start in zip(plan.paths, plan.offsets):
        poses = slice(start, start + len(path.poses))
        weights, repeat = plan.weights[poses], noise.get(path.test.name)
        squares = {}
        for i, item in enumerate(machine.error_names):
            if not np.any(weights[:, :, i] @ path.directions.T):
                continue
            if i < 6 * n_axes:
                a, c = divmod(i, 6)
                values = motion[a][:, plan.index[a][poses], c]              # (m, P)
            else:
                values = assembly[:, i - 6 * n_axes, None]
            deviations = (values + plan.item_means[poses, i])[..., None] * weights[:, :, i]
            squares[item] = _mean_square(_path_results(plan, path, deviations, repeat,
                                                       (0.0, 0.0)))
        if isinstance(path.test, PositioningTest):
            zero = np.zeros((len(assembly), len(path.poses), 3))
            for key, scale in (("repeatability", (1.0, 0.0)), ("reversal", (0.0, 1.0))):
                squares[f"{path.test.axis}.{key}"] = _mean_square(
                    _path_results(plan, path, zero, repeat, scale))
        table = pd.DataFrame(squares, index=list(path.test.quantities))
        total = table.sum(axis=1)
        for quantity, row in table.iterrows():
            if total[quantity] > 0:
                rows += [{"test": path.test.name, "quantity": quantity, "item": item,
                          "share": value / total[quantity]}
                         for item, value in row.items() if value > 0]
    return pd.DataFrame(rows, columns=["test", "quantity", "item", "share"])


def _mean_square(results) -> np.ndarray:
    square = np.mean(np.square(results), axis=0)
    return np.where(square > NEGLIGIBLE ** 2, square, 0.0)
