"""The machine as an OpenTURNS model: one output at one pose as an ``ot.Function`` of the
errors, with the errors' joint distribution.

The function evaluates the exact chain (Eq. 18, :func:`reliability.model.kinematics.comprehensive_error`)
on whole samples at once, and its gradient is the exact chain's, analytically: the chain's
deviation ``Π_k (I + η_k^) − I`` (``η_k = Ad(B_k⁻¹) ξ_k``) is linear in each twist, so its
derivative along component ``c`` of twist ``k`` is ``P_k (Ad(B_k⁻¹) e_c)^ Q_k`` with ``P_k`` and
``Q_k`` the products of the factors before and after ``k``, read as the six pose errors
(:func:`exact_gradient`; at zero error it is the analytic Jacobian). The distribution reads a
tolerance ``t`` as ``N(0, (t/k)²)``, or that normal truncated at ``±t``, with the machine file's
correlations as a normal copula; OpenTURNS' FORM, SORM, subset sampling and Sobol algorithms
run on the pair unchanged.
"""

from __future__ import annotations

import numpy as np

from ..basics import checks
from ..model.error_draws import check_reading
from ..model.kinematics import (chain_factors, check_frame, ideal_rotation, rows_in_frame,
                                transports, twist_matrix)
from ..model.machine import OUTPUTS
from ..model.transforms import read_pose_error
from ..sampling.sobol import one_pose, output_index
from .optional_packages import optional_import

#: The coverage factor of the toolkit's reading of a tolerance, t = ±kσ.
COVERAGE = 3.0


def exact_gradient(machine, pose, errors, frame: str | None = None) -> np.ndarray:
    """``(6, n_errors)``: the derivative of the exact comprehensive error with respect to
    every error, at one pose and one error vector (module docstring)."""
    q = one_pose(machine, pose)
    x = machine.check_errors(errors)
    frame = check_frame(machine.frame if frame is None else frame)
    factors, blocks = chain_factors(machine, q)
    adjoints = transports(factors)
    steps = [np.eye(4) + twist_matrix(adjoint @ x[6 * b:6 * b + 6])
             for adjoint, b in zip(adjoints, blocks)]
    before = [np.eye(4)]
    for step in steps[:-1]:
        before.append(before[-1] @ step)
    after = [np.eye(4)]
    for step in steps[:0:-1]:
        after.append(step @ after[-1])
    after = after[::-1]
    out = np.empty((6, machine.n_errors))
    for k, (adjoint, b) in enumerate(zip(adjoints, blocks)):
        units = twist_matrix(adjoint.T)  # (6, 4, 4): component c of the twist, carried
        out[:, 6 * b:6 * b + 6] = read_pose_error(before[k] @ units @ after[k]).T
    if frame == "workpiece":
        out = rows_in_frame(out, ideal_rotation(machine, q))
    return out


def openturns_model(machine, output, pose, *, tolerances=None, frame=None, distribution=None):
    """One output of the machine at one pose as an OpenTURNS function and input distribution.

    Parameters
    ----------
    machine : Machine
    output : str or int
        One of ``dx dy dz ex ey ez`` (mm, rad), or its index.
    pose : array_like
        ``(n_axes,)`` axis positions (mm, rad).
    tolerances : array_like, optional
        ``(n_errors,)`` allocation read as ±3σ; the machine's initial allocation by default.
    frame : {'tool', 'workpiece'}, optional
        ``machine.frame`` by default.
    distribution : {'normal', 'truncated'}, optional
        The reading of a tolerance; ``machine.distribution`` by default.

    Returns
    -------
    function : openturns.Function
        ``n_errors`` inputs named as ``machine.error_names``, one output; evaluated on
        samples in one batch, with the exact analytic gradient.
    distribution : openturns.Distribution
        The errors' joint distribution: normal or truncated-normal marginals, the machine's
        correlation as a normal copula (independent otherwise).

    Raises
    ------
    ImportError
        When OpenTURNS is not installed, naming the ``interop`` extra.
    """
    ot = optional_import("openturns", "OpenTURNS")
    o = output_index(output)
    q = one_pose(machine, pose)
    frame = check_frame(machine.frame if frame is None else frame)
    reading = machine.distribution if distribution is None else distribution
    check_reading(reading, COVERAGE)
    t = checks.one_allocation(machine, machine.initial_allocation if tolerances is None
                              else tolerances)

    def on_sample(x):
        return machine.comprehensive_error(q, np.asarray(x, dtype=float), frame)[:, [o]]

    def on_point(x):
        return on_sample(np.atleast_2d(np.asarray(x, dtype=float)))[0]

    def gradient(x):
        return exact_gradient(machine, q, np.asarray(x, dtype=float), frame)[[o]].T

    function = ot.PythonFunction(machine.n_errors, 1, func=on_point, func_sample=on_sample,
                                 gradient=gradient)
    function.setInputDescription(list(machine.error_names))
    function.setOutputDescription([OUTPUTS[o]])
    return function, joint_distribution(ot, machine, t, reading)


def joint_distribution(ot, machine, tolerances, reading: str):
    """The errors' joint distribution in OpenTURNS under ``reading``."""
    sigma = np.asarray(tolerances, dtype=float) / COVERAGE
    marginals = []
    for name, s, t in zip(machine.error_names, sigma, tolerances):
        marginal = ot.Normal(0.0, float(s)) if reading == "normal" else \
            ot.TruncatedNormal(0.0, float(s), -float(t), float(t))
        marginal.setDescription([name])
        marginals.append(marginal)
    if machine.correlation is None:
        copula = ot.IndependentCopula(machine.n_errors)
    else:
        copula = ot.NormalCopula(ot.CorrelationMatrix(np.asarray(machine.correlation)))
    joint = getattr(ot, "JointDistribution", None) or ot.ComposedDistribution
    distribution = joint(marginals, copula)
    distribution.setDescription(list(machine.error_names))
    return distribution
