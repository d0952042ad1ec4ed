"""The continuous allocation over a work zone: the loop's final certificate against an
independent dense search of the zone, and the loop stopped by a time limit or Ctrl-C."""

from __future__ import annotations

import time
import tomllib
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import minimize

from allocation import AllocationProblem
from allocation.per_pose.continuous import certificate_table, solve_continuous
from reliability.basics.errors import InputError, InputTypeError
from reliability.first_order import certificate
from reliability.first_order.certificate import certified_worst
from reliability.first_order.fosm import error_sigma
from reliability.model.kinematics import output_variance
from reliability.model.machine_file import machine_from_dict
from reliability.model.poses import random_poses, workspace_grid
from reliability.model.work_zone import inside_zone, tool_points, tool_tilts

MACHINES = Path(__file__).parent / "machines"
#: A cylinder about the C table's axis, z 0 … 300 mm, tilt 0 … 90°, on the trunnion.
RADIUS, HEIGHT, TILT = 250.0, 300.0, 90.0
CYLINDER = {"shape": "cylinder", "centre": [0.0, 0.0], "radius": RADIUS,
            "z": [0.0, HEIGHT], "tilt": [0.0, TILT]}
RTOL = 1e-3


@pytest.fixture(scope="module")
def zoned():
    table = tomllib.loads((MACHINES / "trunnion5.toml").read_text())
    return machine_from_dict({**table, "workzone": CYLINDER}, "trunnion5 with a cylinder")


@pytest.fixture(scope="module")
def problem(zoned):
    return AllocationProblem.build(zoned, workspace_grid(zoned, 5))


@pytest.fixture(scope="module")
def loop(problem):
    return solve_continuous(problem, rtol=RTOL)


def sigma_of(machine, tolerances, poses):
    variance = np.square(error_sigma(tolerances, 3.0, "normal"))
    return np.sqrt(output_variance(machine, np.atleast_2d(poses), variance))


def zone_margins(machine, q):
    """The zone's constraints at a pose from the chain's tool point and tilt (≥ 0
    inside): R² − r², z, H − z, 90° − tilt."""
    point = tool_points(machine, q[None])[0]
    tilt = tool_tilts(machine, q[None])[0]
    return np.array([(RADIUS ** 2 - point[0] ** 2 - point[1] ** 2) / RADIUS ** 2,
                     point[2] / HEIGHT, (HEIGHT - point[2]) / HEIGHT,
                     np.radians(TILT) - tilt])


def dense_worst(machine, tolerances, allowed, n=20_000, starts=5, seed=11):
    """Largest σ per output over ``n`` random poses of the zone and SLSQP searches
    (finite differences on the chain, each stroke scaled to [0, 1], the zone's
    constraints from the tool point) from the best ``starts`` of them: an independent
    lower bound of the worst σ."""
    poses = random_poses(machine, n, rng=seed)
    sigma = sigma_of(machine, tolerances, poses)
    low = np.array([axis.stroke[0] for axis in machine.axis_specs])
    span = np.array([axis.stroke[1] for axis in machine.axis_specs]) - low
    worst = sigma.max(axis=0)
    for o in range(sigma.shape[1]):
        def negative(u, o=o):
            return -sigma_of(machine, tolerances, low + span * u)[0, o] / allowed[o]

        for start in poses[np.argsort(-sigma[:, o])[:starts]]:
            found = minimize(negative, (start - low) / span, method="SLSQP",
                             bounds=[(0.0, 1.0)] * len(low), options={"ftol": 1e-12},
                             constraints={"type": "ineq",
                                          "fun": lambda u: zone_margins(machine, low + span * u)})
            q = low + span * found.x
            if inside_zone(machine, q[None])[0]:
                worst[o] = max(worst[o], sigma_of(machine, tolerances, q)[0, o])
    return worst


def test_zone_loop_certificate_holds_against_a_dense_search_of_the_zone(zoned, problem,
                                                                          loop):
    """The final certificate at the loop's allocation: per output, its bound is at least
    the largest σ a dense search of the zone finds (20 000 random zone poses and a
    constrained local search from the best five) and within rtol of it; its worst poses
    are in the zone, and on the zone's boundary for some outputs (the tool on the
    cylinder's rim or top, where σ keeps rising outside)."""
    assert loop.certified, loop.reason
    table = loop.certificate
    dense = dense_worst(zoned, loop.tolerances, problem.allowed_sigma)
    bound = table["sigma_bound"].to_numpy()
    assert np.all(bound >= dense * (1 - 1e-12))
    assert np.all(bound <= dense * (1 + RTOL))
    assert np.all(table["sigma"].to_numpy() >= dense / (1 + RTOL))
    worst = table[list(zoned.axes)].to_numpy(dtype=float)
    assert inside_zone(zoned, worst).all()
    on_boundary = [np.abs(zone_margins(zoned, q)).min() < 1e-6 for q in worst]
    assert any(on_boundary)
    assert np.all(table["excess"] <= RTOL) and (table["open"] == 0).all()


def test_the_reported_certificate_is_the_full_certificate_of_the_final_allocation(
        zoned, problem, loop):
    """The loop's last certificate stopped no output early, so it is the table the
    certificate gives at the final allocation without the loop's options: the same worst
    poses, values and bounds."""
    again = certificate_table(problem, loop.tolerances, RTOL)
    columns = list(zoned.axes) + ["sigma", "sigma_bound", "calls", "open", "excess"]
    assert loop.certificate.attrs["current"]
    assert loop.certificate[columns].equals(again[columns])


def test_a_certificate_that_stops_at_short_poses_cuts_them(zoned, problem):
    """At the grid optimum, asked to stop at the first pose short by more than ¼ rtol,
    the certificate stops the outputs it finds short (bound +inf, boxes left open) at a
    pose where σ exceeds that much; every output it does not stop is bounded as by the
    full certificate."""
    t = problem.solve_exact().tolerances
    allowed = problem.allowed_sigma
    stopped = certificate_table(problem, t, RTOL, stop_share=0.25)
    short = np.isinf(stopped["sigma_bound"].to_numpy())
    assert short.any()
    assert np.all(stopped["sigma"].to_numpy()[short] > allowed[short] * (1 + 0.25 * RTOL))
    assert np.all(stopped["open"].to_numpy()[short] > 0)
    poses = stopped[list(zoned.axes)].to_numpy(dtype=float)[short]
    assert inside_zone(zoned, poses).all()
    full = certificate_table(problem, t, RTOL)
    first = int(np.argmax(short))  # outputs before the first stop run in full
    np.testing.assert_array_equal(stopped["sigma_bound"].to_numpy()[:first],
                                  full["sigma_bound"].to_numpy()[:first])
    assert np.all(full["sigma_bound"].to_numpy() >= stopped["sigma"].to_numpy())


def test_a_certificate_past_its_deadline_still_bounds_every_output(zoned, problem,
                                                                   monkeypatch):
    """A deadline already passed stops every output's search after its first box
    evaluation (here; DEADLINE_CALLS by default): the boxes left open count in the bound,
    which stays above the largest σ of 20 000 random zone poses, with a gap wider than
    asked."""
    monkeypatch.setattr(certificate, "DEADLINE_CALLS", 1)
    t = problem.solve_exact().tolerances
    table = certified_worst(zoned, t, rtol=RTOL, deadline=time.perf_counter())
    dense = sigma_of(zoned, t, random_poses(zoned, 20_000, rng=13)).max(axis=0)
    assert np.all(np.isfinite(table["sigma_bound"].to_numpy()))
    assert np.all(table["sigma_bound"].to_numpy() >= dense)
    assert (table["open"] > 0).any() and not table["certified"].all()


def test_time_limit_returns_an_uncertified_result_with_the_reason(problem):
    result = solve_continuous(problem, rtol=RTOL, time_limit=1e-9)
    assert not result.certified and result.solves == 1
    assert result.reason.startswith("not certified to rtol: stopped by the time limit "
                                    "after ")
    assert "NOT certified" in result.statement and result.scaled is None


@pytest.mark.parametrize(("call", "error", "named"), [
    (lambda p: solve_continuous(p, time_limit=-1.0), InputError, "time_limit"),
    (lambda p: solve_continuous(p, time_limit=float("nan")), InputError, "time_limit"),
    (lambda p: certified_worst(p.machine, p.machine.initial_allocation,
                               stop_above=[1.0, 2.0]), InputError, "stop_above"),
    (lambda p: certified_worst(p.machine, p.machine.initial_allocation,
                               close_below=np.zeros(6)), InputError, "close_below"),
    (lambda p: certified_worst(p.machine, p.machine.initial_allocation,
                               deadline="soon"), InputTypeError, "deadline"),
])
def test_bad_stopping_options_are_refused_by_name(problem, call, error, named):
    with pytest.raises(error, match=named):
        call(problem)


def test_ctrl_c_stops_the_loop_with_the_last_allocation(problem):
    """A KeyboardInterrupt raised during the loop (here by the progress callback, at the
    first local search) stops it with the last solve's allocation, uncertified."""
    def interrupt(text):
        raise KeyboardInterrupt

    result = solve_continuous(problem, rtol=RTOL, progress=interrupt)
    assert not result.certified and result.reason.startswith(
        "not certified to rtol: interrupted after ")
    np.testing.assert_array_equal(result.tolerances, problem.solve_exact().tolerances)


def test_scaled_allocation_meets_every_target_by_its_certificate(zoned, problem):
    """The grid optimum scaled by 1/(1 + its largest certified excess): its own
    certificate's bounds meet what the targets allow (σ is linear in a common factor on
    the tolerances), and a dense search of the zone finds no pose short."""
    from allocation.per_pose.continuous import _scaled

    grid = problem.solve_exact()
    table = certificate_table(problem, grid.tolerances, 1e-2)
    scaled = _scaled(grid, table)
    assert scaled is not None and np.all(scaled < grid.tolerances)
    again = certificate_table(problem, scaled, 1e-2)
    assert np.all(again["sigma_bound"].to_numpy() <= problem.allowed_sigma)
    dense = sigma_of(zoned, scaled, random_poses(zoned, 20_000, rng=12)).max(axis=0)
    assert np.all(dense <= problem.allowed_sigma)
