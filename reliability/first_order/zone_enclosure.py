"""Which boxes of poses can hold a pose of the work zone: rigorous enclosures of the tool
point and the tool tilt over boxes (for the certificate of the continuous workspace).

The tool point ``p(q)`` and the z component of the tool axis, ``cos tilt(q)``, are entries
of the ideal chain ``M(q)``: like the Jacobian, each is of degree 1 in every axis
(``(1, u)`` linear, ``(1, cos θ, sin θ)`` rotary), so they are exact per-axis expansions
(:func:`reliability.first_order.pose_expansion.fit_expansion`, checked against the chain)
and their range over a box of poses is enclosed by
:func:`reliability.first_order.pose_expansion.interval_tree` plus the expansion's margin.
A box zone encloses ``(x, y, z, cos tilt)``; a cylinder encloses the squared distance of
the tool point from its axis, ``(x − x_c)² + (y − y_c)²`` (degree 2, like σ²), instead of x
and y: a table turning about the cylinder's axis then leaves it unchanged, where the
ranges of x and y over a turn of the table would be a loose square. A
box is *outside* the zone when the enclosure misses the solid or the tilt range: no pose in
it is in the zone, so the certificate may drop it; it is *inside* when the enclosure lies
within both: every pose in it is in the zone. A box proved neither straddles the zone's
boundary and is kept whole (its bound covers the zone's part of it).
"""

from __future__ import annotations

import math

import numpy as np

from ..basics.errors import InputError
from ..model.work_zone import ANGLE_ROUNDING, LENGTH_ROUNDING, inside_zone, tool_frames
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
        self.machine = machine
        self.zone = machine.work_zone
        cylinder = self.zone.shape == "cylinder"
        self.expansion = fit_expansion(machine, lambda q: _measures(machine, q), 1 + cylinder,
                                       "the tool point")

    def ranges(self, low, high) -> tuple[np.ndarray, np.ndarray]:
        """Enclosures ``(lo, hi)`` of ``(x, y, z, cos tilt)`` (box) or ``(r², z, cos tilt)``
        (cylinder) over boxes of poses ``[low, high]`` (mm, rad; ``(b, n_axes)``), each
        ``(b, 4)`` or ``(b, 3)``."""
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
        return solid | (hi[:, -1] < lowest_cos) | (lo[:, -1] > highest_cos)


    def inside(self, low, high) -> np.ndarray:
        """Whether every pose of each box ``[low, high]`` is in the zone (closed, with its
        rounding), proved by the enclosure; ``(b,)`` bool."""
        lo, hi = self.ranges(low, high)
        solid = _within_box(self.zone, lo, hi) if self.zone.shape == "box" else \
            _within_cylinder(self.zone, lo, hi)
        if self.zone.tilt is None:
            return solid
        lowest_cos = math.cos(math.radians(self.zone.tilt[1])) - COS_ROUNDING
        highest_cos = math.cos(math.radians(self.zone.tilt[0])) + COS_ROUNDING
        return solid & (lo[:, -1] >= lowest_cos) & (hi[:, -1] <= highest_cos)

    def split_shares(self, low, high) -> np.ndarray:
        """Each axis' share of the widest enclosure of a measure (``(x, y, z, cos tilt)`` or
        ``(r², z, cos tilt)``) over boxes of poses, ``(b, n_axes)``: half the box's width
        times the enclosure of the measure's derivative, relative to the sum over axes
        (the largest share over the measures); the axis to split to resolve the boundary."""
        expansion = self.expansion
        local_low, local_high = (expansion.local(np.atleast_2d(v)) for v in (low, high))
        tree = interval_tree(expansion, local_low, local_high, 1)
        half = (local_high - local_low) / 2
        width = np.stack([half[:, a, None] * (np.abs(tree[(a,)][0]) + tree[(a,)][1])
                          for a in range(expansion.n_axes)], axis=1)  # (b, axes, measures)
        total = width.sum(axis=1, keepdims=True)
        share = np.divide(width, total, out=np.zeros_like(width), where=total > 0)
        return share.max(axis=2)

    def contains(self, poses) -> np.ndarray:
        """Whether poses ``(b, n_axes)`` are in the zone
        (:func:`reliability.model.work_zone.inside_zone`)."""
        return inside_zone(self.machine, poses)


def _measures(machine, q) -> np.ndarray:
    """``(x, y, z, cos tilt)`` (box) or ``(r², z, cos tilt)`` (cylinder) of poses."""
    points, axes = tool_frames(machine, q)
    zone = machine.work_zone
    if zone.shape == "box":
        return np.concatenate([points, axes[..., 2:3]], axis=-1)
    squared = np.square(points[..., 0] - zone.centre[0]) + \
        np.square(points[..., 1] - zone.centre[1])
    return np.stack([squared, points[..., 2], axes[..., 2]], axis=-1)


def _misses_box(zone, lo, hi) -> np.ndarray:
    below = hi[:, :3] < np.array(zone.low) - LENGTH_ROUNDING
    above = lo[:, :3] > np.array(zone.high) + LENGTH_ROUNDING
    return np.any(below | above, axis=1)


def _within_box(zone, lo, hi) -> np.ndarray:
    return np.all((lo[:, :3] >= np.array(zone.low) - LENGTH_ROUNDING)
                  & (hi[:, :3] <= np.array(zone.high) + LENGTH_ROUNDING), axis=1)


def _within_cylinder(zone, lo, hi) -> np.ndarray:
    """The enclosures of r² and z within the cylinder's."""
    return (hi[:, 0] <= (zone.radius + LENGTH_ROUNDING) ** 2) & \
        (lo[:, 1] >= zone.z[0] - LENGTH_ROUNDING) & (hi[:, 1] <= zone.z[1] + LENGTH_ROUNDING)


def _misses_cylinder(zone, lo, hi) -> np.ndarray:
    """The enclosure of r² beyond the radius (with its rounding), or of z beside the
    cylinder's height."""
    far = lo[:, 0] > (zone.radius + LENGTH_ROUNDING) ** 2
    return far | (hi[:, 1] < zone.z[0] - LENGTH_ROUNDING) | \
        (lo[:, 1] > zone.z[1] + LENGTH_ROUNDING)
