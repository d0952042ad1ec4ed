"""The machine as a SALib model: the problem dictionary and an evaluator in batches.

:func:`salib_problem` describes the errors as SALib's ``problem`` (``num_vars``, ``names``,
``bounds``, ``dists``) under the machine's reading of a tolerance: ``'norm'`` with bounds
``[0, t/3]`` (mean, σ) or ``'truncnorm'`` with ``[−t, t, 0, t/3]`` (lower, upper, mean, σ).
SALib's samplers then draw error vectors and :func:`salib_evaluate` gives one output of the
exact chain at one pose for each. Both need only numpy; SALib itself samples and analyses.
SALib assumes independent inputs, so a machine with correlated errors is refused.
"""

from __future__ import annotations

import numpy as np

from ..basics import checks
from ..basics.chunks import chunks
from ..basics.errors import InputError
from ..sampling.sobol import one_pose, output_index, require_independent
from .openturns_bridge import COVERAGE

#: Bytes per error vector of one evaluation of the chain, for the batches.
BYTES_PER_SAMPLE = 4 * 4 * 8 * 8


def salib_problem(machine, tolerances=None) -> dict:
    """SALib's problem dictionary of the machine's errors.

    Parameters
    ----------
    machine : Machine
        With independent errors; its ``distribution`` decides ``dists``.
    tolerances : array_like, optional
        ``(n_errors,)`` allocation read as ±3σ; the initial allocation by default.

    Returns
    -------
    dict
        ``num_vars``, ``names`` (``machine.error_names``), ``bounds``, ``dists``.
    """
    require_independent(machine, "SALib's samplers")
    t = checks.one_allocation(machine, machine.initial_allocation if tolerances is None
                              else tolerances)
    sigma = t / COVERAGE
    if machine.distribution == "normal":
        bounds = [[0.0, float(s)] for s in sigma]
        dists = ["norm"] * machine.n_errors
    else:
        bounds = [[-float(b), float(b), 0.0, float(s)] for b, s in zip(t, sigma)]
        dists = ["truncnorm"] * machine.n_errors
    return {"num_vars": machine.n_errors, "names": list(machine.error_names),
            "bounds": bounds, "dists": dists}


def salib_evaluate(machine, samples, output, pose, *, frame=None,
                   memory: int | None = None) -> np.ndarray:
    """One output of the exact chain at one pose for each error vector of ``samples``.

    Parameters
    ----------
    machine : Machine
    samples : array_like
        ``(N, n_errors)`` error vectors (mm, rad), e.g. from ``SALib.sample.sobol.sample``.
    output : str or int
        One of ``dx dy dz ex ey ez``, or its index.
    pose : array_like
        ``(n_axes,)`` axis positions (mm, rad).
    frame : {'tool', 'workpiece'}, optional
        ``machine.frame`` by default.
    memory : int, optional
        Bytes of temporary arrays per batch.

    Returns
    -------
    numpy.ndarray
        ``(N,)``, the form SALib's analysers take.
    """
    o = output_index(output)
    q = one_pose(machine, pose)
    x = np.asarray(samples, dtype=float)
    if x.ndim != 2 or x.shape[1] != machine.n_errors:
        raise InputError(f"samples: expected (N, {machine.n_errors}) error vectors; got shape "
                         f"{x.shape}")
    out = np.empty(len(x))
    for part in chunks(len(x), BYTES_PER_SAMPLE * machine.n_errors, memory):
        out[part] = machine.comprehensive_error(q, x[part], frame)[:, o]
    return out

