"""Tool–workpiece comprehensive error of a serial machine (paper Sec. 3, Eqs. 15–18).

The chain of Eq. (16), generalised to any axes and optional fixed offsets, is

    M_e = Π_i [ O_i · E^m_i · M_i(q_i) · E^p_i ] · T,

with ``O_i`` the fixed offset of axis i (identity in the paper), ``E^m_i`` its motion-error
transform, ``M_i`` its ideal motion, ``E^p_i`` the assembly error of the joint to the next
axis (none after the last axis) and ``T`` the tool offset. The comprehensive error is
``E = M⁻¹ M_e`` (Eq. 18) with ``M`` the error-free chain.

Every error transform is ``I + ξ_k^`` (Eq. 2). Moving each one to the tool frame through
the ideal chain ``B_k`` that follows it gives the identity

    E = Π_k (I + η_k^),    η_k = Ad(B_k⁻¹) ξ_k,

in chain order, which holds exactly (it telescopes ``B_k B_k⁻¹``). The product is formed
on deviations from the identity, so the result is accurate to rounding relative to the
errors themselves rather than to the 500 mm of the chain. Its first-order part,
``Σ_k Ad(B_k⁻¹) ξ_k``, is the analytic Jacobian.
"""

from __future__ import annotations

import numpy as np

from .transforms import adjoint_to_frame, read_pose_error, rotation, skew, translation


def ideal_motion(axis, position) -> np.ndarray:
    """Ideal motion transform ``M_i(q_i)`` of one axis, Eqs. (1), (3), (5), (7), (9), (11)."""
    if axis.kind == "linear":
        return translation(axis.direction, position)
    return rotation(axis.direction, position)


def offset_transform(offset) -> np.ndarray:
    """Fixed translation by an ``(x, y, z)`` offset in mm."""
    out = np.eye(4)
    out[:3, 3] = offset
    return out


def error_locations(machine, q) -> list[np.ndarray]:
    """Ideal transforms ``B_k`` from each error's frame to the tool frame.

    Parameters
    ----------
    machine : Machine
    q : array_like
        ``(..., n_axes)`` positions.

    Returns
    -------
    list of numpy.ndarray
        ``2 n_axes − 1`` arrays ``(..., 4, 4)`` in the order of the error vector's blocks:
        the motion error of each axis, then the assembly error of each joint.
    """
    q = machine.check_positions(q)
    n = len(machine.axis_specs)
    motions = [ideal_motion(axis, q[..., i]) for i, axis in enumerate(machine.axis_specs)]
    after = [None] * (n + 1)  # after[i]: ideal chain from the frame before O_i to the tool
    after[n] = np.broadcast_to(offset_transform(machine.tool_offset), q.shape[:-1] + (4, 4))
    for i in range(n - 1, -1, -1):
        after[i] = offset_transform(machine.axis_specs[i].offset) @ motions[i] @ after[i + 1]
    motion_blocks = [motions[i] @ after[i + 1] for i in range(n)]
    assembly_blocks = [after[i + 1] for i in range(n - 1)]
    return motion_blocks + assembly_blocks


def jacobian(machine, q) -> np.ndarray:
    """Analytic first-order sensitivities of the comprehensive error (DESIGN §2).

    Parameters
    ----------
    machine : Machine
    q : array_like
        ``(..., n_axes)`` positions.

    Returns
    -------
    numpy.ndarray
        ``(..., 6, n_errors)``: ``J[..., o, i] = ∂y_o/∂x_i`` at zero error, with outputs
        δx δy δz εx εy εz and errors in the order of ``machine.error_names``.
    """
    blocks = [adjoint_to_frame(b) for b in error_locations(machine, q)]
    return np.concatenate(blocks, axis=-1)


def chain_order(n_axes: int) -> list[int]:
    """Block indices of the error vector in chain order: motion 0, joint 0, motion 1, …"""
    order = []
    for i in range(n_axes):
        order.append(i)
        if i < n_axes - 1:
            order.append(n_axes + i)
    return order


def twist_matrix(twist) -> np.ndarray:
    """The 4×4 matrix ``ξ^`` of a twist ``(..., 6)`` (last row zero)."""
    twist = np.asarray(twist)
    out = np.zeros(twist.shape[:-1] + (4, 4))
    out[..., :3, :3] = skew(twist[..., 3:])
    out[..., :3, 3] = twist[..., :3]
    return out


def comprehensive_error(machine, q, x) -> np.ndarray:
    """Exact comprehensive error of Eq. (18) for batched poses and errors.

    Parameters
    ----------
    machine : Machine
    q : array_like
        ``(..., n_axes)`` positions (mm, rad).
    x : array_like
        ``(..., n_errors)`` geometric errors (mm, rad); leading dimensions broadcast with q.

    Returns
    -------
    numpy.ndarray
        ``(..., 6)`` = δx δy δz εx εy εz of ``E = M⁻¹ M_e``, read as in
        :func:`reliability.transforms.read_pose_error`.
    """
    q = machine.check_positions(q)
    x = machine.check_errors(x)
    locations = error_locations(machine, q)
    deviation = None  # E − I, accumulated in chain order
    for block in chain_order(len(machine.axis_specs)):
        xi = x[..., 6 * block: 6 * block + 6]
        eta = np.einsum("...ij,...j->...i", adjoint_to_frame(locations[block]), xi)
        step = twist_matrix(eta)
        deviation = step if deviation is None else deviation + step + deviation @ step
    return read_pose_error(deviation)
