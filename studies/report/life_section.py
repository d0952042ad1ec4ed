"""The report's "Over time" section and the figure of ``precrel life``: each output's life
reliability at its worst pose and the machine yield over the life against age, the targets
and the recalibration interval marked (docs/over-time.md)."""

from __future__ import annotations

import numpy as np

from reliability.life.recalibration import age_text
from reliability.model.machine import OUTPUTS
from studies.workflows.life_study import life_study

from .markdown import details, markdown_table
from .plots import OUTPUT_COLOURS
from .section import Section

TITLE = "Over time"
#: The report's horizon (years) and sample sizes: modest, so the report keeps its time.
REPORT_HORIZON = 10.0
REPORT_STEP = 1.0
REPORT_MACHINES = 300
REPORT_PATHS = 4000


def life_figure(study):
    """Two panels against age: each output's life reliability at its worst grid pose with
    its target (dashed), and the machine yield over the life with its interval, the level
    and the recalibration interval (shaded between the interval's crossings); with a
    compensation plan also the yield of machines compensated at acceptance and the
    recalibrations (dotted)."""
    import matplotlib.pyplot as plt

    figure, (left, right) = plt.subplots(1, 2, figsize=(11, 4.2))
    for i, output in enumerate(OUTPUTS):
        left.plot(study.ages, study.life[:, i], color=OUTPUT_COLOURS[output], label=output)
        left.axhline(study.targets[i], color=OUTPUT_COLOURS[output], linestyle="--",
                     linewidth=0.8)
    left.set(xlabel="age [years]", ylabel="P(within the limit at every age up to it)",
             title="Each output at its worst grid pose (dashed: its target)")
    left.legend(ncol=3, fontsize=8)
    right.plot(study.ages, study.machine_yield, color="black", label="machine yield")
    right.fill_between(study.ages, study.yield_lower, study.yield_upper, color="grey",
                       alpha=0.3, label=f"{study.confidence:.0%} interval")
    right.axhline(study.level, color="tab:red", linestyle="--",
                  label=f"level {study.level:.4g}")
    if study.compensated_yield is not None:
        right.plot(study.ages, study.compensated_yield, color="tab:blue",
                   label="compensated at acceptance")
        for number, start in enumerate(study.recalibrations[1:]):
            right.axvline(start, color="tab:blue", linestyle=":", linewidth=0.8,
                          label=None if number else "recalibrations with the plan")
    earliest, age, latest = study.interval
    if not np.isnan(age):
        right.axvline(age, color="tab:red", label=f"recalibrate at {age:.1f} years")
        right.axvspan(earliest, study.horizon if np.isnan(latest) else latest,
                      color="tab:red", alpha=0.1)
    right.set(xlabel="age [years]", ylabel="share of built machines within every limit",
              title=f"Machine yield over the life ({study.machines:,} machines, exact chain)")
    right.legend(fontsize=8)
    figure.suptitle(f"{study.machine}: accuracy over time (drift model {study.kind!r})")
    figure.tight_layout()
    return figure


def answer(study) -> str:
    """The section's first sentence: the recalibration interval (the age at which the
    machine yield over the life falls below the level) and the yield at the horizon."""
    earliest, age, latest = study.interval
    last = len(study.ages) - 1
    horizon = (f"over {study.horizon:g} years the machine yield is "
               f"{study.machine_yield[last]:.3f} [{study.yield_lower[last]:.3f}, "
               f"{study.yield_upper[last]:.3f}] (`life.csv`)")
    if age == 0:
        return (f"**The machine yield is below {study.level:.4g} already at acceptance** "
                f"({study.machine_yield[0]:.3f} [{study.yield_lower[0]:.3f}, "
                f"{study.yield_upper[0]:.3f}], level: {study.level_source}), so there is no "
                f"recalibration interval, and {horizon}.")
    return (f"**Recalibrate after {age_text(age, study.horizon)}** ({study.confidence:.0%} "
            f"interval {age_text(earliest, study.horizon)} to "
            f"{age_text(latest, study.horizon)}), when the machine yield over the life falls "
            f"below {study.level:.4g} ({study.level_source}), and {horizon}.")


def life_builder(study) -> Section:
    """The section of a machine report (:mod:`studies.workflows.machine_study`): the
    optimal allocation's life (the given or the initial one when there is none)."""
    tolerances = study.compared[1] if study.compared is not None else \
        study.machine.initial_allocation
    return life_section(study.machine, tolerances, points=study.points, seed=study.seed)


def life_section(machine, tolerances, *, points: int = 5, seed: int = 0) -> Section:
    """The section for a machine file with ``[drift]``, at the report's modest sizes."""
    study = life_study(machine, tolerances, until=REPORT_HORIZON, step=REPORT_STEP,
                       points=points, machines=REPORT_MACHINES, seed=seed,
                       paths=REPORT_PATHS)
    ages = ", ".join(f"{o} {age_text(a, study.horizon)}"
                     for o, a in zip(OUTPUTS, study.output_ages))
    text = "\n\n".join([
        answer(study),
        markdown_table(study.table()),
        f"Each output's worst-pose life reliability falls below its target at: {ages}.",
        details("How it is computed", _method(study))])
    return Section(TITLE, text, figures={"over_time.png": life_figure(study)},
                   tables={"life.csv": study.to_frame()},
                   summary={"recalibration_years": _plain(study.interval[1]),
                            "life_yield_at_horizon": float(study.machine_yield[-1])})


def _method(study) -> str:
    return (f"The machine file's drift model {study.kind!r} (docs/over-time.md). The life "
            f"reliability is the probability that an output stays within its limit at every "
            f"age up to the one shown, at its worst grid pose: {study.method}. The machine "
            f"yield draws {study.machines:,} built machines as at acceptance, each with its "
            f"own drift, and judges each on the exact chain at every grid pose and every "
            f"age of the grid ({study.ages[1] - study.ages[0]:g}-year steps); the intervals "
            f"are Clopper–Pearson. The report uses modest sample sizes; `precrel life` "
            f"takes more.")


def _plain(value: float):
    return None if np.isnan(value) else float(value)
