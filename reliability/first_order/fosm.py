"""First-order second-moment (FOSM) precision reliability, Eqs. (19)–(23).

At a pose, each comprehensive error ``y`` is treated as normal with mean ``μ`` (the exact
model at the error means, Eq. 20, zero for zero-mean errors) and standard deviation
``σ_y² = Σ_i (∂y/∂x_i)² σ_i²`` (Eq. 20). The requirement is ``|y| < I``.

Two probabilities are reported:

* ``one_sided`` — the paper's ``P = Φ(β)`` with ``β = (I − |μ|)/σ`` (Eqs. 21–23). It counts
  only one tail of ``|y| > I`` and so overstates reliability: at β = 2.326 (the paper's 99 %)
  the true probability of ``|y| < I`` is 98 %.
* ``two_sided`` — the exact ``P(|y| < I) = Φ((I − μ)/σ) − Φ((−I − μ)/σ)`` for a normal
  output. It is the honest default for new designs.

An allocated tolerance ``t`` is read as ``±kσ`` (k = 3): ``σ = t/k``. Sampling that truncates the
normal at ``±t`` (Sec. 5.3) has a slightly smaller spread; ``distribution='truncated'`` uses that
standard deviation instead, and ``exact_two_sided`` is then the exact probability of the linearised
output under truncated errors (:mod:`reliability.first_order.linear_exact`), not the normal
approximation; under ``'normal'`` the two coincide.

The result, :class:`FosmResult`, gives its table (``to_frame``) and its verdicts for reading
(``summary``), and is saved as JSON with its metadata and reloaded with every field
verified (``save``/``load``, :mod:`reliability.basics.saved_results`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pandas as pd
from scipy.stats import norm

from ..basics import checks
from ..basics.chunks import chunks, jacobian_bytes
from ..basics.display import OUTPUT_UNITS, axis_units, output_limits_text, pose_columns
from ..basics.errors import InputError
from ..basics.saved_results import check_count, encode_frame, load_payload, save_payload
from ..basics.ties import worst_rows
from ..model.error_draws import DISTRIBUTIONS
from ..model.kinematics import check_frame, output_variance
from ..model.machine import OUTPUTS
from .linear_exact import linear_two_sided
from .output_covariance import correlated_sigma, euler_terms

SIDES = ("one_sided", "two_sided")
#: The format tag of a saved FOSM result (:mod:`reliability.basics.saved_results`).
SAVED_FORMAT = "precrel.fosm_result"
#: Relative tolerance within which a saved file's β and probabilities must follow from its
#: limits, μ and σ.
CONSISTENCY_RTOL = 1e-9


def error_sigma(tolerances, k: float = 3.0, distribution: str = "normal") -> np.ndarray:
    """Standard deviation of each error from its tolerance ``t = ±kσ``.

    Parameters
    ----------
    tolerances : array_like
        Positive tolerances.
    k : float
        Coverage factor; the paper's ±3σ reading is k = 3.
    distribution : {'normal', 'truncated'}
        'normal': σ = t/k. 'truncated': the standard deviation of N(0, (t/k)²) truncated at
        ±t, ``σ √(1 − 2kφ(k)/(2Φ(k) − 1))`` (0.9866 σ at k = 3).
    """
    k = checks.finite_float(k, "coverage factor k", 0.0, low_open=True)
    sigma = checks.numeric_array(tolerances, "tolerances") / k
    if distribution == "normal":
        return sigma
    if distribution == "truncated":
        mass = 2.0 * norm.cdf(k) - 1.0
        return sigma * np.sqrt(1.0 - 2.0 * k * norm.pdf(k) / mass)
    raise InputError(f"unknown distribution {distribution!r}; use 'normal' or 'truncated'")


def output_variance_terms(jacobian, sigma, correlation=None) -> np.ndarray:
    """Per-error terms ``(∂y/∂x_i)² σ_i²`` of Eq. (20), ``(..., 6, n_errors)``; with a
    correlation matrix, each error's Euler share
    (:func:`reliability.first_order.output_covariance.euler_terms`)."""
    if correlation is not None:
        return euler_terms(jacobian, sigma, correlation)
    return np.square(jacobian) * np.square(sigma)[..., None, :]


def output_sigma(jacobian, sigma, correlation=None) -> np.ndarray:
    """σ of each comprehensive error, Eq. (20): ``(..., 6, n) , (n,) -> (..., 6)``; with a
    correlation matrix ``R``, ``sqrt(jᵀ D R D j)`` (:mod:`reliability.model.correlation`)."""
    if correlation is not None:
        return correlated_sigma(jacobian, sigma, correlation)
    return np.sqrt(np.square(jacobian) @ np.square(sigma))  # Eq. (20)


def reliability_index(limit, sigma, mean=0.0) -> np.ndarray:
    """β = μ_g/σ_g with g = I − |y| (Eqs. 19, 21)."""
    return (limit - np.abs(mean)) / sigma  # Eq. (21)


def one_sided_probability(limit, sigma, mean=0.0) -> np.ndarray:
    """The paper's precision reliability P = Φ(β), Eqs. (22)–(23)."""
    return norm.cdf(reliability_index(limit, sigma, mean))  # Eq. (22)


def two_sided_probability(limit, sigma, mean=0.0) -> np.ndarray:
    """Exact ``P(|y| < I)`` for ``y ~ N(μ, σ²)``: ``Φ((I − μ)/σ) − Φ((−I − μ)/σ)``."""
    upper = norm.cdf((limit - mean) / sigma)
    lower = norm.cdf((-limit - mean) / sigma)
    return upper - lower


def two_sided_failure(limit, sigma, mean=0.0) -> np.ndarray:
    """``P(|y| ≥ I)`` for ``y ~ N(μ, σ²)``, accurate when it is tiny (no ``1 − P``)."""
    return norm.sf((limit - mean) / sigma) + norm.cdf((-limit - mean) / sigma)


def worst_poses(limits, sigma, mean, poses) -> np.ndarray:
    """Each output's worst pose, ``(6,)`` rows: the highest two-sided failure probability,
    ties (within :data:`reliability.basics.ties.TIE_RTOL`) broken by the first pose
    (:func:`reliability.basics.ties.worst_rows`)."""
    return worst_rows(two_sided_failure(limits, sigma, mean), poses)


def probability(limit, sigma, side: str = "two_sided", mean=0.0) -> np.ndarray:
    """The probability named by ``side``: :func:`one_sided_probability` (the paper's)
    or :func:`two_sided_probability` (exact)."""
    if side == "one_sided":
        return one_sided_probability(limit, sigma, mean)
    if side == "two_sided":
        return two_sided_probability(limit, sigma, mean)
    raise InputError(f"unknown side {side!r}; use 'one_sided' or 'two_sided'")


def required_index(target, side: str = "two_sided") -> np.ndarray:
    """β needed at zero mean for probability ``target``: ``Φ⁻¹(R)`` or ``Φ⁻¹((1 + R)/2)``."""
    target = np.asarray(target, dtype=float)
    if np.any(~((target > 0) & (target < 1))):
        raise InputError(f"target probabilities must lie in (0, 1); got {target}")
    if side == "one_sided":
        return norm.ppf(target)
    if side == "two_sided":
        return norm.ppf(0.5 * (1.0 + target))
    raise InputError(f"unknown side {side!r}; use 'one_sided' or 'two_sided'")


@dataclass(frozen=True)
class FosmResult:
    """FOSM reliability of one allocation over a pose set.

    Attributes
    ----------
    poses : ndarray (n_poses, n_axes)
    limits, targets : ndarray (6,)
    mean, sigma, beta : ndarray (n_poses, 6)
        Output mean, standard deviation and reliability index (Eqs. 20–21).
    one_sided, two_sided : ndarray (n_poses, 6)
        Φ(β) (Eq. 22) and P(|y| < I) for a normal output (the normal approximation).
    exact_two_sided : ndarray (n_poses, 6)
        The exact P(|y| < I) of the linearised output under the study's reading: equal to
        ``two_sided`` under ``'normal'``; under ``'truncated'`` the probability for a sum of
        truncated-normal terms (:func:`reliability.first_order.linear_exact.linear_two_sided`,
        exact to 1e-9).
    worst_pose : ndarray (6,) of int
        Per output, the pose of lowest two-sided probability.
    contributions : DataFrame (n_errors × 6)
        Percent of σ² contributed by each error at each output's worst pose. With
        correlated errors (``machine.correlation``) each error's Euler share
        ``a_i (R a)_i / σ²`` (``a = D j``), which may be negative for an error that partly
        cancels a correlated partner; the shares still add up to 100 %.
    axes, units : tuple of str
        Axis names and their units (``'mm'`` or ``'rad'``), for printing poses.
    machine : str
        Name of the machine.
    k : float
        Coverage factor the tolerances were read with (±kσ).
    distribution : str
        How σ followed from the tolerances (:func:`error_sigma`).
    frame : str
        ``"tool"`` (Eq. 18) or ``"workpiece"``: the frame the outputs are expressed in.

    ``summary()`` (and ``repr``) prints the verdicts with worst poses as axis positions;
    ``save(path)`` / ``FosmResult.load(path)`` keep the result as JSON.
    """

    poses: np.ndarray
    limits: np.ndarray
    targets: np.ndarray
    mean: np.ndarray
    sigma: np.ndarray
    beta: np.ndarray
    one_sided: np.ndarray
    two_sided: np.ndarray
    worst_pose: np.ndarray
    contributions: pd.DataFrame
    axes: tuple[str, ...] = ()
    units: tuple[str, ...] = ()
    machine: str = ""
    k: float = 3.0
    distribution: str = "normal"
    frame: str = "tool"
    exact_two_sided: np.ndarray | None = None

    def __post_init__(self):
        if self.exact_two_sided is None:
            if self.distribution != "normal":
                raise InputError("exact_two_sided is required under the 'truncated' reading")
            object.__setattr__(self, "exact_two_sided", self.two_sided)

    def summary(self, top: int = 3) -> str:
        """The verdict per output, the worst poses as axis positions and the ``top``
        contributors to σ² at each worst pose."""
        top = check_count(top, "top")
        meets = self.meets_targets("two_sided")
        short = [o for o, ok in zip(OUTPUTS, meets) if not ok]
        verdict = "every target met" if not short else f"short: {', '.join(short)}"
        name = f" of {self.machine}" if self.machine else ""
        lines = [f"FOSM reliability{name}: {len(self.poses)} poses, tolerances read as "
                 f"±{self.k:g}σ ({self.distribution}); outputs in the {self.frame} frame",
                 f"Worst pose, two-sided: {int(meets.sum())} of {len(OUTPUTS)} targets met; "
                 f"{verdict}", "", _verdict_table(self).to_string(), "",
                 "Worst pose of each output (axis positions)",
                 _worst_pose_table(self).to_string(), "",
                 "Largest contributors to σ² at the worst pose [% of σ²]"]
        for output in OUTPUTS:
            share = self.contributions[output].nlargest(top)
            lines.append(f"  {output}: " + ", ".join(f"{e} {p:.1f}" for e, p in share.items()))
        return "\n".join(lines)

    def __repr__(self) -> str:
        return self.summary()

    @staticmethod
    def reliability_fields(limits, sigma, mean) -> dict:
        """``beta``, ``one_sided`` and ``two_sided`` (Eqs. 21–22 and the exact
        probability) from the limits and the output means and σ, ``(n_poses, 6)`` each:
        how :func:`fosm` computes them and what a reloaded result is checked against."""
        return {"beta": reliability_index(limits, sigma, mean),
                "one_sided": one_sided_probability(limits, sigma, mean),
                "two_sided": two_sided_probability(limits, sigma, mean)}

    @staticmethod
    def worst_rows(limits, sigma, mean, poses) -> np.ndarray:
        """Each output's worst pose, ``(6,)`` rows: :func:`worst_poses` (how :func:`fosm`
        picks them and what a reloaded result is checked against)."""
        return worst_poses(limits, sigma, mean, poses)

    def save(self, path, overwrite: bool = False):
        """Save as JSON with its metadata (:mod:`reliability.basics.saved_results`); an
        existing file is kept unless ``overwrite``. Returns the path."""
        return save_payload(path, SAVED_FORMAT, self.payload(), overwrite)

    def payload(self) -> dict:
        """The JSON-ready fields :meth:`save` writes (also inside other saved results)."""
        return {"machine": self.machine, "axes": self.axes, "units": self.units,
                   "k": self.k, "distribution": self.distribution, "frame": self.frame,
                   "poses": self.poses,
                   "limits": self.limits, "targets": self.targets, "mean": self.mean,
                   "sigma": self.sigma, "beta": self.beta, "one_sided": self.one_sided,
                   "two_sided": self.two_sided, "exact_two_sided": self.exact_two_sided,
                   "worst_pose": self.worst_pose,
                   "contributions": encode_frame(self.contributions)}

    @classmethod
    def load(cls, path) -> "FosmResult":
        """Reload a result written by :meth:`save`; a damaged or inconsistent field raises
        :class:`~reliability.basics.errors.SavedResultError` naming the file and the field.

        The saved β and probabilities are checked against :meth:`reliability_fields` of the
        saved limits, means and σ, and the worst poses against :meth:`worst_rows`; under
        the normal reading ``exact_two_sided`` must equal ``two_sided``, and a file written
        before that field existed loads (the field is ``two_sided``) unless its reading was
        'truncated'.
        """
        return cls.from_payload(load_payload(path, SAVED_FORMAT))

    @classmethod
    def from_payload(cls, data) -> "FosmResult":
        """The result from the fields :meth:`payload` wrote, read through ``data`` (a
        :class:`~reliability.basics.saved_results.PayloadReader`), checked as
        :meth:`load` says."""
        axes = data.texts("axes", unique=True)
        units = data.texts("units", size=len(axes))
        for position, unit in enumerate(units):
            if unit not in ("mm", "rad"):
                raise data.error("units", f"entry {position} is {unit!r}; expected 'mm' or "
                                          f"'rad'")
        poses = data.array("poses", (None, len(axes)))
        n = len(poses)
        if n < 1:
            raise data.error("poses", "expected at least one pose")
        limits = data.array("limits", (6,), positive=True)
        targets = data.array("targets", (6,), low=0.0, high=1.0)
        mean = data.array("mean", (n, 6))
        sigma = data.array("sigma", (n, 6), positive=True)
        fields = {"beta": data.array("beta", (n, 6)),
                  "one_sided": data.array("one_sided", (n, 6), low=0.0, high=1.0),
                  "two_sided": data.array("two_sided", (n, 6), low=0.0, high=1.0)}
        _check_consistent(data, fields, cls.reliability_fields(limits, sigma, mean))
        worst = data.array("worst_pose", (6,), dtype=np.int64, low=0, high=n - 1)
        if not np.array_equal(worst, cls.worst_rows(limits, sigma, mean, poses)):
            raise data.error("worst_pose", "is not the pose of lowest two-sided probability "
                                           "(first pose among ties)")
        contributions = data.frame("contributions", columns=OUTPUTS)
        _check_contributions(data, contributions)
        distribution = data.text("distribution", ("normal", "truncated"))
        fields["exact_two_sided"] = _saved_exact_two_sided(data, distribution,
                                                           fields["two_sided"])
        return cls(poses=poses, limits=limits, targets=targets, mean=mean, sigma=sigma,
                   worst_pose=worst, contributions=contributions, axes=axes, units=units,
                   machine=data.text("machine"), k=data.number("k", positive=True),
                   distribution=distribution,
                   frame=data.text("frame", ("tool", "workpiece")) if "frame" in data.data
                   else "tool", **fields)

    def worst(self, side: str = "two_sided") -> np.ndarray:
        """Lowest probability over the poses, per output (the workspace constraint)."""
        return self._probability(side).min(axis=0)

    def workspace_mean(self, side: str = "two_sided") -> np.ndarray:
        """Mean probability over the poses, per output (expected share in tolerance)."""
        return self._probability(side).mean(axis=0)

    def meets_targets(self, side: str = "two_sided", workspace: str = "worst") -> np.ndarray:
        """Whether each output meets its target, worst case or on the workspace mean."""
        if workspace not in ("worst", "mean"):
            raise InputError(f"unknown workspace criterion {workspace!r}; use 'worst' or 'mean'")
        value = self.worst(side) if workspace == "worst" else self.workspace_mean(side)
        return value >= self.targets

    def to_frame(self) -> pd.DataFrame:
        """One row per output: limit, target, worst pose, σ, β, probabilities, verdicts."""
        rows = np.arange(len(OUTPUTS))
        worst = self.worst_pose
        frame = pd.DataFrame({
            "limit": self.limits,
            "target": self.targets,
            "worst_pose": worst,
            "sigma": self.sigma[worst, rows],
            "beta": self.beta[worst, rows],
            "worst_one_sided": self.worst("one_sided"),
            "worst_two_sided": self.worst("two_sided"),
            "exact_two_sided": self.exact_two_sided[worst, rows],
            "mean_one_sided": self.workspace_mean("one_sided"),
            "mean_two_sided": self.workspace_mean("two_sided"),
            "meets_one_sided": self.meets_targets("one_sided"),
            "meets_two_sided": self.meets_targets("two_sided"),
        }, index=pd.Index(OUTPUTS, name="output"))
        return frame

    def _probability(self, side: str) -> np.ndarray:
        if side not in SIDES:
            raise InputError(f"unknown side {side!r}; use 'one_sided' or 'two_sided'")
        return getattr(self, side)


# ----- the result printed and saved -------------------------------------------------
def _verdict_table(result) -> pd.DataFrame:
    """Per output: limit, target, worst and mean probabilities, β and σ at the worst pose
    and the verdict, as printed."""
    rows = np.arange(len(OUTPUTS))
    worst = result.worst_pose
    sigma = [f"{s:.4g} {u}" for s, u in zip(result.sigma[worst, rows], OUTPUT_UNITS)]
    exact = {} if result.distribution == "normal" else \
        {"P worst exact linear": result.exact_two_sided.min(axis=0).round(6)}
    return pd.DataFrame({
        "limit": output_limits_text(result.limits),
        "target": result.targets,
        "P worst 2-sided": result.worst("two_sided").round(6),
        "P worst 1-sided": result.worst("one_sided").round(6),
        **exact,
        "P mean 2-sided": result.workspace_mean("two_sided").round(6),
        "β at worst": result.beta[worst, rows].round(3),
        "σ at worst": sigma,
        "meets (2-sided)": np.where(result.meets_targets("two_sided"), "yes", "NO"),
    }, index=pd.Index(OUTPUTS, name="output"))


def _worst_pose_table(result) -> pd.DataFrame:
    """Each output's worst pose as its row number and axis positions with units."""
    axes = result.axes or tuple(f"q{i}" for i in range(result.poses.shape[1]))
    units = result.units or ("",) * len(axes)
    table = pose_columns(result.poses[result.worst_pose], axes, units)
    table.insert(0, "pose #", result.worst_pose)
    table.index = pd.Index(OUTPUTS, name="output")
    return table


def _saved_exact_two_sided(data, distribution: str, two_sided: np.ndarray) -> np.ndarray:
    """The saved exact linear probability; ``two_sided`` itself under the normal reading
    (where it is the exact value), also for files written before the field existed."""
    if "exact_two_sided" not in data.data:
        if distribution == "truncated":
            raise data.error("exact_two_sided", "missing (a file of the 'truncated' reading "
                                                "written before the field existed; recompute "
                                                "the result)")
        return two_sided
    exact = data.array("exact_two_sided", two_sided.shape, low=0.0, high=1.0)
    if distribution == "normal" and not np.array_equal(exact, two_sided):
        raise data.error("exact_two_sided", "differs from two_sided under the normal reading")
    return exact


def _check_consistent(data, fields, expected) -> None:
    """β and both probabilities must be what limits, μ and σ give (Eqs. 21–22)."""
    for key in expected:
        if not np.allclose(fields[key], expected[key], rtol=CONSISTENCY_RTOL, atol=0):
            first = np.argwhere(~np.isclose(fields[key], expected[key],
                                            rtol=CONSISTENCY_RTOL, atol=0))[0]
            raise data.error(key, f"entry {first.tolist()} does not follow from the saved "
                                  f"limits, mean and sigma")


def _check_contributions(data, frame: pd.DataFrame) -> None:
    """The saved contributions must be shares (>= 0) of each output summing to 100 %."""
    values = frame[list(OUTPUTS)]
    try:
        numbers = values.to_numpy(dtype=float)
    except (TypeError, ValueError):
        raise data.error("contributions", "expected numbers") from None
    if not (np.isfinite(numbers).all() and (numbers >= 0).all()
            and np.allclose(numbers.sum(axis=0), 100.0, rtol=1e-9)):
        raise data.error("contributions", "each output's column must be shares "
                                          "(>= 0) summing to 100 %")
    if len(set(frame.index)) != len(frame.index):
        raise data.error("contributions", "error names repeat")


def fosm(machine, tolerances, poses, *, k: float = 3.0, means=None,
         distribution: str = "normal", jacobian=None, allow_outside_stroke: bool = False,
         budget: int | None = None, memory: int | None = None,
         frame: str | None = None) -> FosmResult:
    """FOSM precision reliability of an allocation over a pose set (Eqs. 19–23).

    Parameters
    ----------
    machine : Machine
    tolerances : array_like, pandas.Series or mapping
        ``(n_errors,)`` allocated tolerances, read as ±kσ; a Series or mapping is
        aligned by error name.
    poses : array_like
        ``(n_poses, n_axes)`` positions, e.g. :func:`reliability.model.poses.workspace_grid`.
    k : float
        Coverage factor of the tolerances (3 in the paper).
    means : array_like, optional
        ``(n_errors,)`` error means, or ``(n_poses, n_errors)`` means that vary with the pose (e.g.
        measured profiles, :meth:`reliability.model.measured_profiles.SystematicErrors.means`);
        zero by default. The output mean is the exact model evaluated at the error means (Eq. 20).
        σ uses the sensitivities at zero error; the paper takes them at the means, which differs
        only at second order.
    distribution : {'normal', 'truncated'}
        How σ follows from t, see :func:`error_sigma`; under 'truncated' the result also
        holds the exact probability of the linearised output (``exact_two_sided``), which
        needs independent errors.
    jacobian : ndarray, optional
        Precomputed ``machine.jacobian(poses)`` to reuse across allocations.
    allow_outside_stroke : bool
        Evaluate poses outside an axis' stroke (extrapolation); refused by default.
    budget : int, optional
        Bytes the per-pose results may take (default
        :data:`reliability.basics.checks.DEFAULT_BUDGET`), checked before any work.
    memory : int, optional
        Bytes of temporary arrays allowed (:data:`reliability.basics.chunks.MEMORY_BUDGET` by
        default): the poses are processed in chunks, so only the per-pose results
        ``(n_poses, 6)`` are ever held whole, never the Jacobian of all poses.

    frame : {'tool', 'workpiece'}, optional
        Frame of the outputs; default ``machine.frame`` (the machine file's
        ``[requirements] frame``, else ``"tool"``, Eq. 18). A given ``jacobian`` must be in
        that frame.

    Returns
    -------
    FosmResult
    """
    if frame is not None:
        machine = replace(machine, frame=check_frame(frame))
    t = machine.check_tolerances(tolerances)
    if t.ndim != 1:
        raise InputError(f"tolerances must be one allocation of shape ({machine.n_errors},)")
    poses = np.atleast_2d(machine.check_positions(poses))
    if poses.ndim != 2 or len(poses) == 0:
        raise InputError(f"poses must have shape (n_poses, {len(machine.axes)}) with at least "
                         f"one pose; got {poses.shape}")
    checks.poses_in_strokes(machine, poses, "poses", allow_outside_stroke)
    checks.finite_float(k, "coverage factor k", 0.0, low_open=True)
    checks.choice(distribution, "distribution", DISTRIBUTIONS)
    if distribution == "truncated" and machine.correlation is not None:
        raise InputError("distribution='truncated': the exact linear probability of "
                         "truncated-normal errors assumes independent errors, but this "
                         "machine's errors are correlated (machine.correlation); use "
                         "distribution='normal'")
    checks.require_size(len(poses), 6 * 6 * 8, budget,
                        "the FOSM results (mean, σ, β and probabilities per pose and output)",
                        "evaluate fewer poses per call (split the pose set into chunks)")
    if jacobian is not None:
        jacobian = np.asarray(jacobian, dtype=float)
        if jacobian.shape != poses.shape[:-1] + (6, machine.n_errors):
            raise InputError(f"jacobian must have shape "
                             f"{poses.shape[:-1] + (6, machine.n_errors)}; got {jacobian.shape}")
    error_means = None if means is None else machine.check_errors(means)
    sigma_x = error_sigma(t, k, distribution)
    sigma = pose_sigma(machine, poses, sigma_x, jacobian=jacobian, memory=memory)
    mean = np.zeros_like(sigma)
    if error_means is not None:
        for part in chunks(len(poses), jacobian_bytes(machine), memory):
            part_means = error_means if error_means.ndim == 1 else error_means[part]
            mean[part] = machine.comprehensive_error(poses[part], part_means)  # Eq. (20)
    fields = FosmResult.reliability_fields(machine.limits, sigma, mean)
    if distribution == "truncated":
        fields["exact_two_sided"] = exact_linear_two_sided(
            machine, poses, t, k, mean, jacobian=jacobian, memory=memory)
    worst = worst_poses(machine.limits, sigma, mean, poses)
    rows = np.arange(len(OUTPUTS))
    worst_jacobian = machine.jacobian(poses[worst]) if jacobian is None else jacobian[worst]
    return FosmResult(
        poses=poses, limits=machine.limits, targets=machine.targets, mean=mean, sigma=sigma,
        worst_pose=worst,
        contributions=_contributions(machine, worst_jacobian[rows, rows], sigma_x),
        axes=machine.axes, units=axis_units(machine), machine=machine.name, k=float(k),
        distribution=distribution, frame=machine.frame, **fields,
    )


def pose_sigma(machine, poses, sigma_x, *, jacobian=None, memory: int | None = None
               ) -> np.ndarray:
    """σ of every output at every pose, Eq. (20), in chunks of poses: ``(n_poses, 6)``.

    With correlated errors (``machine.correlation``) σ² = jᵀ D R D j.

    Parameters
    ----------
    machine : Machine
    poses : ndarray (n_poses, n_axes)
    sigma_x : ndarray (n_errors,)
        Standard deviation of each error.
    jacobian : ndarray (n_poses, 6, n_errors), optional
        Precomputed sensitivities; computed chunk by chunk otherwise.
    memory : int, optional
        Bytes of temporary arrays per chunk.
    """
    correlation = machine.correlation
    variance_x = np.square(sigma_x)
    sigma = np.empty((len(poses), len(OUTPUTS)))
    for part in chunks(len(poses), jacobian_bytes(machine), memory):
        if correlation is not None:
            part_jacobian = machine.jacobian(poses[part]) if jacobian is None else jacobian[part]
            sigma[part] = output_sigma(part_jacobian, sigma_x, correlation)
        elif jacobian is None:
            sigma[part] = np.sqrt(output_variance(machine, poses[part], variance_x,
                                                  machine.frame))
        else:
            sigma[part] = np.sqrt(np.square(jacobian[part]) @ variance_x)  # Eq. (20)
    return sigma


def exact_linear_two_sided(machine, poses, tolerances, k, mean, *, jacobian=None,
                           memory: int | None = None) -> np.ndarray:
    """Exact ``P(|μ + Σ_i J_oi x_i| < I_o)`` at every pose for independent errors
    ``x_i`` ~ N(0, (t_i/k)²) truncated at ±t_i, ``(n_poses, 6)``
    (:func:`reliability.first_order.linear_exact.linear_two_sided`), in chunks of poses."""
    scale_x = np.asarray(tolerances, dtype=float) / k  # the untruncated σ of each error
    out = np.empty((len(poses), len(OUTPUTS)))
    for part in chunks(len(poses), jacobian_bytes(machine), memory):
        part_jacobian = machine.jacobian(poses[part]) if jacobian is None else jacobian[part]
        out[part] = linear_two_sided(machine.limits, np.abs(part_jacobian) * scale_x, k=k,
                                     mean=mean[part], memory=memory)
    return out


def _contributions(machine, worst_rows, sigma_x) -> pd.DataFrame:
    """Percent of σ² from each error at each output's worst pose (Eq. 20's terms), from
    the Jacobian row of each output at its worst pose, ``(6, n_errors)``."""
    terms = output_variance_terms(worst_rows, sigma_x, machine.correlation)  # (6, n_errors)
    percent = 100.0 * terms / terms.sum(axis=-1, keepdims=True)
    return pd.DataFrame(percent.T, index=pd.Index(machine.error_names, name="error"),
                        columns=pd.Index(OUTPUTS, name="output"))
