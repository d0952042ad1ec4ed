"""The linearised rows of a machine yield: each row's output to first order in the draws.

A row ``r = (pose, output)`` of the grid is linearised at ``u = 0``: ``y_r ≈ a_r·u`` with
``a_r = J_r s L`` (the analytic Jacobian at the row's pose; ``s = ∂x/∂z`` at 0: ``t/k``, times
``1 − 2Φ(−k)`` under the truncated reading; ``L`` the profile's factor). ``|a_r|`` is Eq. 20's σ
with ``s``: FOSM's σ of the row under the normal reading. The importance proposal
(:mod:`reliability.sampling.row_events`) is built on these rows.

First-order bounds
------------------
For the linearised model, whatever the profile (every row's marginal is FOSM's), the union
(Bonferroni) bound gives ``yield ≥ 1 − Σ_rows P(|y_r| ≥ I_r)`` (floored at 0) and the best
single row ``yield ≤ min_rows P(|y_r| < I_r)``. Row probabilities are normal: exact for the
``normal`` reading, the normal approximation with the truncated σ for ``truncated``.
"""

from __future__ import annotations

import numpy as np
from scipy.special import ndtr

from ..basics import checks
from ..basics.chunks import chunks, jacobian_bytes
from ..first_order.fosm import error_sigma, pose_sigma, two_sided_failure
from ..model.machine import OUTPUTS


class LinearRows:
    """The rows of a :class:`~reliability.sampling.machine_yield.YieldModel` linearised in
    its standard normal draws ``u``: their σ, their vectors ``a_r`` and the first-order
    bounds.

    Parameters
    ----------
    model : YieldModel
        Its machine, grid, reading, memory budget and the profile's factors.
    """

    def __init__(self, model):
        self.model = model
        self.machine = model.machine
        self.experiment = model.experiment
        self.memory = model.memory
        self.k, self.distribution = model.k, model.distribution
        self.dimension = model.dimension

    def row_sigma(self, tolerances) -> np.ndarray:
        """FOSM σ (Eq. 20) of every output at every grid pose under the reading,
        ``(n_poses, 6)``."""
        spread = error_sigma(tolerances, self.k, self.distribution)
        return pose_sigma(self.machine, self.experiment.poses, spread, memory=self.memory)

    def slope_spread(self, tolerances) -> np.ndarray:
        """``∂x/∂z`` at ``z = 0`` of each error: ``t/k`` for the normal reading and
        ``(t/k)(1 − 2Φ(−k))`` for the truncated one (the slope of its copula map at 0, a
        closer linearisation in ``u`` than the truncated σ, ``0.9866 t/k``)."""
        slope = 1.0 if self.distribution == "normal" else 1.0 - 2.0 * float(ndtr(-self.k))
        return np.asarray(tolerances, dtype=float) / self.k * slope

    def event_sigma(self, tolerances) -> np.ndarray:
        """``|a_r|`` of every row, ``(n_poses, 6)``: Eq. (20) with :meth:`slope_spread`
        (FOSM's σ under the normal reading)."""
        return pose_sigma(self.machine, self.experiment.poses,
                          self.slope_spread(tolerances), memory=self.memory)

    def row_vectors(self, rows, tolerances) -> np.ndarray:
        """``a_r`` of rows ``pose · 6 + output``: the linearised output in ``u`` (the
        Jacobian times :meth:`slope_spread` times the profile's factor),
        ``(len(rows), dimension)``, with ``|a_r|`` from :meth:`event_sigma` (in chunks of
        rows)."""
        rows = np.asarray(rows)
        spread = self.slope_spread(tolerances)
        out = np.empty((len(rows), self.dimension))
        for part in chunks(len(rows), jacobian_bytes(self.machine), self.memory):
            out[part] = self._row_vectors(rows[part], spread)
        return out

    def row_signatures(self, rows, tolerances) -> np.ndarray:
        """``(len(rows), 3)``: the projections of ``a_r/I_r`` on three fixed directions;
        rows with the same event ``{|a_r·u| ≥ I_r}`` have the same signature up to rounding
        (compare them with :func:`reliability.basics.ties.first_of_equal_rows` at
        :data:`reliability.sampling.row_events.SIGNATURE_RESOLUTION`; in chunks of rows)."""
        rows = np.asarray(rows)
        spread = self.slope_spread(tolerances)
        limits = np.tile(self.machine.limits, self.experiment.n_poses)
        index = np.arange(self.dimension)[:, None] * np.array([0.7, 1.3, 2.9])
        directions = np.cos(index + np.array([0.0, 1.0, 2.0]))  # fixed, not random
        out = np.empty((len(rows), 3))
        for part in chunks(len(rows), jacobian_bytes(self.machine), self.memory):
            scaled = self._row_vectors(rows[part], spread) / limits[rows[part], None]
            out[part] = scaled @ directions
        return out

    def _row_vectors(self, rows, spread) -> np.ndarray:
        pose, output = np.divmod(rows, len(OUTPUTS))
        n = len(self.machine.axis_specs)
        distinct, where = np.unique(pose, return_inverse=True)  # one Jacobian per pose
        jacobian = self.machine.jacobian(self.experiment.poses[distinct])[where.ravel()]
        c = jacobian[np.arange(len(rows)), output] * spread
        travel = self.model.travel[np.arange(n), self.model.grid_index[pose]]  # (rows, n, P)
        motion = np.einsum("Kac,Kaq,acj->Kaqj", c[:, :6 * n].reshape(-1, n, 6), travel,
                           self.model.item_factors, optimize=True)
        assembly = c[:, 6 * n:] @ self.model.assembly_factor
        return np.concatenate([motion.reshape(len(rows), -1), assembly], axis=1)

    def first_order_bounds(self, tolerances) -> tuple[float, float]:
        """Bounds on the yield of the linearised model: ``1 − Σ_rows p_r`` (floored at 0)
        and ``min_rows (1 − p_r)``, ``p_r = 2Φ(−I/σ_r)``."""
        t = checks.one_allocation(self.machine, tolerances)
        failure = two_sided_failure(self.machine.limits, self.row_sigma(t))
        return bounds_from_rows(failure)


def bounds_from_rows(failure) -> tuple[float, float]:
    """Union bound and best single row from row failure probabilities."""
    failure = np.asarray(failure, dtype=float).ravel()
    return max(0.0, 1.0 - float(failure.sum())), 1.0 - float(failure.max())
