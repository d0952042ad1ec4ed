"""``precrel allocate MACHINE.toml --life T --out a.csv``: the cheapest allocation whose
every output stays within its limit at every pose and every age of ``[0, T]`` with its
target probability, under the machine's ``[drift]``, beside the allocation for acceptance
on the same options (:mod:`studies.workflows.life_allocation`, docs/life-allocation.md).

Writes ``a.csv`` (the columns of ``allocate``'s allocation file, so ``--tolerances`` reads
it), ``a.drawing.csv`` and ``a.life.csv`` (one row: ``life_years``, the drift model, the two
costs and their ratio, the workspace and whether both are certified)."""

from __future__ import annotations


import numpy as np
import pandas as pd

from allocation import AllocationProblem
from allocation.per_pose.continuous import ContinuousAllocation, check_continuous
from allocation.per_pose.life import checked_life, life_loads
from allocation.per_pose.result_files import (allocation_to_csv,
                                              drawing_check_text, drawing_to_csv,
                                              drawing_tolerances, gap_text)
from reliability.basics import display
from reliability.basics.errors import InputError
from reliability.basics.files import write_csv
from reliability.model.machine import OUTPUTS
from reliability.model.poses import workspace_grid
from studies.report.machine_sections import shown_tolerance_table
from studies.report.writer import SIGNIFICANT
from studies.workflows import life_allocation

from . import options


def run(args) -> int:
    """Everything checked before any work, both allocations, the answer, the files."""
    if args.side != "two_sided":
        raise InputError(f"--life: the life target is the two-sided probability of staying "
                         f"within the limit; --side {args.side} is refused with it")
    if args.method != "exact":
        raise InputError("--life needs the certified optimum (--method exact); --method "
                         "gwo is refused with it")
    bounds = options.check_bounds(args.bounds)
    out = options.destination(args.out, args.overwrite)
    drawing = options.beside_destination(out, "drawing", args.overwrite,
                                         override=args.drawing, option="--drawing")
    summary_path = options.beside_destination(out, "life", args.overwrite)
    machine = options.allocation_machine(args)
    try:
        years = checked_life(machine, args.life)
    except InputError as error:
        raise InputError(f"--life {args.life:g}: {error}") from None
    workspace = options.workspace(args)
    limits = options.loop_limits(args, workspace)
    if workspace == "continuous":
        check_continuous(machine, args.side)
    options.say(f"building the problem on the {args.points}-point grid, "
                f"{options.box_words(machine, bounds)}")
    problem = AllocationProblem.build(machine, workspace_grid(machine, args.points),
                                      bounds=bounds, locked=tuple(args.lock))
    found = life_allocation.run(problem, years, workspace=workspace, rtol=args.rtol,
                                progress=lambda text: options.say(f"  {text}"), **limits)
    print(answer_text(found, args.points))
    write_files(args, found, out, drawing, summary_path)
    life = found.life if isinstance(found.life, ContinuousAllocation) else None
    return options.stop_code(life)


def answer_text(found, points: int) -> str:
    """The life allocation's cost against the acceptance allocation's, the drift model
    named beside it, where each holds, the largest changes and the life loads."""
    life, acceptance = found.life_result, found.acceptance_result
    problem = life.problem
    initial = problem.cost.total(problem.reference)
    lines = [
        f"life allocation for {found.years:g} years (life_years {found.years:g}): every "
        f"output within its limit at every pose and at every age of [0, {found.years:g}] "
        f"years with its target probability, to first order",
        f"drift model: {drift_text(found.drift, problem.machine)}",
        f"cost {life.cost:.6g} = {display.percentage_text(life.cost / initial)} of the "
        f"initial allocation; {found.cost_ratio:.4f} × the cost of the allocation for "
        f"acceptance only on the same options ({acceptance.cost:.6g}); "
        f"{options.reading_text(problem.machine)}",
        f"certified optimum: {'yes' if life.certificate['certified'] else 'NO'} (relative "
        f"duality gap {gap_text(life.certificate['relative_gap'])}); time: life "
        f"{found.seconds[1]:.1f} s, acceptance {found.seconds[0]:.1f} s",
        "", "life: " + _where(found.life, points),
        "acceptance: " + _where(found.acceptance, points).splitlines()[0],
        "", "largest life load σ0²/A (≤ 1: the life target holds) at the life problem's "
        f"{len(problem.poses)} poses: " + ", ".join(
            f"{o} {v:.6f}" for o, v in zip(OUTPUTS, found.worst_life_load())),
        "", changes_text(found)]
    return "\n".join(lines)


def drift_text(drift, machine) -> str:
    """The drift model in words: the kind and the rates per year."""
    angular = np.array([name.split(".")[1].startswith("e") for name in machine.error_names])
    parts = [f"{what} {', '.join(f'{v:g}' for v in np.unique(drift.rate[mask]))} {unit}"
             for what, mask, unit in (("translations", ~angular, "mm/year"),
                                      ("rotations", angular, "rad/year")) if mask.any()]
    return (f"{drift.kind} (e(t) = e(0) + r·t, r normal with mean 0 and sd per year: "
            f"{'; '.join(parts)}; the machine file's [drift])")


def _where(result, points: int) -> str:
    """Where an allocation holds: the loop's summary, or the grid's poses."""
    if isinstance(result, ContinuousAllocation):
        return result.summary()
    return (f"workspace: grid — the targets hold at the {len(result.problem.poses)} poses "
            f"of the {points}-point grid (not certified between them)")


def changes_text(found, top: int = 10) -> str:
    """The ``top`` largest changes of the life allocation from the acceptance one."""
    machine = found.life_result.problem.machine
    table = shown_tolerance_table(machine, found.acceptance_result.tolerances,
                                  found.life_result.tolerances)
    change = found.life_result.tolerances / found.acceptance_result.tolerances - 1.0
    order = np.argsort(-np.abs(change), kind="stable")[:top]
    shown = table.iloc[order].rename(columns={"initial": "acceptance", "allocated": "life"})
    return (f"largest changes from the allocation for acceptance ({top} of {len(table)}; "
            f"in the machine file's units):\n{shown.to_string(index=False)}")


def write_files(args, found, out, drawing, summary_path) -> None:
    """``a.csv`` (with ``certified``/``reason`` when not certified), the drawing file with
    whether it meets the life target at the problem's poses, and ``a.life.csv``."""
    result = found.life_result
    reason = (found.life.reason if isinstance(found.life, ContinuousAllocation)
              and not found.life.certified else None)
    allocation_to_csv(result, out, args.overwrite, significant=SIGNIFICANT,
                      not_certified=reason)
    print(f"\nlife allocation written to {out}"
          + ("" if reason is None else " (NOT certified: see its columns certified, reason)"))
    resolution = tuple(args.drawing_resolution)
    drawing_to_csv(result.problem.machine, result.tolerances, drawing, args.overwrite,
                   resolution=resolution)
    _, drawn = drawing_tolerances(result.problem.names, result.tolerances, resolution)
    meets = bool(np.all(life_loads(result.problem, drawn) <= 1.0 + 1e-12))
    print(f"drawing tolerances written to {drawing}, meet the life target at the "
          f"{len(result.problem.poses)} poses of the problem: {'yes' if meets else 'NO'}; "
          + drawing_check_text(result, resolution, targets=False))
    fields = found.fields()
    write_csv(pd.DataFrame([fields]), summary_path, args.overwrite, index=False)
    print(f"summary (life_years {fields['life_years']:g}, the two costs) written to "
          f"{summary_path}")
