"""The worst pose over the continuous workspace, with a certificate (docs/certified-workspace.md).

Eq. (35) asks the targets over the whole stroke of every axis. For each output o,
:func:`certified_worst` finds a pose q* and a rigorous upper bound ``U`` of
``σ_o(q) = (Σ_i J_oi(q)² σ_i²)^½`` (Eq. 20) over the stroke box, with
``(U − σ_o(q*))/σ_o(q*) ≤ rtol``, by branch and bound over pose boxes:

* **bound on a box** (mean-value form): for q in a box of centre c and half-widths h,
  ``σ²(q) = σ²(c) + Σ_a g_a(ξ) (q_a − c_a)`` for some ξ in the box, with
  ``g_a = ∂σ²/∂q_a = 2 Σ_i σ_i² J_oi ∂J_oi/∂q_a``; so ``σ²(q) ≤ σ²(c) + Σ_a h_a |G_a|``
  where ``G_a`` encloses ``g_a`` over the box;
* **enclosures** of J and ∂J/∂q_a over the box by interval arithmetic of the chain in
  midpoint–radius form: each ideal motion's matrix over its interval of positions (cos and
  sin of a rotary interval enclosed by their Taylor remainder), products of interval
  matrices ``[A ± a][B ± b] ⊆ AB ± (|A| b + a |B| + a b)``, the adjoint of a product and the
  derivative formula of :func:`reliability.kinematics.jacobian_and_derivative`
  (``∂Ad(B⁻¹)/∂q_a = −ad(ζ_a) Ad(B⁻¹)``) applied to the enclosures;
* **branch and bound**: boxes whose bound is at most ``(1 + rtol)`` times the best σ found
  at a box centre are closed; the others are halved along the axis contributing most to
  their bound (``h_a |G_a|``); every step evaluates all open boxes at once, in chunks.

The bound's overestimate shrinks like the square of the box size near a maximum (the
enclosure of ``g`` there is centred near zero with a width proportional to the box), so the
number of boxes stays moderate even at rtol = 1e-3. Floating-point rounding of the few
dozen products is covered by widening every bound by the relative margin
:data:`ROUNDING_MARGIN`.
"""

from __future__ import annotations

import time

import numpy as np
import pandas as pd
from scipy.optimize import minimize

from . import checks
from .chunks import chunks
from .errors import InputError
from .fosm import error_sigma
from .kinematics import (ideal_motion, jacobian_and_derivative, offset_transform,
                         output_variance)
from .machine import OUTPUTS
from .ties import TIE_RTOL, worst_rows
from .transforms import AXIS_INDEX, skew

#: Relative widening of every bound, far above the rounding of the chain's products.
ROUNDING_MARGIN = 1e-10
#: Box evaluations one output may spend before the search stops uncertified.
MAX_BOX_CALLS = 2_000_000


def certified_worst(machine, tolerances, *, rtol: float = 1e-3, k: float = 3.0,
                    distribution: str | None = None, max_calls: int = MAX_BOX_CALLS,
                    memory: int | None = None) -> pd.DataFrame:
    """Largest σ of each output over the continuous stroke box, with a rigorous bound.

    Parameters
    ----------
    machine : Machine
        With independent errors (``machine.correlation`` None), outputs in the tool
        frame (``machine.frame``; the enclosure is of the tool-frame chain).
    tolerances : array_like
        ``(n_errors,)`` allocation, read as ±kσ.
    rtol : float
        Relative gap ``(sigma_bound − sigma)/sigma`` at which the search stops, in (0, 1).
    k : float
        Coverage factor.
    distribution : {'normal', 'truncated'}, optional
        Reading of a tolerance (:func:`reliability.fosm.error_sigma`);
        ``machine.distribution`` by default.
    max_calls : int
        Box evaluations per output before the search stops with ``certified`` False.
    memory : int, optional
        Bytes of temporary arrays per chunk of boxes.

    Returns
    -------
    pandas.DataFrame
        Indexed by output: the pose (one column per axis, mm or rad), ``sigma`` there,
        ``sigma_bound`` (an upper bound of σ over every pose of the strokes), ``gap``
        (``sigma_bound/sigma − 1``), ``certified`` (gap ≤ rtol), ``calls`` (boxes
        evaluated), ``seconds``. Among centres whose σ is within
        :data:`reliability.ties.TIE_RTOL` of the largest, the first in lexicographic order
        is reported (:func:`reliability.ties.worst_rows`). ``attrs`` holds ``rtol`` and
        ``distribution``.
    """
    rtol = checks.finite_float(rtol, "rtol", 0.0, 1.0, low_open=True, high_open=True)
    max_calls = checks.positive_int(max_calls, "max_calls")
    if machine.correlation is not None:
        raise InputError("machine: certified_worst bounds σ² = Σ J² σ² of independent "
                         "errors; this machine's errors are correlated")
    if machine.frame != "tool":
        raise InputError(f"machine: certified_worst encloses the tool-frame chain (Eq. 18); "
                         f"this study reads its outputs in the {machine.frame!r} frame "
                         f"(use frame='tool' or the grid and the continuous search)")
    t = machine.check_tolerances(tolerances)
    if t.ndim != 1:
        raise InputError(f"tolerances must be one allocation of shape ({machine.n_errors},)")
    distribution = machine.distribution if distribution is None else distribution
    variance = np.square(error_sigma(t, k, distribution))
    low = np.array([axis.stroke[0] for axis in machine.axis_specs], dtype=float)
    high = np.array([axis.stroke[1] for axis in machine.axis_specs], dtype=float)
    rows = [_search(machine, variance, o, low, high, rtol, max_calls, memory)
            for o in range(len(OUTPUTS))]
    frame = pd.DataFrame(rows, index=pd.Index(OUTPUTS, name="output"))
    frame.attrs.update(rtol=rtol, distribution=distribution)
    return frame


def _search(machine, variance, output, low, high, rtol, max_calls, memory) -> dict:
    """Branch and bound of one output (module docstring)."""
    started = time.perf_counter()
    centre = ((low + high) / 2)[None, :]
    half = ((high - low) / 2)[None, :]
    closed_bound = 0.0
    tied = _start_poses(machine, variance, output, low, high)
    best = float(np.sqrt(output_variance(machine, tied, variance)[:, output]).max())
    calls = 0
    while len(centre) and calls < max_calls:
        sigma, bound, contribution = box_bounds(machine, variance, output, centre, half,
                                                memory)
        calls += len(centre)
        top = sigma.max()
        if top > best * (1 + TIE_RTOL):
            best, tied = top, np.empty((0, len(low)))
        best = max(best, top)
        near = sigma >= best * (1 - TIE_RTOL)
        tied = np.vstack([tied, centre[near]])
        done = bound <= best * (1 + rtol)
        if done.any():
            closed_bound = max(closed_bound, bound[done].max())
        centre, half, contribution = centre[~done], half[~done], contribution[~done]
        centre, half = _halve(centre, half, contribution)
    open_bound = 0.0
    if len(centre):  # stopped by max_calls: the open boxes still count
        open_bound = box_bounds(machine, variance, output, centre, half, memory)[1].max()
    values = np.sqrt(output_variance(machine, tied, variance)[:, output])
    choice = worst_rows(values, tied)
    sigma = float(values[choice])
    sigma_bound = max(closed_bound, open_bound, sigma)
    row = dict(zip(machine.axes, tied[choice]))
    row.update(sigma=sigma, sigma_bound=sigma_bound, gap=sigma_bound / sigma - 1.0,
               certified=bool(sigma_bound <= sigma * (1 + rtol)), calls=int(calls),
               seconds=time.perf_counter() - started)
    return row


def _start_poses(machine, variance, output, low, high, points: int = 5,
                 starts: int = 3) -> np.ndarray:
    """A good first candidate, so that boxes are closed early: the worst poses of the
    ``points``-point grid of the strokes, improved by a bounded local search (L-BFGS-B on
    σ with its analytic gradient) from the ``starts`` worst. Returns the candidates whose
    σ is within :data:`reliability.ties.TIE_RTOL` of the largest."""
    axes = [np.linspace(lo, hi, points) for lo, hi in zip(low, high)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, len(low))
    sigma = np.sqrt(output_variance(machine, grid, variance)[:, output])
    order = np.argsort(-sigma, kind="stable")[:starts]

    def negative(q):
        jac, derivative = jacobian_and_derivative(machine, q)
        row = jac[output]
        value = np.sqrt(np.square(row) @ variance)  # Eq. (20)
        return -value, -(derivative[:, output, :] @ (row * variance)) / max(value, 1e-300)

    found = np.array([minimize(negative, grid[i], jac=True, method="L-BFGS-B",
                               bounds=list(zip(low, high))).x for i in order])
    candidates = np.vstack([grid[order], np.clip(found, low, high)])
    values = np.sqrt(output_variance(machine, candidates, variance)[:, output])
    return candidates[values >= values.max() * (1 - TIE_RTOL)]


def _halve(centre, half, contribution):
    """Each box split in two along the axis of its largest contribution ``h_a |G_a|``."""
    axis = np.argmax(contribution, axis=1)
    rows = np.arange(len(centre))
    half = half.copy()
    half[rows, axis] /= 2
    step = np.zeros_like(centre)
    step[rows, axis] = half[rows, axis]
    return np.vstack([centre - step, centre + step]), np.vstack([half, half])


def box_bounds(machine, variance, output: int, centre, half, memory=None):
    """σ at each box centre, an upper bound of σ over each box, and each axis' share of
    the bound on σ² (module docstring), in chunks of boxes.

    The bound is the smaller of two rigorous ones: the mean-value form
    ``σ²(c) + Σ_a h_a |G_a|`` and the second-order Taylor form
    ``σ²(c) + Σ_a h_a |g_a(c)| + ½ Σ_ab h_a h_b |H_ab|``, with ``G`` and ``H`` enclosures
    of the gradient and of the Hessian of σ² over the box.

    Parameters
    ----------
    machine : Machine
    variance : ndarray (n_errors,)
        Error variances σ_i².
    output : int
    centre, half : ndarray (n_boxes, n_axes)
        Box centres and half-widths.
    memory : int, optional

    Returns
    -------
    sigma, bound : ndarray (n_boxes,)
    contribution : ndarray (n_boxes, n_axes)
    """
    n_axes = len(machine.axis_specs)
    per_box = 8 * 6 * (n_axes + 2) * 6 * machine.n_errors + 8 * 64 * 4 * n_axes
    sigma = np.empty(len(centre))
    bound = np.empty(len(centre))
    contribution = np.empty(centre.shape)
    for part in chunks(len(centre), per_box, memory):
        sigma_sq, gradient = _centre_values(machine, centre[part], variance, output)
        jac, derivative = interval_jacobian(machine, centre[part], half[part])
        h = half[part]
        g_mag = _magnitude(_weighted_product((jac[0][:, None, output], jac[1][:, None, output]),
                                             _row(derivative, output), variance))
        mean_value = h * g_mag  # (b, a)
        hessian = _hessian_magnitude(machine, jac, derivative, output, variance)
        taylor = h * np.abs(gradient) + 0.5 * h * np.einsum("bac,bc->ba", hessian, h)
        use_taylor = taylor.sum(axis=1) < mean_value.sum(axis=1)
        share = np.where(use_taylor[:, None], taylor, mean_value)
        sigma[part] = np.sqrt(sigma_sq)
        bound[part] = np.sqrt(sigma_sq + share.sum(axis=1)) * (1 + ROUNDING_MARGIN)
        contribution[part] = share
    return sigma, bound, contribution


def _centre_values(machine, centre, variance, output):
    """σ² and its gradient ``2 Σ_i σ_i² J_oi ∂J_oi/∂q_a`` at the box centres."""
    jac, derivative = jacobian_and_derivative(machine, centre)
    row = jac[:, output, :]
    sigma_sq = np.square(row) @ variance  # Eq. (20)
    gradient = 2 * np.einsum("bn,ban,n->ba", row, derivative[:, :, output, :], variance)
    return sigma_sq, gradient


def _row(interval, output):
    """Output ``output``'s row of a derivative enclosure, ``(b, a, n)`` each."""
    return interval[0][:, :, output, :], interval[1][:, :, output, :]


def _magnitude(interval) -> np.ndarray:
    """``max |x|`` over an interval ``mid ± rad``."""
    return np.abs(interval[0]) + interval[1]


def _weighted_product(left, right, variance):
    """Enclosure of ``2 Σ_i σ_i² x_i y_i`` over the last axis of two enclosures."""
    mid, rad = _elementwise(left, right)
    return 2 * mid @ variance, 2 * rad @ variance


def _elementwise(left, right):
    """``[x ± a][y ± b] ⊆ xy ± (|x| b + a |y| + a b)`` entry by entry."""
    return left[0] * right[0], np.abs(left[0]) * right[1] + left[1] * (np.abs(right[0])
                                                                       + right[1])


def _hessian_magnitude(machine, jac, derivative, output, variance) -> np.ndarray:
    """``max |∂²σ²/∂q_a∂q_b|`` over each box, ``(b, a, a)``, from
    ``H_ab = 2 Σ_i σ_i² (∂_a J_oi ∂_b J_oi + J_oi ∂_ab J_oi)`` and
    ``∂_ab J = −ad(∂_b ζ_a) J − ad(ζ_a) ∂_b J`` on the gaps axis a moves (derivative of
    :func:`reliability.kinematics.jacobian_and_derivative`'s formula)."""
    n = len(machine.axis_specs)
    d_row = _row(derivative, output)
    j_row = (jac[0][:, None, output, :], jac[1][:, None, output, :])
    out = np.empty((len(jac[0]), n, n))
    for a, axis in enumerate(machine.axis_specs):
        column = 6 * a + (0 if axis.kind == "linear" else 3) + AXIS_INDEX[axis.direction]
        seen = np.zeros(machine.n_errors, dtype=bool)
        seen[:6 * (a + 1)] = True
        seen[6 * n:6 * (n + a)] = True
        zeta = (jac[0][:, :, column], jac[1][:, :, column])  # ζ_a, (b, 6)
        ad_zeta = (_ad_matrix(zeta[0])[:, output, :], np.abs(_ad_matrix(zeta[1]))[:, output, :])
        d_zeta = (derivative[0][:, :, :, column], derivative[1][:, :, :, column])  # (b, c, 6)
        ad_dz = (_ad_matrix(d_zeta[0])[:, :, output, :],
                 np.abs(_ad_matrix(d_zeta[1]))[:, :, output, :])  # (b, c, 6)
        first = _row_product(ad_dz, (jac[0][:, None], jac[1][:, None]))  # (b, c, n)
        second = _row_product((ad_zeta[0][:, None], ad_zeta[1][:, None]), derivative)
        second_mid = -(first[0] + second[0]) * seen
        second_rad = (first[1] + second[1]) * seen
        cross = _elementwise((d_row[0][:, a:a + 1], d_row[1][:, a:a + 1]), d_row)
        curvature = _elementwise(j_row, (second_mid, second_rad))
        mid = 2 * (cross[0] + curvature[0]) @ variance
        rad = 2 * (cross[1] + curvature[1]) @ variance
        out[:, a, :] = np.abs(mid) + rad
    return np.maximum(out, np.swapaxes(out, 1, 2))  # both enclose the same H_ab


def _row_product(row, matrix):
    """Enclosure of ``Σ_r row_r M_r·`` for rows ``(..., 6)`` and matrices ``(..., 6, n)``."""
    r_mid, r_rad = row
    m_mid, m_rad = matrix
    mid = np.einsum("...r,...rn->...n", r_mid, m_mid)
    rad = (np.einsum("...r,...rn->...n", np.abs(r_mid), m_rad)
           + np.einsum("...r,...rn->...n", r_rad, np.abs(m_mid) + m_rad))
    return mid, rad


# ----- interval arithmetic of the chain (midpoint-radius form) ---------------------------
def interval_jacobian(machine, centre, half):
    """Enclosures of the Jacobian and of its derivative over pose boxes.

    Returns
    -------
    jacobian : (ndarray (b, 6, n_errors), ndarray (b, 6, n_errors))
        Midpoint and radius: ``|J(q) − mid| ≤ rad`` entrywise for every q in the box.
    derivative : (ndarray (b, n_axes, 6, n_errors), ndarray (b, n_axes, 6, n_errors))
        The same for ``∂J/∂q_a``.
    """
    n = len(machine.axis_specs)
    blocks = []  # the error block of each gap, in chain order (as chain_factors)
    for i in range(n):
        blocks += [i] if i == n - 1 else [i, n + i]
    shape = (len(centre), 6, machine.n_errors)
    mid, rad = np.zeros(shape), np.zeros(shape)
    for block, (a_mid, a_rad) in zip(blocks, _interval_transports(
            _interval_factors(machine, centre, half))):
        mid[:, :, 6 * block:6 * block + 6] = a_mid
        rad[:, :, 6 * block:6 * block + 6] = a_rad
    d_mid = np.zeros((len(centre), n) + shape[1:])
    d_rad = np.zeros_like(d_mid)
    for a, axis in enumerate(machine.axis_specs):
        column = 6 * a + (0 if axis.kind == "linear" else 3) + AXIS_INDEX[axis.direction]
        ad = (_ad_matrix(mid[:, :, column]), np.abs(_ad_matrix(rad[:, :, column])))  # ad(ζ_a)
        seen = np.zeros(machine.n_errors, dtype=bool)
        seen[:6 * (a + 1)] = True  # motion errors of axes up to a
        seen[6 * n:6 * (n + a)] = True  # assembly errors of the joints before a
        p_mid, p_rad = _product(ad, (mid, rad))
        d_mid[:, a] = -p_mid * seen
        d_rad[:, a] = p_rad * seen
    return (mid, rad), (d_mid, d_rad)


def _interval_factors(machine, centre, half) -> list:
    """The chain's ideal factors (as :func:`reliability.kinematics.chain_factors`: the
    first axis' offset, then each axis' motion followed by the next axis' offset, the last
    motion times the tool offset), each as (midpoint, radius) over the boxes."""
    count = len(centre)
    n = len(machine.axis_specs)
    zero = np.zeros((count, 4, 4))
    factors = [(np.broadcast_to(offset_transform(machine.axis_specs[0].offset),
                                (count, 4, 4)), zero)]
    for i, axis in enumerate(machine.axis_specs):
        factors.append(_motion(axis, centre[:, i], half[:, i]))
        if i < n - 1:
            factors.append((np.broadcast_to(offset_transform(machine.axis_specs[i + 1].offset),
                                            (count, 4, 4)), zero))
    tool = offset_transform(machine.tool_offset)
    last_mid, last_rad = factors[-1]
    factors[-1] = (last_mid @ tool, last_rad @ np.abs(tool))
    return factors


def _motion(axis, position, half):
    """An axis' ideal motion over ``position ± half``: midpoint and radius matrices."""
    mid = ideal_motion(axis, position)
    rad = np.zeros_like(mid)
    i = AXIS_INDEX[axis.direction]
    if axis.kind == "linear":
        rad[:, i, 3] = half
        return mid, rad
    cos_c, sin_c = np.abs(np.cos(position)), np.abs(np.sin(position))
    # |cos(c + δ) − cos c| ≤ |cos c|(1 − cos h) + |sin c| sin h for |δ| ≤ h ≤ π/2
    drop = 1.0 - np.cos(np.minimum(half, np.pi))
    turn = np.where(half <= np.pi / 2, np.sin(half), 1.0)
    cos_r = np.where(half < np.pi, cos_c * drop + sin_c * turn, 2.0)
    sin_r = np.where(half < np.pi, sin_c * drop + cos_c * turn, 2.0)
    j, k = (i + 1) % 3, (i + 2) % 3
    rad[:, j, j] = rad[:, k, k] = cos_r
    rad[:, j, k] = rad[:, k, j] = sin_r
    return mid, rad


def _interval_transports(factors) -> list:
    """``Ad(B_k⁻¹)`` enclosures for ``B_k = G_k … G_m``, k = 1…m (as
    :func:`reliability.kinematics.transports`)."""
    after = factors[-1]
    out = [_interval_adjoint(after)]
    for factor in factors[-2:0:-1]:
        after = _product(factor, after)
        out.append(_interval_adjoint(after))
    return out[::-1]


def _interval_adjoint(transform):
    """``Ad(B⁻¹) = [[Rᵀ, −Rᵀ[p]×], [0, Rᵀ]]`` of an interval rigid transform."""
    b_mid, b_rad = transform
    rt = (np.swapaxes(b_mid[:, :3, :3], -1, -2), np.swapaxes(b_rad[:, :3, :3], -1, -2))
    cross_mid, cross_rad = _product(rt, (skew(b_mid[:, :3, 3]),
                                         np.abs(skew(b_rad[:, :3, 3]))))
    mid = np.zeros((len(b_mid), 6, 6))
    rad = np.zeros_like(mid)
    mid[:, :3, :3] = mid[:, 3:, 3:] = rt[0]
    rad[:, :3, :3] = rad[:, 3:, 3:] = rt[1]
    mid[:, :3, 3:] = -cross_mid
    rad[:, :3, 3:] = cross_rad
    return mid, rad


def _ad_matrix(twist) -> np.ndarray:
    """``ad(v, ω) = [[ω^, v^], [0, ω^]]`` of twists ``(b, 6)``."""
    out = np.zeros(twist.shape[:-1] + (6, 6))
    out[..., :3, :3] = out[..., 3:, 3:] = skew(twist[..., 3:])
    out[..., :3, 3:] = skew(twist[..., :3])
    return out


def _product(left, right):
    """``[A ± a][B ± b] ⊆ AB ± (|A| b + a |B| + a b)`` for batched matrices."""
    a_mid, a_rad = left
    b_mid, b_rad = right
    return a_mid @ b_mid, np.abs(a_mid) @ b_rad + a_rad @ (np.abs(b_mid) + b_rad)
