"""The importance proposal of a machine yield: the ALOE mixture over linearised row events.

The failure set is the union over rows ``r = (pose, output)`` of ``{|y_r(u)| ≥ I_r}``.
Linearised at ``u = 0`` (:mod:`reliability.sampling.linear_rows`), ``y_r ≈ a_r·u`` and each
row event is a pair of half-spaces ``F_r = {|a_r·u| ≥ I_r}`` (where
:func:`reliability.basics.pass_rule.passes` fails) of probability ``p_r = 2Φ(−I_r/|a_r|)``.
Following the ALOE construction of Owen, Maximov & Chertkov (2019, "Importance sampling for
the union of rare events in reliability"), the proposal is the defensive mixture

    q(u) = α φ(u) + (1 − α) Σ_{r∈S} (p_r / P_S) φ(u) 1[u ∈ F_r] / p_r,

over the dominant rows ``S`` (``P_S = Σ_{r∈S} p_r``): with probability ``α`` a plain
draw, otherwise a row chosen with probability ``p_r/P_S`` and ``u`` drawn from ``φ``
conditioned exactly on that row's event (its component along ``a_r`` from the normal
tail beyond ``I_r/|a_r|``, either sign, the rest unchanged). Its density ratio is

    w(u) = φ(u)/q(u) = 1 / (α + (1 − α) N_S(u)/P_S),   N_S(u) = #{r ∈ S: u ∈ F_r},

known exactly and at most ``1/α``. Any subset ``S`` keeps the weights exact; the
linearisation only sets the efficiency. Without the chain, ALOE also estimates the
linearised model's failure probability: ``P_S · mean 1/N_S`` over draws of the pure mixture.
"""

from __future__ import annotations

import numpy as np
from scipy.special import ndtr, ndtri

from ..basics.chunks import chunks
from ..basics.pass_rule import passes
from ..basics.ties import decreasing_order, first_of_equal_rows
from ..first_order.fosm import two_sided_failure

#: α, the plain-normal share of the importance proposal; weights are at most 1/α.
DEFENSIVE = 0.1
#: The proposal's rows: the fewest, by decreasing p_r, that hold this share of Σ p_r ...
EVENT_MASS = 1.0 - 1e-3
#: ... and at most this many.
MAX_EVENTS = 20_000
#: Rows whose signatures agree to this (absolute, in ``a_r/I_r`` projected) have one event.
SIGNATURE_RESOLUTION = 1e-10
#: Draws of the mixture in the chain-free ALOE estimate of the linearised failure probability.
LINEAR_SAMPLES = 2000


class RowEvents:
    """The dominant linearised row events ``S = {|a_r·u| ≥ I_r}`` and the ALOE mixture
    over them (:meth:`draw`, :meth:`weight`); built by :meth:`dominant`."""

    def __init__(self, vectors, thresholds, probabilities, left_out):
        self.vectors = vectors  # (K, D) a_r
        self.norms = np.linalg.norm(vectors, axis=1)
        self.thresholds = thresholds  # (K,) I_r
        self.probabilities = probabilities  # (K,) p_r
        self.total = float(probabilities.sum())  # P_S
        self.left_out = left_out  # Σ p_r over rows not in S

    @property
    def size(self) -> int:
        return len(self.thresholds)

    @classmethod
    def dominant(cls, rows, tolerances):
        """The distinct row events of the linearised ``rows``
        (:class:`~reliability.sampling.linear_rows.LinearRows`; rows with the same event, e.g.
        poses that differ only along an axis the output does not depend on under the
        ``constant`` profile, count once: :meth:`LinearRows.row_signatures`), the fewest by
        decreasing ``p_r`` holding :data:`EVENT_MASS` of their ``Σ p_r``, at most
        :data:`MAX_EVENTS`, without rows whose ``p_r = 2Φ(−I_r/|a_r|)`` is 0 in double
        precision. Any subset keeps the
        weights exact; a larger one makes them more efficient."""
        limits = np.tile(rows.machine.limits, rows.experiment.n_poses)
        failure = two_sided_failure(limits, rows.event_sigma(tolerances).ravel())
        candidates = np.flatnonzero(failure > 0)
        if len(candidates) == 0:
            return cls(np.zeros((0, rows.dimension)), np.zeros(0), np.zeros(0), 0.0)
        signatures = rows.row_signatures(candidates, tolerances)
        distinct = candidates[first_of_equal_rows(signatures / SIGNATURE_RESOLUTION)]
        # decreasing p_r; p_r equal but for rounding (symmetric rows) keep the row order,
        # so that the events, and which event a draw comes from, are the same everywhere
        distinct = distinct[decreasing_order(failure[distinct])]
        cumulative = np.cumsum(failure[distinct])
        total = cumulative[-1]
        count = min(MAX_EVENTS, int(np.searchsorted(cumulative, EVENT_MASS * total)) + 1)
        kept = distinct[:count]
        return cls(rows.row_vectors(kept, tolerances), limits[kept], failure[kept],
                   float(total - cumulative[count - 1]))

    def counts(self, u) -> np.ndarray:
        """``N_S(u)``: the events of ``S`` that contain each draw (in chunks of draws)."""
        out = np.empty(len(u), dtype=np.int64)
        for part in chunks(len(u), 2 * 8 * self.size):
            out[part] = np.count_nonzero(~passes(u[part] @ self.vectors.T, self.thresholds),
                                         axis=1)
        return out

    def weight(self, u) -> np.ndarray:
        """``w(u) = 1/(α + (1 − α) N_S(u)/P_S)``, the exact ``φ/q`` (1 without events:
        the proposal is then ``φ``)."""
        if self.size == 0:
            return np.ones(len(u))
        return 1.0 / (DEFENSIVE + (1.0 - DEFENSIVE) * self.counts(u) / self.total)

    def draw(self, rng, size, defensive: float = DEFENSIVE) -> np.ndarray:
        """``size`` draws of the mixture: plain normals with probability ``defensive``,
        else ``φ`` conditioned on one event chosen with probability ``p_r/P_S``."""
        u = rng.standard_normal((size, self.vectors.shape[1]))
        if self.size == 0:
            return u
        conditioned = np.flatnonzero(rng.random(size) >= defensive)
        row = rng.choice(self.size, size=len(conditioned), p=self.probabilities / self.total)
        direction = self.vectors[row] / self.norms[row, None]
        beta = self.thresholds[row] / self.norms[row]
        tail = -ndtri(rng.random(len(conditioned)) * ndtr(-beta))  # beyond β, exactly
        sign = np.where(rng.random(len(conditioned)) < 0.5, -1.0, 1.0)
        along = np.einsum("kd,kd->k", u[conditioned], direction)
        u[conditioned] += (sign * tail - along)[:, None] * direction
        return u

    def linear_failure(self, rng) -> float:
        """ALOE's estimate of ``P(∪_S F_r)`` for the linearised model, without the chain:
        ``P_S · mean(1/N_S)`` over draws of the pure mixture."""
        if self.size == 0:
            return 0.0
        counts = self.counts(self.draw(rng, LINEAR_SAMPLES, defensive=0.0))
        return self.total * float(np.mean(1.0 / np.maximum(counts, 1)))
