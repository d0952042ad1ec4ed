"""Report section: Monte-Carlo at each output's worst pose beside FOSM, and rare-event
estimates of each output's and the system's failure probability there.

The computations are :func:`reliability.sampling.pose_sampling.sample_at_poses` (crude, optionally
adaptive, Wilson intervals) and :func:`reliability.sampling.verification.rare_event_table`
(importance sampling or subset simulation on the exact model).
"""

from __future__ import annotations

from reliability.basics.streams import spawn
from reliability.sampling.pose_sampling import sample_at_poses
from reliability.sampling.verification import rare_event_table

from .markdown import details, interval_formats, markdown_table, significant_bound
from .section import Section

SCIENTIFIC = "{:.3e}".format


def rare_section(machine, tolerances, *, label: str = "allocation", samples: int = 200_000,
                 precision=None, rare: bool = True, target_cov: float = 0.1,
                 max_evaluations: int = 20_000, k: float = 3.0,
                 distribution: str = "normal", rng=None) -> Section:
    """Report section: Monte-Carlo at the worst poses beside FOSM, and rare-event estimates.

    Parameters
    ----------
    machine : Machine
    tolerances : array_like
        The allocation to verify.
    label : str
        Name of the allocation in the text and the file names.
    samples, precision
        Crude Monte-Carlo samples per pose, or the relative precision to stop at.
    rare : bool
        Also estimate each event's failure probability by importance sampling.
    target_cov, max_evaluations
        Options of :func:`reliability.sampling.rare_events.failure_probability`.
    """
    mc_stream, rare_stream = spawn(rng, 2)
    verification = sample_at_poses(machine, tolerances, samples=samples, precision=precision,
                                   k=k, distribution=distribution, rng=mc_stream)
    mc = verification.to_frame()
    worst = mc.iloc[int(mc["mc_failure"].to_numpy().argmax())]
    text = [f"The largest failure probability by crude Monte-Carlo at the worst poses is "
            f"**{SCIENTIFIC(worst['mc_failure'])}** ({worst['event']} at {worst['pose']}; "
            f"FOSM {SCIENTIFIC(worst['fosm_failure'])}).", "",
            markdown_table(mc[["pose", "event", *verification.axes, "mc_failure", "lower",
                               "upper", "fosm_failure"]],
                           {c: SCIENTIFIC for c in ("mc_failure", "fosm_failure")}
                           | interval_formats(significant_bound(4), lower=("lower",),
                                              upper=("upper",)), index=False), "",
            details("How it is computed", (
                f"Crude Monte-Carlo on the exact model at each output's worst pose of the "
                f"workspace grid, {verification.n_samples} independent error draws per pose "
                f"({distribution} errors, t = ±{k:g}σ), "
                f"{100 * verification.confidence:.0f} % Wilson intervals on the failure "
                f"probability, beside the linear-Gaussian (FOSM two-sided; system: "
                f"six-dimensional normal rectangle) answer."))]
    tables = {f"{label}_worst_pose_mc.csv": mc}
    summary = {f"{label}_worst_pose_mc": {
        "samples": verification.n_samples, "precision": precision,
        "reached": verification.reached,
        "failure": {f"{row.pose}/{row.event}": row.mc_failure for row in mc.itertuples()}}}
    if rare:
        table = rare_event_table(machine, tolerances, target_cov=target_cov,
                                 max_evaluations=max_evaluations, k=k,
                                 distribution=distribution, rng=rare_stream)
        largest = table["probability"].idxmax()
        text += ["", f"By importance sampling, the largest failure probability at the "
                 f"worst grid poses is **{SCIENTIFIC(table.loc[largest, 'probability'])}** "
                 f"({largest}, CoV {table.loc[largest, 'cov']:.3f}).", "",
                 markdown_table(table[["probability", "cov", "lower", "upper",
                                       "n_evaluations", "fosm_probability"]],
                                {c: SCIENTIFIC for c in ("probability", "fosm_probability")}
                                | interval_formats(significant_bound(4), lower=("lower",),
                                                   upper=("upper",))
                                | {"cov": "{:.3f}".format}), "",
                 details("How the rare events are estimated", (
                     f"Failure probability of each output and of the system at its worst "
                     f"grid pose by importance sampling on the exact model (target CoV "
                     f"{target_cov:g}, at most {max_evaluations} evaluations); the interval "
                     f"is estimate ± 1.96 standard errors. fosm_probability is the linear "
                     f"two-sided answer (for the system the union bound Σ_o, an upper "
                     f"bound)."))]
        tables[f"{label}_rare_events.csv"] = table
        summary[f"{label}_rare_events"] = {
            event: {"probability": row["probability"], "cov": row["cov"],
                    "evaluations": int(row["n_evaluations"])}
            for event, row in table.iterrows()}
    return Section(title=f"Verification at the worst poses ({label})", text="\n".join(text),
                   tables=tables, summary=summary)
