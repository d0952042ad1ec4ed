"""The machine compensated: compensation tables from an identification, their files, and the
error a compensated machine keeps (what the measurements cannot see, what lies between table
points, what the table cannot correct).

Built on :mod:`reliability.measured` (the identification and the plan's information),
:mod:`reliability.model` and :mod:`reliability.basics`.
"""
