"""Report section "Component choice": the certified cheapest choice of catalogue classes.

Made from an :class:`allocation.CatalogueResult` (:func:`allocation.solve_catalogue`): the
chosen class of each component with its price, the total price and the proved relative
gap, what binds, each component's one-class neighbours, the worst load per output, and
crude Monte-Carlo on the exact model at each output's worst pose at the choice
(:func:`reliability.sampling.pose_sampling.sample_at_poses`).
"""

from __future__ import annotations

import pandas as pd

from allocation.catalogue.discrete import neighbour_table
from allocation.per_pose.result_files import allocation_frame

from reliability.basics.display import axis_units, pose_text
from reliability.basics.files import SIGNIFICANT
from reliability.model.machine import OUTPUTS
from reliability.sampling.pose_sampling import sample_at_poses

from .markdown import details, interval_formats, markdown_table, percent_bound
from .section import Section

PERCENT = "{:.3%}".format
TITLE = "Component choice"


def catalogue_section(result, *, samples: int = 20_000, rng=None,
                      start_text: str = "the starting allocation") -> Section:
    """The "Component choice" section of ``result`` (a :class:`CatalogueResult`).

    Parameters
    ----------
    result : CatalogueResult
    samples : int
        Monte-Carlo samples at each output's worst grid pose (normal errors, σ = t/k).
    rng : None, int or numpy.random.Generator
        Stream of the Monte-Carlo.
    start_text : str
        Where the tolerances of the items in no component come from, in words.
    """
    catalogue, problem = result.catalogue, result.problem
    currency = f" {catalogue.currency}" if catalogue.currency else ""
    choice = result.to_frame()
    worst = result.worst.reset_index()
    binding = result.binding()
    answer = (f"The cheapest choice of catalogue classes that meets every target at every "
              f"grid pose costs **{result.price:.6g}{currency}** in total, proved within a "
              f"relative gap of {result.gap:.1e}"
              f"{'' if result.feasible else ', but its re-check is ABOVE 1: NOT FEASIBLE'}.")
    method = (f"One class per component of the catalogue ({len(catalogue.components)} "
              f"components, {catalogue.n_choices:,} possible choices), meeting every target "
              f"at every one of {len(problem.poses)} poses (workspace 'grid': a choice of "
              f"classes is made on the grid poses only; {problem.side.replace('_', '-')} "
              f"reading, tolerances ±{problem.k:g}σ). Items in no component keep "
              f"{start_text}; classes are used as given (no search box). Solved by HiGHS "
              f"(scipy.optimize.milp) to a proved relative gap of {result.gap:.1e} (dual "
              f"bound {result.dual_bound:.6g}), re-checked on every row (largest load "
              f"{result.details['max_load']:.6f}).")
    text = [answer, "", markdown_table(choice, index=False), "",
            details("How the choice is found", method), ""]
    if len(binding):
        text += ["What binds: the requirements that forbid loosening a component by one "
                 "class (load = σ² over the σ² the target allows, at the choice).", "",
                 markdown_table(binding, {"worst_load": "{:.4f}".format}, index=False), ""]
    else:
        text += ["What binds: no requirement forbids loosening any component by one "
                 "class.", ""]
    text += ["Moving one component by one class with the others held: the change of the "
             "total price, or the requirement it breaks (and where).", "",
             markdown_table(neighbour_table(result), index=False), "",
             "Worst pose of each output at the choice (ratio: σ over the σ the target "
             "allows; for the stack, the stack over the limit).", "",
             markdown_table(worst, {"load": "{:.4f}".format, "ratio": "{:.4f}".format},
                            index=False), ""]
    checked = _monte_carlo(result, samples, rng)
    short = checked.loc[checked["upper"] < checked["target"], "output"].tolist()
    text += [f"Crude Monte-Carlo on the exact model at each output's worst pose above, "
             f"{samples} normal error draws per pose (σ = t/{problem.k:g}), 95 % Wilson "
             f"interval on the probability of staying inside the limit, beside FOSM: "
             + (f"**below the target for {', '.join(short)}**." if short else
                "every interval reaches the target."), "",
             markdown_table(checked, {c: PERCENT for c in ("mc", "fosm", "target")}
                            | interval_formats(percent_bound(3), lower=("lower",),
                                               upper=("upper",)), index=False)]
    summary = {"catalogue": {"price": result.price, "relative_gap": result.gap,
                             "certified": result.certified, "feasible": result.feasible,
                             "choice": dict(result.choice), "currency": catalogue.currency,
                             "worst_pose_mc": dict(zip(checked["output"], checked["mc"]))}}
    return Section(title=TITLE, text="\n".join(text),
                   tables={"choice.csv": choice,
                           "choice_tolerances.csv": allocation_frame(result, SIGNIFICANT),
                           "choice_neighbours.csv": result.neighbours,
                           "choice_worst_poses.csv": worst, "choice_worst_pose_mc.csv": checked},
                   summary=summary)


def _monte_carlo(result, samples, rng):
    """Per output at its worst pose at the choice (among the problem's poses): MC
    probability of staying inside, its interval, FOSM and the target."""
    problem = result.problem
    poses = problem.poses[result.worst["pose"].to_numpy()]
    frame = sample_at_poses(problem.machine, result.tolerances, poses, samples=samples,
                            rng=rng, k=problem.k, distribution="normal").to_frame()
    own = [f"pose {i}" for i in range(len(OUTPUTS))]
    frame = frame[frame["pose"].map(dict(zip(own, OUTPUTS))) == frame["event"]]
    machine = problem.machine
    positions = [pose_text(pose, machine.axes, axis_units(machine), digits=6) for pose in poses]
    return pd.DataFrame({
        "output": frame["event"].to_numpy(), "worst pose": positions,
        "samples": frame["samples"].to_numpy(), "mc": 1.0 - frame["mc_failure"].to_numpy(),
        "lower": 1.0 - frame["upper"].to_numpy(), "upper": 1.0 - frame["lower"].to_numpy(),
        "fosm": 1.0 - frame["fosm_failure"].to_numpy(), "target": problem.machine.targets})
