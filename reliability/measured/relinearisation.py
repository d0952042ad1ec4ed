"""Gauss–Newton re-linearisation of an identification on the exact chain.

The first-order model reads every reading through the Jacobian at zero errors. Here each
reading ``h_i(x_i)`` is the exact workpiece-frame deviation of the chain (the product of
:func:`reliability.model.kinematics.comprehensive_error`; a ballbar's exact length change
for a ``radial`` reading) at the errors ``x_i`` in force at its pose, and the model is
linearised at the current posterior mean ``θ̂``:

    y_i ≈ h_i(x̂_i) + a_i (θ − θ̂) + b_i s,

``a_i`` the exact chain's sensitivities at ``x̂_i`` (central differences with a step of
:data:`STEP` of each error's prior σ) carried to the coefficients. The
linear-Gaussian update is solved again with the data ``y_i − h_i(x̂_i) + a_i θ̂`` until no
coefficient moves by more than :data:`SETTLED` of its posterior σ, at most
:data:`MAX_ITERATIONS` times.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..acceptance.iso_tests import tool_point
from ..basics.chunks import chunks
from ..model.kinematics import (chain_factors, deviation_from_transports, ideal_rotation,
                                transports, vectors_in_frame)
from ..model.transforms import read_pose_error
from .information import add_readings, empty_blocks, setup_effect, solve
from .measurement_files import QUANTITIES

#: A re-linearisation that moves no coefficient by more than this fraction of its
#: posterior σ has settled.
SETTLED = 1e-3
#: Most re-linearisations.
MAX_ITERATIONS = 10
#: Central-difference step of the exact chain's sensitivities, in units of each error's
#: prior σ.
STEP = 1e-4


@dataclass(frozen=True, eq=False)
class ExactReader:
    """The readings of one chunk on the exact chain, for any errors in force at their poses.

    The chain's ideal transports and rotation depend on the poses only and are formed once
    (:func:`reliability.model.kinematics.deviation_from_transports`), once per distinct pose.
    """

    poses: np.ndarray
    where: np.ndarray
    adjoints: list
    blocks: list
    rotation: np.ndarray
    index: np.ndarray
    radial: np.ndarray
    arm: np.ndarray

    def __call__(self, errors) -> np.ndarray:
        """Every reading at ``errors`` ``(n_distinct, n_errors)`` in force at the distinct
        poses: the quantity's component of the workpiece-frame deviation, or the ballbar's
        exact length change."""
        twists = [errors[..., 6 * b:6 * b + 6] for b in self.blocks]
        deviation = vectors_in_frame(read_pose_error(
            deviation_from_transports(self.adjoints, twists)), self.rotation)[self.where]
        value = deviation[np.arange(len(self.index)), self.index]
        value[self.radial] = np.linalg.norm(self.arm + deviation[self.radial, :3], axis=1) - \
            np.linalg.norm(self.arm, axis=1)
        return value


def exact_reader(machine, measurements, part) -> ExactReader:
    """The :class:`ExactReader` of the readings ``part``."""
    distinct, where = np.unique(measurements.poses[part], axis=0, return_inverse=True)
    factors, blocks = chain_factors(machine, distinct)
    quantity = measurements.quantity[part]
    radial = quantity == "radial"
    return ExactReader(
        poses=distinct, where=where.ravel(), adjoints=transports(factors), blocks=blocks,
        rotation=ideal_rotation(machine, distinct),
        index=np.array([QUANTITIES.index(q) if q != "radial" else 0 for q in quantity]),
        radial=radial, arm=tool_point(machine, measurements.poses[part][radial])
        - measurements.centre[part][radial])


def exact_rows(machine, measurements, part, coefficients, theta) -> tuple[np.ndarray,
                                                                          np.ndarray]:
    """The readings ``part`` on the exact chain at coefficients ``theta``, and their
    sensitivities ``(n, n_coefficients)`` there."""
    read = exact_reader(machine, measurements, part)
    errors = coefficients.values(theta, read.poses)
    rows = np.empty((len(read.where), machine.n_errors))
    for i, step in enumerate(STEP * coefficients.prior_sd):
        move = np.zeros(machine.n_errors)
        move[i] = step
        rows[:, i] = (read(errors + move) - read(errors - move)) / (2.0 * step)
    return read(errors), coefficients.rows(rows, measurements.poses[part])


def gauss_newton(machine, measurements, setups, coefficients, fit, memory=None):
    """Re-linearise ``fit`` at its posterior mean until it settles.

    Returns
    -------
    fit : Fit
        The last solution.
    iterations : int
    settled : bool
    fitted : ndarray (N,)
        Each reading on the exact chain at the last posterior mean, set-ups included.
    """
    width = 8 * (4 * machine.n_errors + 2 * coefficients.size + 64)
    parts = chunks(len(measurements), width, memory)
    settled = False
    for iteration in range(1, MAX_ITERATIONS + 1):
        blocks = empty_blocks(coefficients.size, len(setups.names))
        for part in parts:
            exact, rows = exact_rows(machine, measurements, part, coefficients, fit.theta)
            add_readings(blocks, setups, part, rows,
                         measurements.value[part] - exact + rows @ fit.theta,
                         measurements.u[part])
        new = solve(blocks, setups.names)
        step = np.abs(new.theta - fit.theta) / np.sqrt(np.diag(new.covariance))
        fit = new
        if np.max(step, initial=0.0) <= SETTLED:
            settled = True
            break
    fitted = np.empty(len(measurements))
    for part in parts:
        fitted[part] = _exact_at(machine, measurements, part, coefficients, fit.theta) + \
            setup_effect(setups, part, fit.setup_mean)
    return fit, iteration, settled, fitted


def _exact_at(machine, measurements, part, coefficients, theta) -> np.ndarray:
    read = exact_reader(machine, measurements, part)
    return read(coefficients.values(theta, read.poses))
