"""Argument types, shared options, input files and printing of the ``precrel`` subcommands.

Everything here is about the command line itself: parsing, rewording the library's refusals
in terms of options, and printing. The computations live in the library."""

from __future__ import annotations

import argparse
import contextlib
import contextvars
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


def nonnegative_age(text: str) -> float:
    """A finite number of years ≥ 0 (``--age``)."""
    value = _float(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected a number of years >= 0, got {text!r}")
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


# ----- the shared options: one add_* each, one name, type, meaning and help ------------
#: Where a command's independent tasks run (``sweep``'s tasks, ``allocate --yield``'s
#: built machines).
EXECUTORS = ("serial", "processes", "dask")
#: The kinds of ``--out``: one table is a FILE (the files written beside it are named
#: from its stem), several files a FOLDER.
OUT_KINDS = ("file", "folder")


def _shared(action, origin: str):
    """Tag ``action`` with the ``add_*`` function that declared it (read by the grammar's
    test: one option, one declaration)."""
    action.origin = origin
    return action


def add_machine(parser) -> None:
    """The positional ``MACHINE.toml``."""
    parser.add_argument("machine", metavar="MACHINE.toml", help="machine description file")


def add_out(parser, kind: str, writes: str, *, metavar: str | None = None,
            required: bool = False):
    """``--out``: a FILE (``kind='file'``, the one table the command writes; the files
    written beside it are named from its stem, :func:`beside`) or a FOLDER
    (``kind='folder'``, for a command that writes several files); ``writes`` says what."""
    if kind not in OUT_KINDS:
        raise ValueError(f"kind: expected one of {OUT_KINDS}, got {kind!r}")
    metavar = metavar or ("FILE" if kind == "file" else "DIR")
    action = parser.add_argument("--out", required=required, metavar=metavar, help=writes)
    action.out_kind = kind
    return _shared(action, "add_out")


def beside(out: Path, name: str) -> Path:
    """The file named ``name`` written beside the ``--out`` file ``out``, named from its
    stem: ``a.csv`` -> ``a.drawing.csv``; so runs with different ``--out`` never collide."""
    return out.with_name(f"{out.stem}.{name}.csv")


def add_overwrite(parser):
    """``--overwrite``."""
    return _shared(parser.add_argument(
        "--overwrite", action="store_true",
        help="replace the files an earlier run with the same --out wrote (files of other "
             "--out names are left alone)"), "add_overwrite")


def add_side(parser):
    """``--side``: the reading of a probability."""
    return _shared(parser.add_argument(
        "--side", choices=SIDE_CHOICES, default="two_sided",
        help="probability reading: exact two-sided P(|y| < I) (default) or the paper's "
             "one-sided Phi(beta)"), "add_side")


def add_distribution(parser):
    """``--distribution``: the reading of a tolerance for every computation of the
    command; the machine file's ``[requirements] distribution`` by default."""
    return _shared(parser.add_argument(
        "--distribution", choices=DISTRIBUTION_CHOICES, default=None,
        help="reading of a tolerance t: normal with sigma = t/3, or that normal truncated "
             "at +-t (default: the machine file's [requirements] distribution, else "
             "normal)"), "add_distribution")


def add_frame(parser):
    """``--frame``: the frame of the outputs; the machine file's by default."""
    return _shared(parser.add_argument(
        "--frame", choices=FRAMES, default=None,
        help="frame of the six outputs: tool (Eq. 18, turns with the rotary axes) or "
             "workpiece (default: the machine file's [requirements] frame, else tool)"),
        "add_frame")


def add_study_model(parser) -> None:
    """``--frame`` and ``--distribution``: how the command reads the outputs and the
    tolerances, overriding the machine file's ``[requirements]`` (see :func:`machine`)."""
    add_frame(parser)
    add_distribution(parser)


def add_profile(parser):
    """``--profile``: the error profile along travel; the machine file's by default."""
    return _shared(parser.add_argument(
        "--profile", default=None, metavar="P",
        help="error profile along travel of a built machine: constant, independent (the "
             "paper's grid experiment) or gp:<length mm> (default: the machine file's "
             "[requirements] profile, else constant)"), "add_profile")


def add_machines(parser, default: int = DEFAULT_MACHINES):
    """``--machines``: how many built machines are simulated."""
    return _shared(parser.add_argument(
        "--machines", type=positive_int, default=default, metavar="N",
        help="built machines simulated (default %(default)s)"), "add_machines")


def add_yield_model(parser) -> None:
    """``--profile`` and ``--machines``: how built machines are simulated for the machine
    yield (the machine file's ``[requirements] profile`` by default, see :func:`machine`)."""
    add_profile(parser)
    add_machines(parser)


def add_seed(parser):
    """``--seed``."""
    return _shared(parser.add_argument(
        "--seed", type=seed, default=0, metavar="S",
        help="random seed (default %(default)s); the same seed gives the same result"),
        "add_seed")


def add_points(parser, default: int = 5):
    """``--points``: the grid over the strokes."""
    return _shared(parser.add_argument(
        "--points", type=grid_points, default=default, metavar="P",
        help="grid points per axis over each stroke (default %(default)s)"), "add_points")


def add_bounds(parser):
    """``--bounds LO HI``."""
    return _shared(parser.add_argument(
        "--bounds", type=positive_float, nargs=2, default=None, metavar=("LO", "HI"),
        help="tolerance box as factors of the initial allocation (default: the machine "
             "file's [bounds] table, else 0.5 1.5)"), "add_bounds")


def add_tolerances(parser, *, required: bool = False):
    """``--tolerances CSV``: the allocation in force."""
    return _shared(parser.add_argument(
        "--tolerances", required=required, metavar="CSV",
        help="allocation CSV (columns error, allocated, as 'allocate' writes it; a drawing "
             "file is read as it is); when optional, the machine file's initial allocation "
             "by default"), "add_tolerances")


def add_yield(parser, dest: str, use: str):
    """``--yield Y``: a machine yield in (0, 1) (the share of built machines within every
    limit at every grid pose); ``use`` says what the command does with it."""
    return _shared(parser.add_argument(
        "--yield", dest=dest, type=probability, metavar="Y",
        help=f"a machine yield Y in (0, 1): {use}"), "add_yield")


def add_target(parser, *, many: bool = False):
    """``--target R`` (with ``many``, ``--target R ...``): reliability targets."""
    return _shared(parser.add_argument(
        "--target", type=probability, nargs="+" if many else None, metavar="R",
        help="reliability target in (0, 1), the same for every output (default: the "
             "machine file's targets)"), "add_target")


def add_rtol(parser):
    """``--rtol``: the gap of the continuous workspace's certificate."""
    return _shared(parser.add_argument(
        "--rtol", type=probability, default=DEFAULT_RTOL, metavar="R",
        help="relative gap in sigma at which the certificate over the continuous "
             "workspace stops (--workspace continuous, --certify; default %(default)g)"),
        "add_rtol")


def add_workspace(parser) -> None:
    """``--workspace`` (where the command's poses are) and its ``--rtol``."""
    _shared(parser.add_argument(
        "--workspace", choices=WORKSPACE_CHOICES, default=None,
        help="continuous = every pose of the strokes, certified to --rtol in sigma "
             "(default; not for correlated errors); grid = the --points grid poses only "
             "(docs/continuous-allocation.md)"), "add_workspace")
    add_rtol(parser)


def workspace(args) -> str:
    """``--workspace``, ``'continuous'`` when not given."""
    return "continuous" if args.workspace is None else args.workspace


def add_time_limit(parser):
    """``--time-limit``: wall seconds the continuous workspace's certification may take."""
    return _shared(parser.add_argument(
        "--time-limit", type=positive_float, default=None, metavar="S",
        help="stop the certification over the continuous workspace after S seconds (or at "
             "Ctrl-C) with the best allocation so far, written and marked not certified; "
             "exit code 3 (default: no limit)"), "add_time_limit")


def add_quiet(parser):
    """``--quiet``: no progress lines on stderr."""
    return _shared(parser.add_argument(
        "--quiet", action="store_true",
        help="no progress lines or bars on stderr (results, warnings and errors are still "
             "printed)"), "add_quiet")


def loop_limits(args, chosen: str) -> dict:
    """The continuous loop's keyword for ``--time-limit`` (``time_limit``; none when not
    given, so the loop keeps its default of no limit); refused before any work with the
    ``chosen`` workspace ``'grid'``, which has no certification to stop."""
    if args.time_limit is None:
        return {}
    if chosen != "continuous":
        raise InputError(f"--time-limit {args.time_limit:g} bounds the certification over "
                         f"the continuous workspace; --workspace {chosen} has none to stop "
                         f"(leave out --time-limit)")
    return {"time_limit": args.time_limit}


#: Exit code of a run whose certification over the continuous workspace was stopped by
#: ``--time-limit`` or Ctrl-C: its outputs are written, marked not certified, with the reason
#: (bad input is 2, :data:`studies.cli.program.USAGE_ERROR`).
STOPPED = 3
#: What the continuous loop's reason says when it was stopped before its certificate closed:
#: "not certified to rtol: stopped by the time limit after S s" or "… interrupted after S s"
#: (Ctrl-C).
STOPPED_WORDS = ("stopped by the time limit", "interrupted after")


def stopped_early(continuous) -> bool:
    """Whether the continuous loop stopped before its certificate closed because of the time
    limit or Ctrl-C (its ``reason``, :data:`STOPPED_WORDS`); false for a certified result."""
    return not continuous.certified and any(words in continuous.reason
                                            for words in STOPPED_WORDS)


def stop_code(continuous) -> int:
    """The exit code after the outputs of a continuous allocation are written: 0, or
    :data:`STOPPED` with a line on stderr when its certification was
    stopped by ``--time-limit`` or Ctrl-C (:func:`stopped_early`); None (no continuous
    loop ran): 0."""
    if continuous is None or not stopped_early(continuous):
        return 0
    print(f"precrel: certification stopped ({continuous.reason}); the best allocation so "
          f"far is written, marked not certified (exit code {STOPPED})", file=sys.stderr)
    return STOPPED


def add_executor(parser) -> None:
    """``--executor``, ``--workers`` and ``--scheduler``: where independent tasks run
    (see :func:`executor_kind`)."""
    _shared(parser.add_argument(
        "--executor", choices=EXECUTORS, default=None,
        help="where the tasks run: serial (the default), processes (a local process pool) "
             "or dask (a local cluster of --workers workers, or the scheduler at "
             "--scheduler); the result is the same"), "add_executor")
    _shared(parser.add_argument(
        "--workers", type=positive_int, default=None, metavar="N",
        help=f"processes or local Dask workers (default: the number of CPUs for "
             f"processes, {DASK_WORKERS} for dask)"), "add_executor")
    _shared(parser.add_argument(
        "--scheduler", default=None, metavar="ADDRESS",
        help="address of a running Dask scheduler, e.g. tcp://10.0.0.5:8786 (--executor "
             "dask implied)"), "add_executor")


def executor_kind(args, kinds=EXECUTORS, where: str = "") -> str:
    """``--executor``, with ``dask`` implied by ``--scheduler``, after checking that
    ``--executor``, ``--workers`` and ``--scheduler`` go together and that the executor is
    one of ``kinds``, those the command can use (``where`` names the command's mode in the
    refusal)."""
    kind = "dask" if args.executor is None and args.scheduler is not None else \
        args.executor or "serial"
    if kind not in kinds:
        raise InputError(f"--executor {kind}: not available{where}; use "
                         f"{' or '.join(kinds)}")
    if args.scheduler is not None and kind != "dask":
        raise InputError(f"--scheduler needs --executor dask (or no --executor); got "
                         f"--executor {kind}")
    if args.workers is not None and kind == "serial":
        pools = " or ".join(k for k in kinds if k != "serial")
        raise InputError(f"--workers needs --executor {pools}: it sizes the pool or the "
                         f"local Dask cluster")
    if args.workers is not None and args.scheduler is not None:
        raise InputError(f"--workers sizes a local Dask cluster; the scheduler at --scheduler "
                         f"{args.scheduler} has its own workers: give one of the two")
    return kind


def add_certify(parser, what: str) -> None:
    """``--certify`` (doing ``what``) and its ``--rtol``."""
    parser.add_argument("--certify", action="store_true", help=what)
    add_rtol(parser)


def add_monte_carlo(parser) -> None:
    """``--repeats``, ``--samples`` and ``--seed`` of the Monte-Carlo verification."""
    parser.add_argument("--repeats", type=experiments, default=20, metavar="N",
                        help="grid experiments per allocation (default 20, as the paper's "
                             "Table 9)")
    parser.add_argument("--samples", type=positive_int, default=20_000, metavar="N",
                        help="Monte-Carlo samples at random poses and at each worst pose "
                             "(default 20000)")
    add_seed(parser)


#: The input files several commands read: option -> (metavar, what the file is).
INPUT_FILES = {
    "--catalogue": ("CAT.toml", "a catalogue of classes per component (docs/catalogue.md)"),
    "--tests": ("TESTS.toml", ("ISO 230 acceptance tests ([[tests]] tables, "
                               "docs/acceptance.md)")),
    "--compensation": ("PLAN.toml", ("a measurement plan with a [compensation] table "
                                     "(docs/compensation.md)")),
}


def add_input_file(parser, option: str, use: str, *, required: bool = False):
    """An input file of :data:`INPUT_FILES` (one metavar and kind everywhere); ``use``
    says what this command does with it."""
    metavar, kind = INPUT_FILES[option]
    return _shared(parser.add_argument(option, required=required, metavar=metavar,
                                       help=f"{kind}: {use}"), "add_input_file")


def add_suggest(parser):
    """``--suggest P``: suggested limits of acceptance-test results."""
    return _shared(parser.add_argument(
        "--suggest", type=probability, metavar="P",
        help="add to each acceptance-test result the limit that a share P of the built "
             "machines meet (its P-quantile, with a distribution-free 95 %% interval), and "
             "the probability of passing each test with them"), "add_suggest")


# ----- old spellings, kept for one release ----------------------------------------------
class Deprecated(argparse.Action):
    """An old spelling of an option: it still works, storing into the new option's
    ``dest`` (``const`` when it takes no value), and prints one line
    ``precrel: warning: OLD is deprecated; use NEW`` on stderr."""

    def __init__(self, option_strings, dest, *, replacement: str, nargs=None, const=None,
                 **kwargs):
        super().__init__(option_strings, dest, nargs=nargs, const=const, **kwargs)
        self.replacement = replacement

    def __call__(self, parser, namespace, values, option_string=None):
        warn_deprecated(option_string, self.replacement)
        setattr(namespace, self.dest, self.const if self.nargs == 0 else values)


def warn_deprecated(old: str, new: str) -> None:
    """The one line an old spelling prints on stderr, naming the new one."""
    print(f"precrel: warning: {old} is deprecated; use {new}", file=sys.stderr, flush=True)


def add_deprecated(parser, old: str, replacement: str, dest: str, **kwargs):
    """Declare ``old`` as a deprecated spelling of ``replacement`` (its value goes to
    ``dest``; ``nargs=0, const=...`` for a flag)."""
    return parser.add_argument(old, dest=dest, action=Deprecated, replacement=replacement,
                               help=f"deprecated; use {replacement}", **kwargs)


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


def beside_destination(out: Path, name: str, overwrite: bool, *, override=None,
                       option: str | None = None) -> Path:
    """Where the file ``name`` written beside the ``--out`` file ``out`` goes, checked
    before any work: ``override`` (given by ``option``, e.g. ``--drawing``) else
    :func:`beside`; it must differ from ``out``."""
    if override is None:
        path = beside(out, name)
        try:
            return destination(path, overwrite)
        except InputError:
            if not path.is_file():
                raise
            raise InputError(f"--out {out}: its {name} file {path} exists (an earlier run "
                             f"with the same --out); pass --overwrite to replace both") from None
    path = destination(override, overwrite, option)
    if path.resolve() == out.resolve():
        raise InputError(f"{option} {path} is also --out; give it another name")
    return path


def allocation_machine(args):
    """:func:`machine` for ``allocate``: every ``--lock`` name checked (an InputError names
    the unknown one) and ``--target`` applied to the six outputs when given."""
    loaded = machine(args)
    for name in args.lock:
        if name not in loaded.error_names:
            raise InputError(f"--lock: unknown error {name!r}; the machine's errors are "
                             f"named like {loaded.error_names[0]!r}")
    if args.target is None:
        return loaded
    return dataclasses.replace(loaded, targets=np.full(6, args.target))


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
                disable=None if _SHOWN.get() else True)


def print_warnings(texts) -> None:
    """Each text as one line ``warning: ...`` on stderr; the work goes on."""
    for text in texts:
        print(f"warning: {text}", file=sys.stderr, flush=True)


#: Whether progress lines and bars are shown (``--quiet``: not); see :func:`progress_shown`.
_SHOWN = contextvars.ContextVar("progress_shown", default=True)


@contextlib.contextmanager
def progress_shown(shown: bool):
    """While the context runs, :func:`say` and :func:`progress_bar` print (``shown``) or
    keep silent (``--quiet``)."""
    token = _SHOWN.set(bool(shown))
    try:
        yield
    finally:
        _SHOWN.reset(token)


def say(text: str) -> None:
    """A progress line on stderr (none under ``--quiet``)."""
    if _SHOWN.get():
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
    group = parser.add_mutually_exclusive_group(required=required)
    _shared(group.add_argument("--identification", metavar="DIR",
                               help="this machine as measured: the folder 'precrel identify "
                                    "--out' wrote (docs/measurements.md)"), "add_as_measured")
    add_measurements(group)


def add_measurements(parser, *, required: bool = False):
    """``--measurements meas.csv``: this machine's readings."""
    return _shared(parser.add_argument(
        "--measurements", required=required, metavar="meas.csv",
        help="this machine's measurement file (docs/measurements.md), identified under "
             "--profile (constant or gp:<length mm>) with the allocation in force as prior"),
        "add_measurements")


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
