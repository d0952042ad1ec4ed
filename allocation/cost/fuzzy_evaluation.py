"""Fuzzy comprehensive evaluation of a cost coefficient (Sec. 4.2, Eqs. 29-30).

Each coefficient of the power-exponent cost model (``a``, ``b``, ``c``, ``d`` and the
assembly coefficients ``m_ij``, Table 5) is the score of a fuzzy comprehensive evaluation:
experts weight the evaluation factors (vector ``A``), state for each factor its degree of
membership in each evaluation grade (matrix ``R``), and the grades carry scores ``S``
(Eq. 33: ``S = (5, 4, 3, 2, 1)``). Then ``B = A R`` (Eq. 29) and the coefficient is
``F = B S^T`` (Eq. 30). The paper's worked example, Eqs. 36-39, gives ``a = 1.98``.
"""

from dataclasses import dataclass

import numpy as np
import pandas as pd

from reliability.basics import checks
from reliability.basics.errors import InputError
from reliability.basics.saved_fields import Array, Number, load_fields, save_fields

__all__ = ["FcemResult", "fcem_coefficient"]

#: Tolerance on "sums to one" for the weight vector and each membership row.
SUM_TOLERANCE = 1e-9


@dataclass(frozen=True, eq=False)
class FcemResult:
    """Outcome of one fuzzy comprehensive evaluation.

    Attributes
    ----------
    b : numpy.ndarray
        Membership of the evaluated object in each grade, ``B = A R`` (Eq. 29).
    value : float
        Total score ``F = B S^T`` (Eq. 30), i.e. the cost coefficient.
    scores : numpy.ndarray
        The grade scores ``S`` used (Eq. 33).
    """

    b: np.ndarray
    value: float
    scores: np.ndarray

    def to_frame(self):
        """Return one row per grade with its membership and score.

        Returns
        -------
        pandas.DataFrame
            Index ``grade`` (1-based), columns ``membership`` and ``score``.
        """
        grades = pd.Index(np.arange(1, self.b.size + 1), name="grade")
        return pd.DataFrame({"membership": self.b, "score": self.scores}, index=grades)

    def summary(self) -> str:
        """The cost coefficient and the membership of each grade."""
        grades = ", ".join(f"{g + 1}: {m:.3f}" for g, m in enumerate(self.b))
        return (f"Fuzzy comprehensive evaluation: cost coefficient F = {self.value:.4g} "
                f"(memberships by grade {grades}; scores {self.scores.tolist()})")

    def save(self, path, overwrite: bool = False):
        """Save as JSON (:data:`SAVED_FIELDS`, tag :data:`SAVED_FORMAT`); an existing file
        is kept unless ``overwrite``. Returns the path."""
        return save_fields(self, path, SAVED_FORMAT, SAVED_FIELDS, overwrite)

    @classmethod
    def load(cls, path) -> "FcemResult":
        """Reload a result written by :meth:`save`, checked: the memberships sum to one and
        the value is ``B Sᵀ`` (Eq. 30). A damaged field raises
        :class:`~reliability.basics.errors.SavedResultError` naming the file and field."""
        data, values = load_fields(path, SAVED_FORMAT, SAVED_FIELDS)
        if abs(values["b"].sum() - 1.0) > SUM_TOLERANCE:
            raise data.error("b", "the memberships do not sum to one")
        if not np.isclose(values["value"], values["b"] @ values["scores"], rtol=1e-12):
            raise data.error("value", "is not the memberships times the scores (Eq. 30)")
        return cls(**values)


SAVED_FORMAT = "precrel.fcem_result"
SAVED_FIELDS = (Array("b", ("grades",), low=0.0, high=1.0), Number("value"),
                Array("scores", ("grades",)))


def fcem_coefficient(weights, membership, scores=(5, 4, 3, 2, 1)):
    """Evaluate a cost coefficient by fuzzy comprehensive evaluation.

    Parameters
    ----------
    weights : array_like, shape (m,)
        Factor weights ``A`` (Eq. 36 in the example): finite, non-negative, summing to 1.
    membership : array_like, shape (m, n)
        Fuzzy evaluation matrix ``R`` (Eq. 37): ``R[i, j]`` is the membership of factor
        ``i`` in grade ``j``; finite, non-negative, each row summing to 1.
    scores : array_like, shape (n,), optional
        Grade scores ``S`` (Eq. 33), default ``(5, 4, 3, 2, 1)``.

    Returns
    -------
    FcemResult
        ``b`` (Eq. 29) and ``value`` (Eq. 30).

    Raises
    ------
    InputError
        If any input has the wrong shape, a negative or non-finite entry, or a weight
        vector or membership row that does not sum to 1 (the message names it).

    Examples
    --------
    The paper's coefficient ``a`` (Eqs. 36-39):

    >>> A = [0.4, 0.2, 0.1, 0.3]
    >>> R = [[0, 0, 0.2, 0.2, 0.6], [0, 0, 0.2, 0.4, 0.4],
    ...      [0, 0, 0.6, 0.4, 0], [0, 0.2, 0.2, 0.4, 0.2]]
    >>> round(fcem_coefficient(A, R).value, 12)
    1.98
    """
    scores = _check_scores(scores)
    weights = _check_weights(weights)
    membership = _check_membership(membership, weights.size, scores.size)
    b = weights @ membership  # Eq. (29)
    value = float(b @ scores)  # Eq. (30)
    b.setflags(write=False)
    return FcemResult(b=b, value=value, scores=scores)


def _check_scores(scores):
    scores = np.array(scores, dtype=float)
    if scores.ndim != 1 or scores.size == 0:
        raise InputError(f"scores must be a non-empty 1-D vector, got shape {scores.shape}")
    bad = np.flatnonzero(~np.isfinite(scores))
    if bad.size:
        raise InputError(f"scores[{bad[0]}] = {scores[bad[0]]} is not finite")
    scores.setflags(write=False)
    return scores


def _check_weights(weights):
    weights = checks.numeric_array(weights, "weights")
    if weights.ndim != 1 or weights.size == 0:
        raise InputError(
            f"weights must be a non-empty 1-D vector, got shape {weights.shape}"
        )
    bad = np.flatnonzero(~np.isfinite(weights) | (weights < 0))
    if bad.size:
        raise InputError(
            f"weights[{bad[0]}] = {weights[bad[0]]} must be finite and non-negative"
        )
    total = weights.sum()
    if abs(total - 1.0) > SUM_TOLERANCE:
        raise InputError(f"weights must sum to 1, they sum to {float(total)!r}")
    return weights


def _check_membership(membership, n_factors, n_grades):
    membership = np.asarray(membership, dtype=float)
    if membership.shape != (n_factors, n_grades):
        raise InputError(
            "membership must have shape (len(weights), len(scores)) = "
            f"{(n_factors, n_grades)}, got {membership.shape}"
        )
    bad = np.argwhere(~np.isfinite(membership) | (membership < 0))
    if bad.size:
        row, col = bad[0]
        raise InputError(
            f"membership[{row}, {col}] = {membership[row, col]} must be finite "
            "and non-negative"
        )
    row_sums = membership.sum(axis=1)
    bad_rows = np.flatnonzero(np.abs(row_sums - 1.0) > SUM_TOLERANCE)
    if bad_rows.size:
        row = bad_rows[0]
        raise InputError(
            f"membership row {row} must sum to 1, it sums to {float(row_sums[row])!r}"
        )
    return membership
