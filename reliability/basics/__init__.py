"""Shared basics: the toolkit's exceptions, input checks, random streams, statistics, display
of poses and units, ties, memory chunks, the files results are written to and read from, and
keywords renamed (:mod:`reliability.basics.renamed`).

The ground floor: it imports nothing else of the toolkit.
"""
