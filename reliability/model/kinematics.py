"""Tool–workpiece comprehensive error of a serial machine (paper Sec. 3, Eqs. 15–18).

The chain of Eq. (16), generalised to any axes and optional fixed offsets, is

    M_e = Π_i [ O_i · E^m_i · M_i(q_i) · E^p_i ] · T,

with ``O_i`` the fixed offset of axis i (identity in the paper), ``E^m_i`` its motion-error
transform, ``M_i`` its ideal motion, ``E^p_i`` the assembly error of the joint to the next
axis (none after the last axis) and ``T`` the tool offset. The comprehensive error is
``E = M⁻¹ M_e`` (Eq. 18) with ``M`` the error-free chain.

A chain segment is written ``G_0 (I + ξ_1^) G_1 … (I + ξ_m^) G_m``: ideal rigid factors ``G``
and error transforms ``I + ξ^`` (Eq. 2 is exactly this form). Moving each error to the end
of the segment through the ideal factors that follow it, ``B_k = G_k … G_m``, gives

    (G_0 … G_m)⁻¹ · segment = Π_k (I + η_k^),    η_k = Ad(B_k⁻¹) ξ_k,

in chain order, exactly (the ``B_k B_k⁻¹`` telescope). The product is formed on deviations
from the identity, so rounding is relative to the errors rather than to the 500 mm of the
chain. Its first-order part, ``Σ_k Ad(B_k⁻¹) ξ_k``, is the analytic Jacobian.

**Frames.** Eq. (18) reads ``E`` in the tool frame, which turns with the rotary axes. In the
workpiece frame the same six-vector is expressed in workpiece axes: ``δ_w = R(q) δ_t`` and
``ε_w = R(q) ε_t``, with ``R(q)`` the ideal rotation of the tool frame in the workpiece frame
(the rotation block of ``M``); the Jacobian is ``blockdiag(R, R) J`` likewise.
"""

from __future__ import annotations

import numpy as np

from ..basics.errors import InputError
from .transforms import AXIS_INDEX, adjoint_to_frame, read_pose_error, rotation, skew, translation


#: The frames the six outputs can be expressed in.
FRAMES = ("tool", "workpiece")


def check_frame(frame) -> str:
    """``frame`` if it is one of :data:`FRAMES`, else an InputError naming it."""
    if frame not in FRAMES:
        raise InputError(f"frame must be 'tool' or 'workpiece'; got {frame!r}")
    return frame


def ideal_rotation(machine, q) -> np.ndarray:
    """``R(q)``, the ideal rotation of the tool frame in the workpiece frame, ``(..., 3, 3)``."""
    q = machine.check_positions(q)
    factors, _ = chain_factors(machine, q)
    rotation_ = np.broadcast_to(np.eye(3), q.shape[:-1] + (3, 3))
    for factor in factors:
        rotation_ = rotation_ @ np.asarray(factor)[..., :3, :3]
    return rotation_


def vectors_in_frame(values, rotation_) -> np.ndarray:
    """Six-vectors ``(..., 6)`` of the tool frame expressed in the workpiece frame:
    ``blockdiag(R, R)`` applied to the translation and the rotation part."""
    values = np.asarray(values)
    return np.concatenate([np.einsum("...ij,...j->...i", rotation_, values[..., :3]),
                           np.einsum("...ij,...j->...i", rotation_, values[..., 3:])], axis=-1)


def rows_in_frame(rows, rotation_) -> np.ndarray:
    """Sensitivity rows ``(..., 6, n)`` of the tool frame expressed in the workpiece frame:
    ``blockdiag(R, R) @ rows``."""
    rows = np.asarray(rows)
    return np.concatenate([rotation_ @ rows[..., :3, :], rotation_ @ rows[..., 3:, :]],
                          axis=-2)


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


def chain_factors(machine, q) -> tuple[list[np.ndarray], list[int]]:
    """Ideal factors ``G_0 … G_m`` of the whole chain and the error block of each gap.

    Returns
    -------
    factors : list of ndarray
        ``m + 1`` transforms ``(..., 4, 4)`` (or ``(4, 4)`` when constant).
    blocks : list of int
        For each of the ``m = 2 n_axes − 1`` error transforms in chain order, the index of
        its six-error block in the error vector (motion blocks 0…n−1, joints n…2n−2).
    """
    n = len(machine.axis_specs)
    factors, blocks = [offset_transform(machine.axis_specs[0].offset)], []
    for i, axis in enumerate(machine.axis_specs):
        blocks.append(i)  # motion error E^m_i, then M_i
        factors.append(ideal_motion(axis, q[..., i]))
        if i < n - 1:  # assembly error E^p_i, then the next axis' offset
            blocks.append(n + i)
            factors.append(offset_transform(machine.axis_specs[i + 1].offset))
    factors[-1] = factors[-1] @ offset_transform(machine.tool_offset)
    return factors, blocks


def transports(factors) -> list[np.ndarray]:
    """``Ad(B_k⁻¹)`` for ``B_k = G_k … G_m``, k = 1…m: each gap's error seen at the end."""
    after = factors[-1]
    out = [adjoint_to_frame(after)]
    for factor in factors[-2:0:-1]:
        after = factor @ after
        out.append(adjoint_to_frame(after))
    return out[::-1]


def segment_deviation(factors, twists) -> np.ndarray:
    """``(G_0 … G_m)⁻¹ · G_0 (I + ξ_1^) G_1 … (I + ξ_m^) G_m − I``, exactly.

    Parameters
    ----------
    factors : list of ndarray
        ``m + 1`` ideal rigid transforms ``(..., 4, 4)``; leading dimensions broadcast.
    twists : list of ndarray
        ``m`` error twists ``(..., 6)`` (δx δy δz εx εy εz).

    Returns
    -------
    numpy.ndarray
        ``(..., 4, 4)`` deviation from the identity (last row zero).
    """
    if len(factors) != len(twists) + 1:
        raise InputError("a segment needs one more ideal factor than error twists")
    return deviation_from_transports(transports(factors), twists)


def deviation_from_transports(adjoints, twists) -> np.ndarray:
    """``Π_k (I + (Ad_k ξ_k)^) − I`` in chain order, accumulated on deviations.

    The workhorse of :func:`segment_deviation` for callers that reuse the transports
    ``Ad(B_k⁻¹)`` across many error draws.
    """
    deviation = np.zeros((4, 4))
    for adjoint, xi in zip(adjoints, twists):
        step = twist_matrix(np.einsum("...ij,...j->...i", adjoint, xi))
        deviation = deviation + step + deviation @ step
    return deviation


def twist_matrix(twist) -> np.ndarray:
    """The 4×4 matrix ``ξ^`` of a twist ``(..., 6)`` (last row zero)."""
    twist = np.asarray(twist)
    out = np.zeros(twist.shape[:-1] + (4, 4))
    out[..., :3, :3] = skew(twist[..., 3:])
    out[..., :3, 3] = twist[..., :3]
    return out


def jacobian(machine, q, frame: str = "tool") -> np.ndarray:
    """Analytic first-order sensitivities of the comprehensive error (docs/model.md).

    Parameters
    ----------
    machine : Machine
    q : array_like
        ``(..., n_axes)`` positions.
    frame : {'tool', 'workpiece'}
        Frame the outputs are expressed in (module docstring).

    Returns
    -------
    numpy.ndarray
        ``(..., 6, n_errors)``: ``J[..., o, i] = ∂y_o/∂x_i`` at zero error, with outputs
        δx δy δz εx εy εz and errors in the order of ``machine.error_names``.
    """
    q = machine.check_positions(q)
    factors, blocks = chain_factors(machine, q)
    columns = [None] * len(blocks)
    for block, adjoint in zip(blocks, transports(factors)):
        columns[block] = np.broadcast_to(adjoint, q.shape[:-1] + (6, 6))
    out = np.concatenate(columns, axis=-1)
    if check_frame(frame) == "workpiece":
        out = rows_in_frame(out, ideal_rotation(machine, q))
    return out


def comprehensive_error(machine, q, x, frame: str = "tool") -> np.ndarray:
    """Exact comprehensive error of Eq. (18) for batched poses and errors.

    Parameters
    ----------
    machine : Machine
    q : array_like
        ``(..., n_axes)`` positions (mm, rad).
    x : array_like
        ``(..., n_errors)`` geometric errors (mm, rad); leading dimensions broadcast with q.
    frame : {'tool', 'workpiece'}
        Frame the outputs are expressed in (module docstring).

    Returns
    -------
    numpy.ndarray
        ``(..., 6)`` = δx δy δz εx εy εz of ``E = M⁻¹ M_e``, read as in
        :func:`reliability.model.transforms.read_pose_error` (tool frame), or rotated by ``R(q)``.
    """
    q = machine.check_positions(q)
    x = machine.check_errors(x)
    try:
        shape = np.broadcast_shapes(q.shape[:-1], x.shape[:-1])
    except ValueError:
        raise InputError(f"positions {q.shape} and errors {x.shape} do not broadcast") from None
    factors, blocks = chain_factors(machine, q)
    twists = [x[..., 6 * b: 6 * b + 6] for b in blocks]
    deviation = segment_deviation(factors, twists)
    out = np.broadcast_to(read_pose_error(deviation), shape + (6,))
    if check_frame(frame) == "workpiece":
        out = vectors_in_frame(out, ideal_rotation(machine, q))
    return out


def jacobian_and_derivative(machine, q, frame: str = "tool"
                            ) -> tuple[np.ndarray, np.ndarray]:
    """The Jacobian and its derivative with respect to every axis position, analytically.

    A gap's column block is ``Ad(B⁻¹)`` with ``B = G_k … G_m``. Moving axis ``a`` turns its
    factor ``M_a`` by its unit twist ``ξ_a`` (``(d, 0)`` linear, ``(0, d)`` rotary), which
    seen at the end of the chain is ``ζ_a = Ad(B_a⁻¹) ξ_a`` — the motion-error block of
    axis ``a`` applied to ``ξ_a``. Then ``dB/dq_a = B ζ_a^`` and

        ∂ Ad(B⁻¹) / ∂q_a = −ad(ζ_a) Ad(B⁻¹)

    for every gap up to and including axis ``a``'s motion error (later gaps do not see
    ``q_a``), with ``ad(v, ω) = [[ω^, v^], [0, ω^]]``. In the workpiece frame ``R`` turns
    too: ``dR/dq_a = R ω_ζ^`` with ``ω_ζ`` the rotation part of ``ζ_a``, so
    ``∂(R̄ J)/∂q_a = R̄ (Ω̄ J + ∂J/∂q_a)`` with ``R̄ = blockdiag(R, R)`` and
    ``Ω̄ = blockdiag(ω_ζ^, ω_ζ^)``.

    Parameters
    ----------
    machine : Machine
    q : array_like
        ``(..., n_axes)`` positions.
    frame : {'tool', 'workpiece'}

    Returns
    -------
    jacobian : ndarray (..., 6, n_errors)
    derivative : ndarray (..., n_axes, 6, n_errors)
        ``derivative[..., a, o, i] = ∂J[..., o, i]/∂q_a`` (per mm or per rad).
    """
    q = machine.check_positions(q)
    jac = jacobian(machine, q)
    n = len(machine.axis_specs)
    derivative = np.zeros(jac.shape[:-2] + (n,) + jac.shape[-2:])
    for a, axis in enumerate(machine.axis_specs):
        unit = np.zeros(6)
        unit[(0 if axis.kind == "linear" else 3) + AXIS_INDEX[axis.direction]] = 1.0
        zeta = jac[..., :, 6 * a:6 * a + 6] @ unit  # (..., 6)
        ad = np.zeros(zeta.shape[:-1] + (6, 6))
        ad[..., :3, :3] = ad[..., 3:, 3:] = skew(zeta[..., 3:])
        ad[..., :3, 3:] = skew(zeta[..., :3])
        seen = np.zeros(machine.n_errors, dtype=bool)
        seen[:6 * (a + 1)] = True  # motion errors of axes up to a
        seen[6 * n:6 * (n + a)] = True  # assembly errors of the joints before a
        derivative[..., a, :, :] = -(ad @ jac) * seen
        if check_frame(frame) == "workpiece":
            turn = skew(zeta[..., 3:])
            derivative[..., a, :, :] += np.concatenate([turn @ jac[..., :3, :],
                                                        turn @ jac[..., 3:, :]], axis=-2)
    if frame == "workpiece":
        rotation_ = ideal_rotation(machine, q)
        jac = rows_in_frame(jac, rotation_)
        derivative = rows_in_frame(derivative, rotation_[..., None, :, :])
    return jac, derivative


def output_variance(machine, q, variance_x, frame: str = "tool") -> np.ndarray:
    """``Σ_i J_oi² var_i`` at every pose (Eq. 20's σ²) without forming the Jacobian.

    Accumulates each gap's block ``Ad(B⁻¹)² @ var_block`` in turn: the same sum as
    ``np.square(jacobian(machine, q)) @ variance_x`` in a sixth of the memory.

    Parameters
    ----------
    machine : Machine
    q : array_like
        ``(..., n_axes)`` positions.
    variance_x : array_like
        ``(n_errors,)`` error variances.
    frame : {'tool', 'workpiece'}
        With independent errors the variance of a workpiece-frame output is still
        ``Σ_i J_w,oi² var_i``, each block rotated first.

    Returns
    -------
    numpy.ndarray
        ``(..., 6)``.
    """
    q = machine.check_positions(q)
    variance_x = np.asarray(variance_x, dtype=float)
    factors, blocks = chain_factors(machine, q)
    rotation_ = ideal_rotation(machine, q) if check_frame(frame) == "workpiece" else None
    out = np.zeros(q.shape[:-1] + (6,))
    for block, adjoint in zip(blocks, transports(factors)):
        if rotation_ is not None:
            adjoint = rows_in_frame(adjoint, rotation_)
        out = out + np.square(adjoint) @ variance_x[6 * block:6 * block + 6]
    return out
