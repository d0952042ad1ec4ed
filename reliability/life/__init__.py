"""Accuracy over time: the reliability of a machine whose errors drift with age
(the machine file's ``[drift]`` table, :mod:`reliability.model.drift`)."""
