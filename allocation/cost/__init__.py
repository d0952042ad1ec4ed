"""The price of precision: the power-exponent cost model and the FCEM weights of its items.

A ground floor of :mod:`allocation` beside :mod:`allocation.solvers`: it imports nothing else
of the package.
"""
