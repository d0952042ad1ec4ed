"""Results of Monte-Carlo verification: Tables 8 and 9, intervals, yield, save and reload."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ..basics import checks
from ..basics.display import output_limits_text, percent_number
from ..basics.errors import InputError, InputTypeError, SavedResultError
from ..basics.files import write_csv
from ..basics.renamed import renamed
from ..basics.saved_results import encode_frame
from ..basics.statistics import all_within_share, between_experiment_interval, proportion
from ..model.machine import OUTPUTS

FRAME_COLUMNS = ("repeat", "output", "limit", "inside", "outside", "fraction")
METADATA_COLUMNS = ("distribution", "k", "points")
#: The name of the ``points`` column in tables saved by 0.3 and earlier (still read).
OLD_POINTS_COLUMN = "points_per_axis"


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
    distribution, k, points
        How the errors were drawn and the grid points per axis (``points_per_axis=`` is
        the deprecated spelling of ``points``, :mod:`reliability.basics.renamed`).
    values : ndarray (kept, n_poses, 6) or None
        Per-pose comprehensive errors of the kept experiments (Figs. 10–15).
    """

    limits: np.ndarray
    inside: np.ndarray
    n_poses: int
    distribution: str = "truncated"
    k: float = 3.0
    points: int = 5
    values: np.ndarray | None = None

    def __post_init__(self):
        inside = checks.numeric_array(self.inside, "inside", ndim=2)
        n_poses = checks.positive_int(self.n_poses, "n_poses")
        if inside.shape[1] != len(OUTPUTS):
            raise InputError(f"inside must have shape (repeats, 6); got {inside.shape}")
        bad = np.argwhere((inside < 0) | (inside > n_poses) | (inside != np.round(inside)))
        if len(bad):
            r, o = bad[0]
            raise InputError(f"inside[{r}, {o}] ({OUTPUTS[o]}) = {inside[r, o]!r} must be a "
                             f"whole count in [0, n_poses = {n_poses}]")

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
        if isinstance(repeat, bool) or not isinstance(repeat, (int, np.integer)):
            raise InputTypeError(f"repeat must be an integer; got {repeat!r}")
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
        :func:`reliability.basics.statistics.between_experiment_interval`).
        """
        return between_experiment_interval(self.fractions, confidence, names=OUTPUTS,
                                           poses=self.n_poses)

    def all_inside_share(self, confidence: float = 0.95):
        """Share of experiments (simulated machines) entirely within every limit, with a
        Clopper–Pearson interval (:func:`reliability.basics.statistics.all_within_share` of
        :attr:`all_inside`; Table 9's "all inside" row).

        Under the experiment's error profile, this is the crude estimate of the machine
        yield on the grid; :func:`reliability.sampling.machine_yield.machine_yield` is the
        machine yield with its estimator and bounds."""
        return all_within_share(self.all_inside, confidence)

    def summary(self, confidence: float = 0.95) -> str:
        """A short readable account: the set-up, the machine-level yield and, per output,
        the limit (with its unit), the mean share in tolerance with its interval, and the
        least and most of any experiment."""
        estimate = self.reliability(confidence)
        machines = self.all_inside_share(confidence)
        table = pd.DataFrame({
            "limit": output_limits_text(self.limits, digits=6),
            "mean [%]": _percent(estimate.estimate),
            f"{confidence:.0%} interval [%]": _percent_intervals(estimate),
            "min [%]": _percent(estimate.minimum), "max [%]": _percent(estimate.maximum)},
            index=pd.Index(OUTPUTS, name="output"))
        return "\n".join([
            f"{self.repeats} grid experiments of {self.n_poses:,} poses "
            f"({self.points} points per axis), errors {self.distribution}, "
            f"t = ±{self.k:g}σ",
            f"machine-level yield: {int(self.all_inside.sum())} of {self.repeats} experiments "
            f"entirely within every limit ({machines.estimate:.1%}, {confidence:.0%} "
            f"Clopper–Pearson [{percent_number(machines.lower, 'lower', 1)} %, "
            f"{percent_number(machines.upper, 'upper', 1)} %])",
            "share of poses in tolerance (interval: Wilson score on the effective sample "
            "size from the spread between experiments):",
            table.to_string()])

    def __repr__(self) -> str:
        return f"GridExperimentResult:\n{self.summary()}"

    def to_frame(self) -> pd.DataFrame:
        """Long table, one row per experiment and output (what :meth:`save` writes)."""
        repeat = np.repeat(np.arange(1, self.repeats + 1), len(OUTPUTS))
        inside = self.inside.ravel()
        return pd.DataFrame({"repeat": repeat, "output": np.tile(OUTPUTS, self.repeats),
                             "limit": np.tile(self.limits, self.repeats), "inside": inside,
                             "outside": self.n_poses - inside,
                             "fraction": inside / self.n_poses,
                             "distribution": self.distribution, "k": self.k,
                             "points": self.points})

    @classmethod
    def from_frame(cls, frame: pd.DataFrame, source: str = "grid-experiment table"
                   ) -> "GridExperimentResult":
        """Rebuild from :meth:`to_frame`'s table (per-pose values are not stored).

        The table is verified completely first: every repeat × output present once,
        ``0 ≤ inside ≤ poses``, ``inside + outside`` the same pose count on every row, the
        fraction equal to ``inside / poses``, one limit per output and one value of each
        metadata column. The first problem raises :class:`SavedResultError` naming
        ``source``, the row and the column. A table of 0.3 or earlier, whose grid column is
        ``points_per_axis``, is read as well.
        """
        table = _Table(_current_columns(frame, source), source,
                       FRAME_COLUMNS + METADATA_COLUMNS)
        repeat = table.integers("repeat", minimum=1)
        output = table.labels("output", OUTPUTS, "outputs")
        limit = table.reals("limit", positive=True)
        inside = table.integers("inside", minimum=0)
        outside = table.integers("outside", minimum=0)
        n_poses = table.same("pose counts (inside + outside)", "outside", inside + outside)
        fraction = table.reals("fraction")
        table.close_to("fraction", fraction, inside / n_poses)
        metadata = {c: table.same(c, c, table.frame[c]) for c in METADATA_COLUMNS}
        metadata["distribution"] = table.labels("distribution", ("truncated", "normal"))[0]
        k = table.reals("k", positive=True)[0]
        points = int(table.integers("points", minimum=2)[0])
        table.each_once(("repeat", "output"), repeat, output, OUTPUTS)
        for name in OUTPUTS:
            rows = output == name
            table.same(f"limit of output {name!r}", "limit", limit[rows], rows)
        repeats = int(repeat.max())
        wide = np.zeros((repeats, len(OUTPUTS)), dtype=np.int64)
        wide[repeat - 1, [OUTPUTS.index(o) for o in output]] = inside
        limits = np.array([limit[output == o][0] for o in OUTPUTS])
        return cls(limits=limits, inside=wide, n_poses=int(n_poses),
                   distribution=str(metadata["distribution"]), k=float(k),
                   points=points)

    def save(self, path, overwrite: bool = False) -> Path:
        """Write :meth:`to_frame` to CSV atomically; an existing file is kept unless
        ``overwrite``. Returns the path."""
        return write_csv(self.to_frame(), path, overwrite, index=False)

    @classmethod
    def load(cls, path) -> "GridExperimentResult":
        """Read and verify a file written by :meth:`save` (see :meth:`from_frame`)."""
        return cls.from_frame(read_saved_csv(path), source=str(path))

    def payload(self) -> dict:
        """The table :meth:`save` writes, JSON-ready, for saving inside another result."""
        return {"table": encode_frame(self.to_frame())}

    @classmethod
    def from_payload(cls, data) -> "GridExperimentResult":
        """The result from :meth:`payload`'s fields read through ``data`` (a
        :class:`~reliability.basics.saved_results.PayloadReader`), verified as
        :meth:`from_frame` says."""
        return cls.from_frame(data.frame("table", columns=FRAME_COLUMNS),
                              source=f"{data.path}: field {data.where}.table")


GridExperimentResult.__init__ = renamed("points_per_axis", "points")(
    GridExperimentResult.__init__)


def _current_columns(frame, source: str):
    """``frame`` with a 0.3 table's ``points_per_axis`` column named ``points``; a table
    with both raises :class:`SavedResultError` naming ``source``."""
    if not isinstance(frame, pd.DataFrame) or OLD_POINTS_COLUMN not in frame.columns:
        return frame
    if "points" in frame.columns:
        raise SavedResultError(f"{source}: the table has both columns 'points' and "
                               f"{OLD_POINTS_COLUMN!r} (its former name); keep one")
    return frame.rename(columns={OLD_POINTS_COLUMN: "points"})


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

    def __post_init__(self):
        inside = checks.numeric_array(self.inside, "inside", ndim=1)
        n_samples = checks.positive_int(self.n_samples, "n_samples")
        bad = np.flatnonzero((inside < 0) | (inside > n_samples) | (inside != np.round(inside))
                             ) if inside.shape == (len(OUTPUTS),) else [0]
        if len(bad):
            raise InputError(f"inside must be six whole counts in [0, n_samples = {n_samples}]"
                             f"; got {self.inside!r}")

    def reliability(self, confidence: float = 0.95, method: str = "wilson"):
        """Share in tolerance per output with a binomial interval (samples independent)."""
        return proportion(self.inside, self.n_samples, confidence, method, names=OUTPUTS)

    def summary(self, confidence: float = 0.95) -> str:
        """A short readable account: per output the limit (with its unit), the share in
        tolerance with its Wilson interval, and FOSM over the same poses."""
        estimate = self.reliability(confidence)
        table = pd.DataFrame({
            "limit": output_limits_text(self.limits, digits=6),
            "in tolerance [%]": _percent(estimate.estimate),
            f"{confidence:.0%} Wilson [%]": _percent_intervals(estimate),
            "FOSM two-sided [%]": _percent(self.fosm_two_sided)},
            index=pd.Index(OUTPUTS, name="output"))
        return (f"{self.n_samples:,} random poses, each with fresh errors ({self.distribution}, "
                f"t = ±{self.k:g}σ)\n{table.to_string()}")

    def __repr__(self) -> str:
        return f"RandomPoseResult:\n{self.summary()}"

    def to_frame(self, confidence: float = 0.95) -> pd.DataFrame:
        """One row per output: limit, counts, estimate and interval."""
        frame = self.reliability(confidence).to_frame()
        frame.insert(0, "limit", self.limits)
        frame.insert(1, "inside", self.inside)
        frame["fosm_one_sided"] = self.fosm_one_sided
        frame["fosm_two_sided"] = self.fosm_two_sided
        return frame

    def saved_frame(self) -> pd.DataFrame:
        """The table :meth:`save` writes: one row per output with the counts, the
        FOSM averages and how the errors were drawn."""
        return pd.DataFrame({"output": OUTPUTS, "limit": self.limits, "inside": self.inside,
                             "outside": self.n_samples - self.inside,
                             "fosm_one_sided": self.fosm_one_sided,
                             "fosm_two_sided": self.fosm_two_sided,
                             "distribution": self.distribution, "k": self.k})

    def save(self, path, overwrite: bool = False) -> Path:
        """Write :meth:`saved_frame` to CSV atomically; an existing file is kept unless
        ``overwrite``. Returns the path."""
        return write_csv(self.saved_frame(), path, overwrite, index=False)

    @classmethod
    def from_frame(cls, frame: pd.DataFrame, source: str = "random-pose table"
                   ) -> "RandomPoseResult":
        """Rebuild from :meth:`saved_frame`'s table, verified completely: each output once,
        ``0 ≤ inside ≤ samples``, one sample count, probabilities in [0, 1], one value of
        each metadata column."""
        table = _Table(frame, source, RANDOM_POSE_COLUMNS)
        output = table.labels("output", OUTPUTS, "outputs")
        limit = table.reals("limit", positive=True)
        inside = table.integers("inside", minimum=0)
        outside = table.integers("outside", minimum=0)
        n_samples = table.same("sample counts (inside + outside)", "outside", inside + outside)
        if n_samples < 1:
            table.fail(0, "inside", "needs at least one sample")
        one = table.reals("fosm_one_sided", upper=1.0)
        two = table.reals("fosm_two_sided", upper=1.0)
        distribution = table.labels("distribution", ("truncated", "normal"))
        table.same("distribution", "distribution", distribution)
        k = table.reals("k", positive=True)
        table.same("k", "k", k)
        table.each_once(("output",), output, None, OUTPUTS)
        order = [int(np.flatnonzero(output == o)[0]) for o in OUTPUTS]
        return cls(limits=limit[order], inside=inside[order].astype(np.int64),
                   n_samples=int(n_samples), fosm_one_sided=one[order],
                   fosm_two_sided=two[order], distribution=str(distribution[0]),
                   k=float(k[0]))

    @classmethod
    def load(cls, path) -> "RandomPoseResult":
        """Read and verify a file written by :meth:`save` (see :meth:`from_frame`)."""
        return cls.from_frame(read_saved_csv(path), source=str(path))


RANDOM_POSE_COLUMNS = ("output", "limit", "inside", "outside", "fosm_one_sided",
                       "fosm_two_sided", "distribution", "k")
LARGEST_COUNT = 2**53  # counts beyond this are not exact in a float column


def read_saved_csv(path) -> pd.DataFrame:
    """A saved CSV as text cells, or :class:`SavedResultError` naming the file."""
    path = Path(path)
    try:
        frame = pd.read_csv(path, dtype=str, keep_default_na=False, encoding="utf-8")
    except FileNotFoundError:
        raise
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError,
            ValueError) as exc:
        raise SavedResultError(f"{path}: not a saved result table ({exc})") from None
    if frame.empty:
        raise SavedResultError(f"{path}: the table has a header but no rows")
    return frame


def _plain(value):
    """A numpy scalar as the Python value it holds, for readable messages."""
    return value.item() if isinstance(value, np.generic) else value


class _Table:
    """Column-by-column verification of a saved table; rows are reported as in the file
    (row 1 is the first line after the header)."""

    def __init__(self, frame, source: str, columns):
        if not isinstance(frame, pd.DataFrame):
            raise SavedResultError(f"{source}: expected a table, got {type(frame).__name__}")
        self.frame = frame.reset_index(drop=True)
        self.source = source
        for column in columns:
            if column not in self.frame.columns:
                raise SavedResultError(f"{source}: table lacks column {column!r}")
        extra = [c for c in self.frame.columns if c not in columns]
        if extra:
            raise SavedResultError(f"{source}: unexpected column {extra[0]!r}")
        if len(self.frame) == 0:
            raise SavedResultError(f"{source}: the table has no rows")

    def fail(self, row: int, column: str, problem: str):
        raise SavedResultError(f"{self.source}: row {row + 1}, column {column!r}: {problem}")

    def _numbers(self, column: str) -> np.ndarray:
        cells = self.frame[column]
        values = pd.to_numeric(cells, errors="coerce").to_numpy(dtype=float)
        bad = np.flatnonzero(~np.isfinite(values))
        if len(bad):
            self.fail(int(bad[0]), column, f"{cells.iloc[bad[0]]!r} is not a finite number")
        return values

    def integers(self, column: str, minimum: int) -> np.ndarray:
        values = self._numbers(column)
        bad = np.flatnonzero((values != np.floor(values)) | (values < minimum)
                             | (values > LARGEST_COUNT))
        if len(bad):
            self.fail(int(bad[0]), column, f"{self.frame[column].iloc[bad[0]]!r} is not a "
                                           f"whole number >= {minimum}")
        return values.astype(np.int64)

    def reals(self, column: str, positive: bool = False, upper: float | None = None
              ) -> np.ndarray:
        values = self._numbers(column)
        low_bad = values <= 0 if positive else values < 0
        bad = np.flatnonzero(low_bad | (values > upper if upper is not None else False))
        if len(bad):
            span = "> 0" if positive else f"in [0, {upper}]" if upper is not None else ">= 0"
            self.fail(int(bad[0]), column, f"{float(values[bad[0]])!r} must be {span}")
        return values

    def labels(self, column: str, allowed, what: str | None = None) -> np.ndarray:
        values = self.frame[column].astype(str).to_numpy()
        bad = np.flatnonzero(~np.isin(values, allowed))
        if len(bad):
            self.fail(int(bad[0]), column, f"{values[bad[0]]!r} is not one of the "
                                           f"{what or column} {tuple(allowed)}")
        return values

    def same(self, what: str, column: str, values, rows=None):
        """The one value ``values`` take; the first row that differs is refused."""
        values = np.asarray(values)
        positions = np.arange(len(self.frame)) if rows is None else np.flatnonzero(rows)
        differ = np.flatnonzero(values != values[0])
        if len(differ):
            self.fail(int(positions[differ[0]]), column,
                      f"more than one value of {what}: {_plain(values[differ[0]])!r} and "
                      f"{_plain(values[0])!r} (row {int(positions[0]) + 1})")
        return values[0]

    def close_to(self, column: str, values, expected) -> None:
        bad = np.flatnonzero(~np.isclose(values, expected, rtol=1e-9, atol=0))
        if len(bad):
            self.fail(int(bad[0]), column, f"{float(values[bad[0]])!r} does not match "
                                           f"inside / poses = {float(expected[bad[0]])!r}")

    def each_once(self, columns, first, second, outputs) -> None:
        """Every key (repeat × output, or output) present exactly once."""
        keys = pd.DataFrame({"a": first} if second is None else {"a": first, "b": second})
        duplicated = np.flatnonzero(keys.duplicated().to_numpy())
        if len(duplicated):
            self.fail(int(duplicated[0]), columns[-1],
                      f"{' × '.join(columns)} {tuple(keys.iloc[duplicated[0]])} appears "
                      f"more than once")
        if second is None:
            missing = [o for o in outputs if o not in set(first)]
            if missing:
                raise SavedResultError(f"{self.source}: output {missing[0]!r} is missing; "
                                       f"the table must have outputs {outputs}")
            return
        repeats = int(first.max())
        if len(keys) == repeats * len(outputs):
            return  # no duplicates, repeats within 1..R and known outputs: all present
        present = set(zip(first.tolist(), second.tolist()))
        for r in range(1, repeats + 1):
            for o in outputs:
                if (r, o) not in present:
                    raise SavedResultError(
                        f"{self.source}: repeat {r}, output {o!r} is missing (repeats "
                        f"1..{repeats} × outputs {outputs} must each appear once)")


def _percent(values) -> list[str]:
    return [f"{100 * v:.3f}" for v in np.asarray(values, dtype=float)]


def _percent_intervals(estimate) -> list[str]:
    """Each output's interval as ``"[lower, upper]"`` in percent."""
    return [f"[{percent_number(lo, 'lower', 3)}, {percent_number(hi, 'upper', 3)}]"
            for lo, hi in zip(np.asarray(estimate.lower), np.asarray(estimate.upper))]
