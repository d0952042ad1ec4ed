"""``precrel sweep SPEC.toml --store DIR``: run a sweep of allocate-and-verify tasks.

Tasks run serially, on a local process pool or on a Dask cluster; finished tasks are
stored in DIR as they finish, so an interrupted sweep resumes where it stopped. The
table of results is written to ``DIR/results.csv``.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from tqdm import tqdm

from reliability.basics.errors import InputError
from studies.workflows.sweep import RESULTS_FILE, SweepSpec, run_sweep

from . import options

EXECUTORS = ("serial", "processes", "dask")


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Register ``sweep`` with its options."""
    parser = subparsers.add_parser(
        "sweep", help="run a sweep of allocate-and-verify tasks (resumable)",
        description=__doc__.splitlines()[0].split(": ", 1)[1])
    parser.add_argument("spec", type=Path, help="sweep spec (TOML; see docs/sweeps.md)")
    parser.add_argument("--store", type=Path, required=True,
                        help=f"folder of finished tasks and of {RESULTS_FILE}")
    parser.add_argument("--executor", choices=EXECUTORS, default="serial",
                        help="where tasks run (default: serial)")
    parser.add_argument("--workers", type=int, default=None,
                        help="processes or Dask workers (default: 2 for dask, the number "
                             "of CPUs for processes)")
    parser.add_argument("--scheduler", default=None,
                        help="address of a running Dask scheduler (with --executor dask)")
    options.add_distribution(parser)
    return parser


def run(args) -> int:
    """Run the sweep; prints the resumed count and where the results are."""
    _check(args)
    spec = SweepSpec.from_toml(args.spec)
    if args.distribution is not None:  # the command line overrides the spec's reading
        spec = dataclasses.replace(spec, distribution=args.distribution)
    total = len(spec.tasks())
    with _executor(args) as executor, tqdm(total=total, file=sys.stderr, unit="task",
                                          desc="sweep") as bar:
        def progress(done, _total):
            bar.update(done - bar.n)

        result = run_sweep(spec, args.store, executor=executor, progress=progress,
                           log=print)
    print(f"{result.computed} task(s) computed, {result.resumed} already done; "
          f"results: {result.path}")
    return 0


def _check(args) -> None:
    if args.workers is not None and args.workers < 1:
        raise InputError(f"--workers must be a positive integer; got {args.workers}")
    if args.scheduler is not None and args.executor != "dask":
        raise InputError("--scheduler needs --executor dask")
    if args.executor == "serial" and args.workers is not None:
        raise InputError("--workers needs --executor processes or dask")


@contextlib.contextmanager
def _executor(args):
    """The executor named on the command line, shut down afterwards."""
    if args.executor == "serial":
        yield None
    elif args.executor == "processes":
        pool = ProcessPoolExecutor(max_workers=args.workers)
        try:
            yield pool
        finally:  # on an interrupt, do not wait for tasks that have not started
            pool.shutdown(wait=True, cancel_futures=True)
    else:
        with options.dask_client(args.scheduler, args.workers) as client:
            yield client
