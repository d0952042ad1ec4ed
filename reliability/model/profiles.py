"""Error profiles along travel: how an axis' motion errors at its grid points hang together.

The grid experiment of Sec. 5.3 draws each motion error of an axis independently at each of
the axis' grid points. A real guideway's straightness at 0 mm is not independent of its
straightness at 100 mm: motion errors are smooth functions of the axis position. This module
lets the Monte-Carlo draw them as such, per machine or per axis:

``"independent"`` (:class:`IndependentProfile`)
    The paper's model: a fresh value at every grid point.
``"constant"`` (:class:`ConstantProfile`)
    One value per built machine along the whole travel.
``"gp:<length>"`` (:class:`GaussianProfile`)
    A stationary Gaussian process along travel with correlation length ``length`` (mm):
    squared-exponential in position, periodic for full-turn rotary axes.

Every model changes only the correlation *between* points: the marginal distribution of each
error at every point stays the one the tolerance implies (σ = t/k, truncated at ±t or not), so
FOSM at any one pose (Eqs. 19–23) is unchanged.

A draw has three stages, each a function here, so that further steps (such as a correlation
between error items) can be inserted between them:

1. :func:`standard_normals` — independent N(0, 1) values ``(n_axes, P, 6)``;
2. :func:`correlate_along_travel` — ``z ← L z`` per axis with ``L Lᵀ`` the P × P correlation
   of the axis' profile (unit diagonal, so each value stays N(0, 1));
3. :func:`to_marginal` — each N(0, 1) value mapped to the error's own marginal: ``σ z`` for a
   normal error, and for a truncated one the normal CDF followed by the truncated-normal
   quantile (a monotone map, so the correlation structure is kept as a Gaussian copula).

Positions along a rotary axis are measured as arc length at the axis' rotation radius
(half its ``size``, the diameter D in m), so one correlation length in mm serves every axis.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from ..basics.errors import InputError, InputTypeError
from .error_draws import normal_to_marginal

#: Jitter added to a correlation matrix's diagonal, in turn, until its Cholesky factor exists.
JITTERS = (0.0, 1e-12, 1e-10, 1e-8, 1e-6)


# ----- models ------------------------------------------------------------------------
@dataclass(frozen=True)
class IndependentProfile:
    """Independent at every grid point (the paper's grid experiment, Sec. 5.3)."""

    def correlation(self, axis, points) -> np.ndarray:
        """``(P, P)`` identity."""
        return np.eye(len(points))

    def factor(self, axis, points) -> np.ndarray:
        """``(P, P)`` identity: every point keeps its own draw."""
        return np.eye(len(points))

    def __str__(self) -> str:
        return "independent"


@dataclass(frozen=True)
class ConstantProfile:
    """One value per built machine along the whole travel (perfect correlation)."""

    def correlation(self, axis, points) -> np.ndarray:
        """``(P, P)`` matrix of ones."""
        return np.ones((len(points), len(points)))

    def factor(self, axis, points) -> np.ndarray:
        """Every point takes the first point's draw: ones in the first column."""
        out = np.zeros((len(points), len(points)))
        out[:, 0] = 1.0
        return out

    def __str__(self) -> str:
        return "constant"


@dataclass(frozen=True)
class GaussianProfile:
    """A stationary Gaussian process along travel with correlation length ``length`` (mm).

    The correlation of one error between positions at travel distance ``d`` is

    * ``exp(−d² / (2 ℓ²))`` (squared exponential) on a linear or limited rotary axis;
    * ``exp(−2 sin²(Δθ/2) / (ℓ/r)²)`` (periodic) on a full-turn rotary axis of radius ``r``,
      so that 0 and 2π are the same position; for small angles it equals the squared
      exponential in arc length ``r Δθ``.

    Rotary positions are measured as arc length at the rotation radius ``r = size/2``
    (``size`` is the diameter in m, so ``r = 500 · size`` mm).

    Parameters
    ----------
    length : float
        Correlation length ℓ in mm, finite and > 0. Short lengths approach
        :class:`IndependentProfile`, long ones :class:`ConstantProfile`.
    """

    length: float

    def __post_init__(self):
        if isinstance(self.length, bool) or not isinstance(self.length, (int, float, np.number)):
            raise InputTypeError(f"GaussianProfile length must be a number (mm); "
                                 f"got {self.length!r}")
        if not (math.isfinite(self.length) and self.length > 0):
            raise InputError(f"GaussianProfile length must be finite and > 0 (mm); "
                             f"got {self.length!r}")
        object.__setattr__(self, "length", float(self.length))

    def correlation(self, axis, points) -> np.ndarray:
        """``(P, P)`` correlation of the profile at an axis' positions ``points``."""
        points = np.asarray(points, dtype=float)
        if axis.kind == "rotary":
            radius = 500.0 * axis.size  # mm, from the diameter in m
            if axis.full_turn:
                half = np.sin(0.5 * (points[:, None] - points[None, :]))
                return np.exp(-2.0 * half ** 2 / (self.length / radius) ** 2)
            points = radius * points
        distance = points[:, None] - points[None, :]
        return np.exp(-0.5 * (distance / self.length) ** 2)

    def factor(self, axis, points) -> np.ndarray:
        """Lower-triangular ``L`` with ``L Lᵀ`` the correlation (see :func:`cholesky_factor`)."""
        return cholesky_factor(self.correlation(axis, points))

    def __str__(self) -> str:
        return f"gp:{self.length:g}"


PROFILE_TYPES = (IndependentProfile, ConstantProfile, GaussianProfile)


def cholesky_factor(correlation) -> np.ndarray:
    """Cholesky factor of a correlation matrix, with documented jitter.

    A smooth profile's correlation at grid points far closer than its length is numerically
    singular. The diagonal is raised by the first jitter ``ε`` of :data:`JITTERS` for which
    the Cholesky factorisation succeeds, and the result divided by ``1 + ε`` so that it
    stays a correlation matrix (unit diagonal: every point keeps its marginal exactly);
    off-diagonal correlations shrink by the factor ``1/(1 + ε) ≥ 1 − 10⁻⁶``.

    Parameters
    ----------
    correlation : array_like
        ``(P, P)`` symmetric positive semi-definite matrix with unit diagonal.

    Returns
    -------
    numpy.ndarray
        ``(P, P)`` lower-triangular ``L`` with ``L Lᵀ = (C + ε I)/(1 + ε)``.
    """
    c = np.asarray(correlation, dtype=float)
    for jitter in JITTERS:
        try:
            factor = np.linalg.cholesky(c + jitter * np.eye(len(c)))
        except np.linalg.LinAlgError:
            continue
        return factor / math.sqrt(1.0 + jitter)
    raise InputError(f"correlation matrix is not positive semi-definite even with a jitter "
                     f"of {JITTERS[-1]:g} on its diagonal")


def profile_model(spec):
    """An error-profile model from its name or the model itself.

    Parameters
    ----------
    spec : str or profile model
        ``"independent"``, ``"constant"``, ``"gp:<length in mm>"`` (e.g. ``"gp:200"``), or
        an :class:`IndependentProfile`, :class:`ConstantProfile` or :class:`GaussianProfile`.
    """
    if isinstance(spec, PROFILE_TYPES):
        return spec
    if not isinstance(spec, str):
        raise InputTypeError(f"profile must be 'independent', 'constant', 'gp:<length mm>' or a "
                             f"profile model; got {spec!r}")
    if spec == "independent":
        return IndependentProfile()
    if spec == "constant":
        return ConstantProfile()
    if spec.startswith("gp:"):
        try:
            length = float(spec[3:])
        except ValueError:
            raise InputError(f"profile {spec!r}: the correlation length after 'gp:' must be "
                             f"a number of mm, e.g. 'gp:200'") from None
        return GaussianProfile(length)
    raise InputError(f"unknown profile {spec!r}; use 'independent', 'constant' or "
                     f"'gp:<length mm>'")


def axis_profiles(machine, profile="independent") -> tuple:
    """One profile model per axis of ``machine``, in chain order.

    Parameters
    ----------
    machine : Machine
    profile : str, profile model, or mapping
        One model for every axis, or ``{axis name: model}``; axes not named are
        independent. Unknown axis names are refused.
    """
    if isinstance(profile, Mapping):
        unknown = [name for name in profile if name not in machine.axes]
        if unknown:
            raise InputError(f"profile names unknown axis {unknown[0]!r}; the machine's axes "
                             f"are {machine.axes}")
        return tuple(_axis_model(name, profile.get(name, "independent"))
                     for name in machine.axes)
    model = profile_model(profile)
    return tuple(model for _ in machine.axes)


def _axis_model(axis_name, spec):
    """:func:`profile_model` whose refusal names the axis."""
    try:
        return profile_model(spec)
    except (InputError, InputTypeError) as exc:
        raise type(exc)(f"axis {axis_name!r}: {exc}") from None


def travel_factors(machine, profiles, axis_points) -> np.ndarray:
    """``(n_axes, P, P)``: each axis' Cholesky factor of its along-travel correlation."""
    return np.stack([model.factor(axis, points) for model, axis, points
                     in zip(profiles, machine.axis_specs, axis_points)])


# ----- the three stages of a draw -----------------------------------------------------
def standard_normals(rng, shape) -> np.ndarray:
    """Stage 1: independent N(0, 1) values of the given shape from generator ``rng``."""
    return rng.standard_normal(shape)


def correlate_along_travel(z, factors) -> np.ndarray:
    """Stage 2: ``(..., n_axes, P, 6)`` N(0, 1) values correlated along each axis' travel.

    ``factors`` are :func:`travel_factors`; each has unit-norm rows, so every value stays
    N(0, 1) and the six errors of a point stay independent of each other. Leading axes of
    ``z`` (several experiments) are kept.
    """
    return np.einsum("apq,...aqc->...apc", factors, z)


def to_marginal(z, tolerances, k: float = 3.0, distribution: str = "truncated") -> np.ndarray:
    """Stage 3: map N(0, 1) values to errors of tolerance ``t`` (σ = t/k).

    'normal': ``σ z``. 'truncated': ``σ F⁻¹(Φ(z))`` with ``F`` the N(0, 1) CDF truncated at
    ±k, i.e. N(0, σ²) truncated at ±t. It is evaluated on the lower tail and mirrored,
    ``−sign(z) Φ⁻¹(Φ(−k) + Φ(−|z|)(1 − 2Φ(−k)))``, so that large ``|z|`` lose no accuracy.
    """
    return normal_to_marginal(z, k, distribution) * (np.asarray(tolerances, dtype=float) / k)


def draw_motion_errors(factors, tolerances, rng, k: float = 3.0,
                       distribution: str = "truncated") -> np.ndarray:
    """One experiment's motion errors along travel: the three stages in turn.

    Parameters
    ----------
    factors : ndarray
        ``(n_axes, P, P)`` from :func:`travel_factors`.
    tolerances : ndarray
        ``(n_axes, 6)`` motion-error tolerances.
    rng : numpy.random.Generator
    k : float
    distribution : {'truncated', 'normal'}

    Returns
    -------
    numpy.ndarray
        ``(n_axes, P, 6)`` errors, each with its tolerance's marginal at every point.
    """
    z = standard_normals(rng, factors.shape[:2] + (6,))
    z = correlate_along_travel(z, factors)
    return to_marginal(z, tolerances[:, None, :], k, distribution)
