"""First-order methods: FOSM (Eqs. 19–23), the exact probability of the linearised output,
system reliability, the output covariance, and the worst pose over the workspace (a local
search and a certificate).

Built on :mod:`reliability.model` and :mod:`reliability.basics`.
"""
