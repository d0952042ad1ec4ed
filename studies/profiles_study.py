"""What error profiles along travel change: Table 9's spread and the machine-level yield.

    python -m studies.profiles_study                      # 20 and 2000 repeats, seed 2023
    python -m studies.profiles_study --repeats 20 200 --out profiles_out

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
import io
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from threadpoolctl import threadpool_limits  # noqa: E402

import allocation  # noqa: E402
import reliability  # noqa: E402
from reliability.files import atomic_write_bytes, atomic_write_text, write_csv  # noqa: E402
from reliability.fosm import fosm  # noqa: E402
from reliability.measured import SystematicErrors, read_profile_csv  # noqa: E402
from reliability.paper_tables import TABLE6, TABLE9, TABLE9_ALL_INSIDE  # noqa: E402
from reliability.poses import workspace_grid  # noqa: E402
from reliability.profiles import profile_model  # noqa: E402
from reliability.sampling import GridExperiment  # noqa: E402

from .profiles_section import profiles_section  # noqa: E402

#: Profiles compared, from independent to constant (lengths in mm).
PROFILES = ("independent", "gp:30", "gp:100", "gp:300", "gp:1000", "gp:3000", "constant")
#: Table 9's spread is shown for these outputs.
SPREAD_OUTPUTS = ("dx", "ex", "ey")
#: The made-up straightness profile shipped with the documentation.
EXAMPLE_PROFILE = Path(__file__).resolve().parent.parent / "docs" / "examples" / \
    "x_vertical_straightness.csv"
EXAMPLE_ERROR = "X.dz"


@dataclass
class ProfilesStudy:
    """Tables the profile study is made of (see :func:`run_profiles_study`)."""

    comparison: pd.DataFrame
    paper_check: pd.DataFrame | None = None
    systematic: pd.DataFrame | None = None
    timings: dict = field(default_factory=dict)


def profile_length(spec) -> float:
    """Correlation length of a profile for plotting: 0 independent, ∞ constant, else ℓ."""
    model = profile_model(spec)
    if str(model) == "independent":
        return 0.0
    if str(model) == "constant":
        return np.inf
    return model.length


def profile_comparison(machine, allocations: dict, profiles=PROFILES, repeats=(20, 2000),
                       seed: int = 2023, keep=None, log=lambda message: None) -> pd.DataFrame:
    """Yield, Table 9's spread and mean fractions for every allocation, profile and count.

    Parameters
    ----------
    machine : Machine
    allocations : dict[str, array_like]
        Label → tolerances.
    profiles : sequence
        Profile specifications (:func:`reliability.profiles.profile_model`).
    repeats : sequence of int
        Numbers of experiments; each count is its own run from the same seed.
    seed : int
    keep : dict, optional
        Filled with ``(label, profile, repeats) → GridExperimentResult``.
    log : callable

    Returns
    -------
    pandas.DataFrame
        One row per (allocation, profile, repeats).
    """
    rows = []
    for spec in profiles:
        experiment = GridExperiment(machine, profile=spec)
        for label, t in allocations.items():
            for count in repeats:
                start = time.perf_counter()
                result = experiment.run(t, repeats=int(count), rng=seed, keep_values="none")
                seconds = time.perf_counter() - start
                log(f"  {label:>10} {str(spec):>11} x {count}: {seconds:.2f} s")
                if keep is not None:
                    keep[(label, str(spec), int(count))] = result
                rows.append(_row(label, spec, result, seconds))
    return pd.DataFrame(rows)


def _row(label, spec, result, seconds) -> dict:
    fit = result.machine_yield()
    spread = result.reliability()
    row = {"allocation": label, "profile": str(spec), "length_mm": profile_length(spec),
           "repeats": result.repeats, "yield": fit.estimate, "yield_lower": fit.lower,
           "yield_upper": fit.upper}
    columns = list(reliability.OUTPUTS)
    for output in SPREAD_OUTPUTS:
        row[f"std_{output}"] = spread.std[columns.index(output)]
    for output in SPREAD_OUTPUTS:
        row[f"mean_{output}"] = spread.estimate[columns.index(output)]
        row[f"se_{output}"] = spread.standard_error[columns.index(output)]
    row["seconds"] = seconds
    return row


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


def systematic_effect(machine, tolerances, systematic, *, repeats: int = 2000,
                      seed: int = 2023, points_per_axis: int = 5) -> pd.DataFrame:
    """FOSM and Monte-Carlo reliability without and with a systematic error profile.

    Returns one row per output: the worst-pose and workspace-mean two-sided FOSM
    probability without and with the measured means over the grid, the largest output
    mean, and the grid experiment's mean fraction with its standard error, with the means
    added.
    """
    poses = workspace_grid(machine, points_per_axis)
    jacobian = machine.jacobian(poses)
    plain = fosm(machine, tolerances, poses, jacobian=jacobian, distribution="truncated")
    shifted = fosm(machine, tolerances, poses, jacobian=jacobian, distribution="truncated",
                   means=systematic.means(poses))
    mc = GridExperiment(machine, points_per_axis, systematic=systematic).run(
        tolerances, repeats=repeats, rng=seed, keep_values="none").reliability()
    return pd.DataFrame({
        "limit": machine.limits,
        "worst_without": plain.worst("two_sided"), "worst_with": shifted.worst("two_sided"),
        "mean_without": plain.workspace_mean("two_sided"),
        "mean_with": shifted.workspace_mean("two_sided"),
        "largest_output_mean": np.abs(shifted.mean).max(axis=0),
        "mc_mean_with": mc.estimate, "mc_se_with": mc.standard_error,
    }, index=pd.Index(reliability.OUTPUTS, name="output"))


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
                                                 seed=seed)
                        for label, t in allocations.items()}, names=["allocation"])
    timings.update({f"{r.allocation}/{r.profile}/{r.repeats}": r.seconds
                    for r in comparison.itertuples()})
    return ProfilesStudy(comparison=comparison, paper_check=check, systematic=effect,
                         timings=timings)


def parse_arguments(argv=None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="python -m studies.profiles_study",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, nargs="+", default=[20, 2000],
                        help="numbers of grid experiments (default 20 2000)")
    parser.add_argument("--seed", type=int, default=2023, help="random seed (default 2023)")
    parser.add_argument("--out", type=Path, default=None,
                        help="folder for the report section's CSV tables and figure")
    parser.add_argument("--overwrite", action="store_true", help="replace existing files")
    return parser.parse_args(argv)


def main(argv=None) -> int:
    args = parse_arguments(argv)
    if any(r < 2 for r in args.repeats):
        print("--repeats: every count must be >= 2", file=sys.stderr)
        return 2
    with threadpool_limits(limits=1):  # small matrix products: threads only contend
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
        written = write_section(profiles_section(study), args.out, args.overwrite)
        print(f"\nwrote {len(written)} files to {args.out}", file=sys.stderr)
    return 0


def write_section(section, out: Path, overwrite: bool = False) -> list[Path]:
    """Write a section's markdown, CSV tables and PNG figures into folder ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    written = [atomic_write_text(out / "profiles.md", f"## {section.title}\n\n{section.text}\n",
                                 overwrite)]
    for name, table in section.tables.items():
        written.append(write_csv(table, out / name, overwrite, index=False))
    for name, figure in section.figures.items():
        buffer = io.BytesIO()
        figure.savefig(buffer, format="png", dpi=120)
        written.append(atomic_write_bytes(out / name, buffer.getvalue(), overwrite))
    return written


if __name__ == "__main__":
    sys.exit(main())
