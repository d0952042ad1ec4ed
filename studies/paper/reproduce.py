"""Reproduce the case study of Hu, Wang & Ma (2023) from nothing but the code and a seed.

    python -m studies.reproduce_paper --out figures --seed 2023 --overwrite

Steps: FCEM (Eqs. 36–39) → the allocation problem of Eq. (35) under the paper's one-sided
reading and the exact two-sided one → GWO with the paper's settings (500 iterations,
100 wolves) and the certified exact optimum → FOSM on the 5^6 grid → 20 repeated grid
experiments (Sec. 5.3) for the paper's Table 6 allocation and for the exact optima →
Tables 4–9 as CSV, Figs. 8–15 (and a few more) as PNG, and ``report.md`` setting our numbers
beside the paper's; in ``machine/``, the same machine through the study every machine's
report uses (:mod:`studies.workflows.machine_study`, as ``precrel report``). The same seed
gives the same files.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

import allocation
from allocation.per_pose.result_files import MULTIPLIER_DIGITS, gap_text
import reliability
from reliability.basics.display import axis_units, pose_frame
from reliability.basics.files import as_written, atomic_write_bytes, write_csv
from reliability.basics.statistics import all_within_share
from reliability.basics.streams import spawn
from reliability.first_order.fosm import fosm
from reliability.first_order.workspace_search import continuous_worst
from reliability.sampling.fosm_comparison import fosm_versus_monte_carlo
from reliability.sampling.grid_experiment import GridExperiment
from reliability.sampling.pose_sampling import sample_random_poses
from studies.cli import options, program
from studies.report import machine_sections, plots
from studies.report.section import Section
from studies.report.writer import SIGNIFICANT, png_bytes
from studies.report.writer import write_report as write_machine_report
from studies.workflows.machine_study import run as run_machine_study
from studies.workflows.machine_study import summary
from studies.workflows.timing import one_blas_thread

from .report import write_report
from .tables import TABLE6, TABLE7, TABLE8, TABLE9, TABLE9_ALL_INSIDE

#: Eqs. (36)–(37): the factor weights and evaluation matrix behind a = 1.98.
FCEM_WEIGHTS = (0.4, 0.2, 0.1, 0.3)
FCEM_MEMBERSHIP = ((0, 0, 0.2, 0.2, 0.6), (0, 0, 0.2, 0.4, 0.4),
                   (0, 0, 0.6, 0.4, 0), (0, 0.2, 0.2, 0.4, 0.2))
#: Figs. 10–15 in the paper's order.
SCATTER_FIGURES = {"fig10.png": "dx", "fig11.png": "ex", "fig12.png": "dy",
                   "fig13.png": "ey", "fig14.png": "dz", "fig15.png": "ez"}
#: Allocations run through the grid experiment, with the side their optimum was built for.
VERIFIED = ("paper", "exact", "exact_two_sided")
#: The two-sided optimum refined until its target holds between grid points too.
REFINED = "exact_two_sided_workspace"
SIDES = {"": "one_sided", "_two_sided": "two_sided"}
#: Subfolder holding the paper's machine run through the generic machine study: the report
#: ``precrel report --seed S`` writes for any machine, under the machine file's one reading.
MACHINE_REPORT = "machine"
#: Resolution of the paper's figures (a report's figures: studies.report.writer.FIGURE_DPI).
FIGURE_DPI = 110
OUTPUT_FILES = (
    "table4_initial.csv", "table5_coefficients.csv", "table6_allocation.csv",
    "table7_cost.csv", "table8_experiment.csv", "table9_repeats.csv", "table9_summary.csv",
    "fosm_summary.csv", "fosm_vs_mc.csv", "random_pose.csv", "machine_yield.csv",
    "exact_active_constraints.csv", "exact_requirements.csv", "continuous_worst.csv",
    "gwo_history.csv", "fig08.png", "fig09.png",
    *SCATTER_FIGURES, "fig_convergence.png", "fig_fosm_vs_mc.png", "fig_repeats.png",
    "report.md", f"{MACHINE_REPORT}/report.md", f"{MACHINE_REPORT}/report.html",
    f"{MACHINE_REPORT}/summary.json", f"{MACHINE_REPORT}/allocation.csv")


@dataclass
class Study:
    """Everything the tables, figures and report are made from."""

    seed: int
    repeats: int
    machine: object
    fcem: object
    problems: dict = field(default_factory=dict)
    solutions: dict = field(default_factory=dict)
    allocations: dict = field(default_factory=dict)
    fosm: dict = field(default_factory=dict)
    grid: dict = field(default_factory=dict)
    random: dict = field(default_factory=dict)
    continuous: dict = field(default_factory=dict)
    refined_poses: np.ndarray | None = None
    timings: dict = field(default_factory=dict)


class Progress:
    """Prints each step with the elapsed time, to stderr."""

    def __init__(self, quiet: bool = False):
        self.start = time.perf_counter()
        self.quiet = quiet

    def __call__(self, message: str) -> None:
        if not self.quiet:
            print(f"[{time.perf_counter() - self.start:6.1f} s] {message}", file=sys.stderr,
                  flush=True)

    @property
    def elapsed(self) -> float:
        return time.perf_counter() - self.start


def run_study(seed: int = 2023, repeats: int = 20, wolves: int = 100,
              iterations: int = 500, random_samples: int = 50_000,
              log=lambda message: None) -> Study:
    """Run every computation of the case study (no files written)."""
    machine = reliability.hobbing_machine()
    streams = iter(spawn(seed, 16))
    study = Study(seed=seed, repeats=repeats, machine=machine,
                  fcem=allocation.fcem_coefficient(FCEM_WEIGHTS, FCEM_MEMBERSHIP))
    study.allocations["initial"] = machine.initial_allocation.copy()
    study.allocations["paper"] = machine.error_vector(TABLE6, default=None)
    for suffix, side in SIDES.items():
        log(f"allocation problem, {side.replace('_', '-')} FOSM, worst case over 5^6 poses")
        problem = allocation.AllocationProblem.build(machine, side=side)
        study.problems[side] = problem
        exact = problem.solve_exact()
        log(f"  exact optimum: cost {exact.cost:.5g}, relative gap "
            f"{gap_text(exact.certificate['relative_gap'])}; GWO {iterations} x {wolves} ...")
        gwo = problem.solve_gwo(n_wolves=wolves, n_iterations=iterations, rng=next(streams))
        study.solutions[f"exact{suffix}"], study.solutions[f"gwo{suffix}"] = exact, gwo
        study.allocations[f"gwo{suffix}"] = gwo.tolerances
        study.allocations[f"exact{suffix}"] = exact.tolerances
    log("two-sided optimum refined until it holds between grid points (pose cutting planes)")
    refined, added = allocation.solve_over_workspace(study.problems["two_sided"])
    study.solutions[REFINED], study.allocations[REFINED] = refined, refined.tolerances
    study.refined_poses = added
    poses = study.problems["one_sided"].poses
    jacobian = study.problems["one_sided"].jacobian
    for name, t in study.allocations.items():
        study.fosm[name] = fosm(machine, t, poses, jacobian=jacobian)
    log("worst poses between grid points (continuous search)")
    for name in ("initial", *VERIFIED, REFINED):
        study.continuous[name] = continuous_worst(machine, study.allocations[name], poses)
    experiment = GridExperiment(machine)
    for name in VERIFIED:
        log(f"grid experiment x {repeats}: {name} allocation")
        study.grid[name] = experiment.run(study.allocations[name], repeats=repeats,
                                          rng=next(streams))
        study.random[name] = sample_random_poses(machine, study.allocations[name],
                                                 random_samples, rng=next(streams))
    return study


# ----- tables ------------------------------------------------------------------------
def tables(study: Study) -> dict[str, pd.DataFrame]:
    """All CSV tables, by file name."""
    machine, costs = study.machine, study.problems["one_sided"].cost
    names = pd.Index(machine.error_names, name="error")
    out = {"table4_initial.csv": pd.DataFrame({"initial": study.allocations["initial"]},
                                              index=names)}
    out["table5_coefficients.csv"] = _coefficients(study)
    table6 = pd.DataFrame(study.allocations, index=names)
    for name in ("paper", "gwo", "exact", "gwo_two_sided", "exact_two_sided", REFINED):
        # from the tolerance as written, so that the rate's digits follow the tolerance's
        # (a solve fixes a tolerance's sixth digit, the rate's sixth one is finer)
        table6[f"{name}_rate"] = as_written(table6[name].to_numpy()) / table6["initial"] - 1.0
    out["table6_allocation.csv"] = table6
    out["table7_cost.csv"] = _costs(study, costs)
    out["fosm_summary.csv"] = pd.concat(
        {name: result.to_frame() for name, result in study.fosm.items()},
        names=["allocation"])
    paper_grid = study.grid["paper"]
    table8 = paper_grid.table8(0)
    table8["paper_inside"] = TABLE8["inside"]
    table8["paper_fraction"] = TABLE8["inside"] / 15625
    out["table8_experiment.csv"] = table8
    out["table9_repeats.csv"] = pd.concat(
        [pd.DataFrame(result.fractions, columns=list(reliability.OUTPUTS))
         .assign(allocation=name, repeat=np.arange(1, result.repeats + 1))
         for name, result in study.grid.items()]
    )[["allocation", "repeat", *reliability.OUTPUTS]].set_index(["allocation", "repeat"])
    summary = {name: result.table9().loc[["Avg", "Min", "Max"]]
               for name, result in study.grid.items()}
    summary["paper (published)"] = TABLE9.agg(["mean", "min", "max"]).set_axis(
        ["Avg", "Min", "Max"])
    out["table9_summary.csv"] = pd.concat(summary, names=["allocation", "statistic"])
    out["fosm_vs_mc.csv"] = pd.concat(
        {name: fosm_versus_monte_carlo(study.fosm[name], result).set_index("output")
         for name, result in study.grid.items()}, names=["allocation"])
    out["random_pose.csv"] = pd.concat(
        {name: result.to_frame() for name, result in study.random.items()},
        names=["allocation"])
    out["machine_yield.csv"] = _yields(study)
    out["exact_active_constraints.csv"] = pd.concat(
        {side: _binding_rows(study, study.solutions[f"exact{suffix}"].active)
         for suffix, side in SIDES.items()}, names=["side", "row"])
    out["exact_requirements.csv"] = pd.concat(
        {side: _solver_digits(study.solutions[f"exact{suffix}"].requirements)
         for suffix, side in SIDES.items()}, names=["side"])
    out["continuous_worst.csv"] = pd.concat(
        {name: _shown_poses(study, frame) for name, frame in study.continuous.items()},
        names=["allocation"])
    out["gwo_history.csv"] = pd.concat(
        {side: study.solutions[f"gwo{suffix}"].history for suffix, side in SIDES.items()},
        names=["side"])
    return out


def _shown_poses(study: Study, frame: pd.DataFrame) -> pd.DataFrame:
    """``frame`` with its axis columns as ``C_deg``, ``X_mm``, … (positions for people)."""
    axes = list(study.machine.axes)
    shown = pose_frame(frame[axes].to_numpy(), axes, axis_units(study.machine), style="csv")
    return pd.concat([frame.drop(columns=axes), shown.set_axis(frame.index)], axis=1)


def _binding_rows(study: Study, active: pd.DataFrame) -> pd.DataFrame:
    """The binding (output, pose) rows without their individual multipliers: where
    several rows are alike the split of λ among them is not unique, so only the per-output
    ranges (``exact_requirements.csv``) are results."""
    return _shown_poses(study, active.drop(columns=["multiplier", "elasticity"]))


def _solver_digits(requirements: pd.DataFrame) -> pd.DataFrame:
    """Multipliers and elasticities (every float column) to :data:`MULTIPLIER_DIGITS`
    significant digits, what the dual solve fixes."""
    columns = requirements.columns[[kind == "f" for kind in requirements.dtypes.map(
        lambda d: d.kind)]]
    return requirements.assign(**{c: as_written(requirements[c], MULTIPLIER_DIGITS)
                                  for c in columns})


def _coefficients(study: Study) -> pd.DataFrame:
    c = study.machine.cost_coefficients
    rows = {"a": (c.a, study.fcem.value), "b": (c.b, np.nan), "c": (c.c, np.nan),
            "d": (c.d, np.nan)}
    rows.update({f"m[{joint}]": (value, np.nan) for joint, value in c.assembly.items()})
    return pd.DataFrame(rows.values(), columns=["table5", "fcem_recomputed"],
                        index=pd.Index(rows.keys(), name="coefficient"))


def _costs(study: Study, costs) -> pd.DataFrame:
    initial = costs.total(study.allocations["initial"])
    rows = []
    for name, t in study.allocations.items():
        result = study.fosm[name]
        rows.append({"allocation": name, "cost": costs.total(t),
                     "relative_to_initial": costs.total(t) / initial,
                     "meets_one_sided_worst": bool(result.meets_targets("one_sided").all()),
                     "meets_two_sided_worst": bool(result.meets_targets("two_sided").all()),
                     "paper_reported": TABLE7.get(name, np.nan)})
    return pd.DataFrame(rows).set_index("allocation")


def _yields(study: Study) -> pd.DataFrame:
    rows = {name: result.all_inside_share().to_frame().iloc[0]
            for name, result in study.grid.items()}
    frame = pd.DataFrame(rows).T
    frame.index.name = "allocation"
    frame["all_inside"] = [int(result.all_inside.sum()) for result in study.grid.values()]
    published = all_within_share(TABLE9_ALL_INSIDE, trials=len(TABLE9)).to_frame().iloc[0]
    frame.loc["paper (published)"] = published
    frame.loc["paper (published)", "all_inside"] = TABLE9_ALL_INSIDE
    return frame


# ----- figures -----------------------------------------------------------------------
def figures(study: Study, frames: dict[str, pd.DataFrame]) -> dict[str, plt.Figure]:
    """All figures, by file name; ``frames`` are the :func:`tables` they share data with."""
    machine = study.machine
    n_motion = 6 * len(machine.axes)
    shown = {"initial (Table 4)": study.allocations["initial"],
             "paper (Table 6)": study.allocations["paper"],
             "GWO (ours)": study.allocations["gwo"], "exact optimum": study.allocations["exact"]}
    out = {}
    for name, part, title in (
            ("fig08.png", slice(0, n_motion), "Fig. 8: motion-error allocations"),
            ("fig09.png", slice(n_motion, None), "Fig. 9: assembly-error allocations")):
        fig, ax = plt.subplots(figsize=(14, 5), layout="constrained")
        plots.plot_allocation_comparison({k: v[part] for k, v in shown.items()},
                                         names=machine.error_names[part], ax=ax,
                                         title=f"{title} (one-sided 99 % target, relative "
                                               f"to Table 4)")
        out[name] = fig
    values = study.grid["paper"].values[0]
    for name, output in SCATTER_FIGURES.items():
        index = reliability.OUTPUTS.index(output)
        fig, ax = plt.subplots(figsize=(9, 4.5), layout="constrained")
        plots.plot_comprehensive_error_scatter(values[:, index], machine.limits[index],
                                               output_label=output, ax=ax)
        number = name[3:5]
        ax.set_title(f"Fig. {int(number)}: {ax.get_title()}\n(Table 6 allocation, grid "
                     f"experiment 1 of {study.repeats})")
        out[name] = fig
    out["fig_convergence.png"] = _convergence_figure(study)
    out["fig_fosm_vs_mc.png"] = _comparison_figure(study, frames["fosm_vs_mc.csv"])
    fig, ax = plt.subplots(figsize=(11, 4.5), layout="constrained")
    plots.plot_repeats(frames["table9_repeats.csv"].reset_index(), by="allocation", ax=ax)
    out["fig_repeats.png"] = fig
    return out


def _convergence_figure(study: Study) -> plt.Figure:
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.5), layout="constrained")
    for ax, (suffix, side) in zip(axes, SIDES.items()):
        history = study.solutions[f"gwo{suffix}"].history.rename(
            columns={"cost": "best_objective"})
        plots.plot_convergence(history, optimum=study.solutions[f"exact{suffix}"].cost, ax=ax)
        ax.set_title(f"GWO, {side.replace('_', '-')} constraint\n{ax.get_title()}")
    return fig


def _comparison_figure(study: Study, comparison: pd.DataFrame) -> plt.Figure:
    fig, axes = plt.subplots(1, len(study.grid), figsize=(7 * len(study.grid), 4.5),
                             layout="constrained", sharey=True)
    for ax, (name, result) in zip(axes, study.grid.items()):
        plots.plot_reliability_comparison(comparison.loc[name].reset_index(), target=0.99,
                                          ax=ax)
        ax.set_title(f"{name} allocation: grid mean FOSM vs\n{result.repeats} grid "
                     f"experiments")
    return fig


# ----- driver --------------------------------------------------------------------------
def write_outputs(study: Study, out: Path, log) -> None:
    """Write tables, figures and the report into ``out``."""
    frames = tables(study)
    for name, frame in frames.items():
        write_csv(frame, out / name, overwrite=True, float_format=f"%.{SIGNIFICANT}g")
    log("tables written; drawing figures")
    for name, fig in figures(study, frames).items():
        atomic_write_bytes(out / name, png_bytes(fig, FIGURE_DPI), overwrite=True)
    write_report(study, frames, out / "report.md")
    log(f"the generic machine report into {out / MACHINE_REPORT}/")
    generic = run_machine_study(study.machine, rng=study.seed, repeats=study.repeats)
    paper = Section("Comparison with the paper",
                    f"This is the report `precrel report --seed {study.seed}` writes for any "
                    f"machine (the optimum certified over the continuous workspace; the "
                    f"paper's tables in `../` hold on its 5-point grid), "
                    "under the machine file's one reading of a tolerance (its Monte-Carlo "
                    "draws as its FOSM reads; the paper's own experiments, in `../`, draw "
                    "truncated normals beside a normal FOSM). The "
                    "comparison of every number with the paper's Tables 4–9 and "
                    "Figs. 8–15 is in `../report.md` and the CSV files beside it.")
    write_machine_report(out / MACHINE_REPORT, [*machine_sections.sections(generic), paper],
                         summary(generic),
                         title=f"Precision allocation and reliability of "
                               f"{study.machine.name}", overwrite=True)


def parse_arguments(argv=None) -> argparse.Namespace:
    parser = program.ArgumentParser(
        prog="python -m studies.reproduce_paper", name="reproduce_paper",
        description="Reproduce Tables 4-9 and Figs. 8-15 of Hu, Wang & Ma (2023).")
    parser.add_argument("--out", default="figures", help="output folder (default figures/)")
    parser.add_argument("--seed", type=options.seed, default=2023,
                        help="random seed, an integer >= 0 (default 2023)")
    parser.add_argument("--repeats", type=options.positive_int, default=20,
                        help="grid experiments per allocation (default 20, as Table 9)")
    parser.add_argument("--wolves", type=options.positive_int, default=100,
                        help="GWO pack size (default 100, the paper's)")
    parser.add_argument("--iterations", type=options.positive_int, default=500,
                        help="GWO iterations (default 500, the paper's)")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace files a previous run left in the output folder")
    parser.add_argument("--quiet", action="store_true", help="no progress output")
    args = parser.parse_args(argv)
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        parser.error(f"--out {out}: is a file; expected a folder")
    if not out.parent.is_dir():
        parser.error(f"--out {out}: folder {out.parent} does not exist")
    existing = [name for name in OUTPUT_FILES if (out / name).exists()]
    if existing and not args.overwrite:
        parser.error(f"--out {out}: already holds {len(existing)} of this study's files "
                     f"(e.g. {existing[0]}); pass --overwrite to replace them")
    return args


@one_blas_thread
def main(argv=None) -> int:
    """Run the case study; return the exit code (2 with one ``error:`` line for bad options)."""
    try:
        args = parse_arguments(argv)
    except SystemExit as exit_:  # --help, or a refusal already printed
        return int(exit_.code or 0)
    import matplotlib
    matplotlib.use("Agg")
    out = Path(args.out)
    out.mkdir(exist_ok=True)
    log = Progress(args.quiet)
    study = run_study(seed=args.seed, repeats=args.repeats, wolves=args.wolves,
                      iterations=args.iterations, log=log)
    log("computations done; writing tables")
    write_outputs(study, out, log)
    log(f"done: {len(OUTPUT_FILES)} files in {out}/")
    return 0


if __name__ == "__main__":
    sys.exit(main())
