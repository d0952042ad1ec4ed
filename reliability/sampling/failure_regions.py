"""Where built machines fail first: the failure regions and shares of a machine yield.

Among failing machines, the requirement that fails first is the row with the largest
``|y_r|/I_r`` over the grid: its output and its pose region. A region bins the worst pose per
axis into the low, middle or high third of the axis' stroke, showing only the axes along which
that output's mean σ² changes most (at most :data:`MAX_REGION_AXES`, each by more than
:data:`REGION_SPREAD`; the others hardly decide where it fails); an output no axis decides has
one region, the axis positions all its failing rows' worst poses share. Shares are weighted by
the importance weight ``w`` under importance sampling; their intervals are Wilson intervals on
Kish's effective number of failing machines ``(Σw)²/Σw²``.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..basics.statistics import share_interval
from ..model.machine import OUTPUTS

#: An axis is shown in a failure region when an output's mean σ² over the grid points of
#: the axis changes by more than this share between its least and its largest ...
REGION_SPREAD = 0.25
#: ... and it is one of the output's this many axes of largest change.
MAX_REGION_AXES = 2
THIRDS = ("low", "middle", "high")
SHARE_COLUMNS = ("output", "region", "share", "lower", "upper", "failures")


class FailureRegions:
    """The pose regions of a grid's rows, and the shares of failing machines by region.

    Parameters
    ----------
    machine : Machine
    experiment : GridExperiment
        The grid whose poses the rows index.
    grid_index : ndarray (n_poses, n_axes) of int
        Each pose's grid point along each axis.
    """

    def __init__(self, machine, experiment, grid_index):
        self.machine = machine
        self.experiment = experiment
        self.grid_index = grid_index

    def deciding_axes(self, sigma) -> np.ndarray:
        """``(6, n_axes)`` bool: for each output, the (at most :data:`MAX_REGION_AXES`)
        axes along which its mean σ² over the grid changes most, by more than
        :data:`REGION_SPREAD`."""
        n = len(self.machine.axis_specs)
        variance = np.square(sigma)
        spread = np.zeros((len(OUTPUTS), n))
        for a in range(n):
            profile = self._mean_along(a, variance)  # (points of axis a in use, 6)
            with np.errstate(divide="ignore", invalid="ignore"):
                spread[:, a] = np.where(profile.min(axis=0) > 0,
                                        profile.max(axis=0) / profile.min(axis=0) - 1.0, 0.0)
        rank = np.argsort(np.argsort(-spread, axis=1, kind="stable"), axis=1, kind="stable")
        return (spread > REGION_SPREAD) & (rank < MAX_REGION_AXES)

    def _mean_along(self, a: int, values) -> np.ndarray:
        """Mean of per-pose ``values (n_poses, 6)`` at each grid point of axis ``a`` that
        some pose uses, ``(used points, 6)``."""
        points = self.experiment.points
        index = self.grid_index[:, a]
        counts = np.bincount(index, minlength=points)
        sums = np.stack([np.bincount(index, weights=column, minlength=points)
                         for column in values.T], axis=-1)
        used = counts > 0
        return sums[used] / counts[used, None]

    def region_texts(self, rows, deciding) -> list[str]:
        """The worst pose of each row as its stroke thirds along the deciding axes; for an
        output no axis decides, the axis positions all its rows' worst poses share."""
        pose, output = np.divmod(np.asarray(rows), len(OUTPUTS))
        position = self.experiment.poses[pose]
        shared = {o: self._shared_text(position[output == o])
                  for o in np.unique(output) if not deciding[o].any()}
        return [shared[o] if o in shared else
                ", ".join(self._third_text(a, q[a]) for a in np.flatnonzero(deciding[o]))
                for q, o in zip(position, output)]

    def _shared_text(self, positions) -> str:
        """What a set of grid poses shares, e.g. ``48 poses, all with Y = ±300 mm,
        Z = 0 or 500 mm (C, X any)``."""
        poses = np.unique(positions, axis=0)
        shared, free = [], []
        for a, axis in enumerate(self.machine.axis_specs):
            values = np.unique(poses[:, a])
            if len(values) == len(self.experiment.axis_points[a]):
                free.append(axis.name)
                continue
            unit = "deg" if axis.kind == "rotary" else "mm"
            shown = np.degrees(values) if axis.kind == "rotary" else values
            words = (f"±{shown[1]:.4g}" if len(shown) == 2 and np.isclose(shown[0], -shown[1])
                     else " or ".join(f"{v:.4g}" for v in shown))
            shared.append(f"{axis.name} = {words} {unit}")
        if not shared:
            return f"{len(poses)} poses sharing no axis position"
        rest = f" ({', '.join(free)} any)" if free else ""
        return f"{len(poses)} pose{'s' if len(poses) > 1 else ''}, all with " \
               f"{', '.join(shared)}{rest}"

    def _third_text(self, a, position) -> str:
        axis = self.machine.axis_specs[a]
        low, high = axis.stroke
        third = min(2, int(3 * (position - low) / (high - low)))
        edges = low + (high - low) * np.array([third, third + 1]) / 3
        if axis.kind == "rotary":
            edges, unit = np.degrees(edges), "deg"
        else:
            unit = "mm"
        return f"{axis.name} {THIRDS[third]} ({edges[0]:.4g} to {edges[1]:.4g} {unit})"

    def failure_shares(self, sigma, rows, weights, confidence) -> pd.DataFrame:
        """Weighted shares of (output, region) among the failing machines' worst rows.

        Parameters
        ----------
        sigma : ndarray (n_poses, 6)
            FOSM σ of every row (:meth:`deciding_axes` reads it).
        rows : ndarray of int
            Each failing machine's worst row ``pose · 6 + output``.
        weights : ndarray
            Each failing machine's importance weight (1 under crude sampling).
        confidence : float
            Level of the Wilson intervals.

        Returns
        -------
        DataFrame
            Columns :data:`SHARE_COLUMNS`, largest share first.
        """
        if len(rows) == 0:
            return pd.DataFrame(columns=list(SHARE_COLUMNS))
        frame = pd.DataFrame({
            "output": np.asarray(OUTPUTS)[rows % len(OUTPUTS)],
            "region": self.region_texts(rows, self.deciding_axes(sigma)),
            "weight": weights, "square": np.square(weights), "failures": 1})
        groups = frame.groupby(["output", "region"], sort=False).sum().reset_index()
        total, squares = frame["weight"].sum(), frame["square"].sum()
        share = groups["weight"].to_numpy() / total
        effective = total ** 2 / squares  # Kish's effective number of failing machines
        lower, upper = share_interval(share, effective, confidence)
        out = pd.DataFrame({"output": groups["output"], "region": groups["region"],
                            "share": share, "lower": np.asarray(lower, dtype=float),
                            "upper": np.asarray(upper, dtype=float),
                            "failures": groups["failures"].astype(int)})
        return out.sort_values(["share", "output", "region"], ascending=[False, True, True],
                               kind="stable").reset_index(drop=True)
