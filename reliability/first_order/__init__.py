"""First-order methods: FOSM (Eqs. 19–23), the exact probability of the linearised output,
system reliability, the output covariance, each event's worst pose on the workspace grid, and
the worst pose over the continuous workspace (a local search and a certificate).

Built on :mod:`reliability.model` and :mod:`reliability.basics`.
"""
