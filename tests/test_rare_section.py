"""The rare-event report section and command-line helpers: content and serialisable summary."""

from __future__ import annotations

import json

from studies.rare_section import rare_section, verify_precision_text, verify_rare_text
from studies.section import Section


def test_rare_section_has_both_tables_and_json_summary(hobbing):
    section = rare_section(hobbing, hobbing.initial_allocation, label="initial",
                           samples=2000, target_cov=0.3, max_evaluations=2000, rng=1)
    assert isinstance(section, Section)
    assert set(section.tables) == {"initial_worst_pose_mc.csv", "initial_rare_events.csv"}
    assert len(section.tables["initial_rare_events.csv"]) == 7  # six outputs and the system
    assert "| worst dx | dx |" in section.text
    json.dumps(section.summary)


def test_command_line_helpers_return_text_and_entries(hobbing):
    text, entries = verify_precision_text(hobbing, hobbing.initial_allocation, 0.5,
                                          max_samples=4000, rng=2)
    assert "Relative half-width target 0.5" in text
    assert entries["samples"] <= 4000
    json.dumps(entries)
    text, entries = verify_rare_text(hobbing, hobbing.initial_allocation, target_cov=0.3,
                                     max_evaluations=2000, rng=3)
    assert set(entries) == {"dx", "dy", "dz", "ex", "ey", "ez", "system"}
    assert "importance" in text
    json.dumps(entries)
