"""The bracket of an allocation for a machine yield, in words: one lower bound and one gap
by default, every other bound and stage on request (``verbose``).

The lower bound printed is the best the result has
(:attr:`~allocation.machine_yield.yield_target.YieldAllocation.lower_bound`): the log-concave
bound at 95 % confidence where the theorem holds, else the certified pose-chain (or row)
bound, with why the log-concave one is missing. The gap is the verified cost minus that
bound, over the verified cost (the design margin the verification needs included).
"""

from __future__ import annotations

from reliability.basics.display import interval_text, percentage_text
from reliability.model.machine import OUTPUTS
from reliability.sampling.radial_yield import CONTROLLED_METHOD

from ..per_pose.problem import DEFAULT_FACTORS
from .yield_controlled import DESIGN_Z, RAYS_FACTOR

#: What each kind of lower bound rests on.
BOUND_KINDS = {
    "log-concave": "log-concave bound: the yield is log-concave in the log-tolerances; it "
                   "assumes the linearised outputs, the normal reading and independent "
                   "errors, each scaled along travel by its own tolerance",
    "pose chain": "pose-chain bound: the six outputs' joint event at each pose, bounded "
                  "through their fresh errors; FOSM two-sided on the linearised outputs",
    "row": "row bound: every (output, pose) row at the yield's probability alone; FOSM "
           "two-sided on the linearised outputs"}


def finding_lines(result, verbose: bool = False) -> list[str]:
    """The bound, the cost with the stage that gave it, the gap, the calibration, the
    verified yield and the naive method, one line each; with ``verbose`` also every other
    bound and every stage's cost."""
    lines = [bound_line(result), cost_line(result), gap_line(result),
             calibration_text(result), verified_line(result), naive_line(result)]
    return lines + (verbose_lines(result) if verbose else [])


def bound_line(result) -> str:
    """The one lower bound: its value, confidence and what it assumes."""
    initial = result.initial_cost
    kind = result.lower_bound_kind
    value = percentage_text(result.lower_bound / initial, bound="lower")
    if kind == "log-concave":
        bound = result.log_concave
        return (f"lower bound {value} of the initial cost at "
                f"{result.lower_bound_confidence:.0%} confidence ({BOUND_KINDS[kind]}; "
                f"profile {result.profile}; {bound.machines:,} {bound.sample or 'rays'})")
    refused = f"; the log-concave bound: {result.log_concave_text}" \
        if result.log_concave_text else ""
    return f"lower bound {value} of the initial cost, certified ({BOUND_KINDS[kind]}{refused})"


def cost_line(result) -> str:
    """The cost and the stage that gave it."""
    initial = result.initial_cost
    return (f"cost {result.cost:.6g} = {percentage_text(result.cost / initial)} of the initial "
            f"allocation ({initial:.6g}), found by the {result.method} stage"
            f"{narrower_box_text(result)}: the cheapest found by this search; not "
            f"certified: see the lower bound")


def gap_line(result) -> str:
    """The one gap, over the verified cost and over the initial cost."""
    return (f"gap {percentage_text(result.gap_of_cost, bound='upper')} of the verified cost "
            f"({percentage_text(result.gap / result.initial_cost, bound='upper')} of the "
            f"initial cost), the design margin included")


def target_words(result) -> str:
    """What the calibration aimed at, in words."""
    c = result.calibration_yield
    if c.method == CONTROLLED_METHOD:
        return (f"yield {result.yield_target:g} plus {DESIGN_Z:.2f} standard errors of the "
                f"radial control variate on {c.n:,} fresh calibration machines and "
                f"{RAYS_FACTOR * c.n:,} rays")
    return (f"the design yield {result.design_yield_target:.4f} on {c.n:,} fresh calibration "
            f"machines")


def calibration_text(result) -> str:
    """How the search's allocation (or the naive start's, or the convex step's) became the
    result, in words."""
    initial = result.initial_cost
    c = result.calibration_yield
    there = f"yield {c.estimate:.4f} there"
    search = (f"the search ended at {percentage_text(result.search_cost / initial)} of the "
              f"initial cost (yield {result.design_yield.estimate:.4f} on its "
              f"{result.design_yield.n:,} design machines)")
    if result.method == "convex step":
        return (f"{search}; the convex steps from it ended at "
                f"{percentage_text(result.convex_step_cost / initial)}, scaled to "
                f"{target_words(result)}: the result ({there})")
    if result.method == "naive start":
        scaled = percentage_text(result.search_calibrated_cost / initial)
        return (f"{search}, {scaled} once scaled to {target_words(result)}: dearer than the "
                f"naive start scaled the same way, which is the result ({there})")
    if not result.calibrated:
        return (f"{search}; no scale inside the box reaches {target_words(result)} ({there}): "
                f"kept as it is")
    return f"{search}, scaled to {target_words(result)} ({there})"


def verified_line(result) -> str:
    """The verified yield, its interval and how it was estimated."""
    v = result.verified_yield
    verdict = "verified" if result.verified else \
        "NOT verified: the interval reaches below the target"
    if v.method == CONTROLLED_METHOD:
        how = (f"95% interval estimate ± 1.96 standard errors {interval_text(v.lower, v.upper)}"
               f" (radial control variate, clipped to [0, 1]) from {v.n:,} fresh built "
               f"machines on the exact chain and {RAYS_FACTOR * v.n:,} fresh rays")
    else:
        how = (f"95% Clopper-Pearson {interval_text(v.lower, v.upper)} from {v.n:,} fresh "
               f"built machines")
    return f"verified yield {v.estimate:.4f}, {how}: {verdict}"


def naive_line(result) -> str:
    """The naive method beside the result."""
    n = result.naive.verified_yield
    return (f"naive method ({result.naive.text()}, calibrated the same way): cost "
            f"{percentage_text(result.naive.cost / result.initial_cost)} of the initial "
            f"allocation, verified yield {n.estimate:.4f} {interval_text(n.lower, n.upper)} "
            f"from {n.n:,} machines")


def verbose_lines(result) -> list[str]:
    """Every bound and every stage's cost."""
    initial = result.initial_cost
    row = percentage_text(result.row_bound / initial, bound="lower")
    lines = [f"certified bounds: {BOUND_KINDS['row']}: {row}"]
    if result.chain_bound is not None:
        chain = percentage_text(result.chain_bound.bound / initial, bound="lower")
        lines.append(f"certified bounds: {BOUND_KINDS['pose chain']}: {chain}")
    if result.log_concave is not None:
        lines.append(f"log-concave {result.log_concave.text(initial)}")
    else:
        lines.append(f"log-concave bound: {result.log_concave_text}")
    stages = [f"{result.search_stage} {percentage_text(result.search_cost / initial)} "
              f"({percentage_text(result.search_calibrated_cost / initial)} calibrated)",
              f"naive start {percentage_text(result.naive.search_cost / initial)} "
              f"({percentage_text(result.naive.cost / initial)} calibrated)"]
    if result.convex_step_cost is not None:
        stages.append(f"convex step {percentage_text(result.convex_step_cost / initial)} "
                      f"({percentage_text(result.convex_step_calibrated_cost / initial)} "
                      f"calibrated)")
    targets = ", ".join(f"{name} {target:.6g}" for name, target
                        in zip(OUTPUTS, result.output_targets))
    return lines + [f"stages: {'; '.join(stages)}",
                    f"convex steps: {result.convex_step_text}",
                    f"per-output per-pose targets of the first stage: {targets}"]


def narrower_box_text(result) -> str:
    """Where the search that gave the allocation ran, when not in the box asked for."""
    if not result.from_narrower_box:
        return ""
    low, high = DEFAULT_FACTORS
    return (f" of the search in this box intersected with the default factor box "
            f"[{low:g}, {high:g}] × the initial allocation "
            f"({result.search_problem.box_text()}), cheaper than this box's own search")
