"""Allocation for a machine-yield target: the search, its certified lower bounds, the error
shape, the yield's log-concave bound and the equal-yield margin.

Built on :mod:`allocation.per_pose`, :mod:`allocation.solvers` and :mod:`allocation.cost`.
"""
