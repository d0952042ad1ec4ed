"""Argument types, shared options, input files and printing of the ``precrel`` subcommands.

Everything here is about the command line itself: parsing, rewording the library's refusals
in terms of options, and printing. The computations live in the library."""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import sys
from pathlib import Path

import numpy as np

from allocation.per_pose.continuous import DEFAULT_RTOL, WORKSPACE_CHOICES, continuous_unavailable
from allocation.per_pose.problem import DEFAULT_FACTORS, bounds_source
from allocation.per_pose.result_files import read_allocation_csv
from allocation.catalogue.catalogue import load_catalogue, unit_warnings
from reliability.acceptance import definitions
from reliability.basics import display
from reliability.basics.errors import InputError
from reliability.basics.files import check_destination
from reliability.measured.identification import identify
from reliability.measured.identification import read_identification
from reliability.measured.measurement_files import read_measurements
from reliability.model.kinematics import FRAMES
from reliability.model.machine_file import load_machine
from reliability.model.machine_checks import tolerance_warnings, unit_mistakes
from reliability.sampling.machine_yield import DEFAULT_MACHINES

SIDE_CHOICES = ("one_sided", "two_sided")
DISTRIBUTION_CHOICES = ("normal", "truncated")


# ----- argument types (argparse reports their errors as one line, exit 2) ---------------
def positive_int(text: str) -> int:
    """An integer >= 1."""
    value = _integer(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {text!r}")
    return value


def experiments(text: str) -> int:
    """Grid experiments: an integer >= 2 (their spread gives the error bar)."""
    value = _integer(text)
    if value < 2:
        raise argparse.ArgumentTypeError(f"expected at least 2 experiments (their spread "
                                         f"gives the interval), got {text!r}")
    return value


def grid_points(text: str) -> int:
    """Grid points per axis: an integer >= 2 (both stroke ends)."""
    value = _integer(text)
    if value < 2:
        raise argparse.ArgumentTypeError(f"expected at least 2 points per axis, got {text!r}")
    return value


def seed(text: str) -> int:
    """A random seed: an integer >= 0."""
    value = _integer(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected a seed >= 0, got {text!r}")
    return value


def probability(text: str) -> float:
    """A reliability target strictly between 0 and 1."""
    value = _float(text)
    if not 0.0 < value < 1.0:
        raise argparse.ArgumentTypeError(f"expected a probability in (0, 1), got {text!r}")
    return value


def positive_float(text: str) -> float:
    """A finite number > 0."""
    value = _float(text)
    if not value > 0.0:
        raise argparse.ArgumentTypeError(f"expected a number > 0, got {text!r}")
    return value


def _integer(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None


def _float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not np.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return value


def add_machine(parser) -> None:
    parser.add_argument("machine", metavar="MACHINE.toml", help="machine description file")


def add_side(parser) -> None:
    parser.add_argument("--side", choices=SIDE_CHOICES, default="two_sided",
                        help="probability reading: exact two-sided P(|y| < I) (default) or "
                             "the paper's one-sided Phi(beta)")


def add_distribution(parser) -> None:
    """``--distribution``: the reading of a tolerance for every computation of the
    command; the machine file's ``[requirements] distribution`` by default."""
    parser.add_argument("--distribution", choices=DISTRIBUTION_CHOICES, default=None,
                        help="reading of a tolerance t: normal with sigma = t/3, or that "
                             "normal truncated at +-t (default: the machine file's "
                             "[requirements] distribution, else normal)")


def add_study_model(parser) -> None:
    """``--frame`` and ``--distribution``: how the command reads the outputs and the
    tolerances, overriding the machine file's ``[requirements]`` (see :func:`machine`)."""
    parser.add_argument("--frame", choices=FRAMES, default=None,
                        help="frame of the six outputs: tool (Eq. 18, turns with the rotary "
                             "axes) or workpiece (default: the machine file's [requirements] "
                             "frame, else tool)")
    add_distribution(parser)


def add_yield_model(parser) -> None:
    """``--profile`` and ``--machines``: how built machines are simulated for the machine
    yield (the machine file's ``[requirements] profile`` by default, see :func:`machine`)."""
    parser.add_argument("--profile", default=None, metavar="P",
                        help="error profile along travel of a built machine: constant, "
                             "independent (the paper's grid experiment) or gp:<length mm> "
                             "(default: the machine file's [requirements] profile, else "
                             "constant)")
    parser.add_argument("--machines", type=positive_int, default=DEFAULT_MACHINES,
                        metavar="N",
                        help=f"built machines simulated for the yield (default "
                             f"{DEFAULT_MACHINES}; at most this many when few would fail "
                             f"and importance sampling is used)")


def add_certify(parser, what: str) -> None:
    """``--certify`` (doing ``what``) and its ``--rtol``."""
    parser.add_argument("--certify", action="store_true", help=what)
    parser.add_argument("--rtol", type=probability, default=1e-3, metavar="R",
                        help="relative gap between the certified bound of sigma and sigma "
                             "at which --certify stops (default 0.001)")


def add_workspace(parser) -> None:
    """``--workspace`` (where the allocation's targets hold) and its ``--rtol``."""
    parser.add_argument("--workspace", choices=WORKSPACE_CHOICES, default=None,
                        help="where the targets hold: continuous = over the whole strokes, "
                             "certified to --rtol in sigma by adding the certificate's worst "
                             "poses to the grid (default; not for correlated errors); "
                             "grid = at the --points grid poses only "
                             "(docs/continuous-allocation.md)")
    parser.add_argument("--rtol", type=probability, default=DEFAULT_RTOL, metavar="R",
                        help=f"relative tolerance in sigma of --workspace continuous "
                             f"(default {DEFAULT_RTOL:g})")


def workspace(args) -> str:
    """``--workspace``, ``'continuous'`` when not given."""
    return "continuous" if args.workspace is None else args.workspace


def add_points(parser, default: int = 5) -> None:
    parser.add_argument("--points", type=grid_points, default=default, metavar="P",
                        help=f"grid points per axis over each stroke (default {default})")


def add_bounds(parser) -> None:
    parser.add_argument("--bounds", type=positive_float, nargs=2, default=None,
                        metavar=("LO", "HI"),
                        help="tolerance box as factors of the initial allocation (default: "
                             "the machine file's [bounds] table, else 0.5 1.5)")


def add_monte_carlo(parser) -> None:
    """``--repeats``, ``--samples`` and ``--seed`` of the Monte-Carlo verification."""
    parser.add_argument("--repeats", type=experiments, default=20, metavar="N",
                        help="grid experiments per allocation (default 20, as the paper's "
                             "Table 9)")
    parser.add_argument("--samples", type=positive_int, default=20_000, metavar="N",
                        help="random-pose samples and samples per worst pose (default 20000)")
    parser.add_argument("--seed", type=seed, default=0, metavar="S",
                        help="random seed (default 0)")


def box_words(machine, bounds) -> str:
    """The search box a command uses, in words: ``--bounds``, the machine file's
    ``[bounds]``, or the default factors."""
    source = bounds_source(machine, bounds)
    if source == "machine file":
        return "box from the machine file's [bounds]"
    low, high = DEFAULT_FACTORS if bounds is None else bounds
    where = "--bounds" if source == "given" else "default; the machine file has no [bounds]"
    return f"box {low:g}–{high:g} × initial allocation ({where})"


def wider_box_advice(machine, bounds) -> str:
    """What to widen when the targets are out of reach in the box: ``--bounds`` when it was
    given or no ``[bounds]`` table exists; else the file's achievable tolerances, saying that
    ``--bounds`` would replace them by factors of the initial allocation."""
    if bounds_source(machine, bounds) != "machine file":
        return "a wider box (--bounds LO HI, factors of the initial allocation) may reach it"
    return ("the box is the machine file's [bounds] table (achievable tolerances): widen it "
            "there if the suppliers can deliver more; --bounds LO HI would replace it by "
            "factors of the initial allocation")


# ----- checks done before any work ----------------------------------------------------
def check_bounds(bounds) -> tuple[float, float] | None:
    """``--bounds LO HI``: factors of the reference allocation, 0 < LO <= HI (None when not
    given: the machine file's box, or the default factors)."""
    if bounds is None:
        return None
    low, high = bounds
    if low > high:
        raise InputError(f"--bounds: LO = {low:g} exceeds HI = {high:g}; expected "
                         f"0 < LO <= HI (factors of the initial allocation)")
    return float(low), float(high)


def check_certifiable(machine, option: str, alternative: str) -> None:
    """Refuse ``option`` (``--certify`` or ``--workspace continuous``) before any work when
    the continuous certificate cannot cover the study
    (:func:`allocation.per_pose.continuous.continuous_unavailable`); ``alternative`` says what
    to pass instead."""
    why = continuous_unavailable(machine)
    if why is not None:
        raise InputError(f"{option}: not available for this study: {why}; {alternative}")


def destination(path, overwrite: bool, option: str = "--out", *, folder: bool = False,
                markers=()) -> Path:
    """:func:`reliability.basics.files.check_destination`, its refusals reworded for ``option``."""
    try:
        return check_destination(path, overwrite, folder=folder, markers=markers)
    except FileExistsError:
        earlier = [name for name in markers if (Path(path) / name).exists()]
        held = f"holds an earlier report ({earlier[0]})" if folder else "exists"
        raise InputError(f"{option} {path}: {held}; pass --overwrite to replace it") from None
    except IsADirectoryError:
        raise InputError(f"{option} {path}: is a folder; expected a file name") from None
    except NotADirectoryError:
        raise InputError(f"{option} {path}: is a file; expected a folder") from None
    except FileNotFoundError:
        raise InputError(f"{option} {path}: folder {Path(path).parent} does not "
                         f"exist") from None


def machine(args, *, warn: bool = True):
    """Load ``args.machine`` (a MachineDescriptionError or OSError names the file), in the
    frame of ``--frame``, with the reading of ``--distribution`` and the error profile of
    ``--profile`` when the command has those options and they are given (a bad
    ``--profile`` is an InputError naming it); its unit mistakes are printed as warnings
    unless ``warn`` is false (``check`` lists them itself)."""
    loaded = load_machine(args.machine)
    if warn:
        print_warnings(unit_mistakes(loaded))
    chosen = {name: getattr(args, name, None) for name in ("frame", "distribution", "profile")}
    chosen = {name: value for name, value in chosen.items() if value is not None}
    try:
        return dataclasses.replace(loaded, **chosen) if chosen else loaded
    except InputError as error:
        raise InputError(f"--profile: {error}") from None


def reading_text(machine) -> str:
    """The study's reading of a tolerance, as printed beside every answer."""
    return ("tolerances read as normal, sigma = t/3, truncated at +-t (distribution "
            "'truncated')" if machine.distribution == "truncated" else
            "tolerances read as normal, sigma = t/3 (distribution 'normal')")


def read_tolerances(path, machine) -> np.ndarray:
    """``--tolerances CSV``: :func:`allocation.read_allocation_csv`, its refusals naming the
    option."""
    try:
        tolerances = read_allocation_csv(path, machine)
    except InputError as exc:
        raise InputError(f"--tolerances {exc}") from None
    except OSError as exc:
        raise InputError(f"--tolerances {path}: cannot be read ({exc.strerror or exc})") \
            from None
    print_warnings(tolerance_warnings(machine, tolerances, f"--tolerances {path}"))
    return tolerances


def read_tests(path, machine) -> tuple:
    """``--tests TESTS.toml``: :func:`reliability.acceptance.definitions.read_tests`, with
    limits that look written in µm printed as warnings."""
    tests = definitions.read_tests(path, machine)
    print_warnings(definitions.unit_warnings(tests, str(path)))
    return tests


def read_catalogue(path, machine):
    """``--catalogue CAT.toml``: :func:`allocation.load_catalogue`, with class tolerances
    that look written in µm or arc seconds printed as warnings."""
    catalogue = load_catalogue(path, machine)
    print_warnings(unit_warnings(catalogue))
    return catalogue


# ----- printing ------------------------------------------------------------------------
def pose_text(machine, pose) -> str:
    """A pose as axis positions with units, e.g. ``X=-300 mm, C=1.571 rad``."""
    return display.pose_text(pose, machine.axes, display.axis_units(machine), digits=6)


def percent(value: float) -> str:
    """A probability in per cent (:func:`reliability.basics.display.percent_text`)."""
    return display.percent_text(value)


def progress_bar(total: int, description: str):
    """A tqdm progress bar on stderr, hidden when stderr is not a terminal."""
    from tqdm import tqdm
    return tqdm(total=total, desc=description, file=sys.stderr, leave=False,
                disable=None)


def print_warnings(texts) -> None:
    """Each text as one line ``warning: ...`` on stderr; the work goes on."""
    for text in texts:
        print(f"warning: {text}", file=sys.stderr, flush=True)


def say(text: str) -> None:
    """A progress line on stderr."""
    print(text, file=sys.stderr, flush=True)


#: Workers of a local Dask cluster when ``--workers`` is not given.
DASK_WORKERS = 2


@contextlib.contextmanager
def dask_client(scheduler=None, workers=None, option: str = "--executor dask"):
    """A Dask client of the running scheduler at ``scheduler``, else of a local cluster of
    ``workers`` (default :data:`DASK_WORKERS`) one-thread workers, closed afterwards; Dask
    (the ``dask`` extra) is imported here, and its absence is refused naming ``option``."""
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise InputError(f"{option} needs the dask extra: "
                         f"pip install 'precision-reliability[dask]'") from None
    if scheduler is None:
        with LocalCluster(n_workers=workers or DASK_WORKERS, threads_per_worker=1,
                          dashboard_address=None) as cluster, Client(cluster) as client:
            yield client
        return
    try:
        client = Client(scheduler)
    except (OSError, ValueError) as error:  # no answer; not an address
        raise InputError(f"--scheduler {scheduler}: no Dask scheduler answers there "
                         f"({error})") from None
    with client:
        yield client


# ----- this machine as measured -------------------------------------------------------
def add_as_measured(parser, *, required: bool = False) -> None:
    """``--identification DIR`` or ``--measurements CSV``: this machine as measured, for its
    reliability beside the design-time numbers (``verify``, ``report``) or, ``required``, as
    the command's input (``compensate``)."""
    also = "" if required else "also this machine's reliability as measured: "
    group = parser.add_mutually_exclusive_group(required=required)
    group.add_argument("--identification", metavar="DIR",
                       help=f"{also}the folder 'precrel identify --out' wrote "
                            f"(docs/measurements.md)")
    group.add_argument("--measurements", metavar="CSV",
                       help="this machine's measurement file instead, identified here under "
                            "--profile (constant or gp:<length mm>) with the allocation in "
                            "force as prior")


def as_measured_identification(args, machine, tolerances=None):
    """The identification of ``--identification`` or ``--measurements`` (identified under
    the machine's profile with ``tolerances`` as the prior's allocation, the initial one
    when None); None without either."""
    if args.identification is not None:
        try:
            return read_identification(args.identification, machine)
        except InputError as exc:
            raise InputError(f"--identification {exc}") from None
    if args.measurements is not None:
        return identify(machine, read_measurements(args.measurements, machine),
                        tolerances=tolerances, profile=identified_profile(machine))
    return None


def identified_profile(machine) -> str:
    """The profile readings are identified under: the machine's (``--profile``, else the
    machine file's ``[requirements] profile``), refused when it is ``independent``."""
    if machine.profile == "independent":
        raise InputError("--measurements: profile 'independent' (--profile or the machine "
                         "file's [requirements] profile) cannot be identified, a fresh value "
                         "at every position; pass --profile constant or gp:<length mm>")
    return machine.profile
