"""Users keep working: every name exported at the top of ``reliability`` and ``allocation`` in
0.3.0 is still exported there, as the same kind of object.

The lists are written out here (not read from the packages), so a name that disappears from
``__all__`` or stops importing fails this test.
"""

import importlib

import pytest

#: ``reliability.__all__`` of release 0.3.0.
RELIABILITY_0_3_0 = (
    "Axis", "COMPONENTS", "CompensationTables", "CostCoefficients", "FosmResult",
    "GridExperiment", "GridExperimentResult", "Identification", "Machine",
    "MachineDescriptionError", "OUTPUTS", "PoseSamplingResult", "RandomPoseResult",
    "SystemReliability", "compensation_tables", "fosm", "hobbing_machine", "identify",
    "interop", "load_machine", "machine_from_dict", "machine_from_toml", "random_poses", "rare",
    "read_compensation", "read_identification", "read_measurements", "sample_at_poses",
    "sample_random_poses", "system_reliability", "workspace_grid", "worst_system_reliability",
    "write_compensation")
#: ``allocation.__all__`` of release 0.3.0.
ALLOCATION_0_3_0 = (
    "AllocationProblem", "AllocationResult", "Catalogue", "CatalogueClass",
    "CatalogueInfeasibleError", "CatalogueResult", "Component", "ContinuousAllocation",
    "ConvexSolution", "CostModel", "FcemResult", "GwoResult", "InfeasibleAllocationError",
    "ScreenedRows", "TargetUnreachableError", "YieldAllocation", "YieldUnreachableError",
    "allocate_for_yield", "allocation_point", "cost_reliability_front", "cost_weights",
    "fcem_coefficient", "grey_wolf", "grey_wolf_reference", "load_catalogue",
    "read_allocation_csv", "requirement_table", "screen_rows", "solve_catalogue",
    "solve_continuous", "solve_convex_allocation", "solve_exact", "solve_gwo",
    "solve_over_workspace", "system_allocation")


@pytest.mark.parametrize("package, names", [("reliability", RELIABILITY_0_3_0),
                                            ("allocation", ALLOCATION_0_3_0)])
def test_every_0_3_0_name_is_still_exported(package, names):
    module = importlib.import_module(package)
    missing = [name for name in names if name not in module.__all__]
    assert not missing, f"{package}.__all__ lost {missing}"
    unresolved = [name for name in names if not hasattr(module, name)]
    assert not unresolved, f"{package} no longer resolves {unresolved}"


def test_exported_errors_are_still_exceptions():
    import allocation
    import reliability
    for error in (reliability.MachineDescriptionError, allocation.InfeasibleAllocationError,
                  allocation.TargetUnreachableError, allocation.YieldUnreachableError,
                  allocation.CatalogueInfeasibleError):
        assert issubclass(error, Exception), error
    assert issubclass(allocation.TargetUnreachableError, allocation.InfeasibleAllocationError)
