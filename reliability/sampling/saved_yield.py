"""A machine yield saved inside another result (a verification, a yield allocation).

:class:`SavedYield` writes every field of a
:class:`~reliability.sampling.machine_yield.YieldEstimate` and reads it back checked
(:mod:`reliability.basics.saved_fields`): the estimate and its interval are the saved ones,
so a reloaded result reaches the same verdicts.
"""

from __future__ import annotations

from ..basics.saved_fields import (Frame, Integer, Number, Text, read_fields,
                                   write_fields)
from .machine_yield import SHARE_COLUMNS, YieldEstimate

FIELDS = (Number("estimate", low=0.0, high=1.0), Number("lower", low=0.0, high=1.0),
          Number("upper", low=0.0, high=1.0), Number("confidence", low=0.0, high=1.0),
          Number("cov", finite=False), Integer("machines", low=1),
          Text("method", ("crude", "importance")), Text("method_reason"), Text("profile"),
          Text("distribution", ("normal", "truncated")), Text("workspace"),
          Integer("n_poses", low=1), Integer("failures", low=0),
          Number("first_order_lower", finite=False), Number("first_order_upper", finite=False),
          Frame("failure_shares", SHARE_COLUMNS),
          Number("target_cov", optional=True, positive=True))


class SavedYield:
    """The payload writer and reader of a :class:`YieldEstimate` (for
    :class:`~reliability.basics.saved_fields.Nested`)."""

    @staticmethod
    def payload(estimate) -> dict:
        """The JSON-ready fields of ``estimate``."""
        return write_fields(estimate, FIELDS)

    @staticmethod
    def from_payload(data) -> YieldEstimate:
        """The estimate saved by :meth:`payload`, read through ``data`` and checked: the
        interval holds the estimate and the failures are among the machines."""
        values = read_fields(data, FIELDS)
        if not values["lower"] <= values["estimate"] <= values["upper"]:
            raise data.error("estimate", "lies outside its interval [lower, upper]")
        if values["failures"] > values["machines"]:
            raise data.error("failures", "exceeds 'machines'")
        return YieldEstimate(**values)
