"""Where every random draw comes from: one door for ``rng=``, two rules for extra streams.

Every function of the toolkit that draws takes ``rng=None`` and passes it through
:func:`generator`, the only place an argument becomes a :class:`numpy.random.Generator`.
Extra, independent streams come from one of two named rules, so a reader can tell from
the call which draws a number depends on:

- :func:`spawn` — ``n`` children of a seed or generator, for the steps of one computation
  (:func:`verification_streams`, ``spawn(seed, 4)``, gives the grid, random-pose,
  worst-pose and machine-yield streams of a verification; the first three are those of
  ``spawn(seed, 3)``; :func:`yield_allocation_streams`, ``spawn(seed, 4)``, the samples of
  an allocation for a machine-yield target);
- :func:`extra_stream` — stream ``index`` of the family ``[seed, 1]``, for work added on top
  of a computation that already consumes ``spawn(seed, ...)``, so that adding it changes none
  of the earlier numbers (the optional report sections, ``precrel verify --precision`` and
  ``--rare``).

A function whose named streams need the integer itself (they are derived from it, not from
a generator) takes it as ``rng`` too and reads it with :func:`integer_seed`: an integer, or
None for a fresh one that the result records; a Generator is refused by name.

Each quantity a report prints draws from one named stream of the report's seed, the same
stream the command that computes that quantity alone draws from: :func:`machine_yield_stream`
(the machine yield, ``precrel verify``), :func:`acceptance_stream` (acceptance tests, ``precrel
acceptance``), :func:`system_stream`, :func:`rare_stream`, :func:`profiles_stream` and
:func:`catalogue_stream` (docs/reproducibility.md has the whole mapping).

The Monte-Carlo verification of an allocation with seed ``S`` draws from
:func:`verification_streams` of ``S`` wherever it runs: ``precrel verify --seed S``, both
allocations of ``precrel report --seed S``, a sweep task with seed ``S`` (its grid
experiments) and :func:`reliability.sampling.verification.verify` with ``rng=S``. The same seed and
allocation therefore give the same numbers in Python, on the command line and in a sweep,
on any machine (numpy's ``SeedSequence`` and ``PCG64`` are platform independent).
"""

from __future__ import annotations

import numbers

import numpy as np

from .errors import InputError, InputTypeError

#: The entropy word that marks :func:`extra_stream`'s family beside the seed.
EXTRA_FAMILY = 1


def generator(rng, name: str = "rng") -> np.random.Generator:
    """A generator from ``None``, a non-negative int, a SeedSequence, a BitGenerator or a
    Generator (returned as is, so its state is shared with the caller).

    Raises
    ------
    InputTypeError
        ``rng`` is of another type (a float, a string, a bool).
    InputError
        ``rng`` is a negative integer.
    """
    if rng is None or isinstance(rng, (np.random.Generator, np.random.SeedSequence,
                                       np.random.BitGenerator)):
        return np.random.default_rng(rng)
    if isinstance(rng, (bool, np.bool_)) or not isinstance(rng, numbers.Integral):
        raise InputTypeError(f"{name} must be None, a non-negative integer seed, a "
                             f"numpy SeedSequence or a Generator; got {rng!r} "
                             f"({type(rng).__name__})")
    if rng < 0:
        raise InputError(f"{name} seed must be a non-negative integer; got {rng}")
    return np.random.default_rng(int(rng))


def spawn(rng, n: int, name: str = "rng") -> list[np.random.Generator]:
    """``n`` independent child generators of ``rng`` (see :meth:`Generator.spawn`).

    ``spawn(seed, n)[i]`` is the same stream for every ``n > i``.
    """
    return generator(rng, name).spawn(n)


def extra_stream(seed: int, index: int) -> np.random.Generator:
    """Stream ``index`` of the extra family of ``seed``: ``SeedSequence([seed, 1],
    spawn_key=(index,))``, independent of every stream :func:`spawn` derives from ``seed``.

    The extra streams in use: 0, :func:`system_stream`; 1, :func:`rare_stream`; 2,
    :func:`profiles_stream`; 3, :func:`catalogue_stream`; 4, :func:`sensitivity_stream`;
    5, :func:`zone_stream`; 6, this machine as measured
    (``studies.workflows.as_measured.AS_MEASURED_STREAM``); 7, the compensated machines of
    ``precrel verify --compensation`` (``studies.cli.compensate.VERIFY_STREAM``); 8,
    :func:`compensated_acceptance_stream`.
    """
    seed = _seed(seed)
    return np.random.default_rng(np.random.SeedSequence([seed, EXTRA_FAMILY],
                                                        spawn_key=(int(index),)))


def verification_streams(rng) -> list[np.random.Generator]:
    """The grid-experiment, random-pose, worst-pose and machine-yield streams of a
    Monte-Carlo verification with seed (or generator) ``rng``: ``spawn(rng, 4)``, whichever
    command runs it (the first three are ``spawn(rng, 3)``, as before the yield was
    added)."""
    return spawn(rng, 4)


def machine_yield_stream(seed) -> np.random.Generator:
    """The machine-yield stream of seed ``seed``: the fourth of :func:`verification_streams`,
    drawn by the yield of ``precrel verify --seed S``, of both allocations of ``precrel report
    --seed S`` and by :func:`reliability.sampling.machine_yield.machine_yield` with this
    stream as ``rng``."""
    return verification_streams(_seed(seed))[3]


def acceptance_stream(seed) -> np.random.Generator:
    """The acceptance-test stream of seed ``seed``: the seed's own generator, drawn by
    ``precrel acceptance --seed S`` and, afresh for each allocation, by the acceptance-test
    section of ``precrel report --seed S``, so that the report's numbers of an allocation
    are those of the command given that allocation."""
    return generator(_seed(seed), "seed")


def system_stream(seed) -> np.random.Generator:
    """The system-reliability stream of seed ``seed`` (extra stream 0): the report's
    system-reliability section and ``precrel verify --precision``."""
    return extra_stream(seed, 0)


def rare_stream(seed) -> np.random.Generator:
    """The rare-event stream of seed ``seed`` (extra stream 1): the report's rare-event
    section and ``precrel verify --rare``."""
    return extra_stream(seed, 1)


def profiles_stream(seed) -> np.random.Generator:
    """The stream of each grid experiment of the error-profile comparison with seed
    ``seed`` (extra stream 2; :func:`studies.workflows.profile_comparison.profile_comparison`,
    afresh for every allocation, profile and number of experiments)."""
    return extra_stream(seed, 2)


def catalogue_stream(seed) -> np.random.Generator:
    """The stream of the component-choice section's Monte-Carlo with seed ``seed`` (extra
    stream 3; :func:`studies.report.catalogue_section.catalogue_section`)."""
    return extra_stream(seed, 3)


def yield_allocation_streams(seed) -> list[np.random.Generator]:
    """The design, verification, shape-design, bootstrap, calibration and convex-step
    streams of an allocation for a machine-yield target with seed ``seed``:
    ``spawn(seed, 6)`` (the first five are those of ``spawn(seed, 5)``).

    :func:`allocation.allocate_for_yield` draws the standard normal draws of its four
    samples of built machines, once each, from the first, second, third and fifth
    (:meth:`reliability.sampling.machine_yield.YieldModel.draws`), and the machines of its
    convex steps from the sixth; the paired comparison
    :func:`allocation.machine_yield.yield_margin.equal_yield_margin` with seed ``S`` uses the
    second of ``S`` (its shared sample) and the fourth (the bootstrap's Poisson weights).
    """
    return spawn(seed, 6, "seed")


def integer_seed(rng, name: str = "rng") -> int:
    """The integer seed a function's named streams derive from: ``rng`` itself, or a fresh
    one drawn from the operating system's entropy when ``rng`` is None (so that a result
    recording its seed can be reproduced).

    Parameters
    ----------
    rng : None or int
        A non-negative integer seed, or None.
    name : str
        The argument's name in messages.

    Returns
    -------
    int

    Raises
    ------
    InputTypeError
        ``rng`` is a Generator (or anything else that is not an integer): named streams
        derive from an integer seed (:func:`spawn`, :func:`extra_stream`), which a
        Generator does not expose.
    InputError
        ``rng`` is a negative integer.
    """
    if rng is None:
        return int(np.random.default_rng().integers(2**63))
    if isinstance(rng, (bool, np.bool_)) or not isinstance(rng, numbers.Integral):
        raise InputTypeError(f"{name} must be None or a non-negative integer seed (the "
                             f"named streams derive from an integer seed, so a Generator "
                             f"is refused); got {rng!r} ({type(rng).__name__})")
    if rng < 0:
        raise InputError(f"{name} seed must be a non-negative integer; got {rng}")
    return int(rng)


def _seed(seed) -> int:
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, numbers.Integral):
        raise InputTypeError(f"seed must be a non-negative integer; got {seed!r} "
                             f"({type(seed).__name__})")
    if seed < 0:
        raise InputError(f"seed must be a non-negative integer; got {seed}")
    return int(seed)


def sensitivity_stream(seed) -> np.random.Generator:
    """The yield-sensitivity stream of seed ``seed`` (extra stream 4): the built machines of
    ``precrel sensitivity --yield-gradient --seed S`` and of the report's "What each
    tolerance buys" section (``report --sensitivity --seed S``)."""
    return extra_stream(seed, 4)


def zone_stream(seed) -> np.random.Generator:
    """The work-zone stream of seed ``seed`` (extra stream 5): the built machines of the
    report's "The work zone" section (``report --seed S`` on a machine with a work zone)."""
    return extra_stream(seed, 5)


def compensated_acceptance_stream(seed) -> np.random.Generator:
    """The stream of the compensated machines' acceptance tests with seed ``seed`` (extra
    stream 8): ``precrel acceptance --compensation --seed S`` and, afresh for each
    allocation, the acceptance-test section of ``precrel report --seed S --tests
    --compensation``."""
    return extra_stream(seed, 8)
