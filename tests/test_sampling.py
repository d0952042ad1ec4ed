"""Tests of the Monte-Carlo sampling engine, :mod:`reliability.sampling.grid_experiment` (Sec.
5.3).

What is checked, and against what:

* :meth:`GridExperiment.evaluate` (the head/tail factorisation) against
  :meth:`GridExperiment.reference_evaluate` (the per-pose exact model) to 1e-12 of each
  output's size, and against a literal product of Eqs. (16)–(18) written out here with
  its own transforms and ``numpy.linalg.inv``, within a rounding bound derived from the
  chain's lever length. Machines: the paper's hobbing machine (6 axes), and three described
  here with :func:`reliability.machine_from_dict` (3 linear axes with offsets, a 5-axis with
  three rotary axes, a 2-axis), so that odd axis counts exercise the head/tail split.
* The structure of a grid experiment: pose order, which poses a motion-error draw reaches.
* :func:`draw_errors` against the truncated-normal moments of ``scipy.stats.truncnorm`` and
  the normal tail probability.
* :meth:`GridExperiment.run`: reproducibility, independence of ``batch``, refusals.
* Statistical agreement of grid Monte-Carlo and FOSM where the model is linear-normal, of
  random-pose sampling and its own FOSM, and of our Table 9 with the paper's.

Statistical tolerances are ``Z = 4`` standard errors of the estimator (stated per test);
all seeds are fixed, so every result is reproducible.
"""

from __future__ import annotations

import contextlib
import itertools
import math
import signal

import numpy as np
import pytest
from scipy import stats

import reliability
from reliability import OUTPUTS, machine_from_dict
from reliability.first_order.fosm import fosm
from reliability.model.error_draws import draw_errors
from reliability.model.poses import random_poses, workspace_grid
from reliability.sampling.grid_experiment import GridExperiment
from reliability.sampling.pose_sampling import sample_random_poses
from studies.paper.tables import TABLE6, TABLE9

Z = 4.0                    # tolerance of every statistical check, in standard errors
EPS = np.finfo(float).eps
TABLE4_LIN, TABLE4_ANG = 0.003, 1.45e-5


# ----------------------------------------------------------------------- test machines
def _description(name, axes, tool_offset, limits=(0.02, 0.02, 0.02, 5e-5, 5e-5, 5e-5)):
    """A machine in the TOML layout, with Table-4-like requirements and cost data."""
    names = [a["name"] for a in axes]
    joints = [f"{a}-{b}" for a, b in zip(names[:-1], names[1:])]
    return {
        "name": name,
        "axes": axes,
        "tool_offset": list(tool_offset),
        "requirements": {c: {"limit": lim, "target": 0.99} for c, lim in zip(OUTPUTS, limits)},
        "initial_allocation": {"translation": TABLE4_LIN, "rotation": TABLE4_ANG},
        "cost": {"a": 2.0, "b": 1.5, "c": 1.8, "d": 1.4,
                 "assembly": {j: 1.0 + 0.1 * i for i, j in enumerate(joints)}},
    }


# Three linear axes, every frame offset so that lever arms are not all along one axis,
# and a tool 150 mm below the last frame. Odd: head = X, Y; tail = Z.
LIN3 = _description("3-axis linear, offsets", [
    {"name": "X", "kind": "linear", "direction": "x", "stroke": [-200.0, 300.0], "size": 1.5,
     "offset": [10.0, -20.0, 30.0]},
    {"name": "Y", "kind": "linear", "direction": "y", "stroke": [0.0, 400.0], "size": 1.2,
     "offset": [-50.0, 15.0, 200.0]},
    {"name": "Z", "kind": "linear", "direction": "z", "stroke": [-300.0, 0.0], "size": 0.9,
     "offset": [5.0, 60.0, 450.0]},
], tool_offset=(0.0, 0.0, -150.0))

# Five axes, three rotary (full-turn C, tilting A, swivelling B last so that the tail
# rotates), offsets everywhere, a tool offset off the spindle axis. Odd: head = C A X.
ROT5 = _description("5-axis, rotary C A B", [
    {"name": "C", "kind": "rotary", "direction": "z", "full_turn": True, "size": 0.6,
     "offset": [0.0, 0.0, -80.0]},
    {"name": "A", "kind": "rotary", "direction": "x", "stroke": [-2.0, 0.5], "size": 0.8,
     "offset": [0.0, 30.0, -120.0]},
    {"name": "X", "kind": "linear", "direction": "x", "stroke": [-300.0, 300.0], "size": 1.4},
    {"name": "Y", "kind": "linear", "direction": "y", "stroke": [-200.0, 200.0], "size": 1.0,
     "offset": [0.0, -50.0, -300.0]},
    {"name": "B", "kind": "rotary", "direction": "y", "stroke": [-1.0, 1.0], "size": 0.5,
     "offset": [25.0, 0.0, 450.0]},
], tool_offset=(10.0, -5.0, -150.0))

# Two axes (even, head = 1 axis, tail = 1 axis), rotary then linear.
PAIR2 = _description("2-axis, rotary + linear", [
    {"name": "B", "kind": "rotary", "direction": "y", "stroke": [-1.5, 1.5], "size": 0.7,
     "offset": [0.0, 40.0, 0.0]},
    {"name": "Z", "kind": "linear", "direction": "z", "stroke": [0.0, 250.0], "size": 0.8,
     "offset": [100.0, 0.0, 50.0]},
], tool_offset=(0.0, 20.0, -90.0))

# One axis: a machine_from_dict accepts it (no joints, no assembly errors).
ONE1 = _description("1-axis", [
    {"name": "X", "kind": "linear", "direction": "x", "stroke": [0.0, 100.0], "size": 1.0,
     "offset": [1.0, 2.0, 3.0]},
], tool_offset=(0.0, 0.0, -50.0))


@pytest.fixture(scope="module")
def machines():
    return {"hobbing": reliability.hobbing_machine(),
            "lin3": machine_from_dict(LIN3, source="LIN3"),
            "rot5": machine_from_dict(ROT5, source="ROT5"),
            "pair2": machine_from_dict(PAIR2, source="PAIR2")}


@pytest.fixture(scope="module")
def hob():
    return reliability.hobbing_machine()


@pytest.fixture(scope="module")
def table6(hob):
    return hob.error_vector(TABLE6, default=None)


@contextlib.contextmanager
def _time_limit(seconds, what):
    """Turn a call that never returns into a test failure (a hang guard, not a timing test).

    The rejection loop of ``draw_errors`` runs Python bytecode between numpy calls, so a
    SIGALRM handler gets to raise inside it.
    """
    def handler(signum, frame):
        raise TimeoutError(f"{what} did not return within {seconds} s")

    previous = signal.signal(signal.SIGALRM, handler)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


# ----------------------------------------------------------- an independent Eq. 16-18
def _rotation(direction, angle):
    """Right-hand rotation about a coordinate axis (Eqs. 7, 9, 11), written out again."""
    c, s = np.cos(angle), np.sin(angle)
    out = np.zeros(np.shape(angle) + (4, 4))
    out[..., 3, 3] = 1.0
    if direction == "x":
        out[..., 0, 0] = 1.0
        out[..., 1, 1], out[..., 1, 2], out[..., 2, 1], out[..., 2, 2] = c, -s, s, c
    elif direction == "y":
        out[..., 1, 1] = 1.0
        out[..., 0, 0], out[..., 0, 2], out[..., 2, 0], out[..., 2, 2] = c, s, -s, c
    else:
        out[..., 2, 2] = 1.0
        out[..., 0, 0], out[..., 0, 1], out[..., 1, 0], out[..., 1, 1] = c, -s, s, c
    return out


def _translation(vector):
    vector = np.asarray(vector, dtype=float)
    out = np.zeros(vector.shape[:-1] + (4, 4))
    out[..., [0, 1, 2, 3], [0, 1, 2, 3]] = 1.0
    out[..., :3, 3] = vector
    return out


def _ideal(axis, position):
    """Ideal motion of one axis, Eqs. (1)-(11)."""
    if axis.kind == "rotary":
        return _rotation(axis.direction, position)
    vector = np.zeros(np.shape(position) + (3,))
    vector[..., "xyz".index(axis.direction)] = position
    return _translation(vector)


def _error_matrix(x):
    """Eq. (2): the small-angle error transform, ``x = (dx, dy, dz, ex, ey, ez)``."""
    dx, dy, dz, ex, ey, ez = np.moveaxis(np.asarray(x, dtype=float), -1, 0)
    one, zero = np.ones_like(dx), np.zeros_like(dx)
    return np.stack([np.stack([one, -ez, ey, dx], -1),
                     np.stack([ez, one, -ex, dy], -1),
                     np.stack([-ey, ex, one, dz], -1),
                     np.stack([zero, zero, zero, one], -1)], -2)


def _grid_index(n_axes, points):
    """``(P^n, n_axes)`` point index of every grid pose, first axis slowest."""
    return np.array(list(itertools.product(range(points), repeat=n_axes)))


def literal_grid_errors(machine, points, motion, assembly):
    """Eqs. (16)-(18) literally: ``E = inv(M) @ M_e`` pose by pose, read as in docs/model.md.

    ``M_e = Π_i [O_i E^m_i M_i E^p_i] T`` and ``M = Π_i [O_i M_i] T``, the motion errors
    of axis i at pose p being ``motion[:, i, index[p, i]]``.
    """
    specs = machine.axis_specs
    index = _grid_index(len(specs), len(points[0]))
    q = np.stack([points[i][index[:, i]] for i in range(len(specs))], axis=-1)
    actual = np.broadcast_to(np.eye(4), (motion.shape[0], len(q), 4, 4))
    ideal = np.broadcast_to(np.eye(4), (len(q), 4, 4))
    for i, axis in enumerate(specs):
        offset, move = _translation(axis.offset), _ideal(axis, q[:, i])
        actual = actual @ offset @ _error_matrix(motion[:, i][:, index[:, i]]) @ move
        ideal = ideal @ offset @ move
        if i < len(specs) - 1:
            actual = actual @ _error_matrix(assembly[:, i])[:, None]
    tool = _translation(machine.tool_offset)
    e = np.linalg.inv(ideal @ tool) @ (actual @ tool)                # Eq. (18)
    return np.concatenate([e[..., :3, 3],
                           0.5 * np.stack([e[..., 2, 1] - e[..., 1, 2],
                                           e[..., 0, 2] - e[..., 2, 0],
                                           e[..., 1, 0] - e[..., 0, 1]], -1)], -1)


def lever_length(machine):
    """Largest translation the ideal chain can reach (mm): offsets, strokes, tool."""
    length = sum(np.linalg.norm(a.offset) for a in machine.axis_specs)
    length += sum(max(abs(s) for s in a.stroke) for a in machine.axis_specs
                  if a.kind == "linear")
    return length + np.linalg.norm(machine.tool_offset)


def _large_draws(machine, points, repeats, seed):
    """Errors far above any tolerance (0.05 mm, 1 mrad) so second-order terms show."""
    rng = np.random.default_rng(seed)
    scale = np.array([0.05] * 3 + [1e-3] * 3)
    n = len(machine.axis_specs)
    return (rng.standard_normal((repeats, n, points, 6)) * scale,
            rng.standard_normal((repeats, n - 1, 6)) * scale)


# ------------------------------------------------------------------ 1. exactness
@pytest.mark.parametrize("points", [3, 5])
@pytest.mark.parametrize("name", ["hobbing", "lin3", "rot5", "pair2"])
def test_evaluate_matches_reference_and_literal_product(machines, name, points):
    m = machines[name]
    g = GridExperiment(m, points)
    motion, assembly = _large_draws(m, points, repeats=2, seed=11)

    fast = g.evaluate(motion, assembly)
    reference = g.reference_evaluate(motion, assembly)
    size = np.abs(reference).max(axis=(0, 1))
    relative = np.abs(fast - reference).max(axis=(0, 1)) / size
    assert np.all(relative <= 1e-12), f"evaluate vs reference, relative per output: {relative}"

    # Literal Eq. 16-18: M_e and M hold entries up to the lever length L, so rounding in
    # inv(M) @ M_e - I is a few eps * L absolutely for δ and a few eps for ε. Bound: 64 eps.
    literal = literal_grid_errors(m, g.axis_points, motion, assembly)
    bound = 64 * EPS * np.array([1 + lever_length(m)] * 3 + [1.0] * 3)
    difference = np.abs(fast - literal).max(axis=(0, 1))
    assert np.all(difference <= bound), (
        f"evaluate vs literal product: abs diff {difference}, bound {bound}")

    # The comparison has teeth: with these errors the first-order model is far off.
    x = np.concatenate([motion[:, np.arange(len(m.axis_specs)),
                               _grid_index(len(m.axis_specs), points)].reshape(2, g.n_poses, -1),
                        np.repeat(assembly.reshape(2, 1, -1), g.n_poses, axis=1)], axis=-1)
    linear = np.einsum("poi,rpi->rpo", m.jacobian(g.poses), x)
    assert np.all(np.abs(linear - reference).max(axis=(0, 1)) / size > 1e-6)


def test_evaluate_at_tolerance_sized_errors(hob, table6):
    """Table 6 draws (the paper's regime): evaluate vs reference still within 1e-12."""
    g = GridExperiment(hob, 5)
    children = np.random.default_rng(3).spawn(3)
    draws = [g._draw(table6, child, 3.0, "truncated") for child in children]
    motion, assembly = np.stack([d[0] for d in draws]), np.stack([d[1] for d in draws])
    fast, reference = g.evaluate(motion, assembly), g.reference_evaluate(motion, assembly)
    relative = np.abs(fast - reference).max(axis=(0, 1)) / np.abs(reference).max(axis=(0, 1))
    assert np.all(relative <= 1e-12), relative


def test_one_axis_machine_is_evaluated():
    """A 1-axis machine (accepted by machine_from_dict) has an empty tail and no joint.

    The failure guarded against: ``_segment(1, 1)`` adding the gap of joint 0, which does
    not exist (IndexError in ``_deviation``), and head and tail both carrying the tool
    offset.
    """
    m = machine_from_dict(ONE1, source="ONE1")
    g = GridExperiment(m, 4)
    motion, assembly = _large_draws(m, 4, repeats=2, seed=5)
    assert assembly.shape == (2, 0, 6)
    fast = g.evaluate(motion, assembly)
    literal = literal_grid_errors(m, g.axis_points, motion, assembly)
    bound = 64 * EPS * np.array([1 + lever_length(m)] * 3 + [1.0] * 3)
    assert np.all(np.abs(fast - literal).max(axis=(0, 1)) <= bound)


# --------------------------------------------------------------- 2. shapes and order
@pytest.mark.parametrize("name", ["hobbing", "lin3", "rot5", "pair2"])
def test_poses_follow_workspace_grid(machines, name):
    m = machines[name]
    for points in (2, 3):
        g = GridExperiment(m, points)
        assert g.n_poses == points ** len(m.axis_specs)
        np.testing.assert_array_equal(g.poses, workspace_grid(m, points))
        motion, assembly = _large_draws(m, points, repeats=3, seed=0)
        assert g.evaluate(motion, assembly).shape == (3, g.n_poses, 6)


@pytest.mark.parametrize("name", ["hobbing", "lin3", "rot5", "pair2"])
def test_motion_error_reaches_exactly_the_poses_at_its_point(machines, name):
    """A draw at point j of axis i moves the poses with axis i at point j, and no other."""
    m = machines[name]
    n, points = len(m.axis_specs), 3
    g = GridExperiment(m, points)
    index = _grid_index(n, points)
    twist = np.array([0.01, -0.02, 0.015, 2e-5, -1e-5, 3e-5])
    for axis, point in itertools.product(range(n), range(points)):
        motion = np.zeros((2, n, points, 6))
        motion[0, axis, point] = twist          # repeat 1 stays error-free
        out = g.evaluate(motion, np.zeros((2, n - 1, 6)))
        moved = np.any(out[0] != 0, axis=-1)
        np.testing.assert_array_equal(moved, index[:, axis] == point,
                                      err_msg=f"axis {m.axes[axis]}, point {point}")
        assert not np.any(out[1]), "an error-free repeat picked up another repeat's error"


@pytest.mark.parametrize("name", ["hobbing", "lin3", "rot5", "pair2"])
def test_assembly_error_reaches_every_pose(machines, name):
    m = machines[name]
    n, points = len(m.axis_specs), 3
    g = GridExperiment(m, points)
    for joint in range(n - 1):
        assembly = np.zeros((1, n - 1, 6))
        assembly[0, joint] = [0.01, 0.02, -0.01, 1e-5, 2e-5, -3e-5]
        out = g.evaluate(np.zeros((1, n, points, 6)), assembly)
        assert np.all(np.any(out[0] != 0, axis=-1)), f"joint {m.joints[joint]}"


def test_evaluate_refuses_wrong_shapes(hob):
    g = GridExperiment(hob, 3)
    with pytest.raises(ValueError, match="motion errors"):
        g.evaluate(np.zeros((1, 6, 5, 6)), np.zeros((1, 5, 6)))
    with pytest.raises(ValueError, match="assembly errors"):
        g.evaluate(np.zeros((1, 6, 3, 6)), np.zeros((2, 5, 6)))
    with pytest.raises(ValueError, match="points must be"):
        GridExperiment(hob, 1)


# ------------------------------------------------------------------- 3. draw_errors
def test_truncated_draws_stay_within_tolerance_and_have_truncnorm_moments():
    t = np.array([0.003, 1.45e-5, 2.0])
    n = 200_000
    x = draw_errors(t, (n,), rng=2023)
    assert x.shape == (n, 3)
    assert np.all(np.abs(x) <= t), "a truncated draw exceeds its tolerance"
    assert np.all(np.abs(x).max(axis=0) > 0.99 * t), "truncated tighter than ±t"

    # σ of N(0, (t/3)²) truncated at ±3σ; SE of the root-mean-square about the known
    # mean 0 is σ_T sqrt((κ − 1) / (4n)), κ the truncated kurtosis (delta method).
    dist = stats.truncnorm(-3.0, 3.0)
    sigma_t = dist.std() * t / 3.0
    kurtosis = dist.moment(4) / dist.var() ** 2
    se = sigma_t * math.sqrt((kurtosis - 1.0) / (4 * n))
    rms = np.sqrt(np.mean(x ** 2, axis=0))
    assert np.all(np.abs(rms - sigma_t) <= Z * se), (
        f"rms {rms}, truncnorm σ {sigma_t}, z {(rms - sigma_t) / se}")
    assert np.all(np.abs(x.mean(axis=0)) <= Z * sigma_t / math.sqrt(n))
    # ... and the check can tell truncated from untruncated: t/3 is 9 SE away.
    assert np.all(np.abs(rms - t / 3.0) > Z * se)


def test_normal_draws_exceed_tolerance_at_the_normal_rate():
    t = np.array([0.003, 1.45e-5])
    n = 200_000
    x = draw_errors(t, (n,), distribution="normal", rng=7)
    p = 2.0 * (1.0 - stats.norm.cdf(3.0))                    # 0.0027
    outside = np.sum(np.abs(x) > t, axis=0)
    se = math.sqrt(n * p * (1 - p))                            # binomial SE of the count
    assert np.all(np.abs(outside - n * p) <= Z * se), f"outside {outside}, expected {n * p}"
    rms = np.sqrt(np.mean(x ** 2, axis=0))
    assert np.all(np.abs(rms / (t / 3) - 1) <= Z * math.sqrt(2 / (4 * n)))


def test_draw_errors_shape_seed_and_refusals():
    t = np.full((2, 3), 0.01)
    assert draw_errors(t, (4, 5), rng=0).shape == (4, 5, 2, 3)
    np.testing.assert_array_equal(draw_errors(t, (4,), rng=1), draw_errors(t, (4,), rng=1))
    assert not np.array_equal(draw_errors(t, (4,), rng=1), draw_errors(t, (4,), rng=2))
    with pytest.raises(ValueError, match="uniform"):
        draw_errors(t, (4,), distribution="uniform")


@pytest.mark.parametrize("k", [0.0, -3.0, float("nan"), float("inf")])
def test_draw_errors_refuses_bad_coverage_factor(k):
    """σ = t/k needs a finite k > 0. Unchecked, k <= 0 would make the rejection loop of
    the truncated draw endless (|z| > k always), nan would give nan errors, inf zeros."""
    with _time_limit(1.0, f"draw_errors(k={k})"):
        with pytest.raises(ValueError, match=r"\bk\b"):
            draw_errors([0.01, 1e-5], (10,), k=k, rng=0)


# ------------------------------------------------------------------------ 4. run()
def _assert_same_values(a, b):
    """Same draws, same values up to rounding: evaluating a different number of repeats
    together changes BLAS blocking, so per-pose values may differ in the last ulp
    (seen: 1e-20 absolute on 1e-5 values). Counts are compared exactly elsewhere."""
    size = np.abs(b).reshape(-1, 6).max(axis=0)
    assert np.all(np.abs(a - b).reshape(-1, 6).max(axis=0) <= 1e-12 * size)


@pytest.fixture(scope="module")
def grid3(hob):
    return GridExperiment(hob, 3)


def test_run_same_seed_same_counts_and_matches_its_documented_procedure(hob, grid3):
    t = 2 * hob.initial_allocation
    a = grid3.run(t, repeats=5, rng=42, keep_values="all")
    b = grid3.run(t, repeats=5, rng=42, keep_values="none")
    np.testing.assert_array_equal(a.inside, b.inside)
    assert a.inside.dtype.kind == "i" and a.inside.shape == (5, 6)
    assert a.n_poses == 729 and a.points == 3
    assert a.distribution == "truncated" and a.k == 3.0
    np.testing.assert_array_equal(a.limits, hob.limits)
    # Repeat r: errors from the r-th generator spawned from the seed; Eq. (19) strict.
    np.testing.assert_array_equal(np.sum(np.abs(a.values) < hob.limits, axis=1), a.inside)
    children = np.random.default_rng(42).spawn(5)
    for r, child in enumerate(children):
        motion, assembly = grid3._draw(t, child, 3.0, "truncated")
        values = grid3.evaluate(motion[None], assembly[None])[0]
        _assert_same_values(values, a.values[r])
    c = grid3.run(t, repeats=5, rng=43, keep_values="none")
    assert not np.array_equal(a.inside, c.inside)


def test_run_repeat_does_not_depend_on_batch_or_on_repeats(hob, grid3):
    t = 2 * hob.initial_allocation
    one = grid3.run(t, repeats=7, rng=5, batch=1, keep_values="all")
    many = grid3.run(t, repeats=7, rng=5, batch=50, keep_values="all")
    uneven = grid3.run(t, repeats=7, rng=5, batch=3, keep_values="all")
    for other in (many, uneven):
        np.testing.assert_array_equal(one.inside, other.inside)
        _assert_same_values(one.values, other.values)
    prefix = grid3.run(t, repeats=3, rng=5, keep_values="all")
    np.testing.assert_array_equal(prefix.inside, one.inside[:3])
    _assert_same_values(prefix.values, one.values[:3])


def test_run_repeats_get_different_draws(hob, grid3):
    t = 2 * hob.initial_allocation
    values = grid3.run(t, repeats=6, rng=9, keep_values="all").values
    for r, s in itertools.combinations(range(6), 2):
        assert not np.any(values[r] == values[s]), f"repeats {r} and {s} share values"


@pytest.mark.parametrize("keep, shape", [("first", (1, 729, 6)), ("all", (4, 729, 6)),
                                         ("none", None)])
def test_run_keep_values(hob, grid3, keep, shape):
    t = 2 * hob.initial_allocation
    result = grid3.run(t, repeats=4, rng=1, keep_values=keep, batch=3)
    if shape is None:
        assert result.values is None
    else:
        assert result.values.shape == shape
        everything = grid3.run(t, repeats=4, rng=1, keep_values="all")
        _assert_same_values(result.values, everything.values[:shape[0]])


def test_run_reports_progress(hob, grid3):
    calls = []
    grid3.run(hob.initial_allocation, repeats=5, rng=0, batch=2,
              progress=lambda done, total: calls.append((done, total)))
    assert calls == [(2, 5), (4, 5), (5, 5)]


@pytest.mark.parametrize("options, match", [
    ({"repeats": 0}, "repeats"), ({"repeats": -2}, "repeats"), ({"repeats": 2.5}, "repeats"),
    ({"repeats": True}, "repeats"), ({"keep_values": "some"}, "keep_values"),
    ({"batch": 0}, "batch"), ({"batch": 1.5}, "batch"), ({"batch": True}, "batch"),
    ({"distribution": "uniform"}, "uniform"),
])
def test_run_refuses_bad_options(hob, grid3, options, match):
    with pytest.raises(ValueError, match=match):
        grid3.run(hob.initial_allocation, **{"repeats": 2, "rng": 0, **options})


@pytest.mark.parametrize("position, value", [(7, 0.0), (40, float("nan")), (65, -1e-5),
                                             (0, float("inf"))])
def test_run_refuses_bad_tolerances_naming_the_error(hob, grid3, position, value):
    t = hob.initial_allocation.copy()
    t[position] = value
    with pytest.raises(ValueError, match=hob.error_names[position].replace(".", r"\.")):
        grid3.run(t, repeats=2, rng=0)
    with pytest.raises(ValueError, match="shape"):
        grid3.run(hob.initial_allocation[:-1], repeats=2, rng=0)


@pytest.mark.parametrize("k", [0.0, -3.0, float("nan")])
def test_run_refuses_bad_coverage_factor(hob, grid3, k):
    """Unchecked, run(k=0) would never return (see
    test_draw_errors_refuses_bad_coverage_factor)."""
    with _time_limit(1.0, f"GridExperiment.run(k={k})"):
        with pytest.raises(ValueError, match=r"\bk\b"):
            grid3.run(hob.initial_allocation, repeats=2, rng=0, k=k)


# ------------------------------------------------- 5. grid Monte-Carlo versus FOSM
@pytest.mark.parametrize("distribution", ["truncated", "normal"])
def test_grid_mean_fraction_agrees_with_fosm_where_linear_normal(hob, grid3, distribution):
    """E[fraction in one experiment] = mean over the grid poses of P(|y| < I) (linearity of
    expectation). At 2× Table 4 the model is linear to ~1e-4 and y is close to normal, so
    the two-sided FOSM (σ of the distribution actually drawn) must agree with the mean of
    2000 experiments within Z = 4 between-experiment standard errors."""
    t = 2 * hob.initial_allocation
    result = grid3.run(t, repeats=2000, rng=2024, distribution=distribution,
                       keep_values="none", batch=250)
    mc = result.reliability()
    prediction = fosm(hob, t, grid3.poses, distribution=distribution).workspace_mean()
    z = (mc.estimate - prediction) / mc.standard_error
    assert np.all(mc.estimate < 0.97), f"not a regime where P is clearly below 1: {mc.estimate}"
    assert np.all(np.abs(z) <= Z), f"MC {mc.estimate}, FOSM {prediction}, z {z}"
    # Teeth: a 10 % error in σ would be caught for every output.
    off = fosm(hob, 1.1 * t, grid3.poses, distribution=distribution).workspace_mean()
    assert np.all(np.abs(mc.estimate - off) > Z * mc.standard_error)


def test_grid_mean_fraction_agrees_with_fosm_on_five_axis_machine(machines):
    """The same check on the 5-axis machine (odd head/tail split, rotary tail)."""
    m = machines["rot5"]
    g = GridExperiment(m, 3)
    t = 2.5 * m.initial_allocation
    result = g.run(t, repeats=2000, rng=77, keep_values="none", batch=500)
    mc = result.reliability()
    prediction = fosm(m, t, g.poses, distribution="truncated").workspace_mean()
    z = (mc.estimate - prediction) / mc.standard_error
    assert np.all(mc.estimate < 0.97), mc.estimate
    assert np.all(np.abs(z) <= Z), f"MC {mc.estimate}, FOSM {prediction}, z {z}"


# ------------------------------------------------------- 6. random-pose sampling
@pytest.fixture(scope="module")
def random_normal(hob):
    return sample_random_poses(hob, 3 * hob.initial_allocation, 50_000, rng=31,
                               distribution="normal")


def test_random_pose_counts_agree_with_two_sided_fosm(random_normal):
    """Samples are independent: inside ~ Binomial(n, mean P) where the mean P over the
    sampled poses is what fosm_two_sided reports. Z = 4 binomial standard errors."""
    r = random_normal
    p = r.fosm_two_sided
    se = np.sqrt(p * (1 - p) / r.n_samples)
    z = (r.inside / r.n_samples - p) / se
    assert np.all(p < 0.95), p
    assert np.all(np.abs(z) <= Z), f"MC {r.inside / r.n_samples}, FOSM {p}, z {z}"


def test_one_sided_fosm_is_optimistic(random_normal):
    """The paper's Φ(β) lies above the 95 % Wilson interval of the sampled share: it
    counts one tail of |y| > I only."""
    estimate = random_normal.reliability()
    assert np.all(random_normal.fosm_one_sided > estimate.upper), (
        f"one-sided {random_normal.fosm_one_sided}, Wilson upper {estimate.upper}")


def test_random_pose_fosm_uses_the_spread_actually_drawn(hob):
    """With truncated draws (the default) the like-with-like FOSM uses the truncated σ
    (``error_sigma(t, k, 'truncated')``), as the grid comparison does.

    With σ = t/k for truncated draws, fosm_two_sided would sit 0.004-0.007 below what it
    should at 3× Table 4 (about 4-5 binomial SE of the sampled
    share at 1e5 samples). The reference mean over poses is taken on independent random
    poses; its own noise is std(P over poses)/sqrt(n), and Z = 4 of the combined noise
    is allowed.
    """
    t, n = 3 * hob.initial_allocation, 20_000
    result = sample_random_poses(hob, t, n, rng=4, distribution="truncated")
    other = fosm(hob, t, random_poses(hob, n, 99), distribution="truncated").two_sided
    # (For the hobbing machine's ε outputs P does not vary with the pose: the noise is 0
    # and only rounding, 1e-12, is allowed.)
    se = other.std(axis=0, ddof=1) * math.sqrt(2.0 / n)
    difference = result.fosm_two_sided - other.mean(axis=0)
    assert np.all(np.abs(difference) <= Z * se + 1e-12), (
        f"reported {result.fosm_two_sided}, truncated FOSM {other.mean(axis=0)}, "
        f"difference {difference}, noise {se}")


def test_random_poses_are_deterministic_with_seed(hob):
    t = 2 * hob.initial_allocation
    a = sample_random_poses(hob, t, 3000, rng=8, chunk=1000)
    b = sample_random_poses(hob, t, 3000, rng=8, chunk=1000)
    c = sample_random_poses(hob, t, 3000, rng=9, chunk=1000)
    np.testing.assert_array_equal(a.inside, b.inside)
    np.testing.assert_array_equal(a.fosm_two_sided, b.fosm_two_sided)
    assert not np.array_equal(a.fosm_two_sided, c.fosm_two_sided)
    assert a.n_samples == 3000 and a.distribution == "truncated" and a.k == 3.0


@pytest.mark.parametrize("options, match", [
    ({"n_samples": 0}, "n_samples"), ({"n_samples": 2.5}, "n_samples"),
    ({"chunk": 0}, "chunk"), ({"distribution": "uniform"}, "uniform"), ({"k": 0.0}, r"\bk\b"),
])
def test_random_poses_refusals_name_the_argument(hob, options, match):
    """The messages name n_samples and chunk, not 'repeats' and 'batch' (the checks are
    shared with run()), which a caller of sample_random_poses never passed."""
    kwargs = {"n_samples": 10, "rng": 0, **options}
    with pytest.raises(ValueError, match=match):
        sample_random_poses(hob, hob.initial_allocation, **kwargs)


def test_random_poses_refuse_bad_tolerances(hob):
    t = hob.initial_allocation.copy()
    t[12] = -0.001
    with pytest.raises(ValueError, match=r"Z\.dx"):
        sample_random_poses(hob, t, 10, rng=0)


# ---------------------------------------------------- 9. the paper's Table 9
def test_table9_regression_against_the_paper(hob, table6):
    """100 grid experiments with the Table 6 allocation against the 20 of Table 9.

    Per output: |mean_ours − mean_paper| <= Z sqrt(se_ours² + se_paper²), with
    se = std(ddof=1)/sqrt(n) of each set of experiments, Z = 4.

    Caveat, measured with 1000 experiments: our means lie below the paper's for all six
    outputs (ex by ~3 combined SE at 100 experiments), and our per-experiment spread is
    3-200× the paper's. The fractions are heavy-tailed (most experiments at 1, a few far
    below), so 20 experiments tend to miss the tail and their std understates the spread:
    se_paper from Table 9 is optimistic and this check is tighter than it looks.
    """
    g = GridExperiment(hob, 5)
    result = g.run(table6, repeats=100, rng=20230217, keep_values="none")
    ours = result.reliability()
    paper = TABLE9[list(OUTPUTS)]
    paper_mean = paper.mean().to_numpy()
    paper_se = paper.std(ddof=1).to_numpy() / math.sqrt(len(paper))
    combined = np.sqrt(ours.standard_error ** 2 + paper_se ** 2)
    z = (ours.estimate - paper_mean) / combined
    lines = [f"{o}: ours {ours.estimate[i]:.5f} ± {ours.standard_error[i]:.5f} "
             f"(std {ours.std[i]:.5f}), paper {paper_mean[i]:.5f} ± {paper_se[i]:.5f} "
             f"(std {paper.std(ddof=1).iloc[i]:.5f}), z {z[i]:+.2f}"
             for i, o in enumerate(OUTPUTS)]
    assert np.all(np.abs(z) <= Z), "Table 9 regression:\n" + "\n".join(lines)
