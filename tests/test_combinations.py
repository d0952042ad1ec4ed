"""The combination matrix in the suite (tests/combination_matrix.py): every command on the
paper's machine, a five-axis machine with a rotary table and a swivel head and a three-axis
mill, in both frames, with the box, reading and profile rotated over the cells. Each cell
works, or is refused in one line naming what to change with nothing printed before; no
traceback, no lost report."""

import pytest

from combination_matrix import covering_cells, run_cell


@pytest.mark.parametrize("cell", covering_cells(suite=True), ids=lambda cell: cell.label())
def test_cell_works_or_is_refused_in_one_line(cell, tmp_path):
    outcome = run_cell(cell, tmp_path)
    assert outcome.status in ("works", "refused"), outcome.message
    if outcome.status == "refused":
        assert "\n" not in outcome.message and outcome.message.startswith("precrel: error:")
