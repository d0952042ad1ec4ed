"""The machine files with a work zone (tests/machines/*_zone.toml): each is its plain
machine plus the zone its header states, and the grid allocation runs on its zone's poses."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from allocation import AllocationProblem
from reliability.model.machine_file import load_machine
from reliability.model.poses import full_grid, workspace_grid
from reliability.model.work_zone import WorkZone, inside_zone

HERE = Path(__file__).parent / "machines"
ROOT = Path(__file__).parent.parent

#: Each zone file, its plain machine and the zone its header comment states.
ZONE_FILES = {
    "swivel5_zone": (HERE / "swivel5.toml",
                     WorkZone("cylinder", centre=(0.0, 0.0), radius=250.0, z=(0.0, 300.0),
                              tilt=(0.0, 60.0))),
    "trunnion5_zone": (HERE / "trunnion5.toml",
                       WorkZone("cylinder", centre=(0.0, 0.0), radius=250.0,
                                z=(0.0, 300.0), tilt=(0.0, 90.0))),
    "hobbing_zone": (ROOT / "reliability" / "machines" / "hobbing.toml",
                     WorkZone("cylinder", centre=(0.0, 0.0), radius=250.0,
                              z=(100.0, 350.0))),
}


@pytest.mark.parametrize("name", sorted(ZONE_FILES))
def test_zone_file_is_its_plain_machine_with_the_stated_zone(name):
    plain_path, zone = ZONE_FILES[name]
    zoned = load_machine(HERE / f"{name}.toml")
    assert zoned.work_zone == zone
    assert replace(zoned, work_zone=None) == load_machine(plain_path)


@pytest.mark.parametrize("name", sorted(ZONE_FILES))
def test_grid_allocation_keeps_to_the_zone(name):
    zoned = load_machine(HERE / f"{name}.toml")
    grid = workspace_grid(zoned, 3)
    assert inside_zone(zoned, grid).all()
    assert 0 < len(grid) < len(full_grid(zoned, 3))
    problem = AllocationProblem.build(zoned, grid)
    result = problem.solve_exact()
    assert result.certificate["certified"]
    assert len(result.problem.poses) == len(grid)
    assert np.all(result.tolerances <= problem.upper * (1 + 1e-9))
