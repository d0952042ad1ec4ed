"""The machine as measured: measurement files, simulated measurements of a plan, and the
identification of a built machine's errors from its readings.

Built on :mod:`reliability.acceptance` (a plan is a test file), :mod:`reliability.model` and
:mod:`reliability.basics`.
"""
