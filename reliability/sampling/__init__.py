"""Sampling on the exact chain: the grid experiment of Sec. 5.3, Monte-Carlo at given or
random poses, rare events, the machine yield, and the verification of an allocation.

Built on :mod:`reliability.first_order`, :mod:`reliability.model` and
:mod:`reliability.basics`.
"""
