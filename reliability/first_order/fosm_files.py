"""A FOSM result printed for reading, saved as JSON and reloaded with every field verified.

The functions take the result (:class:`reliability.first_order.fosm.FosmResult`) or, to reload one,
its class, so this module sits below :mod:`reliability.first_order.fosm` and does not import it.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..basics.display import OUTPUT_UNITS, output_limits_text, pose_columns
from ..model.machine import OUTPUTS
from ..basics.saved_results import check_count, encode_frame, load_payload, save_payload

KIND = "precrel.fosm_result"
CONSISTENCY_RTOL = 1e-9  # saved β and probabilities must follow from limits, μ and σ


def fosm_summary(result, top: int = 3) -> str:
    """The verdict per output, the worst poses as axis positions, the top contributors."""
    top = check_count(top, "top")
    meets = result.meets_targets("two_sided")
    short = [o for o, ok in zip(OUTPUTS, meets) if not ok]
    verdict = "every target met" if not short else f"short: {', '.join(short)}"
    name = f" of {result.machine}" if result.machine else ""
    lines = [f"FOSM reliability{name}: {len(result.poses)} poses, tolerances read as "
             f"±{result.k:g}σ ({result.distribution}); outputs in the {result.frame} frame",
             f"Worst pose, two-sided: {int(meets.sum())} of {len(OUTPUTS)} targets met; "
             f"{verdict}", "", _verdict_table(result).to_string(), "",
             "Worst pose of each output (axis positions)",
             _worst_pose_table(result).to_string(), "",
             "Largest contributors to σ² at the worst pose [% of σ²]"]
    for output in OUTPUTS:
        share = result.contributions[output].nlargest(top)
        lines.append(f"  {output}: " + ", ".join(f"{e} {p:.1f}" for e, p in share.items()))
    return "\n".join(lines)


def _verdict_table(result) -> pd.DataFrame:
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
    axes = result.axes or tuple(f"q{i}" for i in range(result.poses.shape[1]))
    units = result.units or ("",) * len(axes)
    table = pose_columns(result.poses[result.worst_pose], axes, units)
    table.insert(0, "pose #", result.worst_pose)
    table.index = pd.Index(OUTPUTS, name="output")
    return table


def save_fosm(result, path, overwrite: bool = False):
    """Write ``result`` as JSON (see :mod:`reliability.basics.saved_results`)."""
    payload = {"machine": result.machine, "axes": result.axes, "units": result.units,
               "k": result.k, "distribution": result.distribution, "frame": result.frame,
               "poses": result.poses,
               "limits": result.limits, "targets": result.targets, "mean": result.mean,
               "sigma": result.sigma, "beta": result.beta, "one_sided": result.one_sided,
               "two_sided": result.two_sided, "exact_two_sided": result.exact_two_sided,
               "worst_pose": result.worst_pose,
               "contributions": encode_frame(result.contributions)}
    return save_payload(path, KIND, payload, overwrite)


def load_fosm(cls, path):
    """Reload a file written by :func:`save_fosm` as ``cls`` (a
    :class:`~reliability.first_order.fosm.FosmResult`); a damaged or inconsistent field raises
    :class:`~reliability.basics.errors.SavedResultError` naming the file and the field.

    The saved β and probabilities are checked against ``cls.reliability_fields`` of the
    saved limits, means and σ; under the normal reading ``exact_two_sided`` must equal
    ``two_sided``, and a file written before that field existed loads (the field is
    ``two_sided``) unless its reading was 'truncated'.
    """
    data = load_payload(path, KIND)
    axes = data.texts("axes", unique=True)
    units = data.texts("units", size=len(axes))
    for position, unit in enumerate(units):
        if unit not in ("mm", "rad"):
            raise data.error("units", f"entry {position} is {unit!r}; expected 'mm' or 'rad'")
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
    fields["exact_two_sided"] = _exact_two_sided(data, distribution, fields["two_sided"])
    return cls(poses=poses, limits=limits, targets=targets, mean=mean, sigma=sigma,
               worst_pose=worst, contributions=contributions, axes=axes, units=units,
               machine=data.text("machine"), k=data.number("k", positive=True),
               distribution=distribution,
               frame=data.text("frame", ("tool", "workpiece")) if "frame" in data.data
               else "tool", **fields)


def _exact_two_sided(data, distribution: str, two_sided: np.ndarray) -> np.ndarray:
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
