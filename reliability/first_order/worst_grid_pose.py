"""Each output's worst pose on the workspace grid, under the reading of a tolerance.

The pose of the grid where an event is most likely to fail, linear-Gaussian (Eq. 20):

* an output (``'dx'`` … ``'ez'``): the pose of largest σ. For a zero-mean output the two-sided
  failure probability grows with σ, so this is FOSM's worst pose; ranking by σ keeps the order
  where that probability rounds to 0.
* ``'system'``: the pose of largest Σ_o two-sided failure probability of the six outputs (the
  union bound of the machine failing anywhere at that pose).

σ follows from the tolerances as FOSM reads them (:func:`reliability.first_order.fosm.error_sigma`,
:func:`reliability.first_order.fosm.pose_sigma`): ``t = ±kσ``, or the spread of the normal
truncated at ``±t`` under ``distribution='truncated'``, and the machine's correlation when it has
one. The truncated reading scales every σ by the same factor, so it leaves an output's worst pose
where it was, but the system's sum of failure probabilities weighs the outputs differently at
another scale and its worst pose can move. Ties are broken by
:func:`reliability.basics.ties.worst_rows`.
"""

from __future__ import annotations

import numpy as np

from ..basics import checks
from ..basics.errors import InputError
from ..basics.ties import worst_rows
from ..model.error_draws import DISTRIBUTIONS
from ..model.machine import OUTPUTS
from ..model.poses import workspace_grid
from .fosm import error_sigma, pose_sigma, two_sided_failure

#: The events a worst pose is sought for: each output, and the machine at a pose.
EVENTS = OUTPUTS + ("system",)


def worst_grid_poses(machine, tolerances, events=OUTPUTS, *, points: int = 5, k: float = 3.0,
                     distribution: str | None = None) -> np.ndarray:
    """The worst pose of each event on the ``points``-point workspace grid.

    Parameters
    ----------
    machine : Machine
    tolerances : array_like
        ``(n_errors,)`` allocation (mm, rad), read as ``±kσ``.
    events : sequence of str
        Outputs ``'dx'`` … ``'ez'`` and ``'system'`` (:data:`EVENTS`); each output by default.
    points : int
        Grid points per axis (:func:`reliability.model.poses.workspace_grid`).
    k : float
        Coverage factor of the tolerances.
    distribution : {'normal', 'truncated'}, optional
        The reading of a tolerance; the machine's own (``machine.distribution``) by default.

    Returns
    -------
    numpy.ndarray
        ``(len(events), n_axes)``: the worst pose of each event, in the order of ``events``.

    Raises
    ------
    InputError
        An unknown event or distribution, or tolerances that are not one allocation.
    """
    columns = _event_columns(events)
    distribution = machine.distribution if distribution is None else \
        checks.choice(distribution, "distribution", DISTRIBUTIONS)
    t = checks.one_allocation(machine, tolerances)
    grid = workspace_grid(machine, points)
    sigma = pose_sigma(machine, grid, error_sigma(t, k, distribution))  # Eq. (20)
    scores = np.column_stack([sigma, two_sided_failure(machine.limits, sigma).sum(axis=1)])
    return grid[worst_rows(scores[:, columns], grid)]


def _event_columns(events) -> list[int]:
    """The score column of each event; a single name or an unknown one is refused."""
    if isinstance(events, str):
        raise InputError(f"events must be a sequence of event names, e.g. ({events!r},); "
                         f"got the string {events!r}")
    events = tuple(events)
    unknown = [e for e in events if e not in EVENTS]
    if unknown or not events:
        raise InputError(f"events must be one or more of {EVENTS}; got {events!r}")
    return [EVENTS.index(e) for e in events]
