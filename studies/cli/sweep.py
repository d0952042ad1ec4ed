"""``precrel sweep SPEC.toml --out DIR``: run a sweep of allocate-and-verify tasks.

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

from studies.workflows.sweep import RESULTS_FILE, SweepSpec, run_sweep

from . import options


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Register ``sweep`` with its options."""
    parser = subparsers.add_parser(
        "sweep", help="run a sweep of allocate-and-verify tasks (resumable)",
        description=__doc__.splitlines()[0].split(": ", 1)[1])
    parser.add_argument("spec", type=Path, help="sweep spec (TOML; see docs/sweeps.md)")
    where = parser.add_mutually_exclusive_group(required=True)
    options.add_out(where, "folder", f"folder of finished tasks and of {RESULTS_FILE}")
    options.add_deprecated(where, "--store", "--out", dest="out", metavar="DIR")
    options.add_executor(parser)
    options.add_distribution(parser)
    return parser


def run(args) -> int:
    """Run the sweep; prints the resumed count and where the results are."""
    kind = options.executor_kind(args)
    spec = SweepSpec.from_toml(args.spec)
    if args.distribution is not None:  # the command line overrides the spec's reading
        spec = dataclasses.replace(spec, distribution=args.distribution)
    total = len(spec.tasks())
    with _executor(kind, args) as executor, tqdm(total=total, file=sys.stderr, unit="task",
                                          desc="sweep") as bar:
        def progress(done, _total):
            bar.update(done - bar.n)

        result = run_sweep(spec, Path(args.out), executor=executor, progress=progress,
                           log=print)
    print(f"{result.computed} task(s) computed, {result.resumed} already done; "
          f"results: {result.path}")
    return 0


@contextlib.contextmanager
def _executor(kind: str, args):
    """The executor of ``kind`` (:func:`options.executor_kind`), shut down afterwards."""
    if kind == "serial":
        yield None
    elif kind == "processes":
        pool = ProcessPoolExecutor(max_workers=args.workers)
        try:
            yield pool
        finally:  # on an interrupt, do not wait for tasks that have not started
            pool.shutdown(wait=True, cancel_futures=True)
    else:
        with options.dask_client(args.scheduler, args.workers) as client:
            yield client
