"""The allocation problem of Eq. (34) at poses, its solutions and their files, and what is built
on it: the cost-reliability front, the continuous workspace, the system target, correlated
and compensated errors, and the requirement table.

Built on :mod:`allocation.solvers` and :mod:`allocation.cost`.
"""
