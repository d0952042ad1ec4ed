"""Precision allocation (paper Secs. 4.2–4.4): cost model, FCEM, the problem of Eq. (34)
and its solvers — the Grey Wolf Optimiser as in the paper, a certified exact optimum, and the
certified cheapest choice of catalogue components (:mod:`allocation.catalogue.discrete`).

Its rooms run one way: :mod:`~allocation.solvers` and :mod:`~allocation.cost` (the ground
floor) <- :mod:`~allocation.per_pose` <- :mod:`~allocation.catalogue` and
:mod:`~allocation.machine_yield`.

>>> import reliability, allocation
>>> machine = reliability.hobbing_machine()
>>> problem = allocation.AllocationProblem.build(machine, side="two_sided")  # doctest: +SKIP
>>> best = problem.solve_exact()                                          # doctest: +SKIP
"""

from .catalogue.catalogue import Catalogue, CatalogueClass, Component, load_catalogue
from .catalogue.discrete import CatalogueInfeasibleError, CatalogueResult, solve_catalogue
from .cost.cost import CostModel, cost_weights
from .cost.fuzzy_evaluation import FcemResult, fcem_coefficient
from .machine_yield.yield_target import YieldAllocation, YieldUnreachableError, allocate_for_yield
from .per_pose.continuous import ContinuousAllocation, solve_continuous, solve_over_workspace
from .per_pose.elasticity import requirement_table
from .per_pose.front import allocation_point, cost_reliability_front
from .per_pose.problem import AllocationProblem, ScreenedRows, screen_rows
from .per_pose.result_files import read_allocation_csv
from .per_pose.solve import AllocationResult, TargetUnreachableError, solve_exact, solve_gwo
from .per_pose.system_target import system_allocation
from .solvers.convex import ConvexSolution, InfeasibleAllocationError, solve_convex_allocation
from .solvers.gwo import GwoResult, grey_wolf, grey_wolf_reference

__all__ = ["AllocationProblem", "AllocationResult", "Catalogue", "CatalogueClass",
           "CatalogueInfeasibleError", "CatalogueResult", "Component",
           "ContinuousAllocation", "ConvexSolution", "CostModel", "FcemResult",
           "GwoResult", "InfeasibleAllocationError", "ScreenedRows",
           "TargetUnreachableError", "YieldAllocation", "YieldUnreachableError",
           "allocate_for_yield", "allocation_point", "cost_reliability_front",
           "cost_weights", "fcem_coefficient", "grey_wolf", "grey_wolf_reference",
           "load_catalogue", "read_allocation_csv", "requirement_table", "screen_rows",
           "solve_catalogue", "solve_continuous", "solve_convex_allocation", "solve_exact",
           "solve_gwo", "solve_over_workspace", "system_allocation"]
