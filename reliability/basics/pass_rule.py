"""One rule for "within its limit": the only place the toolkit decides whether an output passes.

The paper's limit state of an output ``y`` with allowable value ``I`` is ``g = I - |y|``
(Eq. 19): the output is safe where ``g > 0`` and fails where ``g <= 0``. So an output passes
its limit when

    |y| < I        (strictly; a value exactly on the limit fails)

Every estimator reads a pass through :func:`passes`: the grid experiment, random-pose and
worst-pose sampling, the machine yield, the acceptance tests (an ISO 230 test value against
its limit), the as-measured machine and the compensated machines. For continuous outputs the
two readings of the boundary have the same probability; the rule matters only to make every
count in the toolkit the same count.
"""

from __future__ import annotations

import numpy as np


def passes(values, limits) -> np.ndarray:
    """Whether each value lies within its limit: ``|y| < I`` (Eq. 19, ``g = I - |y| > 0``).

    Parameters
    ----------
    values : array_like
        Outputs (or test values), any shape.
    limits : array_like
        Allowable values ``I > 0``, broadcast against ``values`` (e.g. the six limits of a
        machine along the last axis).

    Returns
    -------
    numpy.ndarray of bool
        True where the value passes. NaN never passes.
    """
    return np.abs(values) < limits
