"""The combination matrix: every command on three machines, in both frames, with the box from
factors or from an absolute ``[bounds]`` table, under both readings of a tolerance and two
error profiles.

A cell *works* (exit 0; a report folder holds its report) or is *refused*: exit 2, one line
on stderr naming what to change, nothing on stdout. Anything else (a traceback, a lost
report, a refusal after results were printed) is a defect.

``tests/test_combinations.py`` runs a covering subset in the suite (every command on every
machine in both frames, with the box, reading and profile rotated so each pair of their
values meets every command, in one frame per machine and command, and one report); ``python tests/combination_matrix.py``
runs the covering set with every report, ``--full`` the whole product, each printing one
line per cell and a tally.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import itertools
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import tomli_w

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from reliability.model.machine import machine_to_dict  # noqa: E402
from reliability.model.machine_file import hobbing_machine, load_machine  # noqa: E402
from studies.cli import main  # noqa: E402

#: The machines: how to load each, its catalogue and its acceptance tests.
MACHINES = {
    "paper": (None, ROOT / "docs/examples/paper_catalogue.toml",
              ROOT / "docs/examples/paper_tests.toml"),
    "swivel5": (ROOT / "tests/machines/swivel5.toml", ROOT / "tests/catalogues/swivel5.toml",
                ROOT / "tests/acceptance_tests/swivel5.toml"),
    "mill3": (ROOT / "tests/machines/mill3.toml", ROOT / "tests/catalogues/mill3.toml",
              ROOT / "tests/acceptance_tests/mill3.toml"),
}
FRAMES = ("tool", "workpiece")
BOXES = ("factors", "table")
READINGS = ("normal", "truncated")
PROFILES = ("constant", "gp:300")
COMMANDS = ("check", "predict", "allocate", "allocate --yield", "choose",
            "verify", "report", "front", "sweep", "acceptance")
#: Small sizes: the matrix checks that combinations join, not the numbers (the paper's
#: six-axis machine on a 2-point grid, the others on 3 points).
POINTS = "3"
MACHINE_COUNT = "30"
SAMPLES = "200"


@dataclass(frozen=True)
class Cell:
    """One combination."""

    command: str
    machine: str
    frame: str
    box: str
    reading: str
    profile: str

    def label(self) -> str:
        return (f"{self.command} | {self.machine} | {self.frame} | {self.box} | "
                f"{self.reading} | {self.profile}")


@dataclass(frozen=True)
class Outcome:
    """What a cell did: ``status`` 'works', 'refused' or 'defect'."""

    status: str
    message: str
    seconds: float


def machine_file(cell: Cell, folder: Path) -> Path:
    """The cell's machine as a file: its frame, reading and profile in ``[requirements]``;
    under box 'table' an absolute ``[bounds]`` table of 0.5–1.5 × the initial allocation,
    under box 'factors' none (the commands get ``--bounds 0.5 1.5``)."""
    source = MACHINES[cell.machine][0]
    machine = hobbing_machine() if source is None else load_machine(source)
    data = machine_to_dict(machine)
    data["requirements"].update(frame=cell.frame, distribution=cell.reading,
                                profile=cell.profile)
    data.pop("bounds", None)
    if cell.box == "table":
        initial = machine.initial_allocation
        translational = np.array([name.split(".")[1][0] == "d" for name in
                                  machine.error_names])
        data["bounds"] = {
            "translation": [0.5 * float(np.median(initial[translational])),
                            1.5 * float(np.median(initial[translational]))],
            "rotation": [0.5 * float(np.median(initial[~translational])),
                         1.5 * float(np.median(initial[~translational]))]}
    path = folder / f"{cell.machine}.toml"
    path.write_text(tomli_w.dumps(data))
    return path


def initial_csv(path: Path, folder: Path) -> Path:
    """The machine's initial allocation as a ``--tolerances`` file."""
    machine = load_machine(path)
    out = folder / "initial.csv"
    pd.DataFrame({"error": machine.error_names,
                  "allocated": machine.initial_allocation}).to_csv(out, index=False)
    return out


def sweep_spec(cell: Cell, machine: Path, folder: Path) -> Path:
    """A one-task sweep of the cell's machine."""
    spec = {"machines": [str(machine)], "sides": ["two_sided"], "targets": [0.99],
            "profiles": [cell.profile], "seeds": [0], "repeats": [2],
            "points": int(POINTS)}
    if cell.box == "factors":
        spec["bounds"] = [0.5, 1.5]
    path = folder / "sweep.toml"
    path.write_text(tomli_w.dumps(spec))
    return path


def arguments(cell: Cell, folder: Path) -> list[str]:
    """The command line of ``cell``, its files written into ``folder``."""
    machine = machine_file(cell, folder)
    catalogue, tests = MACHINES[cell.machine][1:]
    box = ["--bounds", "0.5", "1.5"] if cell.box == "factors" else []
    m = str(machine)
    small = ["--points", "2" if cell.machine == "paper" else POINTS]
    verification = ["--repeats", "2", "--samples", SAMPLES, "--machines", MACHINE_COUNT]
    return {
        "check": ["check", m],
        "predict": ["predict", m, *small],
        "allocate": ["allocate", m, *small, *box, "--out", str(folder / "a.csv")],
        "allocate --yield": ["allocate", m, *small, *box, "--yield", "0.9", "--machines",
                             MACHINE_COUNT, "--out", str(folder / "y.csv")],
        "choose": ["choose", m, *small, "--catalogue", str(catalogue),
                   "--out", str(folder / "c.csv")],
        "verify": ["verify", m, *small, *verification, "--tolerances",
                   str(initial_csv(machine, folder))],
        "report": ["report", m, *small, *box, *verification, "--tests", str(tests),
                   "--catalogue", str(catalogue), "--skip", "front", "system", "rare",
                   "profiles", "--out", str(folder / "report")],
        "front": ["front", m, *small, *box, "--count", "2", "--out",
                  str(folder / "f.csv")],
        "sweep": ["sweep", str(sweep_spec(cell, machine, folder)), "--out",
                  str(folder / "store")],
        "acceptance": ["acceptance", m, "--tests", str(tests), "--machines", MACHINE_COUNT],
    }[cell.command]


def run_cell(cell: Cell, folder: Path) -> Outcome:
    """Run ``cell`` in-process; classify what it did."""
    folder.mkdir(parents=True, exist_ok=True)
    argv = arguments(cell, folder)
    out, err = io.StringIO(), io.StringIO()
    start = time.perf_counter()
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code = main(argv)
    except Exception as exc:  # a traceback is the defect this matrix looks for
        return Outcome("defect", f"{type(exc).__name__}: {exc}", time.perf_counter() - start)
    seconds = time.perf_counter() - start
    errors = [line for line in err.getvalue().splitlines() if line.startswith("precrel:")]
    if code == 0:
        if cell.command == "report" and not (folder / "report" / "report.md").exists():
            return Outcome("defect", "exit 0 but no report.md", seconds)
        return Outcome("works", "", seconds)
    message = errors[-1] if errors else err.getvalue().strip()[-300:]
    if code == 2 and len(errors) == 1 and not out.getvalue().strip():
        return Outcome("refused", message, seconds)
    return Outcome("defect", f"exit {code}, stdout {len(out.getvalue())} chars: {message}",
                   seconds)


def all_cells() -> list[Cell]:
    """The whole product."""
    return [Cell(*values) for values in itertools.product(
        COMMANDS, MACHINES, FRAMES, BOXES, READINGS, PROFILES)]


#: Reports kept in the suite's covering set (a report runs the whole study, the slowest
#: cell by far); the others run with ``--full``, and the paper's report at full settings in
#: ``tests/test_reproduce.py``.
SUITE_REPORTS = {("mill3", "workpiece")}


def covering_cells(suite: bool = False) -> list[Cell]:
    """Every command on every machine in both frames; box, reading and profile rotated
    through the four runs of a two-level orthogonal array, so that for every command each
    pair of their values (and each with each frame) occurs. ``suite``: every command on
    every machine in one frame, alternating between the machines (and between commands),
    so that each command meets both frames; of the reports only :data:`SUITE_REPORTS`."""
    array = [(0, 0, 0), (0, 1, 1), (1, 0, 1), (1, 1, 0)]
    cells = []
    for command in COMMANDS:
        for index, (machine, frame) in enumerate(itertools.product(MACHINES, FRAMES)):
            if suite and command == "report":
                if (machine, frame) not in SUITE_REPORTS:
                    continue
            elif suite and (index // 2 + index + COMMANDS.index(command)) % 2:
                continue
            box, reading, profile = array[(index + COMMANDS.index(command)) % 4]
            cells.append(Cell(command, machine, frame, BOXES[box], READINGS[reading],
                              PROFILES[profile]))
    return cells


def _main() -> int:
    import tempfile

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--full", action="store_true", help="the whole product")
    parser.add_argument("--part", default="1/1", metavar="I/N",
                        help="run every N-th cell from the I-th (to split a run over processes)")
    args = parser.parse_args()
    first, every = (int(value) for value in args.part.split("/"))
    cells = (all_cells() if args.full else covering_cells())[first - 1::every]
    tally, start = {}, time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        for number, cell in enumerate(cells):
            outcome = run_cell(cell, Path(tmp) / str(number))
            tally.setdefault(outcome.status, []).append((cell, outcome))
            print(f"{outcome.status:8s} {outcome.seconds:6.1f} s  {cell.label()}"
                  f"{'  ' + outcome.message if outcome.message else ''}", flush=True)
    print(f"\n{len(cells)} cells in {time.perf_counter() - start:.0f} s: " + ", ".join(
        f"{len(found)} {status}" for status, found in sorted(tally.items())))
    messages = {}
    for cell, outcome in tally.get("refused", []):
        messages.setdefault(outcome.message.split(":", 2)[-1].strip()[:120], []).append(cell)
    for message, found in messages.items():
        print(f"  refused {len(found)}x: {message}")
    return 0 if "defect" not in tally else 1


if __name__ == "__main__":
    sys.exit(_main())
