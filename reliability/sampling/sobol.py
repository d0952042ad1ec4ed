"""Sobol indices of each output at a pose on the exact chain (Saltelli 2010, Jansen 1999).

For an output ``y = f(x)`` of independent errors ``x`` (each read from its tolerance as
normal with σ = t/k, or that normal truncated at ±t), the first-order index of error ``i`` is
``S1_i = Var(E[y | x_i]) / Var(y)`` and its total index ``ST_i = E[Var(y | x_{~i})] / Var(y)``.
From two independent samples ``A`` and ``B`` of ``N`` error vectors and the ``n`` matrices
``AB_i`` (``A`` with column ``i`` taken from ``B``), at ``N (n + 2)`` evaluations of the chain,

    S1_i ≈ mean(f(B) (f(AB_i) − f(A))) / V        (Saltelli et al. 2010),
    ST_i ≈ mean((f(A) − f(AB_i))²) / (2 V)         (Jansen 1999),

with ``V`` the variance of ``f(A)`` and ``f(B)`` pooled. Their intervals are bootstrap
intervals, ``± z · sd`` over resamples of the ``N`` rows, the convention of SALib's
``S1_conf`` and ``ST_conf``.

Where the chain is linear in the errors, ``y = Σ_i J_i x_i``, the indices are known: both equal
the FOSM variance share ``J_i² σ_i² / Σ_j J_j² σ_j²`` (Eq. 20), so no error interacts with
another. The exact chain is that linear model plus products of errors; an output whose total
index of some error exceeds its first-order index by more than the two intervals together
shows an interaction (:meth:`SobolIndices.interactions`).

Sobol indices need independent errors; a machine with correlated errors is refused.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.stats import norm

from ..basics import checks, streams
from ..basics.errors import InputError
from ..basics.renamed import renamed
from ..basics.saved_fields import Array, Integer, Number, Text, Texts, load_fields, save_fields
from ..first_order.fosm import error_sigma
from ..first_order.worst_grid_pose import worst_grid_poses
from ..model.error_draws import check_reading, normal_to_marginal
from ..model.machine import OUTPUTS

#: Rows of the samples ``A`` and ``B`` when not told otherwise.
DEFAULT_SAMPLES = 2000
#: Bootstrap resamples of the intervals (SALib's default too).
DEFAULT_RESAMPLES = 100
#: Columns of :meth:`SobolIndices.to_frame` (and of ``sobol.csv``).
SOBOL_COLUMNS = ("output", "error", "S1", "S1_conf", "ST", "ST_conf")


def output_index(output) -> int:
    """The position of ``output`` (a name of :data:`OUTPUTS` or its index) among the six."""
    if isinstance(output, str):
        if output not in OUTPUTS:
            raise InputError(f"output: expected one of {OUTPUTS}; got {output!r}")
        return OUTPUTS.index(output)
    if isinstance(output, (int, np.integer)) and not isinstance(output, bool) \
            and 0 <= output < len(OUTPUTS):
        return int(output)
    raise InputError(f"output: expected a name of {OUTPUTS} or an index 0-5; got {output!r}")


def one_pose(machine, pose) -> np.ndarray:
    """``pose`` checked as one set of axis positions ``(n_axes,)`` (mm, rad)."""
    q = machine.check_positions(pose)
    if q.shape != (len(machine.axes),):
        raise InputError(f"pose: expected {len(machine.axes)} axis positions "
                         f"({', '.join(machine.axes)}); got shape {q.shape}")
    return q


def require_independent(machine, what: str) -> None:
    """Refuse a machine with correlated errors where ``what`` assumes independent errors."""
    if machine.correlation is not None:
        raise InputError(f"machine {machine.name!r}: {what} assume independent errors, but "
                         f"the machine file correlates some (its [[correlation]] pairs)")


@dataclass(frozen=True, eq=False)
class SobolIndices:
    """First-order and total Sobol indices of the six outputs, each at its pose.

    Attributes
    ----------
    errors : tuple of str
        Error names, in the machine's order.
    poses : ndarray (6, n_axes)
        The pose of each output (mm, rad).
    S1, S1_conf, ST, ST_conf : ndarray (6, n_errors)
        Indices and the half-widths of their bootstrap intervals at ``confidence``.
    analytic : ndarray (6, n_errors)
        The indices of the chain linearised at zero error: the FOSM variance shares.
    variance : ndarray (6,)
        Pooled variance of each output over the samples.
    samples : int
        Rows ``N`` of each of the samples ``A`` and ``B``.
    model_calls : int
        Error vectors evaluated on the chain per output, ``N (n_errors + 2)``.
    confidence : float
    distribution : str
        The reading of a tolerance.
    """

    errors: tuple[str, ...]
    poses: np.ndarray
    S1: np.ndarray
    S1_conf: np.ndarray
    ST: np.ndarray
    ST_conf: np.ndarray
    analytic: np.ndarray
    variance: np.ndarray
    samples: int
    model_calls: int
    confidence: float
    distribution: str

    def to_frame(self) -> pd.DataFrame:
        """One row per output and error: ``output, error, S1, S1_conf, ST, ST_conf``."""
        n = len(self.errors)
        return pd.DataFrame({
            "output": np.repeat(OUTPUTS, n), "error": np.tile(self.errors, len(OUTPUTS)),
            "S1": self.S1.ravel(), "S1_conf": self.S1_conf.ravel(),
            "ST": self.ST.ravel(), "ST_conf": self.ST_conf.ravel()},
            columns=list(SOBOL_COLUMNS))

    def comparison(self) -> pd.DataFrame:
        """:meth:`to_frame` with the FOSM share (``analytic``) and whether the error
        interacts with others (``interaction``: ``ST − S1 > S1_conf + ST_conf``)."""
        frame = self.to_frame()
        frame["analytic"] = self.analytic.ravel()
        frame["interaction"] = self.interaction_flags().ravel()
        return frame

    def interaction_flags(self) -> np.ndarray:
        """``(6, n_errors)`` bool: the total index exceeds the first-order one by more
        than the two intervals together."""
        return (self.ST - self.S1) > (self.S1_conf + self.ST_conf)

    def interactions(self) -> pd.DataFrame:
        """The rows of :meth:`comparison` flagged as interacting."""
        frame = self.comparison()
        return frame[frame["interaction"]].reset_index(drop=True)

    def largest_analytic_gap(self) -> float:
        """The largest ``|S1 − FOSM share|`` over outputs and errors."""
        return float(np.nanmax(np.abs(self.S1 - self.analytic)))

    def summary(self, top: int = 3) -> str:
        """The ``top`` errors of each output by first-order index, beside the FOSM share."""
        level = f"{self.confidence:.0%}"
        lines = [f"Sobol indices ({self.samples} x ({len(self.errors)} + 2) chain evaluations "
                 f"per output, {level} bootstrap intervals; tolerances read "
                 f"{self.distribution!r}); largest |S1 - FOSM share| "
                 f"{self.largest_analytic_gap():.3g}"]
        for o, output in enumerate(OUTPUTS):
            if not self.variance[o] > 0:
                lines.append(f"  {output}: no error moves it at its pose")
                continue
            order = np.argsort(-self.S1[o], kind="stable")[:top]
            parts = [f"{self.errors[i]} S1 {self.S1[o, i]:.3f}±{self.S1_conf[o, i]:.3f} "
                     f"ST {self.ST[o, i]:.3f}±{self.ST_conf[o, i]:.3f} "
                     f"(FOSM {self.analytic[o, i]:.3f})" for i in order]
            lines.append(f"  {output}: " + "; ".join(parts))
        flagged = int(self.interaction_flags().sum())
        lines.append(f"  interactions (ST - S1 beyond both intervals): {flagged}")
        return "\n".join(lines)

    def save(self, path, overwrite: bool = False):
        """Save as JSON (:data:`SAVED_FIELDS`, tag :data:`SAVED_FORMAT`); an existing file
        is kept unless ``overwrite``. Returns the path."""
        return save_fields(self, path, SAVED_FORMAT, SAVED_FIELDS, overwrite)

    @classmethod
    def load(cls, path) -> "SobolIndices":
        """Reload indices written by :meth:`save`, every field checked (NaN marks an
        output no error moves); the interaction flags follow from the saved indices. A
        damaged field raises :class:`~reliability.basics.errors.SavedResultError` naming
        the file and field."""
        data, values = load_fields(path, SAVED_FORMAT, SAVED_FIELDS)
        if values["model_calls"] != values["samples"] * (len(values["errors"]) + 2):
            raise data.error("model_calls", "is not samples × (errors + 2)")
        return cls(**values)


SAVED_FORMAT = "precrel.sobol_indices"
_INDEX_SHAPE = (len(OUTPUTS), "errors")
SAVED_FIELDS = (Texts("errors", "errors", unique=True), Array("poses", (len(OUTPUTS), None)),
                *(Array(name, _INDEX_SHAPE, nan=True)
                  for name in ("S1", "S1_conf", "ST", "ST_conf", "analytic")),
                Array("variance", (len(OUTPUTS),), low=0.0), Integer("samples", low=1),
                Integer("model_calls", low=1), Number("confidence", low=0.0, high=1.0),
                Text("distribution"))


@renamed("points_per_axis", "points")
def sobol_indices(machine, tolerances=None, poses=None, *, samples: int = DEFAULT_SAMPLES,
                  distribution: str | None = None, frame: str | None = None,
                  k: float = 3.0, confidence: float = 0.95,
                  resamples: int = DEFAULT_RESAMPLES, points: int = 5,
                  rng=None) -> SobolIndices:
    """First-order and total Sobol indices of every output at a pose, on the exact chain.

    Parameters
    ----------
    machine : Machine
        With independent errors.
    tolerances : array_like, optional
        ``(n_errors,)`` allocation read as ±kσ; the machine's initial allocation by default.
    poses : array_like, optional
        One pose ``(n_axes,)`` for every output, or one per output ``(6, n_axes)`` (mm,
        rad); each output's worst pose of the ``points`` grid by default.
    samples : int
        Rows ``N`` of the samples ``A`` and ``B``.
    distribution : {'normal', 'truncated'}, optional
        The reading of a tolerance; ``machine.distribution`` by default.
    frame : {'tool', 'workpiece'}, optional
        Frame of the outputs; ``machine.frame`` by default.
    k : float
        Coverage factor.
    confidence : float
        Level of the bootstrap intervals.
    resamples : int
        Bootstrap resamples.
    points : int
        Grid of the default poses (points per axis); ``points_per_axis=`` is its deprecated
        spelling (:mod:`reliability.basics.renamed`).
    rng : None, int or numpy.random.Generator
        Split into the stream of the samples and the stream of the bootstrap.

    Returns
    -------
    SobolIndices
    """
    require_independent(machine, "Sobol indices")
    distribution = machine.distribution if distribution is None else distribution
    k = check_reading(distribution, k)
    t = checks.one_allocation(machine, machine.initial_allocation if tolerances is None
                              else tolerances)
    samples = checks.positive_int(samples, "samples", minimum=2)
    resamples = checks.positive_int(resamples, "resamples")
    confidence = checks.finite_float(confidence, "confidence", 0.0, 1.0, low_open=True,
                                     high_open=True)
    at = _output_poses(machine, t, poses, points, distribution, k)
    draw_rng, boot_rng = streams.spawn(rng, 2)
    u = draw_rng.standard_normal((2, samples, machine.n_errors))
    a, b = normal_to_marginal(u, k, distribution) * (t / k)
    values = _outputs_on_design(machine, at, a, b, frame)
    rows = boot_rng.integers(0, samples, size=(resamples, samples))
    z = norm.ppf(0.5 + confidence / 2)
    estimates = [_indices_with_intervals(*values[o], rows, z) for o in range(len(OUTPUTS))]
    s1, s1_conf, st, st_conf, variance = (np.array(part) for part in zip(*estimates))
    return SobolIndices(errors=machine.error_names, poses=at, S1=s1, S1_conf=s1_conf, ST=st,
                        ST_conf=st_conf,
                        analytic=fosm_shares(machine, t, at, distribution=distribution, k=k,
                                             frame=frame),
                        variance=variance, samples=samples,
                        model_calls=samples * (machine.n_errors + 2), confidence=confidence,
                        distribution=distribution)


def fosm_shares(machine, tolerances, poses, *, distribution: str = "normal", k: float = 3.0,
                frame: str | None = None) -> np.ndarray:
    """``(6, n_errors)``: each error's share ``J_i² σ_i² / Σ_j J_j² σ_j²`` of each output's
    variance at that output's pose (``poses`` ``(6, n_axes)``); NaN where the output does
    not move."""
    jacobian = machine.jacobian(poses, frame)[np.arange(len(OUTPUTS)), np.arange(len(OUTPUTS))]
    terms = np.square(jacobian * error_sigma(tolerances, k, distribution))
    total = terms.sum(axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(total > 0, terms / total, np.nan)


def _output_poses(machine, t, poses, points, distribution, k) -> np.ndarray:
    if poses is None:
        return worst_grid_poses(machine, t, points=points, k=k,
                                distribution=distribution)
    q = machine.check_positions(poses)
    if q.shape == (len(machine.axes),):
        return np.tile(q, (len(OUTPUTS), 1))
    if q.shape != (len(OUTPUTS), len(machine.axes)):
        raise InputError(f"poses: expected one pose ({len(machine.axes)},) or one per output "
                         f"({len(OUTPUTS)}, {len(machine.axes)}); got shape {q.shape}")
    return q


def _outputs_on_design(machine, poses, a, b, frame) -> list:
    """Per output ``(f(A), f(B), f(AB) (N, n))`` at its pose; each distinct pose once."""
    distinct, where = np.unique(poses, axis=0, return_inverse=True)
    values = [None] * len(OUTPUTS)
    for index, q in enumerate(distinct):
        f_a = machine.comprehensive_error(q, a, frame)
        f_b = machine.comprehensive_error(q, b, frame)
        f_ab = np.empty(a.shape + (len(OUTPUTS),))
        for i in range(a.shape[1]):
            mixed = a.copy()
            mixed[:, i] = b[:, i]
            f_ab[:, i] = machine.comprehensive_error(q, mixed, frame)
        for o in np.flatnonzero(np.ravel(where) == index):
            values[o] = (f_a[:, o], f_b[:, o], f_ab[:, :, o])
    return values


def _indices_with_intervals(f_a, f_b, f_ab, rows, z):
    """S1, its half-width, ST, its half-width (each ``(n,)``) and the pooled variance."""
    s1, st, variance = _indices(f_a, f_b, f_ab)
    boot = [_indices(f_a[r], f_b[r], f_ab[r])[:2] for r in rows]
    boot_s1, boot_st = (np.array(part) for part in zip(*boot))
    return s1, z * boot_s1.std(axis=0, ddof=1), st, z * boot_st.std(axis=0, ddof=1), variance


def _indices(f_a, f_b, f_ab):
    variance = float(np.var(np.concatenate([f_a, f_b]), ddof=1))
    with np.errstate(invalid="ignore", divide="ignore"):
        first = np.mean(f_b[:, None] * (f_ab - f_a[:, None]), axis=0) / variance
        total = 0.5 * np.mean(np.square(f_a[:, None] - f_ab), axis=0) / variance
    return first, total, variance
