"""Homogeneous 4×4 transforms used by the chain model (paper Eqs. 1–14).

All functions are batched: leading dimensions of their inputs broadcast and are kept in
the output. Conventions follow the paper: a rigid motion is ``[[R, p], [0, 1]]``, and an
error transform is the small-angle matrix of Eq. (2), which is exactly ``I + ξ^`` with the
twist ``ξ = (δx, δy, δz, εx, εy, εz)``.
"""

from __future__ import annotations

import numpy as np

AXIS_INDEX = {"x": 0, "y": 1, "z": 2}


def translation(direction: str, distance) -> np.ndarray:
    """Pure translation along a coordinate axis, Eqs. (1), (3), (5).

    Parameters
    ----------
    direction : {'x', 'y', 'z'}
    distance : array_like
        Displacement in mm, any shape ``(...)``.

    Returns
    -------
    numpy.ndarray
        ``(..., 4, 4)`` homogeneous transforms.
    """
    distance = np.asarray(distance, dtype=float)
    out = np.broadcast_to(np.eye(4), distance.shape + (4, 4)).copy()
    out[..., AXIS_INDEX[direction], 3] = distance
    return out


def rotation(direction: str, angle) -> np.ndarray:
    """Pure rotation about a coordinate axis, Eqs. (7), (9), (11).

    Parameters
    ----------
    direction : {'x', 'y', 'z'}
    angle : array_like
        Angle in rad, any shape ``(...)``; positive is counter-clockwise seen from the
        positive end of the axis (right-hand rule).

    Returns
    -------
    numpy.ndarray
        ``(..., 4, 4)`` homogeneous transforms.
    """
    angle = np.asarray(angle, dtype=float)
    c, s = np.cos(angle), np.sin(angle)
    i = AXIS_INDEX[direction]
    j, k = (i + 1) % 3, (i + 2) % 3
    out = np.broadcast_to(np.eye(4), angle.shape + (4, 4)).copy()
    out[..., j, j] = c
    out[..., k, k] = c
    out[..., j, k] = -s
    out[..., k, j] = s
    return out


def error_transform(twist) -> np.ndarray:
    """Small-angle error transform of Eqs. (2) and (14): ``I + ξ^``.

    Parameters
    ----------
    twist : array_like
        ``(..., 6)`` errors in the order δx, δy, δz, εx, εy, εz (mm, rad).

    Returns
    -------
    numpy.ndarray
        ``(..., 4, 4)``; rotation block ``I + [ε]×`` (not orthogonalised, as in the paper).
    """
    twist = np.asarray(twist, dtype=float)
    out = np.broadcast_to(np.eye(4), twist.shape[:-1] + (4, 4)).copy()
    out[..., :3, :3] += skew(twist[..., 3:])
    out[..., :3, 3] = twist[..., :3]
    return out


def skew(vector) -> np.ndarray:
    """Cross-product matrix ``[v]×`` with ``[v]× w = v × w``; ``(..., 3) -> (..., 3, 3)``."""
    v = np.asarray(vector, dtype=float)
    out = np.zeros(v.shape[:-1] + (3, 3))
    out[..., 0, 1], out[..., 0, 2] = -v[..., 2], v[..., 1]
    out[..., 1, 0], out[..., 1, 2] = v[..., 2], -v[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -v[..., 1], v[..., 0]
    return out


def read_pose_error(matrix) -> np.ndarray:
    """Six pose errors of a near-identity transform, as docs/model.md reads Eq. (18).

    δ is the translation column; ε is the skew-symmetric part of the rotation block,
    ``εx = (E32 − E23)/2`` etc., which equals the small-angle parameters of Eq. (2)
    exactly when the matrix has that form.

    Parameters
    ----------
    matrix : array_like
        ``(..., 4, 4)``.

    Returns
    -------
    numpy.ndarray
        ``(..., 6)`` = δx, δy, δz, εx, εy, εz.
    """
    m = np.asarray(matrix, dtype=float)
    out = np.empty(m.shape[:-2] + (6,))
    out[..., :3] = m[..., :3, 3]
    out[..., 3] = 0.5 * (m[..., 2, 1] - m[..., 1, 2])
    out[..., 4] = 0.5 * (m[..., 0, 2] - m[..., 2, 0])
    out[..., 5] = 0.5 * (m[..., 1, 0] - m[..., 0, 1])
    return out


def rigid_inverse(matrix) -> np.ndarray:
    """Inverse of rigid transforms ``[[R, p], [0, 1]]`` as ``[[Rᵀ, −Rᵀp], [0, 1]]``."""
    m = np.asarray(matrix, dtype=float)
    out = np.zeros_like(m)
    rt = np.swapaxes(m[..., :3, :3], -1, -2)
    out[..., :3, :3] = rt
    out[..., :3, 3] = -np.einsum("...ij,...j->...i", rt, m[..., :3, 3])
    out[..., 3, 3] = 1.0
    return out


def adjoint_to_frame(matrix) -> np.ndarray:
    """Matrix that carries a twist through a rigid transform, ``ξ' = Ad(B⁻¹) ξ``.

    For ``B = [[R, p], [0, 1]]`` and twist order (δ, ε),
    ``B⁻¹ (I + ξ^) B = I + ξ'^`` with ``δ' = Rᵀδ − Rᵀ[p]×ε`` and ``ε' = Rᵀε``.
    This is how an error at one link is seen in the tool frame (docs/model.md,
    "Linearisation").

    Parameters
    ----------
    matrix : array_like
        ``(..., 4, 4)`` rigid transforms B from the error's frame to the tool frame.

    Returns
    -------
    numpy.ndarray
        ``(..., 6, 6)``.
    """
    m = np.asarray(matrix, dtype=float)
    rt = np.swapaxes(m[..., :3, :3], -1, -2)
    out = np.zeros(m.shape[:-2] + (6, 6))
    out[..., :3, :3] = rt
    out[..., :3, 3:] = -rt @ skew(m[..., :3, 3])
    out[..., 3:, 3:] = rt
    return out
