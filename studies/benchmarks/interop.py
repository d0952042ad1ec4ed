"""Peer table of the sensitivity tools on the paper's machine: OpenTURNS FORM against our
FOSM, our Sobol indices against the FOSM variance shares, SALib's and OpenTURNS' estimates
on the same function, and d yield / d ln t by the score function against central differences.

Run as ``python -m studies.benchmarks.interop [--samples N] [--machines N] [--points P]
[--seed S]`` (needs the ``interop`` extra). Prints:

1. at each output's worst pose of the 5-point grid (initial allocation, Table 4), our FOSM β
   and two-sided failure probability against OpenTURNS FORM (AbdoRackwitz, both tails) on
   :func:`reliability.interop.openturns_model`, with FORM's model calls and time;
2. per output, our Sobol first-order indices against the FOSM variance shares (largest
   difference), and against SALib (Saltelli sampling, ``sobol.analyze``) and OpenTURNS
   (``SaltelliSensitivityAlgorithm``) on the same chain: the largest difference in units of
   the combined interval half-widths (SALib's bootstrap, ours; OpenTURNS' asymptotic), model
   calls and times;
3. d yield / d ln t of the ten most influential items and groups by the score function on the
   yield's draws against central differences (h = 0.1) on the same draws, with standard
   errors, on the paper's machine and on the 5-axis test machine with a C table and a B
   swivel head (tests/machines/swivel5.toml), under the constant profile on a ``--points``
   grid.

Nothing is asserted; the numbers are the result.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.stats import norm

import reliability
from reliability.first_order.fosm import fosm
from reliability.first_order.worst_grid_pose import worst_grid_poses
from reliability.interop import openturns_model, salib_evaluate, salib_problem
from reliability.model.machine import OUTPUTS
from reliability.sampling.machine_yield import YieldModel
from reliability.sampling.sobol import sobol_indices
from reliability.sampling.yield_sensitivity import yield_sensitivity
from studies.workflows.timing import one_blas_thread

SWIVEL = Path(__file__).resolve().parents[2] / "tests" / "machines" / "swivel5.toml"


def form_table(machine, t, poses) -> pd.DataFrame:
    """FOSM against OpenTURNS FORM at each output's worst pose."""
    import openturns as ot
    reference = fosm(machine, t, poses)
    rows = []
    for o, output in enumerate(OUTPUTS):
        function, distribution = openturns_model(machine, o, poses[o])
        vector = ot.CompositeRandomVector(function, ot.RandomVector(distribution))
        start = time.perf_counter()
        tails = []
        for side, limit in ((ot.Greater(), machine.limits[o]), (ot.Less(), -machine.limits[o])):
            algorithm = ot.FORM(ot.AbdoRackwitz(), ot.ThresholdEvent(vector, side, float(limit)),
                                distribution.getMean())
            algorithm.run()
            tails.append(algorithm.getResult())
        rows.append({"output": output, "beta FOSM": reference.beta[o, o],
                     "beta FORM": tails[0].getHasoferReliabilityIndex(),
                     "P fail FOSM": 1.0 - reference.two_sided[o, o],
                     "P fail FORM": sum(r.getEventProbability() for r in tails),
                     "FORM calls": function.getEvaluationCallsNumber(),
                     "FORM time [s]": time.perf_counter() - start})
    return pd.DataFrame(rows)


def sobol_table(machine, t, poses, samples, seed) -> pd.DataFrame:
    """Ours against the FOSM shares, SALib and OpenTURNS, per output at its worst pose."""
    import openturns as ot
    from SALib.analyze import sobol as salib_analyze
    from SALib.sample import sobol as salib_sample
    start = time.perf_counter()
    ours = sobol_indices(machine, t, poses, samples=samples, rng=seed)
    our_time = time.perf_counter() - start
    problem = salib_problem(machine, t)
    rows = []
    for o, output in enumerate(OUTPUTS):
        start = time.perf_counter()
        x = salib_sample.sample(problem, samples, calc_second_order=False, seed=seed)
        salib = salib_analyze.analyze(problem, salib_evaluate(machine, x, o, poses[o]),
                                      calc_second_order=False, seed=seed)
        salib_time = time.perf_counter() - start
        start = time.perf_counter()
        function, distribution = openturns_model(machine, o, poses[o], tolerances=t)
        ot.RandomGenerator.SetSeed(seed)
        design = ot.SobolIndicesExperiment(distribution, samples, False).generate()
        algorithm = ot.SaltelliSensitivityAlgorithm(design, function(design), samples)
        ot_s1 = np.asarray(algorithm.getFirstOrderIndices())
        ot_interval = algorithm.getFirstOrderIndicesInterval()
        ot_half = 0.5 * (np.asarray(ot_interval.getUpperBound())
                         - np.asarray(ot_interval.getLowerBound()))
        ot_time = time.perf_counter() - start
        s1, half = ours.S1[o], ours.S1_conf[o]
        with np.errstate(invalid="ignore", divide="ignore"):  # errors that move nothing
            salib_gap = np.abs(s1 - salib["S1"]) / np.hypot(half, salib["S1_conf"])
            ot_gap = np.abs(s1 - ot_s1) / np.hypot(half, ot_half)
        rows.append({
            "output": output,
            "max |S1 - FOSM share|": np.nanmax(np.abs(s1 - ours.analytic[o])),
            "max |ours - SALib| / halfwidths": np.nanmax(salib_gap),
            "max |ours - OT| / halfwidths": np.nanmax(ot_gap),
            "calls ours": ours.model_calls, "calls SALib": len(x), "calls OT": design.getSize(),
            "time ours [s]": our_time / len(OUTPUTS), "time SALib [s]": salib_time,
            "time OT [s]": ot_time})
    return pd.DataFrame(rows)


def yield_table(machine, t, points, machines, seed) -> pd.DataFrame:
    """Score function against central differences for the ten largest items and groups."""
    model = YieldModel(machine, points=points)
    draws = model.draws(machines, rng=seed)
    start = time.perf_counter()
    score = yield_sensitivity(model, t, draws=draws)
    score_time = time.perf_counter() - start
    top = score.ranked().head(10)
    members = [tuple(name.split("+")) for name in top["error"]]
    start = time.perf_counter()
    check = yield_sensitivity(model, t, draws=draws, method="difference",
                              errors=[m[0] for m in members if len(m) == 1],
                              groups=[m for m in members if len(m) > 1])
    difference_time = time.perf_counter() - start
    theirs = check.to_frame().set_index("error").loc[top["error"]]
    frame = pd.DataFrame({"error": top["error"].to_numpy(),
                          "score": top["dyield_dlnt"].to_numpy(),
                          "se score": top["se"].to_numpy(),
                          "difference": theirs["dyield_dlnt"].to_numpy(),
                          "se difference": theirs["se"].to_numpy()})
    frame["z"] = (frame["score"] - frame["difference"]) / np.hypot(frame["se score"],
                                                                   frame["se difference"])
    frame.attrs["text"] = (f"{machine.name}: yield {score.yield_estimate:.4f} on {machines} "
                           f"machines, {model.workspace}, profile {model.profile}; score "
                           f"{score_time:.2f} s for all {len(score.errors)} rows, differences "
                           f"{difference_time:.2f} s for 10")
    return frame


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=1024)
    parser.add_argument("--machines", type=int, default=4000)
    parser.add_argument("--points", type=int, default=3)
    parser.add_argument("--seed", type=int, default=2023)
    args = parser.parse_args(argv)
    return run(args)


@one_blas_thread
def run(args) -> int:
    pd.set_option("display.width", 200)
    machine = reliability.hobbing_machine()
    t = machine.initial_allocation
    poses = worst_grid_poses(machine, t)
    print("1. OpenTURNS FORM against FOSM at each output's worst pose (initial allocation)")
    print(form_table(machine, t, poses).to_string(index=False, float_format="{:.6g}".format))
    print(f"\n2. Sobol first-order indices, N = {args.samples} "
          f"(intervals at 95 %, z = {norm.ppf(0.975):.2f})")
    print(sobol_table(machine, t, poses, args.samples, args.seed)
          .to_string(index=False, float_format="{:.3g}".format))
    print("\n3. d yield / d ln t: score function against central differences (h = 0.1)")
    for subject in (machine, reliability.load_machine(SWIVEL)):
        table = yield_table(subject, subject.initial_allocation, args.points, args.machines,
                            args.seed)
        print(table.attrs["text"])
        print(table.to_string(index=False, float_format="{:.4f}".format))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
