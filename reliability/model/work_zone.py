"""The work zone: the poses that cut parts (the machine file's ``[workzone]`` table).

A work zone is a box or an upright cylinder in the workpiece frame (mm), with an optional
range of tool tilt. A pose is inside when its tool point, the origin of the tool frame
(the file's ``tool_offset`` after the last axis), lies in the solid and the tilt of its
tool axis lies in the range. The tool axis is the tool frame's z axis; its tilt is the
angle between it and the workpiece z axis, 0° to 180°. Both are read off the ideal chain
``M(q)`` (:func:`reliability.model.kinematics.chain_factors`), batched over poses.

The zone is closed: a point within :data:`LENGTH_ROUNDING` of its surface, or a tilt
within :data:`ANGLE_ROUNDING` of an end of the range, counts as inside, so that rounding
in the chain does not drop a grid pose that lies on the boundary.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..basics.errors import InputError
from .kinematics import chain_factors

SHAPES = ("box", "cylinder")
#: mm: how far outside its surface a tool point still counts as inside the zone.
LENGTH_ROUNDING = 1e-6
#: rad: how far outside its range a tilt still counts as inside it.
ANGLE_ROUNDING = 1e-9


@dataclass(frozen=True)
class WorkZone:
    """A box or an upright cylinder in the workpiece frame, and a range of tool tilt.

    Attributes
    ----------
    shape : {'box', 'cylinder'}
    low, high : tuple of float or None
        The box's corners ``(x, y, z)``, mm (box only).
    centre : tuple of float or None
        The cylinder's axis ``(x, y)``, mm (cylinder only).
    radius : float or None
        The cylinder's radius, mm (cylinder only).
    z : tuple of float or None
        The cylinder's ``(lo, hi)`` height, mm (cylinder only).
    tilt : tuple of float or None
        ``(lo, hi)`` angle between the tool axis and the workpiece z axis, degrees; None
        for any tilt.
    """

    shape: str
    low: tuple[float, float, float] | None = None
    high: tuple[float, float, float] | None = None
    centre: tuple[float, float] | None = None
    radius: float | None = None
    z: tuple[float, float] | None = None
    tilt: tuple[float, float] | None = None

    def __post_init__(self):
        if self.shape not in SHAPES:
            raise InputError(f"work zone shape must be 'box' or 'cylinder'; got {self.shape!r}")
        given = {"box": ("low", "high"), "cylinder": ("centre", "radius", "z")}
        for shape, names in given.items():
            for name in names:
                if (getattr(self, name) is None) == (shape == self.shape):
                    expected = "needs" if shape == self.shape else "takes no"
                    raise InputError(f"a {self.shape} work zone {expected} {name!r}")
        for name, low, high in self._ranges():
            if not low < high:
                raise InputError(f"work zone {name}: lo = {low:g} must be < hi = {high:g}")
        if self.radius is not None and not self.radius > 0:
            raise InputError(f"work zone radius must be > 0 mm; got {self.radius:g}")
        if self.tilt is not None and not 0.0 <= self.tilt[0] <= self.tilt[1] <= 180.0:
            raise InputError(f"work zone tilt must be [lo, hi] with 0 <= lo <= hi <= 180 "
                             f"degrees; got {list(self.tilt)}")

    def _ranges(self):
        if self.shape == "box":
            return [(f"{axis} (min, max)", low, high)
                    for axis, low, high in zip("xyz", self.low, self.high)]
        return [("z", *self.z)]

    @property
    def tilt_radians(self) -> tuple[float, float] | None:
        """The tilt range in rad, or None for any tilt."""
        return None if self.tilt is None else tuple(math.radians(v) for v in self.tilt)

    def bounding_box(self) -> tuple[np.ndarray, np.ndarray]:
        """The smallest box ``(low, high)`` (mm, workpiece frame) holding the solid."""
        if self.shape == "box":
            return np.array(self.low), np.array(self.high)
        centre, r = np.array(self.centre), self.radius
        return (np.array([*(centre - r), self.z[0]]), np.array([*(centre + r), self.z[1]]))

    def contains(self, points, tilts=None) -> np.ndarray:
        """Whether tool points ``(..., 3)`` (mm) with tool tilts ``(...)`` (rad) are inside.

        Parameters
        ----------
        points : array_like
            ``(..., 3)`` tool points in the workpiece frame, mm.
        tilts : array_like, optional
            ``(...)`` tool tilts, rad; needed when the zone has a tilt range.

        Returns
        -------
        numpy.ndarray of bool
            ``(...)``.
        """
        points = np.asarray(points, dtype=float)
        if points.ndim < 1 or points.shape[-1] != 3:
            raise InputError(f"points must have shape (..., 3) (x, y, z in mm); got "
                             f"{points.shape}")
        inside = self._solid_contains(points)
        if self.tilt is None:
            return inside
        if tilts is None:
            raise InputError("tilts are needed: this work zone has a tilt range "
                             f"{list(self.tilt)} degrees")
        low, high = self.tilt_radians
        tilts = np.asarray(tilts, dtype=float)
        return inside & (tilts >= low - ANGLE_ROUNDING) & (tilts <= high + ANGLE_ROUNDING)

    def _solid_contains(self, points: np.ndarray) -> np.ndarray:
        if self.shape == "box":
            return np.all((points >= np.array(self.low) - LENGTH_ROUNDING)
                          & (points <= np.array(self.high) + LENGTH_ROUNDING), axis=-1)
        distance = np.hypot(points[..., 0] - self.centre[0], points[..., 1] - self.centre[1])
        height = points[..., 2]
        return ((distance <= self.radius + LENGTH_ROUNDING)
                & (height >= self.z[0] - LENGTH_ROUNDING)
                & (height <= self.z[1] + LENGTH_ROUNDING))

    def text(self) -> str:
        """The zone in words, e.g. ``cylinder about (0, 0) mm, radius 250 mm, z 0 … 300 mm,
        tool tilt 0 … 60°``."""
        if self.shape == "box":
            solid = f"box {_point(self.low)} … {_point(self.high)} mm"
        else:
            solid = (f"cylinder about {_point(self.centre)} mm, radius {self.radius:g} mm, "
                     f"z {self.z[0]:g} … {self.z[1]:g} mm")
        tilt = "any tool tilt" if self.tilt is None else \
            f"tool tilt {self.tilt[0]:g} … {self.tilt[1]:g}°"
        return f"{solid}, {tilt}"

    def to_dict(self) -> dict:
        """The machine file's ``[workzone]`` table of this zone."""
        if self.shape == "box":
            table = {"shape": "box", "min": list(self.low), "max": list(self.high)}
        else:
            table = {"shape": "cylinder", "centre": list(self.centre),
                     "radius": self.radius, "z": list(self.z)}
        if self.tilt is not None:
            table["tilt"] = list(self.tilt)
        return table


def _point(values) -> str:
    return "(" + ", ".join(f"{v:g}" for v in values) + ")"


def tool_frames(machine, q) -> tuple[np.ndarray, np.ndarray]:
    """The ideal tool point and tool axis of poses, in the workpiece frame.

    Parameters
    ----------
    machine : Machine
    q : array_like
        ``(..., n_axes)`` positions (mm, rad).

    Returns
    -------
    points : ndarray (..., 3)
        The tool point, mm.
    axes : ndarray (..., 3)
        The unit tool axis (the tool frame's z axis).
    """
    q = machine.check_positions(q)
    factors, _ = chain_factors(machine, q)
    product = np.broadcast_to(np.eye(4), q.shape[:-1] + (4, 4))
    for factor in factors:
        product = product @ np.asarray(factor)
    return product[..., :3, 3], product[..., :3, 2]


def tool_points(machine, q) -> np.ndarray:
    """The ideal tool point of poses ``(..., n_axes)`` in the workpiece frame, ``(..., 3)`` mm."""
    return tool_frames(machine, q)[0]


def tool_tilts(machine, q) -> np.ndarray:
    """The angle (rad, 0 to π) between the tool axis and the workpiece z axis, ``(...)``."""
    return tilt_of_axes(tool_frames(machine, q)[1])


def tilt_of_axes(axes) -> np.ndarray:
    """The angle (rad) between unit vectors ``(..., 3)`` and the z axis, accurate near 0."""
    axes = np.asarray(axes, dtype=float)
    return np.arctan2(np.hypot(axes[..., 0], axes[..., 1]), axes[..., 2])


def inside_zone(machine, q) -> np.ndarray:
    """Whether poses ``(..., n_axes)`` are in the machine's work zone, ``(...)`` bool; every
    pose is when the machine has none."""
    q = machine.check_positions(q)
    zone = machine.work_zone
    if zone is None:
        return np.ones(q.shape[:-1], dtype=bool)
    points, axes = tool_frames(machine, q)
    return zone.contains(points, tilt_of_axes(axes))


def zone_text(machine) -> str:
    """What the workspace is, in words: the work zone, or every pose of the strokes."""
    if machine.work_zone is None:
        return "no work zone: every pose of the strokes"
    return (f"work zone {machine.work_zone.text()} (tool point and tilt in the workpiece "
            f"frame)")


def grid_text(machine, points: int, n_poses: int) -> str:
    """The grid a study used, in words: ``5-point grid (15 625 poses; no work zone: every
    pose of the strokes)`` or ``5-point grid, 105 of its 3 125 poses inside the work zone
    …``.

    Parameters
    ----------
    machine : Machine
    points : int
    n_poses : int
        The grid poses the study used.
    """
    whole = int(points) ** len(machine.axis_specs)
    if machine.work_zone is None:
        return f"{points}-point grid ({_count(whole)} poses; {zone_text(machine)})"
    return (f"{points}-point grid, {_count(n_poses)} of its {_count(whole)} poses "
            f"inside the {zone_text(machine)}")


def _count(n: int) -> str:
    return f"{n:,}".replace(",", " ")
