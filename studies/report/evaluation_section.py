"""The report's "Acceptance as measured" section: the measured machine's ISO values from the
acceptance runs of ``--measurements``, against the limits of ``--tests`` and among the
machines built to the initial allocation (:mod:`studies.workflows.acceptance_evaluation`),
the table ``precrel evaluate --machine --tests`` prints."""

from __future__ import annotations

from studies.workflows.acceptance_evaluation import (printed_table, verdicts_by_test,
                                                     worst_sentences)

from .evaluation_plots import run_figures
from .markdown import details, markdown_table
from .section import Section

TITLE = "Acceptance as measured"


def evaluation_section(runs, evaluated, *, source: str, seed: int) -> Section:
    """The section of ``runs`` (:class:`~reliability.measured.acceptance_runs.AcceptanceRuns`
    read from ``source``) evaluated against the design: ``evaluated`` is what
    :func:`~studies.workflows.acceptance_evaluation.evaluate_against_design` returns, drawn
    from the acceptance stream of ``seed``."""
    table, result, tests = evaluated
    verdicts = verdicts_by_test(table, tests)
    parts = [_answer(verdicts), markdown_table(printed_table(table), index=False),
             "\n".join(f"- {row.test}: " + ("no limit" if row.passes != row.passes else
                                             "passes" if row.passes else "**fails**")
                       for row in verdicts.itertuples()),
             details("How the runs are evaluated", (
                 f"The acceptance runs of {source}: each run's ISO 230-2, ISO 230-4 and ISO "
                 f"10791-6 values (µm), against the limit of the test of its name and among "
                 f"{result.n_machines} machines built to the initial allocation (the "
                 f"acceptance prediction's stream of seed {seed}, profile {result.profile}: "
                 f"`precrel evaluate {source} --machine MACHINE.toml --tests TESTS.toml "
                 f"--machines {result.n_machines} --seed {seed}` prints the same numbers). "
                 f"The percentile is the share of predicted machines whose value is at most "
                 f"the measured one."))]
    parts += worst_sentences(table, result, tests)
    parts += [f"Left out: {sentence}." for sentence in runs.left_out]
    figures = run_figures(runs)
    tables = {"evaluation.csv": table, "evaluation_positions.csv": runs.positions_frame()}
    summary = {"evaluation": {row.test: None if row.passes != row.passes else bool(row.passes)
                              for row in verdicts.itertuples()}}
    return Section(TITLE, "\n\n".join(parts), figures=figures, tables=tables, summary=summary)


def _answer(verdicts) -> str:
    """How many of the tests with a limit the measured machine passes, and which fail."""
    limited = verdicts[verdicts["passes"].notna()]
    failed = [test for test, ok in zip(limited["test"], limited["passes"]) if not ok]
    return (f"As measured, the machine passes **{len(limited) - len(failed)} of "
            f"{len(limited)}** acceptance tests with a limit"
            + (f"; it fails {', '.join(failed)}." if failed else "."))
