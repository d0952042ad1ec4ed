"""The covariance of the six outputs under correlated errors, and each error's share of it.

With ``σ_i = t_i/k`` and ``D = diag(σ)`` the error covariance is ``Σ = D R D`` and
the output variance ``σ_y² = jᵀ Σ j`` (Eq. 20 with the cross terms the paper drops;
``R = I`` gives Eq. 20 back). The share of error ``i`` in ``σ_y²`` is its Euler
allocation ``a_i (R a)_i / σ_y²`` with ``a = D j``: the shares add up to 100 %, reduce to
Eq. 20's terms without correlation, and one of them can be negative when an error partly
cancels a correlated partner.
"""

from __future__ import annotations

import numpy as np


def output_covariance(jacobian, tolerances, correlation=None, k: float = 3.0) -> np.ndarray:
    """Covariance of the six outputs, ``J D R D Jᵀ`` with ``D = diag(t/k)``.

    Parameters
    ----------
    jacobian : array_like
        ``(..., 6, n)`` sensitivities.
    tolerances : array_like
        ``(n,)`` tolerances read as ±kσ.
    correlation : array_like, optional
        ``(n, n)`` correlation matrix; ``None`` for independent errors.
    k : float

    Returns
    -------
    numpy.ndarray
        ``(..., 6, 6)``; its diagonal is ``σ_y²`` (Eq. 20 with cross terms).
    """
    a = np.asarray(jacobian, dtype=float) * (np.asarray(tolerances, dtype=float) / k)
    if correlation is None:
        return a @ np.swapaxes(a, -1, -2)
    return a @ np.asarray(correlation) @ np.swapaxes(a, -1, -2)


def euler_terms(jacobian, sigma, correlation=None) -> np.ndarray:
    """Each error's share of ``σ_y²``: ``a_i (R a)_i`` with ``a = j σ``, ``(..., 6, n)``.

    The terms sum to ``σ_y²``; without correlation they are Eq. (20)'s ``(∂y/∂x_i)² σ_i²``.
    """
    a = np.asarray(jacobian, dtype=float) * np.asarray(sigma)[..., None, :]
    return a * a if correlation is None else a * (a @ np.asarray(correlation))


def correlated_sigma(jacobian, sigma, correlation) -> np.ndarray:
    """σ of each output, ``sqrt(jᵀ D R D j)``: ``(..., 6, n), (n,), (n, n) -> (..., 6)``."""
    return np.sqrt(np.maximum(euler_terms(jacobian, sigma, correlation).sum(axis=-1), 0.0))
