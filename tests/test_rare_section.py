"""The rare-event report section, the verification tables behind it and the command line's
``verify --precision`` / ``--rare`` text."""

from __future__ import annotations

import json
from types import SimpleNamespace

from reliability.sampling.verification import rare_event_table, reachable_events
from studies.cli.verify import precision_text, rare_text
from studies.report.rare_section import rare_section
from studies.report.section import Section


def test_rare_section_has_both_tables_and_json_summary(hobbing):
    section = rare_section(hobbing, hobbing.initial_allocation, label="initial",
                           samples=2000, target_cov=0.3, max_evaluations=2000, rng=1)
    assert isinstance(section, Section)
    assert set(section.tables) == {"initial_worst_pose_mc.csv", "initial_rare_events.csv"}
    assert len(section.tables["initial_rare_events.csv"]) == 7  # six outputs and the system
    assert "| worst dx | dx |" in section.text
    json.dumps(section.summary)


def test_rare_event_table_has_one_row_per_event(hobbing):
    table = rare_event_table(hobbing, hobbing.initial_allocation, target_cov=0.3,
                             max_evaluations=2000, rng=3)
    assert list(table.index) == ["dx", "dy", "dz", "ex", "ey", "ez", "system"]
    assert (table["probability"] > 0).all() and (table["n_evaluations"] <= 2000).all()


def test_reachable_events_follow_the_sample_cap(hobbing):
    t = hobbing.initial_allocation
    assert reachable_events(hobbing, t, 0.5, 4000)[-1] == "system"
    assert reachable_events(hobbing, t, 1e-3, 10) == ()  # no probability resolvable


def test_command_line_text(hobbing):
    text = precision_text(hobbing, hobbing.initial_allocation, 0.5, 4000, rng=2)
    assert "Relative half-width target 0.5" in text
    args = SimpleNamespace(rare_method="importance", target_cov=0.3, max_evaluations=2000)
    text = rare_text(hobbing, hobbing.initial_allocation, args, rng=3)
    assert "importance" in text and "system" in text
