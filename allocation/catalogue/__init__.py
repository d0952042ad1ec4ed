"""Component catalogues and the certified cheapest choice of their components (MILP).

Built on :mod:`allocation.per_pose`, :mod:`allocation.solvers` and :mod:`allocation.cost`.
"""
