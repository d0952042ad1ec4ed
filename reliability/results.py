"""Results of Monte-Carlo verification: Tables 8 and 9, intervals, yield, save and reload."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from .files import write_csv
from .machine import OUTPUTS
from .statistics import between_experiment_interval, machine_yield, proportion

FRAME_COLUMNS = ("repeat", "output", "limit", "inside", "outside", "fraction")
METADATA_COLUMNS = ("distribution", "k", "points_per_axis")


@dataclass(frozen=True, eq=False)
class GridExperimentResult:
    """Repeated grid experiments (Sec. 5.3): counts in tolerance per experiment and output.

    Attributes
    ----------
    limits : ndarray (6,)
        Design limits I of the six comprehensive errors.
    inside : ndarray (repeats, 6) of int
        Poses with ``|y| < I`` (Eq. 19) in each experiment.
    n_poses : int
        Poses per experiment (15 625 for 5 points on 6 axes).
    distribution, k, points_per_axis
        How the errors were drawn and the grid.
    values : ndarray (kept, n_poses, 6) or None
        Per-pose comprehensive errors of the kept experiments (Figs. 10–15).
    """

    limits: np.ndarray
    inside: np.ndarray
    n_poses: int
    distribution: str = "truncated"
    k: float = 3.0
    points_per_axis: int = 5
    values: np.ndarray | None = None

    @property
    def repeats(self) -> int:
        """Number of experiments."""
        return self.inside.shape[0]

    @property
    def fractions(self) -> np.ndarray:
        """``(repeats, 6)`` share of poses within the limit (Table 9's entries)."""
        return self.inside / self.n_poses

    @property
    def all_inside(self) -> np.ndarray:
        """``(repeats,)``: every pose met every limit in that experiment."""
        return np.all(self.inside == self.n_poses, axis=1)

    def table8(self, repeat: int = 0) -> pd.DataFrame:
        """One experiment as in Table 8: limit, inside, outside and reliability."""
        if not 0 <= repeat < self.repeats:
            raise IndexError(f"repeat {repeat} out of range for {self.repeats} experiments")
        inside = self.inside[repeat]
        return pd.DataFrame({"limit": self.limits, "inside": inside,
                             "outside": self.n_poses - inside,
                             "fraction": inside / self.n_poses},
                            index=pd.Index(OUTPUTS, name="output"))

    def table9(self) -> pd.DataFrame:
        """All experiments as in Table 9 (repeats 1…n), followed by Avg / Min / Max rows."""
        body = pd.DataFrame(self.fractions, columns=list(OUTPUTS),
                            index=pd.Index(range(1, self.repeats + 1), name="repeat"))
        summary = pd.DataFrame([body.mean(), body.min(), body.max()],
                               index=["Avg", "Min", "Max"])
        return pd.concat([body, summary])

    def reliability(self, confidence: float = 0.95):
        """Mean share in tolerance with a Wilson score interval on Kish's effective sample
        size (always inside [0, 1]).

        The poses of one experiment share its errors, so the spread between experiments
        sets the effective sample size (see
        :func:`reliability.statistics.between_experiment_interval`).
        """
        return between_experiment_interval(self.fractions, confidence, names=OUTPUTS,
                                           poses=self.n_poses)

    def machine_yield(self, confidence: float = 0.95):
        """Share of experiments (simulated machines) entirely within every limit."""
        return machine_yield(self.all_inside, confidence)

    def to_frame(self) -> pd.DataFrame:
        """Long table, one row per experiment and output (saved by :meth:`save_csv`)."""
        repeat = np.repeat(np.arange(1, self.repeats + 1), len(OUTPUTS))
        inside = self.inside.ravel()
        return pd.DataFrame({"repeat": repeat, "output": np.tile(OUTPUTS, self.repeats),
                             "limit": np.tile(self.limits, self.repeats), "inside": inside,
                             "outside": self.n_poses - inside,
                             "fraction": inside / self.n_poses,
                             "distribution": self.distribution, "k": self.k,
                             "points_per_axis": self.points_per_axis})

    @classmethod
    def from_frame(cls, frame: pd.DataFrame) -> "GridExperimentResult":
        """Rebuild from :meth:`to_frame`'s table (per-pose values are not stored)."""
        missing = [c for c in FRAME_COLUMNS + METADATA_COLUMNS if c not in frame.columns]
        if missing:
            raise ValueError(f"grid-experiment table lacks column {missing[0]!r}")
        wide = frame.pivot(index="repeat", columns="output", values="inside")
        unknown = sorted(set(wide.columns) - set(OUTPUTS))
        if unknown or len(wide.columns) != len(OUTPUTS):
            raise ValueError(f"grid-experiment table must have outputs {OUTPUTS}; "
                             f"got {tuple(wide.columns)}")
        totals = (frame["inside"] + frame["outside"]).unique()
        if len(totals) != 1:
            raise ValueError("grid-experiment table has rows with different pose counts")
        metadata = {}
        for column in METADATA_COLUMNS:
            values = frame[column].unique()
            if len(values) != 1:
                raise ValueError(f"grid-experiment table has more than one {column!r}")
            metadata[column] = values[0]
        limits = frame.groupby("output")["limit"].first().reindex(OUTPUTS).to_numpy()
        return cls(limits=limits, inside=wide[list(OUTPUTS)].to_numpy(dtype=np.int64),
                   n_poses=int(totals[0]), distribution=str(metadata["distribution"]),
                   k=float(metadata["k"]), points_per_axis=int(metadata["points_per_axis"]))

    def save_csv(self, path, overwrite: bool = False) -> Path:
        """Write :meth:`to_frame` to CSV; an existing file is kept unless ``overwrite``."""
        return write_csv(self.to_frame(), path, overwrite, index=False)

    @classmethod
    def load_csv(cls, path) -> "GridExperimentResult":
        """Read a file written by :meth:`save_csv`."""
        return cls.from_frame(pd.read_csv(path))


@dataclass(frozen=True, eq=False)
class RandomPoseResult:
    """Pose-level reliability from independent samples (random pose, fresh errors).

    Attributes
    ----------
    limits : ndarray (6,)
    inside : ndarray (6,) of int
        Samples with ``|y| < I`` per output.
    n_samples : int
    fosm_one_sided, fosm_two_sided : ndarray (6,)
        FOSM probabilities (zero mean, σ of the drawn distribution) averaged over the
        sampled poses: what the share in tolerance would be if the model were linear and
        the outputs normal.
    distribution, k
        How the errors were drawn.
    """

    limits: np.ndarray
    inside: np.ndarray
    n_samples: int
    fosm_one_sided: np.ndarray
    fosm_two_sided: np.ndarray
    distribution: str = "truncated"
    k: float = 3.0

    def reliability(self, confidence: float = 0.95, method: str = "wilson"):
        """Share in tolerance per output with a binomial interval (samples independent)."""
        return proportion(self.inside, self.n_samples, confidence, method, names=OUTPUTS)

    def to_frame(self, confidence: float = 0.95) -> pd.DataFrame:
        """One row per output: limit, counts, estimate and interval."""
        frame = self.reliability(confidence).to_frame()
        frame.insert(0, "limit", self.limits)
        frame.insert(1, "inside", self.inside)
        frame["fosm_one_sided"] = self.fosm_one_sided
        frame["fosm_two_sided"] = self.fosm_two_sided
        return frame
