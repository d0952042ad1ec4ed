"""The machine as a model of the reliability ecosystem: an OpenTURNS function and
distribution (:func:`openturns_model`) and a SALib problem with its evaluator
(:func:`salib_problem`, :func:`salib_evaluate`).

OpenTURNS and SALib are optional (``pip install "precision-reliability[interop]"``); they are
imported only when one of these functions is called. Built on :mod:`reliability.sampling`,
:mod:`reliability.first_order`, :mod:`reliability.model` and :mod:`reliability.basics`.
"""

from .openturns_bridge import exact_gradient, openturns_model
from .salib_bridge import salib_evaluate, salib_problem

__all__ = ["exact_gradient", "openturns_model", "salib_evaluate", "salib_problem"]
