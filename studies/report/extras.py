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
  (:func:`studies.report.profiles_section.profiles_section`);

and, when asked for, ``tests`` (:func:`acceptance_builder`) and ``catalogue``
(:func:`catalogue_builder`). Every builder is :func:`guarded`: a section that cannot be
computed is replaced by one that says why, and the report is still written.

Every simulated quantity of the report uses the study's profile, machine count and seed, each
from its own stream (:mod:`reliability.basics.streams`), so that the command computing it
alone with the same seed prints the same numbers (docs/reproducibility.md).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from allocation import AllocationProblem, InfeasibleAllocationError, solve_catalogue
from reliability.basics.display import axis_units, with_positions
from reliability.basics.errors import InputError, InputTypeError
from reliability.basics.streams import (acceptance_stream, catalogue_stream,
                                        compensated_acceptance_stream, rare_stream,
                                        system_stream)
from reliability.measured.acceptance_runs import read_acceptance_runs
from studies.workflows.acceptance_evaluation import evaluate_against_design
from studies.workflows.compensated_acceptance import compensated_acceptance
from studies.workflows.profile_comparison import (ProfilesStudy, profile_comparison,
                                                  profile_length)

from .acceptance_section import TITLE as ACCEPTANCE_TITLE
from .acceptance_section import acceptance_section
from .as_measured_section import TITLE as AS_MEASURED_TITLE
from .catalogue_section import TITLE as CATALOGUE_TITLE
from .catalogue_section import catalogue_section
from .evaluation_section import TITLE as EVALUATION_TITLE
from .evaluation_section import evaluation_section
from .life_section import TITLE as LIFE_TITLE
from .profiles_section import TITLE as PROFILES_TITLE
from .profiles_section import profiles_section
from .rare_section import rare_section
from .section import Section
from .tradeoff_sections import front_section, system_section

#: Every optional section, in report order.
EXTRAS = ("front", "system", "rare", "profiles")
#: Profiles compared in a machine report, from independent to constant (lengths in mm);
#: the study's own profile is added when it is not one of them.
REPORT_PROFILES = ("independent", "gp:100", "gp:1000", "constant")
#: Failures that leave an optional section not computed (said in its place); any other
#: exception is a fault of the toolkit and stops the report.
SECTION_FAILURES = (InputError, InputTypeError, InfeasibleAllocationError,
                    np.linalg.LinAlgError, MemoryError)
#: Heading of each optional section, also used when it cannot be computed.
TITLES = {"front": "Cost against reliability", "system": "System reliability",
          "rare": "Verification at the worst poses", "profiles": PROFILES_TITLE,
          "tests": ACCEPTANCE_TITLE, "catalogue": CATALOGUE_TITLE,
          "sensitivity": "What each tolerance buys", "as_measured": AS_MEASURED_TITLE,
          "evaluation": EVALUATION_TITLE, "compensation": "After compensation",
          "life": LIFE_TITLE}
#: The option that asks for each section not in :data:`EXTRAS`.
OPTIONS = {"tests": "--tests", "catalogue": "--catalogue", "sensitivity": "--sensitivity",
           "as_measured": "--identification or --measurements",
           "evaluation": "--measurements with acceptance runs and --tests",
           "compensation": "--compensation", "life": "the machine file's [drift] table"}


def allocations(study) -> dict:
    """The initial allocation, and the optimum as written when the targets are reachable
    (the given allocation when the study has one)."""
    shown = {"initial": study.machine.initial_allocation}
    if study.compared is not None:
        name, tolerances = study.compared
        shown[name] = tolerances
    return shown


def study_profile(study) -> str:
    """The error profile of the study's machine yield (the machine file's or
    ``--profile``), which every simulated quantity of the report uses."""
    return next(iter(study.checks.values())).machine_yield.profile


def front(study):
    """Cost against reliability, with the stack and the optimum marked."""
    marks = dict([study.compared]) if study.compared else {}
    return front_section(study.machine, poses=study.problem.poses,
                         box={"lower": study.problem.lower, "upper": study.problem.upper},
                         box_text=study.problem.box_text(), marks=marks)


def system(study):
    """System reliability at the worst pose for the initial and the optimal allocation."""
    return system_section(study.machine, allocations(study), poses=study.problem.poses,
                          rng=system_stream(study.seed))


def rare(study, samples: int = 100_000):
    """Worst-pose Monte-Carlo and rare-event estimates of the optimal allocation (of the
    initial one when the targets are out of reach)."""
    label, tolerances = list(allocations(study).items())[-1]
    return rare_section(study.machine, tolerances, label=label,
                        samples=samples, distribution=study.machine.distribution,
                        rng=rare_stream(study.seed))


def profiles(study, repeats: int = 200):
    """Yield and spread between experiments against the correlation length; the rows of
    the study's profile carry the study's own machine yield."""
    own = study_profile(study)
    compared = sorted({*REPORT_PROFILES, own}, key=profile_length)
    comparison = profile_comparison(study.machine, allocations(study), compared,
                                    repeats=(repeats,), rng=study.seed,
                                    points=study.points,
                                    distribution=study.machine.distribution)
    # wall times would make the same seed write different files
    comparison = with_study_yields(comparison.drop(columns="seconds"), study)
    return profiles_section(ProfilesStudy(comparison=comparison, study_profile=own))


def with_study_yields(comparison: pd.DataFrame, study) -> pd.DataFrame:
    """``comparison`` with a ``machines`` column, and the rows of the study's profile
    holding the study's machine yield (estimate, interval, built machines)."""
    comparison = comparison.assign(machines=comparison["repeats"])
    own = comparison["profile"] == study_profile(study)
    for label, check in study.checks.items():
        rows = own & (comparison["allocation"] == label)
        y = check.machine_yield
        comparison.loc[rows, ["yield", "yield_lower", "yield_upper", "machines"]] = \
            [y.estimate, y.lower, y.upper, y.machines]
    return comparison


def acceptance_builder(tests, suggest=None, plan=None, plan_name: str = ""):
    """The builder of the acceptance-test section of ``tests``: both allocations under the
    study's profile, with the study's machine count and seed (and the limits a share
    ``suggest`` of built machines meet, when given); with a compensation ``plan``, each
    result after compensation beside (said in its place when it cannot be computed)."""
    def build(study):
        shown = allocations(study)
        compensated = None if plan is None else compensated_results(plan, tests, shown, study)
        return acceptance_section(study.machine, tests, shown,
                                  machines=study.machines, profile=study_profile(study),
                                  suggest=suggest, seed=study.seed, compensated=compensated,
                                  plan_name=plan_name)
    return build


def evaluation_builder(path, tests):
    """The builder of the "Acceptance as measured" section: the acceptance runs of the
    measurement file ``path`` against ``tests`` and machines built to the initial allocation
    under the study's profile, with the study's machine count and seed."""
    def build(study):
        runs = read_acceptance_runs(path, study.machine)
        evaluated = evaluate_against_design(runs, study.machine, tests,
                                            machines=study.machines,
                                            profile=study_profile(study),
                                            rng=acceptance_stream(study.seed))
        return evaluation_section(runs, evaluated, source=str(path), seed=study.seed)
    return build


def compensated_results(plan, tests, shown: dict, study):
    """Label -> acceptance results after compensation of each allocation in ``shown``
    (each from a fresh :func:`compensated_acceptance_stream` of the study's seed), or the
    reason, when one of :data:`SECTION_FAILURES` stops them."""
    try:
        return {label: compensated_acceptance(plan, tests, t, machines=study.machines,
                                              rng=compensated_acceptance_stream(study.seed))
                for label, t in shown.items()}
    except SECTION_FAILURES as error:
        return str(error)


def catalogue_builder(catalogue, start=None, *, start_text: str = "the initial allocation",
                      samples: int = 20_000):
    """The builder of the component-choice section of ``catalogue``: items in no component
    start from ``start`` (default the initial allocation), on the study's grid and side."""
    def build(study):
        problem = study.problem if start is None else AllocationProblem.build(
            study.machine, study.problem.poses, side=study.side, reference=start)
        choice = solve_catalogue(problem, catalogue)
        return catalogue_section(choice, samples=samples, rng=catalogue_stream(study.seed),
                                 start_text=start_text)
    return build


BUILDERS = {"front": front, "system": system, "rare": rare, "profiles": profiles}


def builders(names=EXTRAS):
    """The guarded section builders for ``names`` (a subset of :data:`EXTRAS`), in report
    order."""
    unknown = sorted(set(names) - set(EXTRAS))
    if unknown:
        raise InputError(f"unknown report section {unknown[0]!r}; choose from {EXTRAS}")
    return [guarded(name, BUILDERS[name]) for name in EXTRAS if name in names]


def guarded(name: str, build):
    """``build``, or, when it raises one of :data:`SECTION_FAILURES`, the section
    :func:`not_computed_section` saying why."""
    def make(study):
        try:
            return build(study)
        except SECTION_FAILURES as error:
            return not_computed_section(name, error, study.machine)
    return make


def not_computed_section(name: str, error: Exception, machine) -> Section:
    """The section ``name`` (a key of :data:`TITLES`) that could not be computed: its
    heading, the reason, the blocking rows when the error has them (``NAME_blocking.csv``,
    poses as ``machine``'s axis positions), and ``summary.json``'s ``not_computed`` entry
    ``{name: reason}``."""
    blocking = getattr(error, "blocking", None)
    tables = {} if blocking is None or blocking.empty else {
        f"{name}_blocking.csv": with_positions(blocking, machine.axes, axis_units(machine))}
    reason = " ".join(str(error).split())
    if tables:
        reason += f" (listed in {name}_blocking.csv)"
    asked = f" (asked for by {OPTIONS[name]})" if name in OPTIONS else ""
    text = (f"**Not computed**{asked}: {reason}\n\nThe rest of the report does not depend on "
            f"this section.")
    return Section(TITLES[name], text, tables=tables, summary={"not_computed": {name: reason}})


def not_computed(sections) -> dict:
    """``{name: reason}`` of the sections that could not be computed."""
    missing = {}
    for section in sections:
        missing.update(section.summary.get("not_computed", {}))
    return missing
