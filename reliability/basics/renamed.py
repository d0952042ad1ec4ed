"""Renamed keywords: the one place an old keyword name is still accepted, for one release.

The toolkit names one idea one way: the grid size per axis is ``points`` (once
``points_per_axis``), randomness is ``rng`` (once ``seed`` where named streams derive from
an integer). A public function whose keyword was renamed carries :func:`renamed`, which
takes the old keyword, warns with a :class:`DeprecationWarning` naming both, and passes the
value on under the new name.
"""

from __future__ import annotations

import functools
import warnings

from .errors import InputTypeError


def renamed(old: str, new: str):
    """Decorator: accept keyword ``old`` as a deprecated spelling of keyword ``new``.

    Parameters
    ----------
    old : str
        The former keyword name.
    new : str
        The keyword the decorated function takes.

    Returns
    -------
    callable
        A decorator. Its function, called with ``old=value``, warns ``"old is deprecated;
        use new"`` (:class:`DeprecationWarning`) and is called with ``new=value``.

    Raises
    ------
    InputTypeError
        The decorated function is called with both ``old`` and ``new``.
    """
    def decorate(function):
        @functools.wraps(function)
        def wrapper(*args, **kwargs):
            return function(*args, **renamed_keywords(kwargs, old, new))
        return wrapper
    return decorate


def renamed_keywords(kwargs: dict, old: str, new: str, stacklevel: int = 3) -> dict:
    """``kwargs`` with ``old`` moved to ``new`` (a :class:`DeprecationWarning` when moved).

    Parameters
    ----------
    kwargs : dict
        Keyword arguments (or the keys of a file) as given.
    old, new : str
        The former and the current name.
    stacklevel : int
        Passed to :func:`warnings.warn`; the default points at the caller of a function
        decorated with :func:`renamed`.

    Returns
    -------
    dict
        A new dict; ``kwargs`` itself is untouched.

    Raises
    ------
    InputTypeError
        Both ``old`` and ``new`` are in ``kwargs``.
    """
    if old not in kwargs:
        return kwargs
    if new in kwargs:
        raise InputTypeError(f"{old} and {new} were both given; {old} is deprecated, "
                             f"give {new} only")
    warnings.warn(f"{old} is deprecated; use {new}", DeprecationWarning,
                  stacklevel=stacklevel)
    moved = dict(kwargs)
    moved[new] = moved.pop(old)
    return moved
