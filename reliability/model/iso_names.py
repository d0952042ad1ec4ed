"""ISO 230-1 symbols for the geometric errors, beside the paper's names.

ISO 230-1 names a motion error of an axis ``E`` + *error direction* + *axis name*: the
direction is one of ``X Y Z`` (a translation along x, y, z) or ``A B C`` (a rotation about
x, y, z). So a linear axis X has ``EXX`` (positioning), ``EYX`` and ``EZX``
(straightness), ``EAX`` (roll), ``EBX`` and ``ECX`` (pitch and yaw, which is which depends
on the axis' orientation); a rotary axis C has ``EXC`` and ``EYC`` (radial), ``EZC``
(axial), ``EAC`` and ``EBC`` (tilt) and ``ECC`` (angular positioning).

In this toolkit an error component ``dx dy dz ex ey ez`` is a translation along, or a
rotation about, the x, y, z directions of the frame the error acts in (the axis' own
frame, Eq. 2), so the mapping is letter for letter::

    dx dy dz ex ey ez  ->  X Y Z A B C

and the motion error ``"<axis>.<comp>"`` is ``"E" + letter(comp) + axis``
(``X.dx`` = ``EXX``, ``X.ey`` = ``EBX``, ``C.ez`` = ``ECC``). The rule does not look at the
axis' name, only at its frame: for an axis named otherwise (``"M"``, ``"X2"``, ``"W"``) the
symbol is still E + direction + the axis' name (``M.ey`` = ``EBM``, ``X2.dx`` = ``EXX2``);
for a linear axis whose direction is ``d`` the positioning error is ``E<D><axis>``
(``D`` = ``d`` upper-cased).

Assembly (joint) errors. ISO 230-1 calls the position-independent errors of an axis
*location errors* and writes them with a ``0`` between direction and axis: ``EB0X`` is the
squareness of X about y, ``EX0C`` and ``EY0C`` the position of the C axis line, ``EA0C``
and ``EB0C`` its orientation. The paper's joint ``"<a>-<b>"`` holds the six errors that
place axis ``b`` on axis ``a`` (Eq. 14), in the frame of ``b`` before its motion, so this
toolkit names them as location errors of ``b``::

    "<a>-<b>.<comp>"  ->  "E" + letter(comp) + "0" + b      ("C-X.ey" = "EB0X")

ISO 230-1 keeps only the location errors that can be identified by measuring the
machine: for a linear axis its two squareness (orientation) errors, for a rotary axis two
position and two orientation errors (sometimes the zero position too). The paper keeps
all six per joint; the extra ones (a linear axis' position along itself, say) have no
ISO 230-1 meaning but keep their symbol here so every error has one.

Every function and file that takes an error name accepts either the paper's name or its
ISO symbol (:meth:`reliability.model.machine.Machine.error_index`).
"""

from __future__ import annotations

from ..basics.errors import InputError

#: ISO 230-1 direction letter of each error component.
ISO_DIRECTIONS = {"dx": "X", "dy": "Y", "dz": "Z", "ex": "A", "ey": "B", "ez": "C"}


def iso_symbol(name: str) -> str:
    """ISO 230-1 symbol of one error name of the paper's form.

    Parameters
    ----------
    name : str
        ``"<axis>.<comp>"`` (motion error) or ``"<a>-<b>.<comp>"`` (assembly error).

    Returns
    -------
    str
        ``"E" + direction + axis`` or ``"E" + direction + "0" + b``.

    Examples
    --------
    >>> iso_symbol("X.dx"), iso_symbol("C.ez"), iso_symbol("C-X.ey")
    ('EXX', 'ECC', 'EB0X')
    """
    owner, _, comp = name.rpartition(".")
    if not owner or comp not in ISO_DIRECTIONS:
        raise InputError(f"error name {name!r} is not of the form '<axis>.<comp>' or "
                         f"'<a>-<b>.<comp>' with comp in {tuple(ISO_DIRECTIONS)}")
    letter = ISO_DIRECTIONS[comp]
    if "-" in owner:
        return f"E{letter}0{owner.split('-')[-1]}"
    return f"E{letter}{owner}"


def iso_names(error_names) -> tuple[str, ...]:
    """ISO 230-1 symbols aligned with ``error_names``.

    Raises
    ------
    InputError
        When two errors would get the same symbol, or a symbol equals another error's
        paper name (possible only for axis names that begin with ``0``, e.g. an axis
        ``"0C"`` whose ``EX0C`` is also the C axis' location error).
    """
    names = tuple(error_names)
    symbols = tuple(iso_symbol(n) for n in names)
    seen = {}
    for name, symbol in zip(names, symbols):
        if symbol in seen:
            raise InputError(f"errors {seen[symbol]!r} and {name!r} would share the ISO 230-1 "
                             f"symbol {symbol!r}; rename the axis (axis names beginning "
                             f"with '0' clash with location-error symbols)")
        seen[symbol] = name
    clash = set(symbols) & set(names)
    if clash:
        raise InputError(f"ISO 230-1 symbol {sorted(clash)[0]!r} is also an error name")
    return symbols


def name_table(machine):
    """Paper name, ISO 230-1 symbol, owner and kind of every error, as a DataFrame."""
    import pandas as pd

    names = machine.error_names
    owners = [n.rpartition(".")[0] for n in names]
    return pd.DataFrame({
        "iso": iso_names(names),
        "owner": owners,
        "kind": ["assembly" if "-" in o else "motion" for o in owners],
    }, index=pd.Index(names, name="error"))
