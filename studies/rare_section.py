"""Verification at the worst poses and rare-event estimates, as a report section and as the
helpers behind ``precrel verify --precision`` and ``--rare``.

* :func:`worst_pose_verification` — crude Monte-Carlo on the exact model at each output's
  worst pose, beside FOSM, with Wilson intervals (optionally adaptive).
* :func:`rare_event_table` — the failure probability of each output and of the system at
  its worst grid pose, by importance sampling (or subset simulation) on the exact model.
* :func:`rare_section` — both, as a :class:`~studies.section.Section`.
* :func:`verify_precision_text`, :func:`verify_rare_text` — printable text and summary
  entries for the command line.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from scipy.stats import norm

from reliability.fosm import fosm
from reliability.pose_sampling import EVENTS, sample_at_poses
from reliability.poses import workspace_grid
from reliability.rare import failure_probability, worst_grid_poses
from studies.report import markdown_table
from studies.section import Section

SCIENTIFIC = "{:.3e}".format


def worst_pose_verification(machine, tolerances, *, samples: int = 200_000, precision=None,
                            max_samples: int = 2_000_000, k: float = 3.0,
                            distribution: str = "normal", rng=None):
    """Crude Monte-Carlo at each output's worst grid pose (and the system event there).

    See :func:`reliability.pose_sampling.sample_at_poses`; with ``precision`` the sampling
    stops once every interval's relative half-width on the failure probability is at most
    ``precision`` (or at ``max_samples``).
    """
    return sample_at_poses(machine, tolerances, samples=samples, precision=precision,
                           max_samples=max_samples, k=k, distribution=distribution, rng=rng)


def rare_event_table(machine, tolerances, *, events=EVENTS, method: str = "importance",
                     target_cov: float = 0.1, max_evaluations: int = 20_000, k: float = 3.0,
                     distribution: str = "normal", rng=None) -> pd.DataFrame:
    """Failure probability of each event at its worst grid pose, one row per event.

    Columns: the pose (axis positions with units), the estimate, its CoV and interval, the
    exact-model evaluations, whether the target CoV was reached and the linear FOSM answer
    (:class:`reliability.rare.RareEventResult`).
    """
    events = tuple(events)
    streams = np.random.default_rng(rng).spawn(len(events))
    poses = worst_grid_poses(machine, tolerances, events, k=k)
    frames = []
    for event, stream, pose in zip(events, streams, poses):
        result = failure_probability(machine, tolerances, pose, event=event, method=method,
                                     target_cov=target_cov, max_evaluations=max_evaluations,
                                     k=k, distribution=distribution, rng=stream)
        frames.append(result.to_frame())
    return pd.concat(frames, ignore_index=True).set_index("event")


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
        Options of :func:`reliability.rare.failure_probability`.
    """
    mc_stream, rare_stream = np.random.default_rng(rng).spawn(2)
    verification = worst_pose_verification(machine, tolerances, samples=samples,
                                            precision=precision, k=k,
                                            distribution=distribution, rng=mc_stream)
    mc = verification.to_frame()
    text = [f"Crude Monte-Carlo on the exact model at each output's worst pose of the "
            f"workspace grid, {verification.n_samples} independent error draws per pose "
            f"({distribution} errors, t = ±{k:g}σ), {100 * verification.confidence:.0f} % "
            f"Wilson intervals on the failure probability, beside the linear-Gaussian "
            f"(FOSM two-sided; system: six-dimensional normal rectangle) answer.", "",
            markdown_table(mc[["pose", "event", *verification.axes, "mc_failure", "lower",
                               "upper", "fosm_failure"]],
                           {c: SCIENTIFIC for c in ("mc_failure", "lower", "upper",
                                                    "fosm_failure")}, index=False)]
    tables = {f"{label}_worst_pose_mc.csv": mc}
    summary = {f"{label}_worst_pose_mc": {
        "samples": verification.n_samples, "precision": precision,
        "reached": verification.reached,
        "failure": {f"{row.pose}/{row.event}": row.mc_failure for row in mc.itertuples()}}}
    if rare:
        table = rare_event_table(machine, tolerances, target_cov=target_cov,
                                 max_evaluations=max_evaluations, k=k,
                                 distribution=distribution, rng=rare_stream)
        text += ["", f"Failure probability of each output and of the system at its worst grid "
                 f"pose by importance sampling on the exact model (target CoV {target_cov:g}, "
                 f"at most {max_evaluations} evaluations); the interval is estimate ± 1.96 "
                 f"standard errors. fosm_probability is the linear two-sided answer (for the "
                 f"system the union bound Σ_o, an upper bound).", "",
                 markdown_table(table[["probability", "cov", "lower", "upper",
                                       "n_evaluations", "fosm_probability"]],
                                {c: SCIENTIFIC for c in ("probability", "lower", "upper",
                                                         "fosm_probability")}
                                | {"cov": "{:.3f}".format})]
        tables[f"{label}_rare_events.csv"] = table
        summary[f"{label}_rare_events"] = {
            event: {"probability": row["probability"], "cov": row["cov"],
                    "evaluations": int(row["n_evaluations"])}
            for event, row in table.iterrows()}
    return Section(title=f"Verification at the worst poses ({label})", text="\n".join(text),
                   tables=tables, summary=summary)


# ----- command-line helpers ------------------------------------------------------------------
def reachable_events(machine, tolerances, precision: float, max_samples: int, *,
                     k: float = 3.0, confidence: float = 0.95) -> tuple[str, ...]:
    """Events whose worst-pose failure probability crude Monte-Carlo can resolve to
    ``precision`` within ``max_samples``.

    A Wilson interval's relative half-width on a failure probability p after n samples is
    about z √((1 − p)/(n p)), so n ≤ max_samples reaches ``precision`` only if
    p ≳ (z/precision)² / max_samples. FOSM's two-sided failure probability at each output's
    worst grid pose decides; the system event (which fails at least as often as any output)
    is kept when any output is.
    """
    z = norm.ppf(0.5 + confidence / 2)
    threshold = (z / precision) ** 2 / max_samples
    grid = fosm(machine, tolerances, workspace_grid(machine), k=k)
    failure = 1.0 - grid.two_sided.min(axis=0)
    kept = tuple(o for o, p in zip(machine.outputs, failure) if p >= threshold)
    return kept + ("system",) if kept else ()


def verify_precision_text(machine, tolerances, precision: float, *,
                          max_samples: int = 2_000_000, k: float = 3.0,
                          distribution: str = "normal", rng=None) -> tuple[str, dict]:
    """``precrel verify --precision P``: adaptive Monte-Carlo at the worst poses.

    Only the events crude sampling can resolve within ``max_samples``
    (:func:`reachable_events`) are sampled; the text names the others, for ``--rare``.
    Returns the text to print (the result's summary) and summary entries.
    """
    events = reachable_events(machine, tolerances, precision, max_samples, k=k)
    skipped = [e for e in EVENTS if e not in events]
    note = (f"\nNot sampled (failure probability too small for {max_samples} samples to reach "
            f"the precision; use --rare): {', '.join(skipped)}" if skipped else "")
    if not events:
        return note.lstrip("\n"), {"precision": float(precision), "events": []}
    result = sample_at_poses(machine, tolerances, precision=precision,
                             max_samples=max_samples, k=k, distribution=distribution,
                             events=events, rng=rng)
    frame = result.to_frame()
    entries = {"samples": result.n_samples, "precision": float(precision),
               "reached": bool(result.reached), "events": list(events),
               "failure": {f"{r.pose}/{r.event}": r.mc_failure for r in frame.itertuples()}}
    return result.summary() + note, entries


def verify_rare_text(machine, tolerances, *, method: str = "importance",
                     target_cov: float = 0.1, max_evaluations: int = 20_000, k: float = 3.0,
                     distribution: str = "normal", rng=None) -> tuple[str, dict]:
    """``precrel verify --rare``: rare-event failure probabilities at the worst poses."""
    table = rare_event_table(machine, tolerances, method=method, target_cov=target_cov,
                             max_evaluations=max_evaluations, k=k,
                             distribution=distribution, rng=rng)
    text = (f"Failure probability at each event's worst grid pose ({method}, exact model, "
            f"{distribution} errors):\n"
            + table.drop(columns=["distribution"]).to_string(float_format="{:.4g}".format))
    entries = {event: {"probability": row["probability"], "cov": row["cov"],
                       "lower": row["lower"], "upper": row["upper"],
                       "evaluations": int(row["n_evaluations"]),
                       "reached": bool(row["reached"])}
               for event, row in table.iterrows()}
    return text, entries
