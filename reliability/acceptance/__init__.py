"""Acceptance tests on the model: ISO 230-2 positioning, ISO 230-4 circular and
ISO 10791-6-style rotary tests of machines built to an allocation, and their files.

Built on :mod:`reliability.model` and :mod:`reliability.basics` only.
"""
