"""What error profiles along travel change: Table 9's spread and the machine-level yield.

    python -m studies.paper.profiles_study                # 20 and 2000 repeats, seed 2023
    python -m studies.paper.profiles_study --repeats 20 200 --out profiles_out

For the paper's Table 6 allocation and the exact two-sided optimum, the grid experiment
(Sec. 5.3) is run with every axis' motion errors independent at each grid point (the
paper's), as Gaussian-process profiles of several correlation lengths, and constant along
travel. Printed per allocation, profile and number of repeats: the machine-level yield with
its Clopper-Pearson interval, the between-experiment standard deviation of the δx, εx and
εy fractions (Table 9's spread) and the mean fractions (per-pose reliability, which the
profile must not change). Then the paper's Table 9 spread is set beside the spread of
20-experiment blocks under each model, and a measured (here made-up) straightness profile
shows how a systematic error uses up the reliability budget.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

import allocation
import reliability
from reliability.model.measured_profiles import SystematicErrors, read_profile_csv
from studies.report.profiles_section import profiles_section
from studies.report.writer import check_output_folder, write_section
from studies.workflows.profile_comparison import (PROFILES, SPREAD_OUTPUTS, ProfilesStudy,
                                                  profile_comparison, systematic_effect)
from studies.workflows.timing import one_blas_thread

from .tables import TABLE6, TABLE9, TABLE9_ALL_INSIDE

#: The made-up straightness profile shipped with the documentation.
EXAMPLE_PROFILE = Path(__file__).resolve().parents[2] / "docs" / "examples" / \
    "x_vertical_straightness.csv"
EXAMPLE_ERROR = "X.dz"


def paper_spread_check(results: dict, label: str, block: int = 20) -> pd.DataFrame:
    """The paper's Table 9 spread beside that of ``block``-experiment blocks per profile.

    Each long run of a profile is cut into blocks of ``block`` consecutive experiments (as
    many as the paper ran); the spread of the δx, εx, εy fractions and the number of
    all-inside experiments within each block give their 2.5 %, 50 % and 97.5 % quantiles
    under that model, and the share of blocks below the paper's value (its percentile,
    ties counted half). Where the paper's value lies inside a model's central 95 % range,
    Table 9 is consistent with that model in that quantity.

    Parameters
    ----------
    results : dict
        ``profile → GridExperimentResult`` for allocation ``label`` (many repeats).
    label : str
        Allocation label (for the table only).
    block : int
        Experiments per block.
    """
    paper_std = TABLE9.std(ddof=1)
    rows = []
    for profile, result in results.items():
        blocks = result.repeats // block
        fractions = result.fractions[:blocks * block].reshape(blocks, block, -1)
        all_inside = result.all_inside[:blocks * block].reshape(blocks, block).sum(axis=1)
        columns = list(reliability.OUTPUTS)
        quantities = {f"std_{o}": fractions[:, :, columns.index(o)].std(axis=1, ddof=1)
                      for o in SPREAD_OUTPUTS}
        quantities["all_inside"] = all_inside
        paper = {f"std_{o}": paper_std[o] for o in SPREAD_OUTPUTS}
        paper["all_inside"] = TABLE9_ALL_INSIDE
        for name, values in quantities.items():
            low, mid, high = np.quantile(values, [0.025, 0.5, 0.975])
            rank = np.mean(values < paper[name]) + 0.5 * np.mean(values == paper[name])
            rows.append({"allocation": label, "profile": profile, "quantity": name,
                         "blocks": blocks, "q025": low, "median": mid, "q975": high,
                         "paper": paper[name], "paper_percentile": 100.0 * rank,
                         "paper_inside": bool(low <= paper[name] <= high)})
    return pd.DataFrame(rows)


def paper_allocations(machine) -> dict:
    """The paper's Table 6 allocation and the certified exact two-sided optimum."""
    optimum = allocation.AllocationProblem.build(machine, side="two_sided").solve_exact()
    return {"table6": machine.error_vector(TABLE6, default=None),
            "two_sided": optimum.tolerances}


def run_profiles_study(repeats=(20, 2000), seed: int = 2023, profiles=PROFILES,
                       log=lambda message: None) -> ProfilesStudy:
    """Every table of the study on the paper's machine (no files written)."""
    machine = reliability.hobbing_machine()
    timings = {}
    start = time.perf_counter()
    allocations = paper_allocations(machine)
    timings["two_sided_optimum_s"] = time.perf_counter() - start
    log("grid experiments per allocation, profile and number of repeats")
    kept = {}
    comparison = profile_comparison(machine, allocations, profiles, repeats, seed, kept, log)
    longest = max(repeats)
    check = None
    if longest >= 40:
        check = paper_spread_check({p: kept[("table6", str(p), longest)] for p in profiles},
                                   "table6")
    log("measured straightness profile (made up) on both allocations")
    systematic = SystematicErrors(machine, (read_profile_csv(EXAMPLE_PROFILE, machine,
                                                             EXAMPLE_ERROR),))
    effect = pd.concat({label: systematic_effect(machine, t, systematic, repeats=longest,
                                                 rng=seed)
                        for label, t in allocations.items()}, names=["allocation"])
    timings.update({f"{r.allocation}/{r.profile}/{r.repeats}": r.seconds
                    for r in comparison.itertuples()})
    return ProfilesStudy(comparison=comparison, paper_check=check, systematic=effect,
                         timings=timings)


def parse_arguments(argv=None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="python -m studies.paper.profiles_study",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, nargs="+", default=[20, 2000],
                        help="numbers of grid experiments (default 20 2000)")
    parser.add_argument("--seed", type=int, default=2023, help="random seed (default 2023)")
    parser.add_argument("--out", type=Path, default=None,
                        help="folder for the section as a report (report.md, report.html, "
                             "summary.json, CSV tables and the figure)")
    parser.add_argument("--overwrite", action="store_true", help="replace existing files")
    return parser.parse_args(argv)


@one_blas_thread
def main(argv=None) -> int:
    args = parse_arguments(argv)
    import matplotlib
    matplotlib.use("Agg")
    if any(r < 2 for r in args.repeats):
        print("--repeats: every count must be >= 2", file=sys.stderr)
        return 2
    if args.out is not None:
        check_output_folder(args.out, args.overwrite)
    study = run_profiles_study(tuple(args.repeats), args.seed,
                               log=lambda message: print(message, file=sys.stderr))
    with pd.option_context("display.width", 200, "display.max_columns", 30,
                           "display.float_format", "{:.6g}".format):
        print("Machine-level yield and Table 9 spread by error profile")
        print(study.comparison.drop(columns="length_mm").to_string(index=False))
        if study.paper_check is not None:
            print("\nPaper's Table 9 (20 experiments, Table 6 allocation) against "
                  "20-experiment blocks of each model")
            print(study.paper_check.to_string(index=False))
        print("\nMeasured straightness profile (X.dz, made up): two-sided reliability")
        print(study.systematic.to_string())
    if args.out is not None:
        written = write_section(args.out, profiles_section(study), overwrite=args.overwrite)
        print(f"\nwrote {len(written)} files to {args.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
