"""The log-concave lower bound of an allocation for a machine yield: whether it runs by
default, on which sample, and why it is missing when it is.

Under the ``constant`` profile the bound and the convex step run on rays (directional
sampling, seconds: :func:`allocation.machine_yield.yield_dual.dual_bound`) and are part of
every run. Under the ``independent`` and ``gp`` profiles they run on crude machines of the
profile (:func:`allocation.machine_yield.yield_dual.crude_bound`; the rows of every grid
pose times every draw along travel, minutes), so only when asked for. Where the theorem
does not hold (the truncated reading, an item correlation) they are refused, and the
result says why (:func:`log_concave_text`).
"""

from __future__ import annotations

from reliability.basics import streams

from .yield_controlled import BOUND_STREAM
from .yield_dual import crude_bound, dual_bound, not_log_concave, on_rays

#: Rays of each sample of the log-concave bound, as a multiple of the machines.
BOUND_MACHINES_FACTOR = 10
#: Rays per machine on which the log-concave bound's point is rescaled to the yield.
RESCALE_FACTOR = 3
#: Confidence of the log-concave bound.
BOUND_CONFIDENCE = 0.95


def bracket_defaults(machine, machines: int, convex_steps, bound_machines):
    """``(convex_steps, bound_machines)`` with the defaults filled in: one step and
    :data:`BOUND_MACHINES_FACTOR` × ``machines`` rays where the estimates run on rays
    (:func:`~allocation.machine_yield.yield_dual.on_rays`), none elsewhere."""
    rays = on_rays(machine, machine.profile, machine.distribution)
    if convex_steps is None:
        convex_steps = 1 if rays else 0
    if bound_machines is None:
        bound_machines = BOUND_MACHINES_FACTOR * machines if rays else 0
    return convex_steps, bound_machines


def result_bound(problem, points, yield_target, start, rays, seed, machines):
    """The lower bound at 95 % from the yield's log-concavity in ``problem``'s box: under
    ``constant`` the tangent at ``start`` (the result, which the convex step brought near
    the optimum) rescaled to ``yield_target`` on :data:`RESCALE_FACTOR` rays per machine,
    the bound on ``rays`` fresh rays; under ``independent`` and ``gp`` one crude step from
    ``start`` and the bound on ``rays`` crude machines. None where the theorem does not
    hold or ``rays`` is 0."""
    machine = problem.machine
    if rays == 0 or not_log_concave(machine, machine.profile, machine.distribution):
        return None
    stream = streams.spawn(seed, BOUND_STREAM + 1)[BOUND_STREAM]
    if machine.profile != "constant":
        return crude_bound(problem, machine.profile, points, yield_target, start,
                           machines=rays, steps=1, confidence=BOUND_CONFIDENCE, rng=stream)
    return dual_bound(problem, points, yield_target, start, machines=rays, steps=0,
                      confidence=BOUND_CONFIDENCE, rng=stream,
                      rescale_rays=RESCALE_FACTOR * machines)


def log_concave_text(machine, rays: int) -> str:
    """Why the log-concave bound was not computed (empty when it was)."""
    why = not_log_concave(machine, machine.profile, machine.distribution)
    if why is not None:
        return f"refused: {why}"
    if rays == 0 and machine.profile != "constant":
        return (f"not computed by default under the profile {machine.profile!r} (it runs on "
                f"crude machines of the profile and takes minutes): ask for it with "
                f"bound_machines (--bound-machines N)")
    return "not asked for" if rays == 0 else ""
