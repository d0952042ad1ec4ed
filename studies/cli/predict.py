"""``precrel predict MACHINE.toml``: FOSM reliability of an allocation over the grid; limits
and σ in the machine file's units (mm and rad when it states none); ``--out`` writes the
table in mm and rad."""

from __future__ import annotations

import numpy as np
import pandas as pd

from reliability.basics.display import (output_people_units, percent_text,
                                        quantity_bound_text, quantity_text, target_text,
                                        top_contributors)
from reliability.basics.errors import InputError
from reliability.basics.files import SIGNIFICANT, write_csv
from reliability.first_order.fosm import fosm, two_sided_probability
from reliability.first_order.workspace_search import certified_worst
from reliability.life.life_fosm import life_reliability
from reliability.model.machine import OUTPUTS
from reliability.model.poses import workspace_grid
from reliability.model.work_zone import grid_text, zone_text

from . import options


def add_parser(subparsers):
    parser = subparsers.add_parser(
        "predict", help="FOSM reliability of an allocation (Eqs. 19-23)",
        description="FOSM per output over the workspace grid: the worst pose as axis "
                    "positions, the reliability index beta, the one- and two-sided "
                    "probabilities and the errors contributing most there.")
    options.add_machine(parser)
    options.add_tolerances(parser)
    options.add_points(parser)
    options.add_study_model(parser)
    options.add_side(parser)
    options.add_certify(parser, "also bound sigma over the whole stroke box (branch and "
                                "bound with a rigorous bound, docs/certified-workspace.md) "
                                "and print each output's certified worst pose")
    options.add_out(parser, "file", "write the table as CSV, one row per output (mm and "
                                    "rad; the worst grid pose's axis positions, sigma, "
                                    "beta, probabilities)", metavar="CSV")
    parser.add_argument("--age", type=options.nonnegative_age, default=None, metavar="YEARS",
                        help="also the reliability at this age of the machine and over its "
                             "life to it (first passage over [0, age]), under the machine "
                             "file's [drift] table (docs/over-time.md)")
    options.add_overwrite(parser)
    return parser


def run(args) -> int:
    out = None if args.out is None else options.destination(args.out, args.overwrite)
    machine = options.machine(args)
    if args.certify:
        options.check_certifiable(machine, "--certify", "leave out --certify")
    if args.age is not None and machine.drift is None:
        raise InputError(f"--age {args.age:g}: {args.machine} has no [drift] table (how the "
                         f"errors change with age, docs/over-time.md)")
    t = machine.initial_allocation if args.tolerances is None else \
        options.read_tolerances(args.tolerances, machine)
    result = fosm(machine, t, workspace_grid(machine, args.points),
                  distribution=machine.distribution)
    source = "initial allocation" if args.tolerances is None else args.tolerances
    print(f"FOSM of the {source} of {machine.name!r} over the "
          f"{grid_text(machine, args.points, len(result.poses))}; target judged "
          f"{args.side.replace('_', '-')}; "
          f"outputs in the {machine.frame} frame; {options.reading_text(machine)}\n")
    print(prediction_table(machine, result, args.side).to_string())
    failing = [o for o, met in zip(OUTPUTS, result.meets_targets(args.side))
               if not met]
    print("\nevery output meets its target" if not failing else
          f"\ntarget NOT met by: {', '.join(failing)}")
    if args.age is not None:
        print(f"\n{age_table_title(machine, args.age)}")
        print(age_table(machine, t, result.poses, args.age).to_string())
    if args.certify:
        options.say(f"certifying the worst pose over the continuous workspace (rtol "
                    f"{args.rtol:g})")
        table = certified_worst(machine, t, rtol=args.rtol)
        print(f"\nWorst pose over the continuous workspace ({zone_text(machine)}), "
              f"certified to {args.rtol:g} in sigma; {options.reading_text(machine)}:")
        print(certificate_table(machine, table, result).to_string())
    if out is not None:
        write_csv(prediction_frame(machine, result), out, args.overwrite,
                  float_format=f"%.{SIGNIFICANT}g")
        print(f"\nwritten {out}")
    return 0


def age_table_title(machine, age: float) -> str:
    """What the age table shows: the drift model and the age."""
    return (f"At age {age:g} years under the machine file's [drift] model "
            f"{machine.drift.kind!r} (docs/over-time.md), each output at its worst grid "
            f"pose over the life:")


def age_table(machine, tolerances, poses, age: float) -> pd.DataFrame:
    """One row per output: the worst grid pose over ``[0, age]``, the probability at the
    age alone and the first passage over ``[0, age]`` (a Monte-Carlo standard error
    beside it under wear)."""
    found = life_reliability(machine, tolerances, poses, [0.0, age] if age > 0 else [0.0],
                             distribution=machine.distribution, rng=0)
    rows = []
    for i, output in enumerate(OUTPUTS):
        life = options.percent(found.life[-1, i])
        if found.life_se[-1, i] > 0:
            life += f" (se {100 * found.life_se[-1, i]:.2g} %)"
        rows.append({"output": output,
                     "worst pose over the life": options.pose_text(
                         machine, poses[found.worst_pose[-1, i]]),
                     "P at the age": options.percent(found.at_age[-1, i]),
                     "P over [0, age]": life})
    return pd.DataFrame(rows).set_index("output")


def prediction_frame(machine, result):
    """The FOSM table of ``--out``: one row per output, the worst grid pose's axis
    positions (mm, rad) before the columns of :meth:`FosmResult.to_frame`."""
    frame = result.to_frame().drop(columns="worst_pose")
    pose = pd.DataFrame(result.poses[result.worst_pose], columns=list(machine.axes),
                        index=frame.index)
    return pd.concat([pose, frame], axis=1)


def certificate_table(machine, table, grid_result) -> pd.DataFrame:
    """One row per output: the certified worst pose (degrees and mm), σ there, the bound
    (rounded up), the grid's worst σ (σ in the machine file's units), the two-sided
    probability at the bound (a lower bound, rounded down), boxes and time."""
    rows = np.arange(len(OUTPUTS))
    grid_sigma = grid_result.sigma[grid_result.worst_pose, rows]
    units = output_people_units(machine.cost_coefficients.units)
    out = []
    for i, output in enumerate(OUTPUTS):
        row = table.loc[output]
        pose = row[list(machine.axes)].to_numpy(dtype=float)
        out.append({
            "output": output,
            "worst pose": options.pose_text(machine, pose),
            "sigma": quantity_text(row["sigma"], units[i], 6),
            "sigma bound": quantity_bound_text(row["sigma_bound"], units[i], 6),
            "grid sigma": quantity_text(grid_sigma[i], units[i], 6),
            "P two-sided at bound": percent_text(
                two_sided_probability(machine.limits[i], row["sigma_bound"]), lower=True),
            "certified": "yes" if row["certified"] else "NO",
            "boxes": int(row["calls"]),
            "time [s]": f"{row['seconds']:.2f}",
        })
    return pd.DataFrame(out).set_index("output")


def prediction_table(machine, result, side: str) -> pd.DataFrame:
    """One row per output: limit in the machine file's units, target, worst pose, β,
    probabilities, top contributors."""
    frame = result.to_frame()
    units = output_people_units(machine.cost_coefficients.units)
    rows = []
    for i, output in enumerate(frame.index):
        row = frame.loc[output]
        pose = result.poses[result.worst_pose[i]]
        rows.append({
            "output": output,
            "limit": quantity_text(row["limit"], units[i], 6),
            "target": target_text(row["target"]),
            "worst pose": options.pose_text(machine, pose),
            "beta": f"{row['beta']:.4f}",
            "P one-sided": options.percent(row["worst_one_sided"]),
            "P two-sided": options.percent(row["worst_two_sided"]),
            **({"P exact linear": options.percent(row["exact_two_sided"])}
               if result.distribution == "truncated" else {}),
            "meets": "yes" if row[f"meets_{side}"] else "NO",
            "top contributors (% of variance)": top_contributors(
                result.contributions, output),
        })
    return pd.DataFrame(rows).set_index("output")
