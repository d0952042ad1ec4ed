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

from ..basics.chunks import chunks
from ..basics.errors import InputError
from ..model.work_zone import ANGLE_ROUNDING, LENGTH_ROUNDING, inside_zone, tool_frames
from .pose_expansion import fit_expansion, interval_tree

#: How far (in cos tilt) an enclosure may pass an end of the tilt range and still count as
#: meeting it: the zone's :data:`ANGLE_ROUNDING`, which moves cos by at most as much.
COS_ROUNDING = ANGLE_ROUNDING
#: Temporary bytes per pose of the chain's tool frame (a few 4 × 4 products per axis).
POSE_BYTES = 4096


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
        # every measure kept, each axis only with the basis functions they use (a cylinder
        # about the table's axis does not depend on the table's angle): the enclosures of
        # every box of the certificate contract these coefficients, so fewer is faster
        self.expansion = fit_expansion(machine, lambda q: _measures(machine, q), 1 + cylinder,
                                       "the tool point").restricted((slice(None),))

    def ranges(self, low, high) -> tuple[np.ndarray, np.ndarray]:
        """Enclosures ``(lo, hi)`` of ``(x, y, z, cos tilt)`` (box) or ``(r², z, cos tilt)``
        (cylinder) over boxes of poses ``[low, high]`` (mm, rad; ``(b, n_axes)``), each
        ``(b, 4)`` or ``(b, 3)``."""
        expansion = self.expansion
        middle, radius = interval_tree(expansion, expansion.local(np.atleast_2d(low)),
                                       expansion.local(np.atleast_2d(high)), 0)[()]
        radius = radius + expansion.margin
        return middle - radius, middle + radius

    def classify(self, low, high, memory=None) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`outside` and :meth:`inside` of boxes of poses ``[low, high]``
        (``(b, n_axes)``), one enclosure each, in chunks of at most ``memory`` bytes of
        temporaries (:data:`reliability.basics.chunks.MEMORY_BUDGET` by default)."""
        low, high = np.atleast_2d(low), np.atleast_2d(high)
        parts = [self._classify(self.ranges(low[part], high[part]))
                 for part in chunks(len(low), self._bytes_per_box(0), memory)]
        if not parts:
            return np.zeros((2, 0), dtype=bool)
        return tuple(np.concatenate(items) for items in zip(*parts))

    def _classify(self, ranges) -> tuple[np.ndarray, np.ndarray]:
        return self._outside(*ranges), self._inside(*ranges)

    def _bytes_per_box(self, order: int) -> int:
        """Temporary bytes per box of an enclosure of the derivatives of ``order``: the
        first contraction's states (midpoint and radius) and their temporaries."""
        return 8 * 4 * self.expansion.coefficients.size * (1 + order * self.expansion.n_axes)

    def outside(self, low, high) -> np.ndarray:
        """Whether each box of poses ``[low, high]`` (``(b, n_axes)``) holds no pose of the
        zone, proved by the enclosure; ``(b,)`` bool."""
        return self.classify(low, high)[0]

    def _outside(self, lo, hi) -> np.ndarray:
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
        return self.classify(low, high)[1]

    def _inside(self, lo, hi) -> np.ndarray:
        solid = _within_box(self.zone, lo, hi) if self.zone.shape == "box" else \
            _within_cylinder(self.zone, lo, hi)
        if self.zone.tilt is None:
            return solid
        lowest_cos = math.cos(math.radians(self.zone.tilt[1])) - COS_ROUNDING
        highest_cos = math.cos(math.radians(self.zone.tilt[0])) + COS_ROUNDING
        return solid & (lo[:, -1] >= lowest_cos) & (hi[:, -1] <= highest_cos)

    def split_shares(self, low, high) -> np.ndarray:
        """Each axis' part of the width of the enclosures that reach across the zone's
        limits over boxes of poses, relative to the zone's size, ``(b, n_axes)``: per
        measure (``(x, y, z, cos tilt)`` or ``(r², z, cos tilt)``) half the box's width
        along the axis times the enclosure of the measure's derivative over the zone's size
        in that measure, summed over the measures whose enclosure reaches across a limit.
        It vanishes as the box shrinks along the axis, so it says which axes leave the
        boundary unresolved. In chunks within
        :data:`reliability.basics.chunks.MEMORY_BUDGET`."""
        low, high = np.atleast_2d(low), np.atleast_2d(high)
        return np.concatenate([self._split_shares(low[part], high[part])
                               for part in chunks(len(low), self._bytes_per_box(1))]
                              or [np.zeros((0, self.expansion.n_axes))])

    def _split_shares(self, low, high) -> np.ndarray:
        expansion = self.expansion
        local_low, local_high = (expansion.local(np.atleast_2d(v)) for v in (low, high))
        tree = interval_tree(expansion, local_low, local_high, 1)
        half = (local_high - local_low) / 2
        width = np.stack([half[:, a, None] * (np.abs(tree[(a,)][0]) + tree[(a,)][1])
                          for a in range(expansion.n_axes)], axis=1)  # (b, axes, measures)
        weight = self._straddling(low, high) / self._sizes()
        return np.einsum("bam,bm->ba", width, weight)

    def _sizes(self) -> np.ndarray:
        """The zone's size in each measure: its extent along x, y, z (box), R² and its
        height (cylinder), the span of cos over the tilt range (1 without one)."""
        zone = self.zone
        solid = np.subtract(zone.high, zone.low) if zone.shape == "box" else \
            np.array([zone.radius ** 2, zone.z[1] - zone.z[0]])
        tilt = 1.0 if zone.tilt is None or zone.tilt[0] == zone.tilt[1] else \
            math.cos(math.radians(zone.tilt[0])) - math.cos(math.radians(zone.tilt[1]))
        return np.append(solid, tilt)

    def _straddling(self, low, high) -> np.ndarray:
        """Which measures' enclosures over boxes of poses reach across one of the zone's
        limits on them (the measures that put a box across the boundary), ``(b,
        n_measures)`` bool."""
        lo, hi = self.ranges(low, high)
        return np.stack([np.any([(lo[:, k] < limit) & (hi[:, k] > limit) for limit in limits],
                                axis=0) if limits else np.zeros(len(lo), dtype=bool)
                         for k, limits in enumerate(self._limits())], axis=1)

    def _limits(self) -> list[list[float]]:
        """Per measure, the zone's limits on it (with the rounding)."""
        zone = self.zone
        if zone.shape == "box":
            solid = [[low - LENGTH_ROUNDING, high + LENGTH_ROUNDING]
                     for low, high in zip(zone.low, zone.high)]
        else:
            solid = [[(zone.radius + LENGTH_ROUNDING) ** 2],
                     [zone.z[0] - LENGTH_ROUNDING, zone.z[1] + LENGTH_ROUNDING]]
        if zone.tilt is None:
            return solid + [[]]
        return solid + [[math.cos(math.radians(zone.tilt[1])) - COS_ROUNDING,
                         math.cos(math.radians(zone.tilt[0])) + COS_ROUNDING]]

    def contains(self, poses) -> np.ndarray:
        """Whether poses ``(b, n_axes)`` are in the zone
        (:func:`reliability.model.work_zone.inside_zone`), in chunks within
        :data:`reliability.basics.chunks.MEMORY_BUDGET`."""
        poses = np.atleast_2d(poses)
        return np.concatenate([inside_zone(self.machine, poses[part])
                               for part in chunks(len(poses), POSE_BYTES)]
                              or [np.zeros(0, dtype=bool)])


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
