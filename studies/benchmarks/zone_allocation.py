"""The default commands on machines with and without a work zone: the continuous workspace's
certified allocation against the grid allocation, and ``predict --certify`` and ``report``.

Run as ``python -m studies.benchmarks.zone_allocation [--quick] [--time-limit S]
[--machines swivel5 trunnion5 hobbing] [--zones with without] [--code DIR]``. For the three
machines with a work zone of the tests (``tests/machines/swivel5_zone.toml``,
``trunnion5_zone.toml`` and ``hobbing_zone.toml``: the plain files
``tests/machines/swivel5.toml``, ``trunnion5.toml`` and the paper's machine
``reliability/machines/hobbing.toml`` plus a cylinder zone) and the same machines without
their zone (the plain files), it runs, each in its own subprocess exactly as a user types it
(``python -m studies ...``, BLAS pinned to one thread):

* ``allocate MACHINE --out a.csv --workspace grid``: the reference, the grid allocation;
* ``allocate MACHINE --out a.csv``: the default, certified over the continuous workspace;
* ``predict MACHINE --certify``: the certificate of the initial allocation;
* ``report MACHINE --out DIR``: the whole study (``--quick``: ``--skip front system rare
  profiles --repeats 2 --samples 2000 --machines 500``);

and prints a markdown table, one row per machine and zone: the grid poses, the wall time of
each command, the ratio of the continuous allocation's time to the grid allocation's (the
reference measured in the same run, so that a busy machine disturbs both alike), the
continuous loop's convex solves and certificate calls and whether it certified (read from
what ``allocate`` prints), and the peak resident memory of the continuous allocation's
process (``os.wait4``'s ``ru_maxrss``: interpreter and libraries included). A run still
going after ``--time-limit`` seconds (default 300; ``--quick``: 60) is stopped and shown as
``> S s, stopped``, so the script never hangs. The load average at the start and the end
says how busy the CPUs were. ``--code DIR`` runs another copy of the
toolkit (for example an earlier commit checked out in DIR) on this copy's machine files, for
before/after tables. Nothing is asserted on times.
"""

from __future__ import annotations

import argparse
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parents[2]
#: Each machine's file with its zone, and without it (the same machine, ``work_zone=None``).
MACHINES = {
    "swivel5": {"with": "tests/machines/swivel5_zone.toml",
                "without": "tests/machines/swivel5.toml"},
    "trunnion5": {"with": "tests/machines/trunnion5_zone.toml",
                  "without": "tests/machines/trunnion5.toml"},
    "hobbing": {"with": "tests/machines/hobbing_zone.toml",
                "without": "reliability/machines/hobbing.toml"},
}
#: The report's options under ``--quick``: no optional section, small Monte-Carlo samples.
QUICK_REPORT = ("--skip", "front", "system", "rare", "profiles", "--repeats", "2",
                "--samples", "2000", "--machines", "500")
#: How often a running command is polled (s).
POLL = 0.2


def run_command(argv, code: Path, time_limit: float) -> dict:
    """Run ``python -m studies *argv`` from ``code`` with a wall-time limit.

    Returns
    -------
    dict
        ``seconds`` (wall), ``stopped`` (killed at the limit), ``code`` (exit code; None
        when stopped), ``peak_mb`` (the process' maximum resident set size) and ``stdout``.
    """
    env = dict(os.environ, PYTHONPATH=str(code))
    with tempfile.TemporaryFile("w+") as out:
        started = time.perf_counter()
        process = subprocess.Popen([sys.executable, "-m", "studies", *argv], cwd=code,
                                   env=env, stdout=out, stderr=subprocess.DEVNULL,
                                   text=True, start_new_session=True)
        status, usage, stopped = _wait(process.pid, started + time_limit)
        seconds = time.perf_counter() - started
        process.returncode = os.waitstatus_to_exitcode(status)  # reaped by os.wait4
        out.seek(0)
        stdout = out.read()
    return {"seconds": seconds, "stopped": stopped,
            "code": None if stopped else process.returncode,
            "peak_mb": usage.ru_maxrss / 1024, "stdout": stdout}


def _wait(pid: int, deadline: float):
    """Wait for ``pid`` until ``deadline`` (``time.perf_counter``), killing its process group
    then; return its wait status, resource usage and whether it was stopped."""
    while time.perf_counter() < deadline:
        done, status, usage = os.wait4(pid, os.WNOHANG)
        if done:
            return status, usage, False
        time.sleep(POLL)
    os.killpg(pid, signal.SIGKILL)
    _, status, usage = os.wait4(pid, 0)
    return status, usage, True


def loop_counts(stdout: str) -> dict:
    """The continuous loop's solves and certificate calls and its verdict, as ``allocate``
    prints them ("N convex solve(s), … C certificate call(s)", "workspace: continuous —
    certified …" or "NOT certified …"); empty strings where the output lacks them."""
    work = re.search(r"(\d+) convex solve\(s\).*?(\d+) certificate call\(s\)", stdout)
    verdict = re.search(r"workspace: continuous — (\S+)", stdout)
    return {"solves": work.group(1) if work else "",
            "calls": work.group(2) if work else "",
            "certified": "" if verdict is None else
            ("yes" if verdict.group(1) == "certified" else "no")}


def grid_poses(stdout: str) -> str:
    """The grid poses the grid allocation holds the targets at, as it prints them."""
    found = re.search(r"the targets hold at the (\d+) poses", stdout)
    return found.group(1) if found else ""


def seconds_text(run: dict, time_limit: float) -> str:
    """The run's wall time, "> S s, stopped" at the limit, or its exit code if it failed."""
    if run["stopped"]:
        return f"> {time_limit:g} s, stopped"
    if run["code"] != 0:
        return f"exit {run['code']}"
    return f"{run['seconds']:.1f}"


def configuration_row(name: str, zone: str, code: Path, time_limit: float,
                      quick: bool) -> str:
    """The markdown row of one machine with or without its zone (four commands run)."""
    machine = str(HERE / MACHINES[name][zone])
    with tempfile.TemporaryDirectory() as folder:
        grid = run_command(["allocate", machine, "--out", f"{folder}/g.csv",
                            "--workspace", "grid"], code, time_limit)
        continuous = run_command(["allocate", machine, "--out", f"{folder}/c.csv"], code,
                                 time_limit)
        predict = run_command(["predict", machine, "--certify"], code, time_limit)
        report = run_command(["report", machine, "--out", f"{folder}/report",
                              *(QUICK_REPORT if quick else ())], code, time_limit)
    counts = loop_counts(continuous["stdout"])
    finished = not (grid["stopped"] or grid["code"]) and continuous["code"] == 0
    ratio = f"{continuous['seconds'] / grid['seconds']:.1f}" if finished else \
        (f"> {time_limit / grid['seconds']:.0f}" if continuous["stopped"] else "")
    cells = [name, zone, grid_poses(grid["stdout"]), seconds_text(grid, time_limit),
             seconds_text(continuous, time_limit), ratio, counts["solves"], counts["calls"],
             counts["certified"], f"{continuous['peak_mb']:.0f}",
             seconds_text(predict, time_limit), seconds_text(report, time_limit)]
    return "| " + " | ".join(cells) + " |"


HEADER = ("| machine | zone | grid poses | allocate grid (s) | allocate continuous (s) "
          "| continuous / grid | solves | certificate calls | certified | peak MB "
          "(continuous) | predict --certify (s) | report (s) |")


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true",
                        help="a smaller report and a 60 s limit per run (unless "
                             "--time-limit is given)")
    parser.add_argument("--time-limit", type=float, default=None, metavar="S",
                        help="wall seconds per run before it is stopped (default 300)")
    parser.add_argument("--machines", nargs="+", choices=tuple(MACHINES),
                        default=tuple(MACHINES))
    parser.add_argument("--zones", nargs="+", choices=("with", "without"),
                        default=("with", "without"))
    parser.add_argument("--code", type=Path, default=HERE,
                        help="folder of the toolkit copy to run (default: this one)")
    args = parser.parse_args(argv)
    time_limit = args.time_limit or (60.0 if args.quick else 300.0)
    if time_limit <= 0:
        parser.error("--time-limit: expected seconds > 0")
    from studies.workflows.timing import limit_blas_threads

    limit_blas_threads()
    print(f"toolkit from {args.code.resolve()}; BLAS threads "
          f"{os.environ['OPENBLAS_NUM_THREADS']}; CPUs {os.cpu_count()}; limit "
          f"{time_limit:g} s per run{'; quick report' if args.quick else ''}; "
          f"{load_text()} at the start\n")
    print(HEADER)
    print("|" + " --- |" * HEADER.count(" | ") + " --- |", flush=True)
    for name in args.machines:
        for zone in args.zones:
            print(configuration_row(name, zone, args.code.resolve(), time_limit, args.quick),
                  flush=True)
    print(f"\n(times are wall seconds of the whole command, interpreter start included; "
          f"'continuous / grid' is the ratio of the two allocate runs of the same row; "
          f"{load_text()} at the end: other processes share the CPUs)")


def load_text() -> str:
    """The machine's 1-minute load average, in words: how busy the CPUs were."""
    return f"load average {os.getloadavg()[0]:.1f}"


if __name__ == "__main__":
    main()
