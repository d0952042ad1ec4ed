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
:func:`allocation.correlated.solve_correlated`; the table also gives the worst-pose
reliability that the optimum designed for an uncorrelated pair actually has under that
correlation.

Run ``python -m studies.correlation_study`` (options: ``--pair A B``, ``--side``,
``--values``).
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
import pandas as pd

from allocation.correlated import solve_correlated
from reliability.fosm import fosm
from reliability.machine import hobbing_machine
from reliability.poses import workspace_grid

PAIR = ("X.ey", "X.dz")
VALUES = tuple(np.round(np.linspace(-0.8, 0.8, 9), 10))


def correlation_sweep(machine=None, pair=PAIR, values=VALUES, *, side: str = "two_sided",
                      progress=None) -> pd.DataFrame:
    """Certified optimal cost of ``machine`` for each correlation of ``pair``.

    Parameters
    ----------
    machine : Machine, optional
        Default the paper's machine; its own correlations are kept, ``pair`` is set on top.
    pair : (str, str)
        Two error names (paper names or ISO 230-1 symbols).
    values : sequence of float
        Correlation coefficients in [-1, 1].
    side : {'one_sided', 'two_sided'}
    progress : callable, optional
        ``progress(done, total)`` after each solve.

    Returns
    -------
    DataFrame
        Indexed by ``rho``: ``cost``, ``cost_vs_rho0`` (ratio to the optimum with the pair
        uncorrelated), ``dual_bound``, ``relative_gap``, ``certified``,
        ``rho0_optimum_worst_P`` (lowest worst-pose probability over the six outputs of
        the uncorrelated pair's optimum when the pair has this correlation: what ignoring
        the correlation costs in reliability).
    """
    machine = hobbing_machine() if machine is None else machine
    values = [float(v) for v in values]
    poses = workspace_grid(machine)
    jacobian = machine.jacobian(poses)
    results = {}
    for done, rho in enumerate(values, 1):
        results[rho] = solve_correlated(machine.with_correlation({tuple(pair): rho}), poses,
                                        side=side)
        if progress is not None:
            progress(done, len(values))
    baseline = results[0.0] if 0.0 in results else solve_correlated(
        machine.with_correlation({tuple(pair): 0.0}), poses, side=side)
    rows = []
    for rho, result in results.items():
        check = fosm(machine.with_correlation({tuple(pair): rho}), baseline.tolerances, poses,
                     jacobian=jacobian)
        rows.append({"rho": rho, "cost": result.cost,
                     "cost_vs_rho0": result.cost / baseline.cost,
                     "dual_bound": result.dual_bound, "relative_gap": result.relative_gap,
                     "certified": result.certified,
                     "rho0_optimum_worst_P": float(check.worst(side).min())})
    return pd.DataFrame(rows).set_index("rho")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pair", nargs=2, default=PAIR, metavar=("A", "B"),
                        help="two error names (paper or ISO 230-1), default X.ey X.dz")
    parser.add_argument("--side", default="two_sided", choices=("one_sided", "two_sided"))
    parser.add_argument("--values", nargs="+", type=float, default=VALUES,
                        help="correlation coefficients (default −0.8 … 0.8 by 0.2)")
    args = parser.parse_args(argv)
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
    return 0


if __name__ == "__main__":
    sys.exit(main())
