"""Solvers of the allocation problem: the certified convex core and the Grey Wolf Optimiser.

The ground floor of :mod:`allocation`: it imports nothing else of the package.
"""
