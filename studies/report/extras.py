"""Optional sections of a machine report beyond FOSM, allocation and verification.

Each builder takes the :class:`studies.workflows.machine_study.MachineStudy` and returns a
:class:`~studies.report.section.Section`:

- ``front``: the certified cost–reliability front and the worst-case stack
  (:func:`studies.report.tradeoff_sections.front_section`);
- ``system``: the probability that all six outputs are inside at once, at the worst pose, for
  the initial and the optimal allocation (:func:`studies.report.tradeoff_sections.system_section`);
- ``rare``: Monte-Carlo at each output's worst pose and rare-event estimates of the optimal
  allocation's failure probabilities (:func:`studies.report.rare_section.rare_section`);
- ``profiles``: machine-level yield and Table 9's spread as the motion errors' correlation
  along travel runs from independent to constant
  (:func:`studies.report.profiles_section.profiles_section`).
"""

from __future__ import annotations

from reliability.basics.errors import InputError
from reliability.basics.streams import extra_stream
from studies.workflows.profile_comparison import ProfilesStudy, profile_comparison

from .profiles_section import profiles_section
from .rare_section import rare_section
from .tradeoff_sections import front_section, system_section

#: Every optional section, in report order.
EXTRAS = ("front", "system", "rare", "profiles")
#: Profiles compared in a machine report, from independent to constant (lengths in mm).
REPORT_PROFILES = ("independent", "gp:100", "gp:1000", "constant")


def allocations(study) -> dict:
    """The initial allocation, and the optimum as written when the targets are reachable."""
    shown = {"initial": study.machine.initial_allocation}
    if study.reachable:
        shown["optimum"] = study.allocated
    return shown


def front(study):
    """Cost against reliability, with the stack and the optimum marked."""
    marks = {"optimum": study.allocated} if study.reachable else {}
    return front_section(study.machine, poses=study.problem.poses,
                         box={"lower": study.problem.lower, "upper": study.problem.upper},
                         box_text=study.problem.box_text(), marks=marks)


def system(study):
    """System reliability at the worst pose for the initial and the optimal allocation."""
    return system_section(study.machine, allocations(study), poses=study.problem.poses,
                          rng=extra_stream(study.seed, 0))


def rare(study, samples: int = 100_000):
    """Worst-pose Monte-Carlo and rare-event estimates of the optimal allocation (of the
    initial one when the targets are out of reach)."""
    label, tolerances = list(allocations(study).items())[-1]
    return rare_section(study.machine, tolerances, label=label,
                        samples=samples, distribution=study.machine.distribution,
                        rng=extra_stream(study.seed, 1))


def profiles(study, repeats: int = 200):
    """Yield and spread between experiments against the correlation length."""
    shown = allocations(study)
    comparison = profile_comparison(study.machine, shown, REPORT_PROFILES,
                                    repeats=(repeats,), seed=study.seed)
    # wall times would make the same seed write different files
    return profiles_section(ProfilesStudy(comparison=comparison.drop(columns="seconds")))


BUILDERS = {"front": front, "system": system, "rare": rare, "profiles": profiles}


def builders(names=EXTRAS):
    """The section builders for ``names`` (a subset of :data:`EXTRAS`), in report order."""
    unknown = sorted(set(names) - set(EXTRAS))
    if unknown:
        raise InputError(f"unknown report section {unknown[0]!r}; choose from {EXTRAS}")
    return [BUILDERS[name] for name in EXTRAS if name in names]
