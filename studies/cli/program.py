"""The ``precrel`` command line: precision reliability and allocation of your own machine.

Each subcommand is a module ``studies.cli.<name>`` with ``add_parser(subparsers)``
(registers the command, its options and help) and ``run(args) -> int`` (the exit code).
Results go to stdout, progress to stderr (none with ``--quiet``). Bad input and the
toolkit's own errors end the program with one line ``precrel: error: ...`` on stderr and
exit code 2; a certification stopped by ``--time-limit`` or Ctrl-C, with its outputs
written, exits with :data:`studies.cli.options.STOPPED` (3).
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import sys

from studies.workflows.timing import limit_blas_threads

#: Subcommand modules under ``studies.cli``, in the order ``--help`` lists them.
COMMANDS = ("check", "predict", "allocate", "choose", "verify", "report", "front", "sweep",
            "acceptance")
COMMANDS += ("sensitivity",)
COMMANDS += ("measure",)
COMMANDS += ("identify",)
COMMANDS += ("plan",)
COMMANDS += ("compensate",)
COMMANDS += ("evaluate",)
COMMANDS += ("life",)
PROG = "precrel"
#: Exit code of bad input (argparse's own convention).
USAGE_ERROR = 2


class ArgumentParser(argparse.ArgumentParser):
    """An argparse parser whose errors are one line on stderr, exit code 2.

    The line starts with ``name:``, the program's name (``precrel`` for every subcommand).
    """

    def __init__(self, *args, name: str = PROG, **kwargs):
        super().__init__(*args, **kwargs)
        self.name = name

    def error(self, message):
        self.exit(USAGE_ERROR, f"{self.name}: error: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    """The parser with every subcommand of :data:`COMMANDS` registered."""
    parser = ArgumentParser(
        prog=PROG,
        description="Precision reliability and precision allocation of a multi-axis "
                    "machine tool described in a TOML file.")
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in COMMANDS:
        module = importlib.import_module(f"studies.cli.{name}")
        sub = module.add_parser(subparsers)
        sub.set_defaults(run=module.run)
    return parser


def _toolkit_errors() -> tuple[type[BaseException], ...]:
    from allocation import InfeasibleAllocationError
    from reliability.basics.errors import InputError, InputTypeError, SavedResultError
    from reliability.basics.errors import MachineDescriptionError
    return (InputError, InputTypeError, SavedResultError, MachineDescriptionError,
            InfeasibleAllocationError, OSError)


def main(argv=None) -> int:
    """Run ``precrel`` with ``argv`` (default ``sys.argv[1:]``); return the exit code."""
    limit_blas_threads()
    from threadpoolctl import threadpool_limits

    try:
        args = build_parser().parse_args(argv)
    except SystemExit as exit_:  # --help, or a usage error already printed
        return int(exit_.code or 0)
    from . import options

    try:
        with threadpool_limits(limits=1), _reader_may_leave(), \
                options.progress_shown(not getattr(args, "quiet", False)):
            return int(args.run(args))
    except _toolkit_errors() as exc:
        print(f"{PROG}: error: {_one_line(exc, args)}", file=sys.stderr)
        return USAGE_ERROR
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted", file=sys.stderr)
        return 130


class _ReaderMayLeave:
    """Standard output that keeps the command running when its reader leaves (``precrel
    allocate ... | head``): the lines after that are dropped, the files are still written."""

    def __init__(self, stream):
        self.stream, self.gone = stream, False

    def write(self, text: str) -> int:
        if not self.gone:
            try:
                self.stream.write(text)
            except BrokenPipeError:
                self.gone = True
        return len(text)

    def flush(self) -> None:
        if not self.gone:
            try:
                self.stream.flush()
            except BrokenPipeError:
                self.gone = True

    def __getattr__(self, name):
        return getattr(self.stream, name)


@contextlib.contextmanager
def _reader_may_leave():
    """:class:`_ReaderMayLeave` in place of ``sys.stdout`` while a command runs."""
    kept = sys.stdout
    sys.stdout = _ReaderMayLeave(kept)
    try:
        yield
    finally:
        sys.stdout = kept


def _one_line(exc: BaseException, args) -> str:
    from allocation import TargetUnreachableError

    text = " ".join(str(exc).split()) or type(exc).__name__
    if isinstance(exc, OSError) and exc.filename and str(exc.filename) not in text:
        text = f"{exc.filename}: {text}"
    if isinstance(exc, TargetUnreachableError):
        text += f"; {_box_advice(args)}"
    return text


def _box_advice(args) -> str:
    """:func:`options.wider_box_advice` for the command's machine and ``--bounds``."""
    from . import options

    try:
        machine = options.machine(args)
    except (AttributeError, *_toolkit_errors()):
        return "a wider box (--bounds LO HI, factors of the initial allocation) may reach it"
    return options.wider_box_advice(machine, getattr(args, "bounds", None))


if __name__ == "__main__":
    sys.exit(main())
