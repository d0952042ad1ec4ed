"""Which boxes of poses can hold a pose of the work zone: rigorous enclosures of the tool
point and the tool tilt over boxes (for the certificate of the continuous workspace).

The tool point ``p(q)`` and the z component of the tool axis, ``cos tilt(q)``, are entries
of the ideal chain ``M(q)``: like the Jacobian, each is of degree 1 in every axis
(``(1, u)`` linear, ``(1, cos θ, sin θ)`` rotary), so they are exact per-axis expansions
(:func:`reliability.first_order.pose_expansion.fit_expansion`, checked against the chain)
and their range over a box of poses is enclosed by
:func:`reliability.first_order.pose_expansion.interval_tree` plus the expansion's margin. A
box is *outside* the zone when the enclosure misses the solid or the tilt range: no pose in
it is in the zone, so the certificate may drop it. A box the enclosure does not prove
outside is kept whole (its bound covers the zone's part of it).
"""

from __future__ import annotations

import math

import numpy as np

from ..basics.errors import InputError
from ..model.work_zone import ANGLE_ROUNDING, LENGTH_ROUNDING, tool_frames
from .pose_expansion import fit_expansion, interval_tree

#: How far (in cos tilt) an enclosure may pass an end of the tilt range and still count as
#: meeting it: the zone's :data:`ANGLE_ROUNDING`, which moves cos by at most as much.
COS_ROUNDING = ANGLE_ROUNDING


class ZoneEnclosure:
    """The work zone of a machine, tested against boxes of poses.

    Parameters
    ----------
    machine : Machine
        With a work zone.
    """

    def __init__(self, machine):
        if machine.work_zone is None:
            raise InputError("machine: it has no work zone to enclose ([workzone] in the "
                             "machine file)")
        self.zone = machine.work_zone
        self.expansion = fit_expansion(machine, lambda q: _point_and_cos(machine, q), 1,
                                       "the tool point")

    def ranges(self, low, high) -> tuple[np.ndarray, np.ndarray]:
        """Enclosures ``(lo, hi)`` of ``(x, y, z, cos tilt)`` over boxes of poses
        ``[low, high]`` (mm, rad; ``(b, n_axes)``), each ``(b, 4)``."""
        expansion = self.expansion
        middle, radius = interval_tree(expansion, expansion.local(np.atleast_2d(low)),
                                       expansion.local(np.atleast_2d(high)), 0)[()]
        radius = radius + expansion.margin
        return middle - radius, middle + radius

    def outside(self, low, high) -> np.ndarray:
        """Whether each box of poses ``[low, high]`` (``(b, n_axes)``) holds no pose of the
        zone, proved by the enclosure; ``(b,)`` bool."""
        lo, hi = self.ranges(low, high)
        solid = _misses_box(self.zone, lo, hi) if self.zone.shape == "box" else \
            _misses_cylinder(self.zone, lo, hi)
        if self.zone.tilt is None:
            return solid
        lowest_cos = math.cos(math.radians(self.zone.tilt[1])) - COS_ROUNDING
        highest_cos = math.cos(math.radians(self.zone.tilt[0])) + COS_ROUNDING
        return solid | (hi[:, 3] < lowest_cos) | (lo[:, 3] > highest_cos)


def _point_and_cos(machine, q) -> np.ndarray:
    points, axes = tool_frames(machine, q)
    return np.concatenate([points, axes[..., 2:3]], axis=-1)


def _misses_box(zone, lo, hi) -> np.ndarray:
    below = hi[:, :3] < np.array(zone.low) - LENGTH_ROUNDING
    above = lo[:, :3] > np.array(zone.high) + LENGTH_ROUNDING
    return np.any(below | above, axis=1)


def _misses_cylinder(zone, lo, hi) -> np.ndarray:
    """The enclosure's z range misses the cylinder's, or its x–y rectangle lies farther
    than the radius from the axis."""
    centre = np.array(zone.centre)
    gap = np.maximum(np.maximum(lo[:, :2] - centre, centre - hi[:, :2]), 0.0)
    far = np.hypot(gap[:, 0], gap[:, 1]) > zone.radius + LENGTH_ROUNDING
    return far | (hi[:, 2] < zone.z[0] - LENGTH_ROUNDING) | \
        (lo[:, 2] > zone.z[1] + LENGTH_ROUNDING)
