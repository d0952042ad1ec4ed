"""Accuracy over time (docs/over-time.md): each output's life reliability at its worst
pose, the machine yield over the life and the recalibration interval, for ``precrel life``
and the report's "Over time" section.

:func:`life_study` runs the first-order life reliability
(:func:`reliability.life.life_fosm.life_reliability`) and the machine yield over the life on
the exact chain (:func:`reliability.life.life_yield.life_yield`) on one age grid, and reads
the recalibration interval off the yield (:mod:`reliability.life.recalibration`). Its
result, :class:`LifeStudy`, gives the long table of ``life.csv`` (``to_frame``), its
verdicts for reading (``summary``), and is saved as JSON (``life_summary.json``) through
:mod:`reliability.basics.saved_fields`, reloaded with every derived field checked.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from reliability.basics import streams
from reliability.basics.saved_fields import (Array, Integer, Number, Text, load_fields,
                                             save_fields)
from reliability.basics.statistics import binomial_interval
from reliability.life.compensated_life import compensated_life, first_cycle_covariance
from reliability.life.life_check import check_life
from reliability.life.life_fosm import age_grid, life_reliability
from reliability.life.life_yield import DEFAULT_LIFE_MACHINES, life_yield
from reliability.life.recalibration import age_text, crossing_age, crossing_interval
from reliability.model.machine import OUTPUTS
from reliability.model.poses import workspace_grid

#: The format tag of ``life_summary.json``.
SAVED_FORMAT = "precrel.life_study"
#: ``life.csv``'s columns, exactly.
CSV_COLUMNS = ("age_years", "output", "probability")
#: The ``output`` of the machine yield's rows in ``life.csv``.
MACHINE = "machine"
#: Relative tolerance within which saved derived fields must follow from the saved counts.
CONSISTENCY_RTOL = 1e-9

FIELDS = (Text("machine"), Text("kind", ("linear", "wear")), Text("level_source"),
          Text("method"),
          Array("ages", ("A",), low=0.0), Array("targets", (6,), low=0.0, high=1.0),
          Array("at_age", ("A", 6), low=0.0, high=1.0),
          Array("life", ("A", 6), low=0.0, high=1.0), Array("life_se", ("A", 6), low=0.0),
          Array("worst_pose", ("A", 6, None)),
          Integer("machines", low=1), Array("passed", ("A",), dtype=int, low=0),
          Array("yield_lower", ("A",), low=0.0, high=1.0),
          Array("yield_upper", ("A",), low=0.0, high=1.0),
          Number("level", low=0.0, high=1.0), Number("confidence", low=0.0, high=1.0),
          Array("interval", (3,), nan=True), Array("output_ages", (6,), nan=True),
          Array("recalibrations", ("C",), optional=True, low=0.0),
          Array("compensated_intervals", ("C", 3), optional=True, nan=True),
          Array("compensated_life", ("A", 6), optional=True, low=0.0, high=1.0),
          Array("rice", ("A", 6), optional=True, low=0.0, high=1.0),
          Array("compensated_yield", ("A",), optional=True, low=0.0, high=1.0),
          Integer("check_machines", optional=True, low=1),
          Array("check", (2, 6), optional=True, low=0.0, high=1.0),
          Array("compensated_check", (2, 6), optional=True, low=0.0, high=1.0))


@dataclass(frozen=True)
class LifeStudy:
    """Reliability and machine yield over a service life.

    Attributes
    ----------
    machine : str
    kind : {'linear', 'wear'}
        The machine file's drift model.
    level_source : str
        Where the yield level came from (``--yield`` or the smallest target).
    method : str
        How the life reliability was computed.
    ages : ndarray (A,)
    targets : ndarray (6,)
    at_age, life, life_se : ndarray (A, 6)
        Each output at its worst grid pose: at the age alone, over ``[0, age]``, and the
        latter's Monte-Carlo standard error (0 where exact).
    worst_pose : ndarray (A, 6, n_axes)
        The axis positions of ``life``'s pose.
    machines : int
    passed : ndarray (A,) of int
        Built machines within every limit at every grid pose and age up to each age.
    yield_lower, yield_upper : ndarray (A,)
        Clopper–Pearson interval of the machine yield at ``confidence``.
    level, confidence : float
    interval : ndarray (3,)
        Recalibration interval ``[earliest, age, latest]`` in years: where the yield's
        interval ends and the yield fall below ``level`` (NaN: beyond the horizon).
    output_ages : ndarray (6,)
        Per output, the age its worst-pose life reliability falls below its target.
    recalibrations, compensated_intervals : ndarray (C,), (C, 3) or None
        With a compensation plan: the age of each recalibration (0 first) and the interval
        to the next, ``[earliest, interval, latest]`` years after it
        (:mod:`reliability.life.compensated_life`).
    compensated_life : ndarray (A, 6) or None
        With a plan: each output's first-order life reliability at its worst pose after
        compensation at acceptance (the first cycle).
    compensated_yield : ndarray (A,) or None
        With a plan: the machine yield from acceptance of machines compensated at
        acceptance and not recalibrated (the first cycle), on the exact chain.
    check_machines : int or None
        With a check: the built machines of the Monte-Carlo check.
    check, compensated_check : ndarray (2, 6) or None
        Monte-Carlo on the exact chain at each output's worst pose over the whole life:
        the share within the limit at every age and its standard error
        (:mod:`reliability.life.life_check`), beside ``life[-1]`` (and, with a plan,
        ``compensated_life[-1]``).
    rice : ndarray (A, 6) or None
        Wear only: the out-crossing (Rice) approximation of ``life`` at the same poses, its
        check (:mod:`reliability.life.wear_paths`).
    """

    machine: str
    kind: str
    level_source: str
    method: str
    ages: np.ndarray
    targets: np.ndarray
    at_age: np.ndarray
    life: np.ndarray
    life_se: np.ndarray
    worst_pose: np.ndarray
    machines: int
    passed: np.ndarray
    yield_lower: np.ndarray
    yield_upper: np.ndarray
    level: float
    confidence: float
    interval: np.ndarray
    output_ages: np.ndarray
    recalibrations: np.ndarray | None = None
    compensated_intervals: np.ndarray | None = None
    compensated_life: np.ndarray | None = None
    rice: np.ndarray | None = None
    compensated_yield: np.ndarray | None = None
    check_machines: int | None = None
    check: np.ndarray | None = None
    compensated_check: np.ndarray | None = None

    @property
    def machine_yield(self) -> np.ndarray:
        """The machine yield over ``[0, age]`` at each age."""
        return self.passed / self.machines

    @property
    def horizon(self) -> float:
        return float(self.ages[-1])

    def to_frame(self) -> pd.DataFrame:
        """``life.csv``: one row per age and output (``dx`` … ``ez``: the life reliability at
        the worst pose; ``machine``: the machine yield), columns :data:`CSV_COLUMNS`."""
        values = np.column_stack([self.life, self.machine_yield])
        names = list(OUTPUTS) + [MACHINE]
        return pd.DataFrame({
            "age_years": np.repeat(self.ages, len(names)),
            "output": np.tile(names, len(self.ages)),
            "probability": values.ravel()})

    def recalibration_text(self) -> str:
        """The recalibration interval in one sentence, or that the yield starts below the
        level (then there is none)."""
        earliest, age, latest = self.interval
        level = f"{self.level:.4g} ({self.level_source})"
        if age == 0:
            return (f"No recalibration interval for {self.machine}: the machine yield is "
                    f"{self.machine_yield[0]:.3f} [{self.yield_lower[0]:.3f}, "
                    f"{self.yield_upper[0]:.3f}] at acceptance, already below {level}")
        return (f"Recalibration interval of {self.machine}: {age_text(age, self.horizon)} "
                f"(the age at which the machine yield over the life falls below {level}); "
                f"{self.confidence:.0%} interval {age_text(earliest, self.horizon)} to "
                f"{age_text(latest, self.horizon)}")

    def summary(self) -> str:
        """The recalibration interval first, then the curves at a few ages."""
        lines = [self.recalibration_text(),
                 f"Drift model {self.kind!r}; {self.machines:,} built machines on the exact "
                 f"chain; life reliability: {self.method}", ""]
        lines.append(self.table().to_string())
        if self.check is not None:
            lines += ["", self.check_table().to_string()]
        if self.rice is not None:
            lines += ["", f"Check of the sampled wear paths: the out-crossing (Rice) "
                          f"approximation differs from them by at most "
                          f"{np.abs(self.life - self.rice).max():.2g} (their standard error "
                          f"is at most {self.life_se.max():.2g})"]
        if self.recalibrations is not None:
            lines += ["", "With the compensation plan (re-measured and re-compensated at each "
                          "recalibration): " + "; ".join(
                              f"after {start:g} years, next in "
                              f"{age_text(interval[1], self.horizon - start)} "
                              f"[{age_text(interval[0], self.horizon - start)}, "
                              f"{age_text(interval[2], self.horizon - start)}]"
                              for start, interval in zip(self.recalibrations,
                                                         self.compensated_intervals))]
        lines.append("")
        lines.append("Age at which each output's worst-pose life reliability falls below its "
                     "target: " + ", ".join(f"{o} {age_text(a, self.horizon)}"
                                             for o, a in zip(OUTPUTS, self.output_ages)))
        return "\n".join(lines)

    def table(self, rows: int = 6) -> pd.DataFrame:
        """The curves at up to ``rows`` ages of the grid (always the last), as printed:
        probabilities to the digits their computation fixes."""
        pick = np.unique(np.linspace(0, len(self.ages) - 1, rows).round().astype(int))
        estimate = self.machine_yield
        frame = pd.DataFrame({o: [f"{v:.4f}" for v in self.life[pick, i]]
                              for i, o in enumerate(OUTPUTS)},
                             index=pd.Index(self.ages[pick], name="age [years]"))
        frame["machine yield"] = [f"{estimate[i]:.3f} [{self.yield_lower[i]:.3f}, "
                                  f"{self.yield_upper[i]:.3f}]" for i in pick]
        return frame

    def check_table(self) -> pd.DataFrame:
        """First order beside Monte-Carlo on the exact chain over the whole life, per
        output at its worst pose; ``z`` the difference in standard errors."""
        rows = {"first order": self.life[-1], "Monte-Carlo": self.check}
        if self.compensated_check is not None:
            rows |= {"compensated first order": self.compensated_life[-1],
                     "compensated Monte-Carlo": self.compensated_check}
        table = {}
        for name, value in rows.items():
            if name.endswith("Monte-Carlo"):
                share, se = value
                first = rows[name.replace("Monte-Carlo", "first order")]
                table[name] = [f"{p:.4f} ± {e:.4f}" for p, e in zip(share, se)]
                table[name.replace("Monte-Carlo", "z")] = [
                    f"{(p - f) / e:+.1f}" if e > 0 else "-" for p, f, e in
                    zip(share, first, se)]
            else:
                table[name] = [f"{p:.4f}" for p in value]
        return pd.DataFrame(table, index=pd.Index(
            OUTPUTS, name=f"over [0, {self.horizon:g}] years, {self.check_machines:,} "
                          f"machines on the exact chain at the worst pose"))

    def save(self, path, overwrite: bool = False):
        """Save as JSON (:mod:`reliability.basics.saved_fields`); returns the path."""
        return save_fields(self, path, SAVED_FORMAT, FIELDS, overwrite)

    @classmethod
    def load(cls, path) -> "LifeStudy":
        """Reload a study written by :meth:`save`; the yield interval, the recalibration
        interval and the outputs' ages must follow from the saved counts and curves
        (SavedResultError naming the field otherwise)."""
        data, values = load_fields(path, SAVED_FORMAT, FIELDS)
        lower, upper = binomial_interval(values["passed"], values["machines"],
                                         values["confidence"], "clopper-pearson")
        _check(data, "yield_lower", values["yield_lower"], lower)
        _check(data, "yield_upper", values["yield_upper"], upper)
        study = cls(**values)
        _check(data, "interval", study.interval, crossing_interval(
            study.ages, study.yield_lower, study.machine_yield, study.yield_upper,
            study.level))
        _check(data, "output_ages", study.output_ages,
               crossing_age(study.ages, study.life, study.targets))
        return study


def _check(data, name, saved, expected) -> None:
    if not np.allclose(saved, expected, rtol=CONSISTENCY_RTOL, atol=0, equal_nan=True):
        raise data.error(name, "does not follow from the saved counts and curves")


def yield_level(machine, level=None) -> tuple[float, str]:
    """The level the machine yield is judged against and where it came from: ``level``
    (``--yield``) or the smallest of the machine file's per-output targets."""
    if level is not None:
        return float(level), "--yield"
    return float(np.min(machine.targets)), "the smallest of the machine file's targets"


def life_study(machine, tolerances, *, until: float, step: float = 0.5, level=None,
               points: int = 5, machines: int = DEFAULT_LIFE_MACHINES, seed: int = 0,
               paths: int | None = None, confidence: float = 0.95, plan=None,
               check: int = 0, memory: int | None = None) -> LifeStudy:
    """The life reliability, the machine yield over the life and the recalibration
    interval of ``tolerances`` on ``machine`` (with a ``[drift]`` table), on the ages
    ``0, step, …, until``.

    The FOSM part uses the grid ``points`` and the machine's reading; the yield draws
    ``machines`` built machines from stream 0 of ``seed`` and the wear paths (wear only)
    from stream 1 (:func:`reliability.basics.streams.spawn`). With a compensation
    ``plan`` the recalibrations of compensated machines are added
    (:func:`reliability.life.compensated_life.compensated_life`, stream 2). With
    ``check`` > 0 that many built machines check the life reliability at the worst poses on
    the exact chain (:func:`reliability.life.life_check.check_life`, streams 3 and 4).
    """
    ages = age_grid(until, step)
    level, source = yield_level(machine, level)
    yield_rng, path_rng, plan_rng, check_rng, plan_check_rng = streams.spawn(seed, 5)
    poses = workspace_grid(machine, points)
    options = {} if paths is None else {"paths": paths}
    fosm = life_reliability(machine, tolerances, poses, ages,
                            distribution=machine.distribution, rng=path_rng, memory=memory,
                            **options)
    curve = life_yield(machine, tolerances, ages, points=points, machines=machines,
                       rng=yield_rng, confidence=confidence, memory=memory)
    interval = crossing_interval(ages, curve.lower, curve.estimate, curve.upper, level)
    compensated = {} if plan is None else _compensated(
        machine, plan, tolerances, ages, level, poses, points=points, machines=machines,
        rng=plan_rng, confidence=confidence, memory=memory)
    checked = {} if check == 0 else _checks(
        machine, tolerances, plan, poses[fosm.worst_pose[-1]], compensated, ages[-1], check,
        (check_rng, plan_check_rng), memory)
    return LifeStudy(
        machine=machine.name, kind=machine.drift.kind, level_source=source,
        method=fosm.method, ages=ages, targets=np.asarray(machine.targets, dtype=float),
        at_age=fosm.at_age, life=fosm.life, life_se=fosm.life_se,
        worst_pose=poses[fosm.worst_pose], machines=curve.machines, passed=curve.passed,
        yield_lower=curve.lower, yield_upper=curve.upper, level=level,
        confidence=curve.confidence, interval=interval,
        output_ages=crossing_age(ages, fosm.life, machine.targets), rice=fosm.rice,
        **{key: value for key, value in compensated.items() if key != "worst"}, **checked)


def _checks(machine, tolerances, plan, worst, compensated, horizon, machines, rngs,
            memory) -> dict:
    """Monte-Carlo on the exact chain at the worst poses, before and after compensation."""
    found = check_life(machine, tolerances, worst, horizon, machines=machines, rng=rngs[0],
                       memory=memory)
    out = {"check_machines": machines, "check": np.vstack([found.share,
                                                           found.standard_error])}
    if plan is not None:
        after = check_life(machine, tolerances, compensated["worst"], horizon,
                           machines=machines, rng=rngs[1], memory=memory,
                           start_covariance=first_cycle_covariance(machine, plan,
                                                                   tolerances))
        out["compensated_check"] = np.vstack([after.share, after.standard_error])
    return out


def _compensated(machine, plan, tolerances, ages, level, poses, **options) -> dict:
    """The recalibrations of compensated machines and the first cycle to first order."""
    cycles = compensated_life(machine, plan, tolerances, ages, level, **options)
    first = life_reliability(machine, tolerances, poses, ages,
                             start_covariance=first_cycle_covariance(machine, plan,
                                                                     tolerances),
                             rng=options["rng"], memory=options["memory"])
    return {"recalibrations": cycles.starts, "compensated_intervals": cycles.intervals,
            "compensated_life": first.life, "compensated_yield": cycles.first_yield,
            "worst": poses[first.worst_pose[-1]]}
