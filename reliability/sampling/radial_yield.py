"""The machine yield of the linearised outputs by directional (radial) sampling, and a
yield of the exact chain with it as a control variate.

The linearised machine. Read the outputs to first order at the poses that decide (Eq. 19,
rows ``a_r = J_o(q) / (3 I_o)``), every error normal with σ = t/3, independent and constant
along travel. A built machine is ``t ∘ z`` with ``z`` standard normal in ``R^n``, and it
passes when every ``|a_r · (t ∘ z)| ≤ 1``: ``t ∘ z`` lies in a symmetric convex polytope.

Directional sampling (Deák 1980; Ditlevsen & Madsen, *Structural Reliability Methods*,
1996, ch. 9). Write ``z = R θ`` with ``θ`` uniform on the unit sphere and ``R² ~ χ²_n``
independent of it. Along the ray of ``θ`` the machine passes for ``R ≤ ρ(θ)`` with

    ρ(θ) = 1 / max_r |a_r · (t ∘ θ)|                                            (R1)

(the polytope is convex and holds the origin), so ``P(pass | θ) = F_{χ²_n}(ρ(θ)²)`` in
closed form and the linearised yield is ``Y_lin = E_θ[F_{χ²_n}(ρ²)]``: an average of
numbers in [0, 1] that vary far less than the 0/1 verdicts of whole machines. One ray costs
one product with the rows, as one machine does. Its gradient follows from (R1): at the
binding row ``r*`` (``y = a_r* · (t ∘ θ)``), ``∂ρ/∂log t_i = −ρ a_r*i t_i θ_i / y``, so

    ∂Y_lin/∂log t_i = −E_θ[2 ρ² f_{χ²_n}(ρ²) s_i],   s_i = a_r*i t_i θ_i / y      (R2)

(the shares ``s_i`` sum to one, so the components sum to the derivative along a common
scale). ρ is Lipschitz in ``log t``, so (R2) is the derivative of the expectation.

The exact chain. On ``N`` built machines judged both on the exact chain and on the
linearised rows (the same draws), the yield of the exact chain is estimated by

    Ŷ = mean_N(1_exact − 1_lin) + Ŷ_lin(M rays)                                  (R3)

unbiased, since ``E[1_lin] = Y_lin``; the two verdicts almost always agree, so the first term
varies little, and the sample on the rays is independent of the machines:
``Var Ŷ = Var(D)/N + Var_dir/M``. The standard error takes ``Var(D) ≤ E[D²]`` with one more
disagreement than observed (so a sample without disagreements still counts some), and the
interval is ``Ŷ ± z·SE`` (normal, by the central limit theorem over machines and rays),
clipped to [0, 1].
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq
from scipy.stats import chi2, norm

from reliability.basics import checks, streams
from reliability.basics.errors import InputError

#: Floats of one block of rays or machines × rows (memory bounded by chunking).
BLOCK_FLOATS = 2_000_000
#: The method name of an interval of (R3).
CONTROLLED_METHOD = "radial control variate"


def directions(rays: int, n: int, rng=None) -> np.ndarray:
    """``rays`` directions uniform on the unit sphere of ``R^n`` ``(rays, n)``: normalised
    standard normal draws from ``rng``."""
    rays = checks.positive_int(rays, "rays")
    n = checks.positive_int(n, "n")
    return as_directions(streams.generator(rng).standard_normal((rays, n)))


def as_directions(draws) -> np.ndarray:
    """Standard normal ``draws (M, n)`` normalised to unit length: directions uniform on
    the sphere (the normal law is rotation invariant)."""
    draws = np.asarray(draws, dtype=float)
    if draws.ndim != 2 or not draws.shape[0]:
        raise InputError(f"draws: expected a non-empty 2-D array (rays, errors), got shape "
                         f"{draws.shape}")
    return draws / np.linalg.norm(draws, axis=1, keepdims=True)


def _check(rows, tolerances, points, name):
    """The rows ``(R, n)``, positive tolerances ``(n,)`` and ``points (K, n)`` as floats;
    InputError naming the argument when a shape or value is off."""
    rows = np.asarray(rows, dtype=float)
    tolerances = np.asarray(tolerances, dtype=float)
    points = np.asarray(points, dtype=float)
    if rows.ndim != 2 or not len(rows):
        raise InputError(f"rows: expected a non-empty 2-D array (rows, errors), got shape "
                         f"{rows.shape}")
    n = rows.shape[1]
    if tolerances.shape != (n,) or not np.all(tolerances > 0):
        raise InputError(f"tolerances: expected {n} positive values (one per column of "
                         f"rows), got shape {tolerances.shape}")
    if points.ndim != 2 or points.shape[1] != n:
        raise InputError(f"{name}: expected a 2-D array with {n} columns (one per error), "
                         f"got shape {points.shape}")
    return rows, tolerances, points


def worst_rows(rows, tolerances, points):
    """Per point ``x`` of ``points (K, n)``: the largest ``|a_r · (t ∘ x)|`` over the rows,
    its row and its signed value, in blocks of points.

    Returns
    -------
    worst, value : ndarray (K,)
    row : ndarray of int (K,)
    """
    rows, tolerances, points = _check(rows, tolerances, points, "points")
    block = max(1, BLOCK_FLOATS // len(rows))
    worst, row, value = [], [], []
    for start in range(0, len(points), block):
        scaled = points[start:start + block] * tolerances
        values = np.abs(scaled @ rows.T)
        where = values.argmax(axis=1)
        worst.append(values[np.arange(len(where)), where])
        row.append(where)
        value.append(np.einsum("ij,ij->i", scaled, rows[where]))
    return np.concatenate(worst), np.concatenate(row), np.concatenate(value)


@dataclass(frozen=True, eq=False)
class Rays:
    """The rays of one allocation: ``1/ρ`` of (R1) per ray and where it binds.

    Attributes
    ----------
    inverse_radius : ndarray (M,)
        ``max_r |a_r · (t ∘ θ)|``.
    row : ndarray of int (M,)
        The binding row ``r*``.
    value : ndarray (M,)
        ``a_r* · (t ∘ θ)`` (signed).
    n : int
        Dimension (errors).
    """

    inverse_radius: np.ndarray
    row: np.ndarray
    value: np.ndarray
    n: int

    def terms(self, scale: float = 1.0) -> np.ndarray:
        """Per ray, ``F_{χ²_n}(ρ²)`` of the allocation times ``scale`` (ρ scales as
        ``1/scale``, (R1))."""
        with np.errstate(divide="ignore"):
            radius = 1.0 / (scale * self.inverse_radius)
        return chi2.cdf(np.square(radius), self.n)

    def estimate(self, scale: float = 1.0) -> tuple[float, float]:
        """``(Ŷ_lin, its standard error)`` of the allocation times ``scale``."""
        terms = self.terms(scale)
        return float(terms.mean()), float(terms.std(ddof=1) / np.sqrt(len(terms)))

    def scale_at(self, level: float) -> float:
        """The factor ``c`` at which the allocation times ``c`` has ``Ŷ_lin = level`` on
        these rays (root in ``log c`` of a decreasing function, bracketed by doubling)."""
        level = checks.probability(level, "level")

        def excess(x):
            return self.estimate(np.exp(x))[0] - level
        low, high = -1.0, 1.0
        for _ in range(60):
            if excess(low) >= 0.0:
                break
            low -= 1.0
        for _ in range(60):
            if excess(high) <= 0.0:
                break
            high += 1.0
        return float(np.exp(brentq(excess, low, high, xtol=1e-12)))


def rays(rows, tolerances, theta) -> Rays:
    """:class:`Rays` of ``tolerances`` along the unit directions ``theta (M, n)``
    (:func:`directions`)."""
    inverse, row, value = worst_rows(rows, tolerances, theta)
    return Rays(inverse_radius=inverse, row=row, value=value, n=theta.shape[1])


def radial_yield(rows, tolerances, theta) -> tuple[float, float]:
    """The linearised machine yield ``E_θ[F_{χ²_n}(ρ²)]`` of ``tolerances`` on the rays
    ``theta`` and its standard error (module docstring, (R1))."""
    return rays(rows, tolerances, theta).estimate()


def radial_gradient(rows, tolerances, theta):
    """The linearised yield, ``∂Y_lin/∂log t_i`` by (R2), and their standard errors.

    Returns
    -------
    value, value_error : float
    gradient, gradient_error : ndarray (n,)
    """
    rows, tolerances, theta = _check(rows, tolerances, theta, "theta")
    found = rays(rows, tolerances, theta)
    n = theta.shape[1]
    squared = np.square(1.0 / found.inverse_radius)
    terms = chi2.cdf(squared, n)
    weight = -2.0 * squared * chi2.pdf(squared, n)
    shares = rows[found.row] * tolerances * theta / found.value[:, None]
    per_ray = weight[:, None] * shares
    root = np.sqrt(len(theta))
    return (float(terms.mean()), float(terms.std(ddof=1) / root), per_ray.mean(axis=0),
            per_ray.std(axis=0, ddof=1) / root)


@dataclass(frozen=True, eq=False)
class ControlledYield:
    """A machine yield of the exact chain by (R3), with its standard error.

    Attributes
    ----------
    estimate, standard_error : float
    linear : float
        ``Ŷ_lin`` on the rays.
    difference : float
        ``mean_N(1_exact − 1_lin)``.
    disagreements : int
        Machines whose two verdicts differ.
    machines, rays : int
    """

    estimate: float
    standard_error: float
    linear: float
    difference: float
    disagreements: int
    machines: int
    rays: int

    def interval(self, confidence: float = 0.95) -> tuple[float, float]:
        """``estimate ± z · standard_error`` at two-sided ``confidence``, clipped to
        [0, 1]."""
        z = norm.ppf(0.5 + 0.5 * confidence)
        return (max(0.0, self.estimate - z * self.standard_error),
                min(1.0, self.estimate + z * self.standard_error))


def controlled_yield(exact_passes, linear_passes, linear, linear_error,
                     rays: int) -> ControlledYield:
    """(R3) from the per-machine verdicts of the exact chain and of the linearised rows on
    the same machines, and ``Ŷ_lin`` with its standard error on ``rays`` rays.

    The machines' part of the variance is bounded by ``E[D²]`` with one disagreement more
    than counted, ``(d + 1)/N`` (module docstring)."""
    exact = np.asarray(exact_passes, dtype=bool)
    lin = np.asarray(linear_passes, dtype=bool)
    if exact.ndim != 1 or exact.shape != lin.shape or not len(exact):
        raise InputError(f"linear_passes: expected one verdict per machine of exact_passes "
                         f"({exact.shape}), got shape {lin.shape}")
    machines = len(exact)
    difference = exact.astype(float) - lin
    disagreements = int(np.count_nonzero(difference))
    variance = (disagreements + 1) / machines
    estimate = float(difference.mean() + linear)
    return ControlledYield(
        estimate=estimate,
        standard_error=float(np.sqrt(variance / machines + linear_error**2)),
        linear=float(linear), difference=float(difference.mean()),
        disagreements=disagreements, machines=machines, rays=int(rays))
