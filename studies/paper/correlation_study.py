"""How the certified optimal cost moves as one error correlation runs from −0.8 to 0.8.

The default pair is the X axis' pitch and its vertical straightness, ``X.ey`` (EBX) and
``X.dz`` (EZX). X carries the column along the bed (x horizontal, z vertical), so a
rotation about y is its pitch. When the carriage runs over a local bump or hollow of its
guideway it rises or sinks *and* tips, so the straightness seen at the functional point and
the pitch share one cause; whether they move together or against each other depends on
where that point sits relative to the carriage's bearing pads, hence the sweep over both
signs. In the tool frame both errors move the hob along z, with opposite-signed
sensitivities at most grid poses, so a positive correlation partly cancels them.

For each coefficient the worst-case problem (two-sided reading, 5-point grid, box
[0.5, 1.5] × Table 4) is solved to a certified optimum by
:func:`allocation.per_pose.correlated.solve_correlated`; the table also gives the worst-pose
reliability that the optimum designed for an uncorrelated pair actually has under that
correlation.

Run ``python -m studies.paper.correlation_study`` (options: ``--pair A B``, ``--side``,
``--values``, ``--out DIR`` to write the report section as a report).
"""

from __future__ import annotations

import argparse
import sys

import pandas as pd

from reliability.model.machine_file import hobbing_machine
from studies.report.correlation_section import correlation_section
from studies.report.writer import check_output_folder, write_section
from studies.workflows.correlation_sweep import VALUES, correlation_sweep
from studies.workflows.timing import one_blas_thread

#: The X axis' pitch and vertical straightness (EBX, EZX).
PAIR = ("X.ey", "X.dz")


@one_blas_thread
def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pair", nargs=2, default=PAIR, metavar=("A", "B"),
                        help="two error names (paper or ISO 230-1), default X.ey X.dz")
    parser.add_argument("--side", default="two_sided", choices=("one_sided", "two_sided"))
    parser.add_argument("--values", nargs="+", type=float, default=VALUES,
                        help="correlation coefficients (default −0.8 … 0.8 by 0.2)")
    parser.add_argument("--out", default=None, metavar="DIR",
                        help="also write the report section as a report into DIR")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace an earlier report in DIR")
    args = parser.parse_args(argv)
    if args.out is not None:
        check_output_folder(args.out, args.overwrite)
    machine = hobbing_machine()
    index = [machine.error_index(n) for n in args.pair]
    a, b = (f"{machine.error_names[i]} ({machine.iso_names[i]})" for i in index)
    print(f"{machine.name}: certified optimal cost ({args.side}, 5-point grid) against the "
          f"correlation of {a} and {b}", flush=True)
    frame = correlation_sweep(machine, args.pair, args.values, side=args.side,
                              progress=lambda d, n: print(f"  solved {d}/{n}",
                                                          file=sys.stderr, flush=True))
    with pd.option_context("display.width", 120, "display.float_format", "{:.6g}".format):
        print(frame.to_string())
    if args.out is not None:
        section = correlation_section(machine, args.pair, side=args.side, sweep=frame)
        written = write_section(args.out, section, overwrite=args.overwrite)
        print(f"wrote {len(written)} files to {args.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
