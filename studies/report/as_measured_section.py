"""The report's "As measured" section: this machine's reliability given what was measured
(:func:`studies.workflows.as_measured.as_measured`), beside the design-time numbers of the
study.

The posterior is judged at the study's grid and at the worst poses of the study's
verification of the allocation the identification's prior came from (certified over the
continuous workspace under the default workspace); that verification's machine yield stands
beside it. An identification whose prior is neither the initial nor the optimal allocation
is judged at the initial allocation's worst poses, without a design-time yield.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from reliability.basics.streams import extra_stream
from studies.workflows.as_measured import (AS_MEASURED_STREAM, acceptance_table, as_measured,
                                           holds_text, output_table)

from .markdown import details, markdown_table
from .section import Section

TITLE = "As measured"


def as_measured_builder(identification, tests=None, *, source: str):
    """The builder of the section for ``identification`` (read from ``source``, named in
    the text), with ``tests`` predicted for this machine when given."""
    def build(study):
        label = prior_allocation(study, identification)
        check = study.checks[label or "initial"]
        result = as_measured(study.machine, identification, points=study.points,
                             poses=check.worst_poses[list(study.machine.axes)].to_numpy(
                                 dtype=float),
                             draws=study.machines, tests=tests,
                             design_yield=None if label is None else check.machine_yield,
                             rng=extra_stream(study.seed, AS_MEASURED_STREAM))
        return as_measured_section(result, source=source, label=label)
    return build


def prior_allocation(study, identification) -> str | None:
    """The study's allocation (``initial``, ``optimum`` or ``given``) the identification's
    prior σ is a third of, or None."""
    shown = {"initial": study.machine.initial_allocation}
    if study.compared is not None:
        name, tolerances = study.compared
        shown[name] = tolerances
    prior = 3.0 * identification.coefficients.prior_sd
    for label, tolerances in shown.items():
        if prior.shape == np.shape(tolerances) and np.allclose(prior, tolerances, rtol=1e-5,
                                                                atol=0.0):
            return label
    return None


def as_measured_section(result, *, source: str, label: str | None) -> Section:
    """The section of an :class:`~studies.workflows.as_measured.AsMeasured`."""
    design = (f"the {label} allocation" if label is not None else
              "its own allocation (t = 3 × prior σ; neither the initial nor the optimal one)")
    method = (
        f"This machine, identified from {source}: {result.draws} machines drawn from the "
        f"posterior of its errors, each evaluated on the exact chain at the "
        f"{result.workspace} (the further poses: each output's worst pose of the study's "
        f"verification), outputs in the {result.machine.frame} frame. The identification's "
        f"prior is {design}; the design-time numbers beside are of it.")
    parts = [
        f"**Probability that this machine holds every limit at every pose: "
        f"{holds_text(result.holds)}** (Clopper–Pearson 95 %)"
        + ("" if result.design_yield is None else
           f"; the design-time machine yield of {design}: "
           f"{holds_text(result.design_yield.to_dict())}."),
        details("How this machine is judged", method),
        "Per output: the share of posterior machines within the limit at every pose, this "
        "machine's worst pose (the largest failure probability from the posterior mean and "
        "σ there) and the share inside there, beside the design's worst pose and its FOSM "
        "two-sided probability:",
        markdown_table(output_table(result), index=False)]
    tables = {"as_measured_outputs.csv": _outputs_frame(result)}
    if result.acceptance is not None:
        parts += ["Each acceptance test's predicted result for this machine (mean and 5–95 % "
                  "of the posterior machines, first-order tool-point deviation as in the "
                  "acceptance section) and its pass probability, beside machines built to "
                  "the allocation (Wilson 95 %):",
                  markdown_table(acceptance_table(result.acceptance), index=False)]
        tables["as_measured_acceptance.csv"] = result.acceptance
    return Section(TITLE, "\n\n".join(parts), tables=tables,
                   summary={"as_measured": result.summary_dict()})


def _outputs_frame(result) -> pd.DataFrame:
    """The per-output table with each pose spread into its axes' columns."""
    frame = result.outputs.drop(columns=["worst_pose", "design_pose"])
    axes = list(result.machine.axes)
    worst = pd.DataFrame(np.stack(result.outputs["worst_pose"]), index=frame.index,
                         columns=[f"worst_{a}" for a in axes])
    design = pd.DataFrame(np.stack(result.outputs["design_pose"]), index=frame.index,
                          columns=[f"design_{a}" for a in axes])
    return pd.concat([frame, worst, design], axis=1)
